//! The `gelrig` command: one module per subcommand, each parsing its arguments and calling
//! the public API ([`crate`]). The `gelrig` binary and the Python package's `gelrig` script
//! both run [`main`].
//!
//! Exit codes: 0 success; 1 run failed or other error; 2 invalid protocol, rig or tracking
//! input (or bad command line); 3 run aborted by a safety limit or settle timeout; 130 run
//! interrupted.

/// `println!` that ends the program quietly when stdout is a closed pipe (`gelrig runs |
/// head`) instead of panicking; other write errors are ignored.
macro_rules! out {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        if let Err(e) = writeln!(std::io::stdout().lock(), $($arg)*)
            && e.kind() == std::io::ErrorKind::BrokenPipe
        {
            std::process::exit(0);
        }
    }};
}

/// `eprintln!` that never panics: a diagnostic to a closed stderr (`gelrig validate P
/// 2>&-`, a reader that went away) is dropped instead of aborting with exit 101.
macro_rules! err {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr().lock(), $($arg)*);
    }};
}

pub(crate) mod cache;
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
pub(crate) mod shape;
pub(crate) mod sim;
pub(crate) mod sweep;
pub(crate) mod track;
pub(crate) mod validate;
pub(crate) mod view;

use std::ffi::OsString;
use std::path::Path;

use clap::{Parser, Subcommand};

use crate::protocol::Budget;
use crate::protocol::Diagnostic;
use crate::protocol::{Loaded, load_with_overrides};

/// How a command ended: the process's exit code (see the module's doc).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Exit(pub u8);

impl Exit {
    /// Success.
    pub const SUCCESS: Exit = Exit(0);
}

impl From<u8> for Exit {
    fn from(code: u8) -> Self {
        Exit(code)
    }
}

impl From<Exit> for std::process::ExitCode {
    fn from(e: Exit) -> Self {
        std::process::ExitCode::from(e.0)
    }
}

#[derive(Parser)]
#[command(
    name = "gelrig",
    version,
    about = "Tactile-force experiments on GelSight sensors, from YAML protocols"
)]
struct Cli {
    /// Solve every contact table afresh instead of reading those an earlier run kept
    /// (`gelrig cache`); the results are the same either way.
    #[arg(long, global = true)]
    no_cache: bool,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Check a protocol and its rig; errors name file, line, column and the fix (exit 2).
    Validate(validate::Cmd),
    /// Expand a protocol into steps, with duration, frames and data volume.
    Plan(plan::Cmd),
    /// Run a protocol; the shipped protocols run on the simulated rig in virtual time.
    Run(run::Cmd),
    /// Continue an interrupted, aborted or failed run where it stopped, in its directory.
    Resume(resume::Cmd),
    /// List runs with their status (completed, aborted, failed, running, interrupted).
    Runs(runs::Cmd),
    /// List the shipped protocols (run one by name: `gelrig run box-normal-flat`).
    Protocols(protocols::Cmd),
    /// Print the JSON Schema of protocol files (or rig files), for editors.
    Schema(schema::Cmd),
    /// Track GelSight markers in frames or a run: markers.csv, optional field pictures.
    Track(track::Cmd),
    /// Analyse a run: relaxation, linearity, hysteresis, slip, force from field; report.html.
    Report(report::Cmd),
    /// Calibrate the GelSight as a force sensor on runs with frames and force: SENSOR.yaml.
    Calibrate(calibrate::Cmd),
    /// Fit the gel (modulus, relaxation, friction, ν) to a bench's runs: MATERIAL.yaml.
    FitMaterial(fit_material::Cmd),
    /// Write a run as MCAP with ROS 2 messages (Foxglove, Rerun, ros2 bag play) or Parquet.
    Export(export::Cmd),
    /// Open finished runs in the browser: runs with their status, plots, frames, reports.
    View(view::Cmd),
    /// Check that every device of a rig file answers (identity, calibration, position).
    Probe(probe::Cmd),
    /// Simulated devices on real transports: `gelrig sim serve --rig R.yaml`.
    Sim(sim::Cmd),
    /// The simulated bench's solved contact tables kept between runs: where, how big; clear.
    Cache(cache::Cmd),
    /// Height maps from frames (slopes from the lights' colours), calibrated on ball presses.
    Shape(shape::Cmd),
    /// A protocol run over a sweep of its parameters, here (-j N) or as a Slurm job array.
    Sweep(sweep::Cmd),
}

/// Runs the command line `args` (the program's name first, as `std::env::args_os` gives it)
/// and returns its exit code. A command line clap refuses prints its message (or the help)
/// and returns 2 (0 for `--help` and `--version`).
pub fn main<I, T>(args: I) -> Exit
where
    I: IntoIterator<Item = T>,
    T: Into<OsString> + Clone,
{
    let cli = match Cli::try_parse_from(args) {
        Ok(cli) => cli,
        Err(e) => {
            let _ = e.print();
            return Exit(if e.use_stderr() { 2 } else { 0 });
        }
    };
    if cli.no_cache {
        tablecache::disable();
    }
    let result = match cli.command {
        Command::Validate(c) => c.run(),
        Command::Plan(c) => c.run(),
        Command::Run(c) => c.run(),
        Command::Resume(c) => c.run(),
        Command::Runs(c) => c.run(),
        Command::Protocols(c) => c.run(),
        Command::Schema(c) => c.run(),
        Command::Track(c) => c.run(),
        Command::Report(c) => c.run(),
        Command::Calibrate(c) => c.run(),
        Command::FitMaterial(c) => c.run(),
        Command::Export(c) => c.run(),
        Command::View(c) => c.run(),
        Command::Probe(c) => c.run(),
        Command::Sim(c) => c.run(),
        Command::Cache(c) => c.run(),
        Command::Shape(c) => c.run(),
        Command::Sweep(c) => c.run(),
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            err!("error: {e:#}");
            Exit(1)
        }
    }
}

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
    /// How finely the simulated bench solves its contact: `fast` (a quarter of the cells across a
    /// curved contact and the field, for checking a protocol's logic), `default`, or `reference` (four times the cells); each
    /// level's error and cost: `gelrig plan` [default: the rig's `sim: {fidelity}`, else
    /// `default`]. The edited rig is what the run records.
    #[arg(long, value_name = "LEVEL")]
    fidelity: Option<crate::sim::Fidelity>,
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
) -> Result<Loaded, Exit> {
    let (protocol, by_name) = crate::protocol::shipped::resolve(protocol);
    if by_name {
        err!("using the shipped protocol {}", protocol.display());
    }
    let overrides = crate::protocol::Overrides {
        set: budget.set.clone(),
        name: budget.name.clone(),
        fidelity: budget.fidelity,
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
            Err(Exit::from(EXIT_INVALID))
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
    library: std::sync::Arc<dyn crate::live::Library>,
) -> anyhow::Result<crate::live::Server> {
    use anyhow::Context as _;
    let parsed: std::net::SocketAddr = addr.parse().with_context(|| {
        format!("`{addr}`: not an address; fix: write HOST:PORT, e.g. 127.0.0.1:8080 (port 0: any free port)")
    })?;
    if !parsed.ip().is_loopback() {
        err!(
            "warning: serving on {parsed}, not loopback: anyone who can reach this machine can watch (the page cannot move anything)"
        );
    }
    Ok(crate::live::Server::start(parsed, library)?)
}
