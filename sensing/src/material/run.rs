//! One run as a material fit reads it, the axis whose position is the gel's depth, and ν as
//! fitted: what the fit and the choice of ν share.

use std::path::PathBuf;

use experiments::protocol::schema::MaterialSpec;

use super::law::ForceLaw;
use crate::run_data::RunData;

/// The axis whose position is the gel's depth. Not `grip`: in a grasp jig the grip's
/// closure is shared with the sponge in series, so its position is not the gel's depth.
pub(super) const PRESSING_AXES: [&str; 1] = ["normal"];

/// One run, read and understood.
pub(super) struct Run {
    pub(super) dir: PathBuf,
    pub(super) data: RunData,
    /// The material its protocol assumed.
    pub(super) assumed: MaterialSpec,
    /// The sensor's kind (`box`, `portable`).
    pub(super) sensor: String,
    /// Each step's move speed, axis unit/s (the protocol's).
    pub(super) speeds: std::collections::BTreeMap<u32, f64>,
    /// The speed of the approach that found the contact on a pressing axis, mm/s.
    pub(super) approach_speed: Option<f64>,
    /// The run's indenter and layer, whose elastic force law is built at any ν.
    pub(super) law: ForceLaw,
    /// The indenter, as its protocol gives it: runs of different indenters tell ν.
    pub(super) indenter: String,
    /// The camera's view on the gel, mm (width, height): the image scale of its frames.
    pub(super) view_mm: (f64, f64),
}

/// ν as fitted, and how.
pub(super) struct FittedNu {
    pub(super) nu: f64,
    pub(super) sd: f64,
    /// d ln E∞/dν, where the method found it (the forces' moduli); else from the laws.
    pub(super) per_nu: Option<f64>,
    /// How it was told, in words.
    pub(super) how: String,
}
