//! `gelrig report`.

use std::path::PathBuf;
use std::process::ExitCode;

use experiments::report::{ReportError, report};

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
}

impl Cmd {
    pub(crate) fn run(self) -> anyhow::Result<ExitCode> {
        match report(&self.run, self.out.as_deref()) {
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
