//! `gelrig export`.

use crate::cli::Exit;
use std::path::PathBuf;

use crate::runs::export::{ExportError, export_mcap, export_parquet};

/// Write a run in a format other tools open: MCAP with ROS 2 messages (Foxglove, Rerun,
/// `ros2 bag play`), or Parquet tables (pandas; a folder of runs becomes one table per kind
/// with a `run` column).
#[derive(clap::Args)]
pub(crate) struct Cmd {
    /// The run directory (Parquet: also a folder of runs).
    #[arg(value_name = "RUN_DIR | RUNS_DIR")]
    run: PathBuf,
    /// The format: `mcap` or `parquet`.
    #[arg(long, default_value = "mcap", value_parser = ["mcap", "parquet"])]
    format: String,
    /// Where to write [default: RUN_DIR/run.mcap; Parquet: the folder RUN_DIR/parquet].
    #[arg(long, value_name = "PATH")]
    out: Option<PathBuf>,
}

impl Cmd {
    pub(crate) fn run(self) -> anyhow::Result<Exit> {
        if self.format == "parquet" {
            let out = self.out.clone().unwrap_or_else(|| self.run.join("parquet"));
            return match export_parquet(&self.run, &out) {
                Ok(e) => {
                    for (table, file, rows) in &e.tables {
                        out!("{table}: {rows} rows → {}", file.display());
                    }
                    out!("{} run(s) into {}", e.runs.len(), e.dir.display());
                    Ok(Exit::SUCCESS)
                }
                Err(e) => failed(e),
            };
        }
        let out = self
            .out
            .clone()
            .unwrap_or_else(|| self.run.join(crate::runs::names::MCAP));
        match export_mcap(&self.run, &out) {
            Ok(e) => {
                for (topic, n) in &e.messages {
                    out!("{topic}: {n} messages");
                }
                out!("wrote {}", e.path.display());
                Ok(Exit::SUCCESS)
            }
            Err(e) => failed(e),
        }
    }
}

/// A write failure is the command's error; a run that cannot be read, exit 2.
fn failed(e: ExportError) -> anyhow::Result<Exit> {
    match e {
        e @ ExportError::Write { .. } => Err(e.into()),
        e => {
            err!("error: {e}");
            Ok(Exit::from(super::EXIT_INVALID))
        }
    }
}
