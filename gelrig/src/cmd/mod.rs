//! One module per subcommand.

pub(crate) mod calibrate;
pub(crate) mod export;
pub(crate) mod fit_material;
pub(crate) mod plan;
pub(crate) mod probe;
pub(crate) mod protocols;
pub(crate) mod report;
pub(crate) mod resume;
pub(crate) mod run;
pub(crate) mod runs;
pub(crate) mod schema;
pub(crate) mod sim;
pub(crate) mod track;
pub(crate) mod validate;
pub(crate) mod view;

use std::path::Path;
use std::process::ExitCode;

use experiments::Diagnostic;
use experiments::protocol::compile::Budget;
use experiments::protocol::{Loaded, load_with_overrides};

/// Exit code for an invalid protocol or rig.
pub(crate) const EXIT_INVALID: u8 = 2;

/// How big a protocol may be, and what the command line changes in it: shared by
/// `validate`, `plan` and `run`, so a protocol that validates also plans and runs.
#[derive(clap::Args, Debug, Clone, Default)]
pub(crate) struct BudgetArgs {
    /// Most steps the protocol may expand into [default: 100000].
    #[arg(long, value_name = "N")]
    max_steps: Option<u64>,
    /// Most data the run may write by the plan's estimate, e.g. `500GB` [default: 100GB].
    #[arg(long, value_name = "SIZE", value_parser = Budget::parse_bytes)]
    max_data: Option<u64>,
    /// Set a value of the protocol without editing its file, e.g. `--set
    /// indenter.diameter=10mm` or `--set sequence.3.stepped.step=0.05mm` (repeatable; the
    /// edited protocol is what the run records).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<String>,
    /// Name the run (and its directory) instead of the protocol's name [default with --set:
    /// the protocol's name and a hash of the settings].
    #[arg(long, value_name = "NAME")]
    name: Option<String>,
}

impl BudgetArgs {
    /// `--name` was given.
    pub(crate) fn has_name(&self) -> bool {
        self.name.is_some()
    }

    pub(crate) fn budget(&self) -> Budget {
        let d = Budget::default();
        Budget {
            max_steps: self.max_steps.unwrap_or(d.max_steps),
            max_bytes: self.max_data.unwrap_or(d.max_bytes),
        }
    }
}

/// Loads a protocol within `budget`, printing diagnostics; `Err(code)` when it has errors.
pub(crate) fn load_or_report(
    protocol: &Path,
    rig: Option<&Path>,
    budget: &BudgetArgs,
) -> Result<Loaded, ExitCode> {
    let (protocol, by_name) = experiments::protocol::shipped::resolve(protocol);
    if by_name {
        err!("using the shipped protocol {}", protocol.display());
    }
    let overrides = experiments::protocol::Overrides {
        set: budget.set.clone(),
        name: budget.name.clone(),
    };
    match load_with_overrides(&protocol, rig, &budget.budget(), &overrides) {
        Ok(loaded) => {
            for w in &loaded.warnings {
                err!("{w}\n");
            }
            Ok(loaded)
        }
        Err(diags) => {
            report(&diags);
            Err(ExitCode::from(EXIT_INVALID))
        }
    }
}

/// Prints diagnostics and a count.
pub(crate) fn report(diags: &[Diagnostic]) {
    for d in diags {
        err!("{d}\n");
    }
    let errors = diags.iter().filter(|d| d.is_error()).count();
    let warnings = diags.len() - errors;
    err!("{errors} error(s), {warnings} warning(s)");
}

/// Starts the live view's server on `addr` (`HOST:PORT`; port 0 for a free one), warning
/// when the address is not loopback: anyone who can reach it can watch (never steer) the run.
pub(crate) fn serve(
    addr: &str,
    library: std::sync::Arc<dyn liveview::Library>,
) -> anyhow::Result<liveview::Server> {
    use anyhow::Context as _;
    let parsed: std::net::SocketAddr = addr.parse().with_context(|| {
        format!("`{addr}`: not an address; fix: write HOST:PORT, e.g. 127.0.0.1:8080 (port 0: any free port)")
    })?;
    if !parsed.ip().is_loopback() {
        err!(
            "warning: serving on {parsed}, not loopback: anyone who can reach this machine can watch (the page cannot move anything)"
        );
    }
    Ok(liveview::Server::start(parsed, library)?)
}
