//! gelrig's live view: while a run goes, the runner writes what it measures to a
//! [`Board`]; a [`Server`] on a thread of its own serves a page that plots it — the force
//! and torque against time with the steps shaded, the step, phase and time left, the settle
//! statistic against its threshold, force against position step by step, the latest frame
//! with its marker arrows and contact outline, the margin to each safety limit, lost force
//! records and dropped frames, the grasp's slip state. The same page shows finished runs
//! (`gelrig view`), read from their directories into a board.
//!
//! The page's script, styles and plotting library (uPlot 1.6.32, MIT, vendored) are compiled
//! into the binary: it works offline. It polls `state.json`, so a reload or a dropped
//! connection just resumes. The server only answers GET requests and holds no handle to
//! any device: the page can watch a run, never move anything.

mod assets;
pub mod board;
pub mod history;
pub mod overlay;
mod server;

pub use board::{Board, CurvePoint, Overlay, RunMeta, Tactile};
pub use server::{Library, RunEntry, Server};

/// Why the live view could not start.
#[derive(Debug, thiserror::Error)]
pub enum LiveError {
    /// The address could not be bound.
    #[error(
        "cannot serve the live view on {addr}: {cause}; fix: give another address, e.g. `127.0.0.1:0` for any free port"
    )]
    Bind {
        /// The address asked for.
        addr: String,
        /// Why (in the message: the CLI prints an error's chain, and this is its end).
        cause: std::io::Error,
    },
}
