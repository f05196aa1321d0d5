//! `gelrig probe`.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context as _;
use experiments::protocol::load_rig;
use simbench::bench::probe;

/// Check that every device of a rig file answers: identity, calibration, position.
#[derive(clap::Args)]
pub(crate) struct Cmd {
    /// The rig file.
    #[arg(value_name = "RIG.yaml")]
    rig: PathBuf,
}

impl Cmd {
    pub(crate) fn run(self) -> anyhow::Result<ExitCode> {
        let (rig, _) = match load_rig(&self.rig) {
            Ok(r) => r,
            Err(diags) => {
                super::report(&diags);
                return Ok(ExitCode::from(super::EXIT_INVALID));
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
            return Ok(ExitCode::SUCCESS);
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
        Ok(ExitCode::from(1))
    }
}
