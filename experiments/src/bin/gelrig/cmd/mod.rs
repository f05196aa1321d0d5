//! One module per subcommand.

pub(crate) mod plan;
pub(crate) mod probe;
pub(crate) mod report;
pub(crate) mod run;
pub(crate) mod runs;
pub(crate) mod schema;
pub(crate) mod sim;
pub(crate) mod track;
pub(crate) mod validate;

use std::path::Path;
use std::process::ExitCode;

use experiments::Diagnostic;
use experiments::protocol::{Loaded, load};

/// Exit code for an invalid protocol or rig.
pub(crate) const EXIT_INVALID: u8 = 2;

/// Loads a protocol, printing diagnostics; `Err(code)` when it has errors.
pub(crate) fn load_or_report(protocol: &Path, rig: Option<&Path>) -> Result<Loaded, ExitCode> {
    match load(protocol, rig) {
        Ok(loaded) => {
            for w in &loaded.warnings {
                eprintln!("{w}\n");
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
        eprintln!("{d}\n");
    }
    let errors = diags.iter().filter(|d| d.is_error()).count();
    let warnings = diags.len() - errors;
    eprintln!("{errors} error(s), {warnings} warning(s)");
}
