//! Re-measuring a claim: its command, run from the repository's root in its own process
//! group (a `cargo run` and what it starts are stopped together at the timeout), its output
//! kept in `target/claims/<id>.log`, and the number its pattern finds there.

use std::collections::HashMap;
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};

use crate::ledger::Measure;

/// What a command gave: the number, or why there is none; and where its output is.
pub(crate) struct Measured {
    pub(crate) value: Result<f64>,
    pub(crate) log: PathBuf,
    pub(crate) seconds: f64,
}

/// Runs the claims' commands from `root`, each command once: claims printed by the same
/// command (a table's rows) share its run.
pub(crate) struct Runner {
    root: PathBuf,
    test_profile: bool,
    done: HashMap<String, (std::result::Result<String, String>, PathBuf, f64)>,
}

impl Runner {
    /// With `test_profile`, each command builds and runs what `cargo test` builds
    /// ([`in_test_profile`]) instead of a release build.
    pub(crate) fn new(root: &Path, test_profile: bool) -> Self {
        Self {
            root: root.to_path_buf(),
            test_profile,
            done: HashMap::new(),
        }
    }

    /// Runs `m` for the claim `id` (or reuses its command's run) and extracts the number.
    pub(crate) fn run(&mut self, id: &str, m: &Measure) -> Measured {
        let key = format!("{}\n{:?}", m.command, m.timeout_s);
        let root = self.root.clone();
        let command = if self.test_profile {
            in_test_profile(&m.command)
        } else {
            m.command.clone()
        };
        let (text, log, seconds) = self.done.entry(key).or_insert_with(|| {
            let log = root.join("target/claims").join(format!("{id}.log"));
            let started = Instant::now();
            let text = run_logged(&command, m.timeout_s, &root, &log).map_err(|e| format!("{e:#}"));
            (text, log, started.elapsed().as_secs_f64())
        });
        let value = match text {
            Ok(t) => extract(m, t),
            Err(e) => Err(anyhow::anyhow!("{e}")),
        };
        Measured {
            value,
            log: log.clone(),
            seconds: *seconds,
        }
    }
}

/// `command` building and running the test profile's artefacts (`target/debug`, which
/// `cargo test` has built) instead of release ones: `--release` dropped, `target/release/`
/// read as `target/debug/`. For figures that do not depend on the build's speed (the
/// `quick` ones): Rust's floating point is the same at every optimisation level, so the
/// figure is the same and CI does not compile the workspace a second time to get it.
pub(crate) fn in_test_profile(command: &str) -> String {
    command
        .replace(" --release", "")
        .replace("target/release/", "target/debug/")
}

fn run_logged(command: &str, timeout_s: Option<u64>, root: &Path, log: &Path) -> Result<String> {
    if let Some(dir) = log.parent() {
        std::fs::create_dir_all(dir).with_context(|| format!("{}", dir.display()))?;
    }
    let out = std::fs::File::create(log).with_context(|| format!("{}", log.display()))?;
    let err = out.try_clone()?;
    let mut child = Command::new("sh")
        .args(["-c", command])
        .current_dir(root)
        .stdin(Stdio::null())
        .stdout(out)
        .stderr(err)
        .process_group(0)
        .spawn()
        .with_context(|| format!("cannot start `{command}`"))?;
    let limit = Duration::from_secs(timeout_s.unwrap_or(1800));
    let started = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait()? {
            break status;
        }
        if started.elapsed() > limit {
            // The whole group: `cargo run` and the program it started; the command alone if
            // the group cannot be signalled (then `wait` cannot block on it either).
            let group = Command::new("kill")
                .args(["-KILL", "--", &format!("-{}", child.id())])
                .status();
            if !group.is_ok_and(|s| s.success()) {
                let _ = child.kill();
            }
            let _ = child.wait();
            bail!(
                "`{}` did not finish within {} s (see {})",
                command,
                limit.as_secs(),
                log.display()
            );
        }
        std::thread::sleep(Duration::from_millis(100));
    };
    let text = std::fs::read_to_string(log).unwrap_or_default();
    if !status.success() {
        bail!("`{command}` failed ({status}; see {})", log.display());
    }
    Ok(text)
}

/// The number `m.pattern`'s first group finds in `text` (its last match: a command that
/// prints progress ends with its result), times `m.scale`.
pub(crate) fn extract(m: &Measure, text: &str) -> Result<f64> {
    let re = regex::Regex::new(&m.pattern)?;
    let caps = re
        .captures_iter(text)
        .last()
        .with_context(|| format!("the output has no match for `{}`", m.pattern))?;
    let found = caps
        .get(1)
        .with_context(|| format!("`{}` has no group", m.pattern))?
        .as_str();
    let number: f64 = found
        .replace(['−'], "-")
        .replace(',', "")
        .parse()
        .with_context(|| format!("`{found}` is not a number"))?;
    Ok(number * m.scale.unwrap_or(1.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn measure(command: &str, pattern: &str) -> Measure {
        Measure {
            command: command.into(),
            pattern: pattern.into(),
            scale: Some(100.0),
            timeout_s: Some(5),
        }
    }

    #[test]
    fn the_test_profile_reads_debug_artefacts_and_builds_nothing_in_release() {
        let c = "cargo build --release -p gelrig && ./target/release/gelrig run x && cargo test -q --release -p shape --test t";
        assert_eq!(
            in_test_profile(c),
            "cargo build -p gelrig && ./target/debug/gelrig run x && cargo test -q -p shape --test t"
        );
        assert_eq!(in_test_profile("echo 1"), "echo 1");
    }

    #[test]
    fn the_last_match_is_the_result() {
        let m = measure("", r"worst ([−0-9.]+)");
        let v = extract(&m, "worst 0.5\nworst −0.0012\n").expect("in a test");
        assert!((v + 0.12).abs() < 1e-12, "{v}");
        assert!(extract(&m, "nothing").is_err());
    }

    #[test]
    fn a_command_that_fails_or_hangs_is_an_error_naming_it() {
        let root = std::env::temp_dir().join(format!("claims-run-{}", std::process::id()));
        std::fs::create_dir_all(&root).expect("in a test");
        let mut runner = Runner::new(&root, false);
        let ok = runner.run("ok", &measure("echo worst 0.25", r"worst ([0-9.]+)"));
        assert_eq!(ok.value.expect("in a test"), 25.0);
        let failed = runner.run("failed", &measure("exit 3", "x"));
        assert!(
            failed
                .value
                .expect_err("an error")
                .to_string()
                .contains("failed")
        );
        let mut slow = measure("sleep 30", "x");
        slow.timeout_s = Some(1);
        let hung = runner.run("hung", &slow);
        assert!(
            hung.value
                .expect_err("an error")
                .to_string()
                .contains("within 1 s")
        );
        assert!(hung.seconds < 10.0);
        // A second claim on the same command reuses its run.
        let again = runner.run("again", &measure("echo worst 0.25", r"worst ([0-9.]+)"));
        assert_eq!(again.log, ok.log);
        let _ = std::fs::remove_dir_all(&root);
    }
}
