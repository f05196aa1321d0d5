//! `gelrig protocols`.

use crate::cli::Exit;

use crate::protocol::shipped;

/// List the shipped protocols (run one by name: `gelrig run box-normal-flat`).
#[derive(clap::Args)]
pub(crate) struct Cmd {}

impl Cmd {
    pub(crate) fn run(self) -> anyhow::Result<Exit> {
        let Some(dir) = shipped::dir() else {
            err!(
                "error: the shipped protocols are not found: fix: set GELRIG_PROTOCOLS to the \
                 `protocols/` folder of a gelrig checkout"
            );
            return Ok(Exit::from(super::EXIT_INVALID));
        };
        let list = shipped::list();
        let width = list.iter().map(|p| p.name.len()).max().unwrap_or(0);
        for p in &list {
            out!("{:<width$}  {}", p.name, p.summary);
        }
        out!(
            "\n{} protocols in {}; run one by name: gelrig run {}",
            list.len(),
            dir.display(),
            list.first().map_or("NAME", |p| p.name.as_str())
        );
        Ok(Exit::SUCCESS)
    }
}
