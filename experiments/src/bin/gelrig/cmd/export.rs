//! `gelrig export`.

use std::path::PathBuf;
use std::process::ExitCode;

use experiments::export::{ExportError, export_mcap};

/// Write a run in a format other tools open: MCAP with ROS 2 messages (Foxglove, Rerun,
/// `ros2 bag play`).
#[derive(clap::Args)]
pub(crate) struct Cmd {
    /// The run directory.
    #[arg(value_name = "RUN_DIR")]
    run: PathBuf,
    /// The format: `mcap`.
    #[arg(long, default_value = "mcap", value_parser = ["mcap"])]
    format: String,
    /// The file to write [default: RUN_DIR/run.mcap].
    #[arg(long, value_name = "PATH")]
    out: Option<PathBuf>,
}

impl Cmd {
    pub(crate) fn run(self) -> anyhow::Result<ExitCode> {
        let out = self
            .out
            .clone()
            .unwrap_or_else(|| self.run.join("run.mcap"));
        match export_mcap(&self.run, &out) {
            Ok(e) => {
                for (topic, n) in &e.messages {
                    out!("{topic}: {n} messages");
                }
                out!("wrote {}", e.path.display());
                Ok(ExitCode::SUCCESS)
            }
            Err(e @ ExportError::Write { .. }) => Err(e.into()),
            Err(e) => {
                err!("error: {e}");
                Ok(ExitCode::from(super::EXIT_INVALID))
            }
        }
    }
}
