//! `gelrig calibrate`.

use crate::cli::Exit;
use std::path::PathBuf;

use crate::force::calibrate::{CalibrateOptions, Method};
use crate::force::{SensorError, calibrate};

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
    /// combined loads) [default: whichever reads the indenters left out of the fit best,
    /// each in turn; with one indenter, the frames held out].
    #[arg(long, value_parser = ["moments", "traction", "scale"])]
    method: Option<String>,
    /// The traction map's cell, mm [default: chosen from 1, 1.5 and 2 mm as the method is].
    #[arg(long, value_name = "MM")]
    cell_mm: Option<f64>,
    /// The traction map's support: this many times the contact region's moment-equivalent
    /// ellipse [default: chosen from 1.1, 1.2, 1.3 and 1.5 as the method is].
    #[arg(long, value_name = "K")]
    support: Option<f64>,
    /// Fit each channel only on the features that turn as it does (Fx, Fy from the mean
    /// displacement, Fz from the radial spread, Tz from the curl): a shape or twist the
    /// calibration never saw does not leak into another channel. For a force sensor whose
    /// axes are the camera's (an indentation rig), not a jig whose sensor is turned:
    /// `--symmetric false` there [default: chosen as the method is].
    #[arg(long, num_args = 0..=1, default_missing_value = "true", value_name = "BOOL")]
    symmetric: Option<bool>,
}

impl Cmd {
    pub(crate) fn run(self) -> anyhow::Result<Exit> {
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
            return Ok(Exit::from(super::EXIT_INVALID));
        }
        let opts = CalibrateOptions {
            method: self.method.as_deref().map(|m| match m {
                "traction" => Method::Traction,
                "scale" => Method::Scale,
                _ => Method::Moments,
            }),
            cell_mm: self.cell_mm,
            support: self.support,
            symmetric: self.symmetric,
        };
        let sensor = match calibrate(&self.runs, &opts) {
            Ok(s) => s,
            Err(e @ SensorError::Write { .. }) => return Err(e.into()),
            Err(e) => {
                err!("error: {e}");
                return Ok(Exit::from(super::EXIT_INVALID));
            }
        };
        sensor.write(&self.out)?;
        report_choice(&sensor);
        out!(
            "calibrated on {} runs, {} frames; method {}{}; held out by {}:",
            sensor.calibrated_on.len(),
            sensor.model.samples,
            method_name(&sensor),
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
        match &sensor.unseen_shape {
            Some(u) => {
                out!("on shapes it never saw ({}):", u.by);
                for (c, s) in &u.channels {
                    out!(
                        "  {c:<7} rmse {:.4}  ({:.2} % of the calibrated span, {:.1} % of the \
                         reading), bias {:+.4}",
                        s.rmse,
                        s.pct_range,
                        100.0 * u.relative.get(c).copied().unwrap_or(0.0),
                        s.bias
                    );
                }
            }
            None => out!(
                "on shapes it never saw: unknown (no indenter could be left out: one \
                 indenter, or each the only one with its kind of load); a reading of another \
                 shape is flagged and its uncertainty widened by {:.0} % of the reading",
                100.0 * crate::force::envelope::UNKNOWN_SHAPE_SHARE
            ),
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
        Ok(Exit::SUCCESS)
    }
}

/// The method as the command line names it, with its settings.
fn method_name(sensor: &crate::force::SensorFile) -> String {
    use crate::force::file::{METHOD_SCALE, METHOD_TRACTION};
    match sensor.method.as_str() {
        METHOD_TRACTION => match &sensor.traction {
            Some(t) => format!("traction (cell {} mm, support {})", t.cell_mm, t.support),
            None => "traction".into(),
        },
        METHOD_SCALE => "scale".into(),
        _ => "moments".into(),
    }
}

/// How the method was chosen, candidate by candidate.
fn report_choice(sensor: &crate::force::SensorFile) {
    let Some(choice) = &sensor.chosen_by else {
        return;
    };
    out!(
        "chosen by the error {} (% of the calibrated span, summed over {}):",
        choice.by,
        choice.scored.join(", ")
    );
    for (k, c) in choice.candidates.iter().enumerate() {
        let settings = match (c.cell_mm, c.support) {
            (Some(cell), Some(k)) => format!(" cell {cell} mm support {k}"),
            _ => String::new(),
        };
        let channels: Vec<String> = c
            .pct_range
            .iter()
            .map(|(n, p)| format!("{n} {p:.2}"))
            .collect();
        out!(
            "  {} {}{}{}: {:.2}  ({})",
            if k == 0 { "*" } else { " " },
            c.method,
            if c.symmetric { " --symmetric" } else { "" },
            settings,
            c.score,
            channels.join(", ")
        );
    }
}
