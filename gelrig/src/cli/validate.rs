//! `gelrig validate`.

use crate::cli::Exit;
use std::path::PathBuf;

/// Check a protocol and its rig.
#[derive(clap::Args)]
pub(crate) struct Cmd {
    /// Protocol file.
    protocol: PathBuf,
    /// Rig file (default: the protocol's `rig:`).
    #[arg(long)]
    rig: Option<PathBuf>,
    #[command(flatten)]
    budget: super::BudgetArgs,
}

impl Cmd {
    pub(crate) fn run(self) -> anyhow::Result<Exit> {
        match super::load_or_report(&self.protocol, self.rig.as_deref(), &self.budget) {
            Ok(loaded) => {
                out!(
                    "{}: ok ({} steps on rig {}, {} warning(s))",
                    self.protocol.display(),
                    loaded.compiled.steps,
                    loaded.rig.name,
                    loaded.warnings.len()
                );
                Ok(Exit::SUCCESS)
            }
            Err(code) => Ok(code),
        }
    }
}
