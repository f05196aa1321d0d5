//! `claims`: the figures gelrig publishes, held to account. Reads `claims.yaml` (every
//! headline figure of the README, the guide and BENCHMARKS: where it is printed, its value,
//! what a re-measurement must satisfy, the command that measures it, the test that guards
//! it), checks that each quote is still in its file and each guard test still exists, and
//! with `--quick` (CI) or `--all` re-measures the figures and compares.
//!
//! ```text
//! cargo run -p claims                 # the ledger against the text and the tests
//! cargo run -p claims -- --quick      # and re-measure the cheap figures
//! cargo run -p claims -- --quick --test-profile   # the same on `cargo test`'s build (CI)
//! cargo run --release -p claims -- --all --write docs/benchmarks/claims.md
//! ```
//!
//! Each command runs in its own process group, so that a timeout stops `cargo run` and the
//! program it started together; Ctrl-C stops `claims` but not the command it is waiting on
//! (its log, `target/claims/<id>.log`, names it).

mod ledger;
mod measure;
mod table;

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, Result};
use clap::Parser;

use ledger::Ledger;

#[derive(Parser)]
#[command(about = "Re-measure gelrig's published figures and compare them with the docs")]
struct Args {
    /// The ledger (default: claims.yaml at the repository's root).
    #[arg(long)]
    ledger: Option<PathBuf>,
    /// Re-measure the claims marked `quick` (seconds each).
    #[arg(long, conflicts_with = "all")]
    quick: bool,
    /// Measure with the test profile's build (`target/debug`, what `cargo test` has built)
    /// instead of a release build: for CI, whose `--quick` figures do not depend on the
    /// build's speed and are the same in either profile.
    #[arg(long, conflicts_with = "all")]
    test_profile: bool,
    /// Re-measure every claim that has a command (tens of minutes).
    #[arg(long)]
    all: bool,
    /// Only these claims (by id).
    #[arg(long)]
    only: Vec<String>,
    /// Write the table of this run (with its date and commit) as Markdown to this file.
    #[arg(long)]
    write: Option<PathBuf>,
}

fn main() -> ExitCode {
    match run(Args::parse()) {
        Ok(true) => ExitCode::SUCCESS,
        Ok(false) => ExitCode::FAILURE,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(2)
        }
    }
}

/// The repository's root: the folder holding `claims.yaml`, from here upwards.
fn root() -> Result<PathBuf> {
    let here = std::env::current_dir()?;
    let manifest = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    here.ancestors()
        .chain(manifest.ancestors())
        .find(|d| d.join("claims.yaml").is_file())
        .map(PathBuf::from)
        .context("no claims.yaml here or above: run from the gelrig repository")
}

fn run(args: Args) -> Result<bool> {
    let root = root()?;
    let path = args.ledger.unwrap_or_else(|| root.join("claims.yaml"));
    let ledger = Ledger::read(&path)?;
    if let Some(unknown) = args
        .only
        .iter()
        .find(|id| !ledger.claims.iter().any(|c| &c.id == *id))
    {
        anyhow::bail!(
            "--only {unknown}: no such claim in {} (its ids are the `id:` lines)",
            path.display()
        );
    }
    let problems = ledger::static_problems(&ledger, &root);
    for p in &problems {
        println!("ledger: {p}");
    }
    println!(
        "{} claims; {} ledger problems (quotes not in their files, guards that do not exist)",
        ledger.claims.len(),
        problems.len()
    );
    let chosen: Vec<&ledger::Claim> = ledger
        .claims
        .iter()
        .filter(|c| args.only.is_empty() || args.only.contains(&c.id))
        .filter(|c| {
            c.measure.is_some() && (args.all || (args.quick && c.quick) || !args.only.is_empty())
        })
        .collect();
    let mut rows = Vec::new();
    let mut runner = measure::Runner::new(&root, args.test_profile);
    for c in chosen {
        let Some(m) = &c.measure else { continue };
        println!("measuring {} …", c.id);
        let got = runner.run(&c.id, m);
        let row = table::Row::new(c, got);
        println!("  {}", row.line());
        rows.push(row);
    }
    let failed = rows.iter().filter(|r| !r.passed()).count();
    if !rows.is_empty() {
        println!("{} measured; {failed} do not hold", rows.len());
    }
    if let Some(out) = &args.write {
        let invocation = std::env::args()
            .skip(1)
            .fold(String::from("cargo run --release -p claims --"), |a, b| {
                a + " " + &b
            });
        let text = table::markdown(&ledger, &rows, &root, &invocation);
        std::fs::write(out, text).with_context(|| format!("{}", out.display()))?;
        println!("wrote {}", out.display());
    }
    Ok(problems.is_empty() && failed == 0)
}

#[cfg(test)]
mod tests {
    /// The repository's own ledger: it parses, and every quote is in its file and every guard
    /// test exists (so `cargo test` fails when the docs drift from it, as `claims` does).
    #[test]
    fn the_repositorys_ledger_matches_its_docs_and_tests() {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .parent()
            .expect("the repository");
        let ledger = crate::ledger::Ledger::read(&root.join("claims.yaml")).expect("the ledger");
        assert!(ledger.claims.len() >= 100, "{} claims", ledger.claims.len());
        let problems = crate::ledger::static_problems(&ledger, root);
        assert!(problems.is_empty(), "{problems:#?}");
    }
}
