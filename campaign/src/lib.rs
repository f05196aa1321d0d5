//! Campaigns: a protocol swept over its parameters (issue 51).
//!
//! - [`Sweep`]: the sweep file — the base protocol, fixed settings, and a [`Design`]
//!   (grid, list, random, Latin hypercube).
//! - [`points`]: the design's points, each named by its parameters with its `--set` pairs
//!   and seed.
//! - [`Shard`]: the points of one task of a job array (`--shard I/N`, Slurm, Kubernetes).
//! - [`Campaign`]: the campaign folder, each point's [`Outcome`], and `campaign.csv`.
//! - [`slurm`]: the `sbatch` scripts for a sweep.
//!
//! Running a point is the front end's (`gelrig sweep` runs each as its own `gelrig run`
//! process); this crate decides what to run and keeps what happened.

pub mod design;
pub mod outcome;
pub mod point;
pub mod shard;
pub mod slurm;
pub mod sweep;

pub use design::{Design, Params, Range};
pub use outcome::{Campaign, Outcome, write_atomic};
pub use point::{Point, points};
pub use shard::Shard;
pub use sweep::Sweep;

/// What a campaign refuses, naming the place and the fix.
#[derive(Debug, thiserror::Error)]
pub enum CampaignError {
    /// The sweep file cannot be read.
    #[error("cannot read {path}: {detail}; fix: check the path")]
    Read {
        /// The file.
        path: std::path::PathBuf,
        /// Why.
        detail: String,
    },
    /// The sweep file is not a sweep.
    #[error("{path}{}: {detail}", if key.is_empty() { String::new() } else { format!(", {key}") })]
    Sweep {
        /// The file.
        path: std::path::PathBuf,
        /// The key (dotted path) at fault, or empty for the file.
        key: String,
        /// What is wrong and what to write.
        detail: String,
    },
    /// A shard that cannot be.
    #[error("{0}")]
    Shard(String),
    /// A file of the campaign cannot be written.
    #[error(
        "cannot write {path}: {detail}; fix: check that the folder is writable and the disk not full"
    )]
    Write {
        /// The file.
        path: std::path::PathBuf,
        /// Why.
        detail: String,
    },
    /// Anything else, with its fix.
    #[error("{0}")]
    Other(String),
}
