//! `gelrig schema`.

use crate::cli::Exit;

/// Print the JSON Schema of protocol files (or rig files).
#[derive(clap::Args)]
pub(crate) struct Cmd {
    /// The rig-file schema instead of the protocol schema.
    #[arg(long)]
    rig: bool,
}

impl Cmd {
    pub(crate) fn run(self) -> anyhow::Result<Exit> {
        let schema = if self.rig {
            schemars::schema_for!(crate::protocol::RigConfig)
        } else {
            schemars::schema_for!(crate::protocol::schema::Protocol)
        };
        out!("{}", serde_json::to_string_pretty(&schema)?);
        Ok(Exit::SUCCESS)
    }
}
