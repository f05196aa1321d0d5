//! `gelrig probe`.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context as _;
use experiments::bench::probe;
use experiments::protocol::load_rig;

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
        let mut failed = Vec::new();
        for p in &results {
            out!(
                "{:<9} {} {}",
                p.role,
                if p.ok { "ok  " } else { "FAIL" },
                p.detail
            );
            if !p.ok {
                failed.push(p.role.clone());
            }
        }
        if failed.is_empty() {
            out!("every device answered");
            Ok(ExitCode::SUCCESS)
        } else {
            err!("error: no answer from: {}", failed.join(", "));
            Ok(ExitCode::from(1))
        }
    }
}
