//! `gelrig calibrate`.

use std::path::PathBuf;
use std::process::ExitCode;

use experiments::sensor::calibrate::{CalibrateOptions, Method};
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
    /// How the field becomes a wrench: `moments` (field moments, 2 µs a frame),
    /// `traction` (the inverse traction map on the contact, milliseconds a frame) or `scale`
    /// (the thesis's fit of the calibration contact's reference fields, superposed for
    /// combined loads).
    #[arg(long, default_value = "moments", value_parser = ["moments", "traction", "scale"])]
    method: String,
    /// The traction map's cell, mm [default: whichever of 1, 1.5 and 2 mm (each with its
    /// best support) gives the smallest held-out error].
    #[arg(long, value_name = "MM")]
    cell_mm: Option<f64>,
    /// The traction map's support: this many times the contact region's moment-equivalent
    /// ellipse [default: whichever of 1.1, 1.2, 1.3 and 1.5 gives the smallest held-out
    /// error].
    #[arg(long, value_name = "K")]
    support: Option<f64>,
    /// Fit each channel only on the features that turn as it does (Fx, Fy from the mean
    /// displacement, Fz from the radial spread, Tz from the curl): a shape or twist the
    /// calibration never saw does not leak into another channel. For a force sensor whose
    /// axes are the camera's (an indentation rig), not a jig whose sensor is turned.
    #[arg(long)]
    symmetric: bool,
}

impl Cmd {
    pub(crate) fn run(self) -> anyhow::Result<ExitCode> {
        let support_ok = self.support.is_none_or(|s| s.is_finite() && s >= 1.0);
        let cell_ok = self.cell_mm.is_none_or(|c| c.is_finite() && c >= 0.1);
        if !(cell_ok && support_ok) {
            let shown =
                |v: Option<f64>| v.map_or_else(|| "(chosen)".to_string(), |v| v.to_string());
            err!(
                "error: --cell-mm {} / --support {}: fix: a cell of at least 0.1 mm and a \
                 support of at least 1 contact radius",
                shown(self.cell_mm),
                shown(self.support)
            );
            return Ok(ExitCode::from(super::EXIT_INVALID));
        }
        let opts = CalibrateOptions {
            method: match self.method.as_str() {
                "traction" => Method::Traction,
                "scale" => Method::Scale,
                _ => Method::Moments,
            },
            cell_mm: self.cell_mm,
            support: self.support,
            symmetric: self.symmetric,
        };
        let sensor = match calibrate(&self.runs, &opts) {
            Ok(s) => s,
            Err(e @ SensorError::Write { .. }) => return Err(e.into()),
            Err(e) => {
                err!("error: {e}");
                return Ok(ExitCode::from(super::EXIT_INVALID));
            }
        };
        sensor.write(&self.out)?;
        out!(
            "calibrated on {} runs, {} frames{}; held out by {}:",
            sensor.calibrated_on.len(),
            sensor.model.samples,
            if sensor.symmetric {
                ", each channel on the features that turn as it does"
            } else {
                ""
            },
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
        match &sensor.relaxation {
            Some(terms) => out!(
                "gel relaxation (Fz read with its memory): g(t) = 1{}",
                terms
                    .iter()
                    .map(|t| format!(" + {:.3}·e^(−t/{:.1} s)", t.weight, t.tau_s))
                    .collect::<String>()
            ),
            None => out!(
                "gel relaxation: not fitted (no held pressing steps of 10 s or more): Fz is read \
                 from the field alone"
            ),
        }
        out!("wrote {}", self.out.display());
        Ok(ExitCode::SUCCESS)
    }
}
