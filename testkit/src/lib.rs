//! How gelrig's tests skip a check that cannot run on this machine — real GelSight frames in
//! `../shared/data`, a Python peer, a browser, a mount namespace — so that no skip goes
//! unseen and CI can forbid them.
//!
//! A skip is printed, and appended as a line to the skip log (`$GELRIG_SKIP_LOG`, else
//! `target/skipped-checks.txt`), which `.ci/run` counts and prints after the tests (libtest
//! hides what passing tests print). Under `GELRIG_REQUIRE_<NEED>=1` the same skip is a
//! failure naming what is missing: CI sets `GELRIG_REQUIRE_DATA`, `_PEERS`, `_BROWSER`,
//! `_MOUNT` and `_SLURM`.
//!
//! A dev-dependency only: nothing a user runs depends on it.

use std::io::Write;
use std::path::{Path, PathBuf};

/// What a check may need that a machine may lack; its name is the `GELRIG_REQUIRE_` switch.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Need {
    /// `../shared/data` beside the repository (real GelSight Mini frames).
    Data,
    /// Independent Python peers (FE oracles, pymodbus, MCAP/Parquet readers) and socat.
    Peers,
    /// A headless Chromium for the live view.
    Browser,
    /// A private mount namespace (`unshare -m`) for a small filesystem.
    Mount,
    /// A running Slurm (`sinfo` answers; `.ci/slurm up` starts one).
    Slurm,
}

impl Need {
    /// The switch's suffix: `GELRIG_REQUIRE_{name}`.
    pub fn name(self) -> &'static str {
        match self {
            Need::Data => "DATA",
            Need::Peers => "PEERS",
            Need::Browser => "BROWSER",
            Need::Mount => "MOUNT",
            Need::Slurm => "SLURM",
        }
    }

    /// Whether this run forbids skipping for want of it (`GELRIG_REQUIRE_<NAME>=1`).
    pub fn required(self) -> bool {
        std::env::var(format!("GELRIG_REQUIRE_{}", self.name())).is_ok_and(|v| v == "1")
    }
}

/// Skips the check `what` for want of `need` (`missing`: what is not there, and how to get
/// it): panics when the run requires `need`, else prints the skip and logs it.
pub fn skip(need: Need, what: &str, missing: &str) {
    record(&skip_log(), need.required(), need, what, missing);
}

fn record(log: &Path, required: bool, need: Need, what: &str, missing: &str) {
    let switch = format!("GELRIG_REQUIRE_{}=1", need.name());
    assert!(
        !required,
        "{what}: cannot run: {missing} ({switch} forbids skipping it)"
    );
    let line = format!("SKIP [{}] {what}: {missing}", need.name());
    println!("{line}");
    eprintln!("{line}");
    let written = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(log)
        // One write of the whole line: tests run in parallel threads and processes.
        .and_then(|mut f| f.write_all(format!("{line}\n").as_bytes()));
    if let Err(e) = written {
        eprintln!("(the skip could not be logged to {}: {e})", log.display());
    }
}

/// The skip log: `$GELRIG_SKIP_LOG`, else `skipped-checks.txt` in the build's `target/`
/// (found from the test binary, `target/<profile>/deps/…`).
pub fn skip_log() -> PathBuf {
    if let Some(p) = std::env::var_os("GELRIG_SKIP_LOG") {
        return PathBuf::from(p);
    }
    std::env::current_exe()
        .ok()
        .and_then(|exe| Some(exe.parent()?.parent()?.parent()?.to_path_buf()))
        .unwrap_or_else(std::env::temp_dir)
        .join("skipped-checks.txt")
}

/// `../shared/data/<sub>` beside the repository whose crate is at `manifest_dir` (pass
/// `env!("CARGO_MANIFEST_DIR")`), or `None` after [`skip`]ping `what`.
pub fn shared_data(manifest_dir: &str, sub: &str, what: &str) -> Option<PathBuf> {
    let repo = Path::new(manifest_dir)
        .ancestors()
        .find(|p| p.join("Cargo.lock").is_file() && p.join("protocols").is_dir())
        .unwrap_or(Path::new(manifest_dir));
    let dir = repo.join("../shared/data").join(sub);
    if dir.is_dir() {
        return Some(dir);
    }
    skip(
        Need::Data,
        what,
        &format!(
            "{} is absent (the real GelSight frames: put ../shared beside the repository)",
            dir.display()
        ),
    );
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    fn log_path(tag: &str) -> PathBuf {
        std::env::temp_dir().join(format!("gelrig-skips-{tag}-{}.txt", std::process::id()))
    }

    #[test]
    fn a_skip_is_printed_and_logged() {
        let log = log_path("logged");
        let _ = std::fs::remove_file(&log);
        record(&log, false, Need::Data, "a check", "x is absent");
        record(&log, false, Need::Mount, "another", "no namespace");
        let text = std::fs::read_to_string(&log).expect("in a test");
        assert_eq!(
            text,
            "SKIP [DATA] a check: x is absent\nSKIP [MOUNT] another: no namespace\n"
        );
        let _ = std::fs::remove_file(&log);
    }

    #[test]
    #[should_panic(expected = "GELRIG_REQUIRE_PEERS=1 forbids skipping it")]
    fn a_required_need_fails_instead_of_skipping() {
        record(
            &log_path("required"),
            true,
            Need::Peers,
            "a peer",
            "pymodbus is missing",
        );
    }
}
