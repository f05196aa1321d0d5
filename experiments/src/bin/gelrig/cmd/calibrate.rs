//! `gelrig calibrate`.

use std::path::PathBuf;
use std::process::ExitCode;

use experiments::sensor::{SensorError, calibrate};

/// Learn the GelSight's map from marker field to force and torque on runs with frames and a
/// force sensor; write it as a sensor file with its held-out error.
#[derive(clap::Args)]
pub(crate) struct Cmd {
    /// Calibration run directories (normal, shear and rotation runs; several indenters).
    #[arg(value_name = "RUN_DIR", required = true)]
    runs: Vec<PathBuf>,
    /// The sensor file to write.
    #[arg(long, value_name = "SENSOR.yaml")]
    out: PathBuf,
}

impl Cmd {
    pub(crate) fn run(self) -> anyhow::Result<ExitCode> {
        let sensor = match calibrate(&self.runs) {
            Ok(s) => s,
            Err(e @ SensorError::Write { .. }) => return Err(e.into()),
            Err(e) => {
                err!("error: {e}");
                return Ok(ExitCode::from(super::EXIT_INVALID));
            }
        };
        sensor.write(&self.out)?;
        out!(
            "calibrated on {} runs, {} frames; held out by {}:",
            sensor.calibrated_on.len(),
            sensor.model.samples,
            sensor.held_out.by
        );
        for (c, s) in &sensor.held_out.channels {
            out!(
                "  {c:<7} rmse {:.4}  ({:.2} % of the calibrated span), bias {:+.4}",
                s.rmse,
                s.pct_range,
                s.bias
            );
        }
        out!("wrote {}", self.out.display());
        Ok(ExitCode::SUCCESS)
    }
}
