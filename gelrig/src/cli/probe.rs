//! `gelrig probe`.

use crate::cli::Exit;
use std::path::PathBuf;

use crate::protocol::load_rig;
use crate::sim::bench::probe;
use anyhow::Context as _;

/// Check that every device of a rig file answers: identity, calibration, position.
#[derive(clap::Args)]
pub(crate) struct Cmd {
    /// The rig file.
    #[arg(value_name = "RIG.yaml")]
    rig: PathBuf,
}

impl Cmd {
    pub(crate) fn run(self) -> anyhow::Result<Exit> {
        let (rig, _) = match load_rig(&self.rig) {
            Ok(r) => r,
            Err(diags) => {
                super::report(&diags);
                return Ok(Exit::from(super::EXIT_INVALID));
            }
        };
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .context("starting the runtime")?;
        let results = rt.block_on(probe(&rig));
        let (mut silent, mut refused) = (Vec::new(), Vec::new());
        for p in &results {
            out!(
                "{:<9} {} {}",
                p.role,
                if p.ok { "ok  " } else { "FAIL" },
                p.detail
            );
            match (p.ok, p.silent) {
                (true, _) => {}
                (false, true) => silent.push(p.role.clone()),
                (false, false) => refused.push(p.role.clone()),
            }
        }
        if silent.is_empty() && refused.is_empty() {
            out!("every device answered");
            return Ok(Exit::SUCCESS);
        }
        if !silent.is_empty() {
            err!("error: no answer from: {}", silent.join(", "));
        }
        if !refused.is_empty() {
            err!(
                "error: answered but not ready: {} (what each said is above)",
                refused.join(", ")
            );
        }
        Ok(Exit::from(1))
    }
}
