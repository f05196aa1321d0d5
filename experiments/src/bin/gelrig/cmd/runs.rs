//! `gelrig runs`.

use std::path::PathBuf;
use std::process::ExitCode;

/// List runs with their status.
#[derive(clap::Args)]
pub(crate) struct Cmd {
    /// Runs directory.
    #[arg(default_value = "runs")]
    dir: PathBuf,
}

impl Cmd {
    pub(crate) fn run(self) -> anyhow::Result<ExitCode> {
        let runs = experiments::runs::list(&self.dir).map_err(anyhow::Error::msg)?;
        if runs.is_empty() {
            out!("no runs in {}", self.dir.display());
            return Ok(ExitCode::SUCCESS);
        }
        out!(
            "{:<12} {:>7}  {:<22} {:<32} dir / note",
            "status",
            "steps",
            "protocol",
            "started"
        );
        for r in runs {
            let name = r
                .dir
                .file_name()
                .map(|n| n.to_string_lossy().to_string())
                .unwrap_or_default();
            out!(
                "{:<12} {:>7}  {:<22} {:<32} {name}",
                r.status,
                r.steps,
                r.protocol,
                r.started
            );
            if !r.note.is_empty() {
                out!("{:<12} {:>7}  {}", "", "", r.note);
            }
        }
        Ok(ExitCode::SUCCESS)
    }
}
