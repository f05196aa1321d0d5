//! `gelrig calibrate RUN_DIR… --out SENSOR.yaml`: the field-to-wrench model fitted on runs
//! with frames and a force sensor, its method and settings chosen by what it reads of the
//! indenters it leaves out of its fit ([`super::choose`]), its error measured on data held
//! out of the fit ([`super::fitting`]), from what it read of the runs ([`super::gather`]).

use std::path::PathBuf;

use super::{SensorError, SensorFile};

pub use super::choose::{CELLS, CalibrateOptions, Method, SUPPORTS};
pub use super::fitting::{span, stats};

/// Fits a sensor on `runs` (run directories; their frames are tracked first if they have
/// no `markers.csv`), choosing what `opts` leaves open.
pub fn calibrate(runs: &[PathBuf], opts: &CalibrateOptions) -> Result<SensorFile, SensorError> {
    let (gathered, first) = super::gather::gather(runs)?;
    super::choose::choose(&gathered, opts, first)
}
