//! `gelrig report`.

use std::path::PathBuf;
use std::process::ExitCode;

use experiments::report::{ReportError, report_with_sensor};
use experiments::sensor::SensorFile;

/// Turn a run directory into the thesis's results: report.html, report.md, plots and
/// summary.json.
#[derive(clap::Args)]
pub(crate) struct Cmd {
    /// The run directory (made by `gelrig run`, dry or real).
    #[arg(value_name = "RUN_DIR")]
    run: PathBuf,
    /// Where to write the report [default: RUN_DIR/report].
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// A calibrated sensor file (`gelrig calibrate`): add "GelSight force against the force
    /// sensor", the wrench read from the field scored against the force sensor.
    #[arg(long, value_name = "SENSOR.yaml")]
    sensor: Option<PathBuf>,
}

impl Cmd {
    pub(crate) fn run(self) -> anyhow::Result<ExitCode> {
        let sensor = match self.sensor.as_deref().map(SensorFile::read) {
            Some(Ok(s)) => Some(s),
            Some(Err(e)) => {
                err!("error: {e}");
                return Ok(ExitCode::from(super::EXIT_INVALID));
            }
            None => None,
        };
        let with = sensor.as_ref().zip(self.sensor.as_deref());
        match report_with_sensor(&self.run, self.out.as_deref(), with) {
            Ok(w) => {
                out!("sections: {}", w.sections.join("; "));
                out!("wrote {}", w.dir.join("report.html").display());
                Ok(ExitCode::SUCCESS)
            }
            Err(e @ ReportError::Write { .. }) => Err(e.into()),
            Err(e) => {
                err!("error: {e}");
                Ok(ExitCode::from(super::EXIT_INVALID))
            }
        }
    }
}
