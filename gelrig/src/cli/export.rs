//! `gelrig export`.

use crate::cli::Exit;
use std::path::PathBuf;

use crate::runs::export::{ExportError, export_dataset, export_mcap, export_parquet};

/// Write a run in a format other tools open: MCAP with ROS 2 messages (Foxglove, Rerun,
/// `ros2 bag play`), Parquet tables (pandas; a folder of runs or a sweep's campaign becomes
/// one table per kind with a `run` column and the sweep's parameters), or a learning dataset
/// (every frame and its labels, in Parquet shards Hugging Face `datasets` loads).
#[derive(clap::Args)]
pub(crate) struct Cmd {
    /// The run directory (Parquet and dataset: also a folder of runs, or a campaign).
    #[arg(value_name = "RUN_DIR | RUNS_DIR | CAMPAIGN")]
    run: PathBuf,
    /// The format: `mcap`, `parquet` or `dataset`.
    #[arg(long, default_value = "mcap", value_parser = ["mcap", "parquet", "dataset"])]
    format: String,
    /// Where to write [default: RUN_DIR/run.mcap; Parquet: the folder RUN_DIR/parquet;
    /// dataset: the folder RUN_DIR/dataset].
    #[arg(long, value_name = "PATH")]
    out: Option<PathBuf>,
}

impl Cmd {
    pub(crate) fn run(self) -> anyhow::Result<Exit> {
        if self.format == "dataset" {
            let out = self.out.clone().unwrap_or_else(|| self.run.join("dataset"));
            return match export_dataset(&self.run, &out) {
                Ok(e) => {
                    out!(
                        "{} frames of {} run(s) in {} shard(s) → {} (card: README.md)",
                        e.frames,
                        e.runs,
                        e.shards.len(),
                        e.dir.display()
                    );
                    Ok(Exit::SUCCESS)
                }
                Err(e) => failed(e),
            };
        }
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
