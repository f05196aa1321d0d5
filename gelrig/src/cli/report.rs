//! `gelrig report`.

use crate::cli::Exit;
use std::path::PathBuf;

use crate::force::SensorFile;
use crate::reports::{ReportError, Written, report_with_sensor};

/// Turn a run directory into the thesis's results: report.html, report.md, plots and
/// summary.json.
#[derive(clap::Args)]
pub(crate) struct Cmd {
    /// The run directory (made by `gelrig run`, dry or real); several to compare them (each
    /// gets its own report, and `--out DIR` the comparison).
    #[arg(value_name = "RUN_DIR", required = true)]
    runs: Vec<PathBuf>,
    /// Where to write the report [default: RUN_DIR/report]; with several runs, where the
    /// comparison goes (required).
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// A calibrated sensor file (`gelrig calibrate`): add "GelSight force against the force
    /// sensor", the wrench read from the field scored against the force sensor.
    #[arg(long, value_name = "SENSOR.yaml")]
    sensor: Option<PathBuf>,
}

impl Cmd {
    pub(crate) fn run(self) -> anyhow::Result<Exit> {
        if self.runs.len() > 1 {
            return self.compare();
        }
        let run = self.runs[0].clone();
        let sensor = match self.sensor.as_deref().map(SensorFile::read) {
            Some(Ok(s)) => Some(s),
            Some(Err(e)) => {
                err!("error: {e}");
                return Ok(Exit::from(super::EXIT_INVALID));
            }
            None => None,
        };
        let with = sensor.as_ref().zip(self.sensor.as_deref());
        finish(report_with_sensor(&run, self.out.as_deref(), with))
    }

    /// `gelrig report RUN_A RUN_B … --out DIR`.
    fn compare(&self) -> anyhow::Result<Exit> {
        let Some(out) = &self.out else {
            err!(
                "error: {} runs to compare and no --out: fix: add --out DIR for the comparison",
                self.runs.len()
            );
            return Ok(Exit::from(super::EXIT_INVALID));
        };
        if self.sensor.is_some() {
            err!("error: --sensor reports one run: fix: report each run with its sensor");
            return Ok(Exit::from(super::EXIT_INVALID));
        }
        finish(crate::reports::compare(&self.runs, out))
    }
}

/// Prints what a report (or comparison) wrote, its headline numbers first; a write failure
/// is an error of the command, bad input exit 2.
fn finish(written: Result<Written, ReportError>) -> anyhow::Result<Exit> {
    match written {
        Ok(w) => {
            for line in crate::reports::headline(&w.summary) {
                out!("{line}");
            }
            out!("sections: {}", w.sections.join("; "));
            out!("wrote {}", w.dir.join("report.html").display());
            Ok(Exit::SUCCESS)
        }
        Err(e @ ReportError::Write { .. }) => Err(e.into()),
        Err(e) => {
            err!("error: {e}");
            Ok(Exit::from(super::EXIT_INVALID))
        }
    }
}
