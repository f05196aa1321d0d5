//! `gelrig plan`.

use crate::cli::Exit;
use std::path::PathBuf;

/// Expand a protocol into steps with duration, frames and data volume.
#[derive(clap::Args)]
pub(crate) struct Cmd {
    /// Protocol file.
    protocol: PathBuf,
    /// Rig file (default: the protocol's `rig:`).
    #[arg(long)]
    rig: Option<PathBuf>,
    #[command(flatten)]
    budget: super::BudgetArgs,
    /// Print the plan as JSON.
    #[arg(long)]
    json: bool,
}

impl Cmd {
    pub(crate) fn run(self) -> anyhow::Result<Exit> {
        let loaded = match super::load_or_report(&self.protocol, self.rig.as_deref(), &self.budget)
        {
            Ok(l) => l,
            Err(code) => return Ok(code),
        };
        let plan = loaded.plan.clone();
        if self.json {
            out!("{}", serde_json::to_string_pretty(&plan)?);
        } else {
            out!("{}", plan.render(&loaded.protocol, &loaded.rig).trim_end());
        }
        Ok(Exit::SUCCESS)
    }
}
