//! `gelrig validate`.

use std::path::PathBuf;
use std::process::ExitCode;

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
    pub(crate) fn run(self) -> anyhow::Result<ExitCode> {
        match super::load_or_report(&self.protocol, self.rig.as_deref(), &self.budget) {
            Ok(loaded) => {
                out!(
                    "{}: ok ({} steps on rig {}, {} warning(s))",
                    self.protocol.display(),
                    loaded.compiled.steps,
                    loaded.rig.name,
                    loaded.warnings.len()
                );
                Ok(ExitCode::SUCCESS)
            }
            Err(code) => Ok(code),
        }
    }
}
