//! `gelrig runs`.

use crate::cli::Exit;
use std::path::PathBuf;

/// List runs with their status.
#[derive(clap::Args)]
pub(crate) struct Cmd {
    /// Runs directory.
    #[arg(default_value = "runs")]
    dir: PathBuf,
}

impl Cmd {
    pub(crate) fn run(self) -> anyhow::Result<Exit> {
        if !self.dir.exists() {
            out!(
                "no runs: {} does not exist (`gelrig run P.yaml` records into runs/, or --out DIR)",
                self.dir.display()
            );
            return Ok(Exit::SUCCESS);
        }
        let runs = crate::runs::listing::list(&self.dir).map_err(anyhow::Error::msg)?;
        if runs.is_empty() {
            out!("no runs in {}", self.dir.display());
            return Ok(Exit::SUCCESS);
        }
        out!(
            "{:<12} {:>7}  {:<22} {:<32} {:>9} {:>6}  {:<18} dir / note",
            "status",
            "steps",
            "protocol",
            "started",
            "duration",
            "seed",
            "rig"
        );
        for r in runs {
            let name = r
                .dir
                .file_name()
                .map(|n| n.to_string_lossy().to_string())
                .unwrap_or_default();
            let duration = r.duration_s.map_or("—".into(), |d| {
                if d < 120.0 {
                    format!("{d:.1} s")
                } else if d < 7200.0 {
                    format!("{:.1} min", d / 60.0)
                } else {
                    format!("{:.1} h", d / 3600.0)
                }
            });
            out!(
                "{:<12} {:>7}  {:<22} {:<32} {:>9} {:>6}  {:<18} {name}",
                r.status,
                r.steps,
                r.protocol,
                r.started,
                duration,
                r.seed.map_or("—".into(), |s| s.to_string()),
                r.rig
            );
            if !r.note.is_empty() {
                out!("{:<12} {:>7}  {}", "", "", r.note);
            }
        }
        Ok(Exit::SUCCESS)
    }
}
