//! Shape from the GelSight's light (issue 50): the gel's slope read from the colour change of
//! each pixel, calibrated on presses of a ball of known size, and integrated into a height map.
//!
//! - [`Rgb`]: a frame as 8-bit RGB, and the colour change against the unpressed background.
//! - [`SlopeModel`]: what a colour change means as a slope. Two are fitted and compared:
//!   a lookup table over colour ([`lut`]), and a local-linear forward model whose response
//!   varies over the frame ([`local_linear`]).
//! - [`Integrator`]: slopes to heights (least squares, DCT, free borders).
//! - [`Depth`]: one frame through the whole chain, and its contact statistics.
//! - [`calibrate`]: fits both models on ball presses and scores each on presses left out.
//!
//! Pure: pixels in, numbers out; reading and writing files is the caller's (`sensing::shape`).

pub mod ball;
pub mod calibrate;
pub mod depth;
mod farfield;
pub mod find;
mod frame;
pub mod local_linear;
pub mod lut;
mod markers;
mod mask;
mod model;
mod poisson;

pub use calibrate::{Calibration, HeldOut, Press, PressScore, calibrate};
pub use depth::{Depth, DepthStats};
pub use find::find_circle;
pub use frame::Rgb;
pub use model::{ModelKind, SlopeMap, SlopeModel};
pub use poisson::Integrator;

/// What the shape chain refuses, naming the fix.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ShapeError {
    /// A frame whose size is not the calibration's or the background's.
    #[error(
        "the frame is {got_w}×{got_h} px, the {what} {want_w}×{want_h}: use frames of the sensor and size it was calibrated on"
    )]
    Size {
        /// What the frame was compared with.
        what: &'static str,
        /// Frame width.
        got_w: usize,
        /// Frame height.
        got_h: usize,
        /// Expected width.
        want_w: usize,
        /// Expected height.
        want_h: usize,
    },
    /// Pixel data that does not hold `width × height × 3` bytes.
    #[error(
        "{len} bytes for a {width}×{height} RGB frame (needs {need}): pass 8-bit RGB, 3 bytes a pixel"
    )]
    Bytes {
        /// Bytes given.
        len: usize,
        /// Width.
        width: usize,
        /// Height.
        height: usize,
        /// Bytes needed.
        need: usize,
    },
    /// Too little to calibrate on.
    #[error("{0}")]
    Calibration(String),
    /// No contact circle found in a press.
    #[error("no contact circle found: {0}")]
    Circle(String),
}
