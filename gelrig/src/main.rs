//! `gelrig`: run tactile-force experiments on GelSight sensors from YAML protocols.
//!
//! Thin by design: each subcommand parses its arguments and calls the `experiments` crate.
//! Exit codes: 0 success; 1 run failed or other error; 2 invalid protocol, rig or tracking
//! input (or bad command line); 3 run aborted by a safety limit or settle timeout; 130 run interrupted.

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

mod cmd;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(
    name = "gelrig",
    version,
    about = "Tactile-force experiments on GelSight sensors, from YAML protocols"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Check a protocol and its rig; errors name file, line, column and the fix (exit 2).
    Validate(cmd::validate::Cmd),
    /// Expand a protocol into steps, with duration, frames and data volume.
    Plan(cmd::plan::Cmd),
    /// Run a protocol; the shipped protocols run on the simulated rig in virtual time.
    Run(cmd::run::Cmd),
    /// Continue an interrupted, aborted or failed run where it stopped, in its directory.
    Resume(cmd::resume::Cmd),
    /// List runs with their status (completed, aborted, failed, running, interrupted).
    Runs(cmd::runs::Cmd),
    /// List the shipped protocols (run one by name: `gelrig run box-normal-flat`).
    Protocols(cmd::protocols::Cmd),
    /// Print the JSON Schema of protocol files (or rig files), for editors.
    Schema(cmd::schema::Cmd),
    /// Track GelSight markers in frames or a run: markers.csv, optional field pictures.
    Track(cmd::track::Cmd),
    /// Analyse a run: relaxation, linearity, hysteresis, slip, force from field; report.html.
    Report(cmd::report::Cmd),
    /// Calibrate the GelSight as a force sensor on runs with frames and force: SENSOR.yaml.
    Calibrate(cmd::calibrate::Cmd),
    /// Fit the gel (modulus, relaxation, friction, ν) to a bench's runs: MATERIAL.yaml.
    FitMaterial(cmd::fit_material::Cmd),
    /// Write a run as MCAP with ROS 2 messages (Foxglove, Rerun, ros2 bag play) or Parquet.
    Export(cmd::export::Cmd),
    /// Open finished runs in the browser: runs with their status, plots, frames, reports.
    View(cmd::view::Cmd),
    /// Check that every device of a rig file answers (identity, calibration, position).
    Probe(cmd::probe::Cmd),
    /// Simulated devices on real transports: `gelrig sim serve --rig R.yaml`.
    Sim(cmd::sim::Cmd),
}

/// mimalloc rather than the system allocator: a dry run allocates and frees frame-sized
/// buffers (a 640×480 frame's 3.7 MB of light levels, the field's transforms) at every frame,
/// and glibc returned them to the kernel and faulted them back each time: 11.8–22 s of
/// system time in a 40–62 s 10-trial lifting-can run (BENCHMARKS.md, "Grasp trials that
/// feel slip").
#[global_allocator]
static ALLOC: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn main() -> ExitCode {
    let cli = Cli::parse();
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
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            err!("error: {e:#}");
            ExitCode::from(1)
        }
    }
}
