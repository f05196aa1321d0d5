//! Safe stop through the real binary and real signals: SIGINT aborts and retracts; SIGKILL
//! loses no completed step and leaves a run that `gelrig runs` calls interrupted.

use std::io::{BufRead, BufReader};
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use nix::sys::signal::{Signal, kill};
use nix::unistd::Pid;
use rundir::write::Status;

use crate::support::{csv_rows, gelrig, manifest, protocol, runs_listing};

/// Starts box-normal-flat at 400× real time (an hour in 9 s) with plain progress lines.
fn start(out: &std::path::Path) -> (Child, mpsc::Receiver<String>) {
    let mut child = Command::new(gelrig())
        .args(["run"])
        .arg(protocol("box-normal-flat"))
        .args(["--time-scale", "400", "--plain", "--out"])
        .arg(out)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let stderr = child.stderr.take().unwrap();
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    (child, rx)
}

/// Waits for a stderr line starting with `prefix`, returning all lines seen.
fn wait_for(rx: &mpsc::Receiver<String>, prefix: &str) -> Vec<String> {
    let deadline = Instant::now() + Duration::from_secs(60);
    let mut seen = Vec::new();
    while Instant::now() < deadline {
        if let Ok(line) = rx.recv_timeout(Duration::from_millis(100)) {
            let hit = line.starts_with(prefix);
            seen.push(line);
            if hit {
                return seen;
            }
        }
    }
    panic!("no line starting with {prefix:?} within 60 s; saw {seen:?}");
}

fn wait_exit(child: &mut Child) -> std::process::ExitStatus {
    let deadline = Instant::now() + Duration::from_secs(30);
    loop {
        if let Some(s) = child.try_wait().unwrap() {
            return s;
        }
        assert!(Instant::now() < deadline, "gelrig did not exit");
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn run_dir(out: &std::path::Path) -> PathBuf {
    let dirs: Vec<PathBuf> = std::fs::read_dir(out)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    assert_eq!(dirs.len(), 1, "{dirs:?}");
    dirs[0].clone()
}

#[test]
fn sigint_aborts_retracts_and_marks_the_run_aborted() {
    let out = tempfile::tempdir().unwrap();
    let (mut child, rx) = start(out.path());
    wait_for(&rx, "step 2/20");
    kill(Pid::from_raw(child.id() as i32), Signal::SIGINT).unwrap();
    let status = wait_exit(&mut child);
    assert_eq!(status.code(), Some(130));
    let dir = run_dir(out.path());
    let m = manifest(&dir);
    assert_eq!(m.status, Status::Aborted);
    assert_eq!(m.reason.as_deref(), Some("interrupted by the operator"));
    assert_eq!(
        m.final_positions["normal"], 0.0,
        "normal axis retracted to the retract position"
    );
    let steps = csv_rows(&dir.join("steps.csv"));
    assert!(steps.len() >= 2 && steps.len() < 20, "{}", steps.len());
    let journal = std::fs::read_to_string(dir.join("journal.jsonl")).unwrap();
    assert!(journal.contains("\"event\":\"stop\"") && journal.contains("\"event\":\"retract\""));
    assert!(runs_listing(out.path()).contains("aborted"));
}

#[test]
fn sigkill_keeps_every_completed_step_and_shows_as_interrupted() {
    let out = tempfile::tempdir().unwrap();
    let (mut child, rx) = start(out.path());
    let seen = wait_for(&rx, "step 3/20");
    kill(Pid::from_raw(child.id() as i32), Signal::SIGKILL).unwrap();
    let status = wait_exit(&mut child);
    assert_eq!(status.code(), None, "killed by a signal");
    // Every step the run reported as done before it died is on disk, whole.
    let mut reported: Vec<String> = seen;
    reported.extend(rx.try_iter());
    let done = reported.iter().filter(|l| l.starts_with("step ")).count();
    let dir = run_dir(out.path());
    let steps = csv_rows(&dir.join("steps.csv"));
    assert!(
        steps.len() >= done && done >= 3,
        "{} rows, {done} reported",
        steps.len()
    );
    for (i, r) in steps.iter().enumerate() {
        assert_eq!(r["step"], (i + 1).to_string());
        assert!(r["fz_n"].parse::<f64>().is_ok());
    }
    let m = manifest(&dir);
    assert_eq!(
        m.status,
        Status::Running,
        "a killed run cannot write its end"
    );
    assert!(m.steps_completed as usize >= done);
    let text = runs_listing(out.path());
    assert!(text.contains("interrupted"), "{text}");
    assert!(!text.contains("running"), "{text}");
}

#[test]
fn a_closed_output_pipe_ends_the_command_quietly() {
    // `gelrig schema | true`: the reader is gone before gelrig has started writing (the
    // schema fits a pipe buffer, so closing after reading would not reach the write).
    let mut child = std::process::Command::new(crate::support::gelrig())
        .arg("schema")
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{:?} {err}", out.status);
    assert!(!err.contains("panicked"), "{err}");
}
