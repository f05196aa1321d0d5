//! `gelrig resume`: a run SIGKILLed at a step and resumed has every step of the same run
//! left uninterrupted, with the same quasistatic values (before the kill: identical; after:
//! within the sensor noise); what it refuses, it refuses before anything moves, or when the
//! re-found contact is off the recorded origin.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use nix::sys::signal::{Signal, kill};
use nix::unistd::Pid;
use rundir::write::Status;

use crate::support::{csv_rows, gelrig, manifest, protocol};

fn only_dir(out: &Path) -> PathBuf {
    let dirs: Vec<PathBuf> = std::fs::read_dir(out)
        .expect("out")
        .map(|e| e.expect("entry").path())
        .collect();
    assert_eq!(dirs.len(), 1, "{dirs:?}");
    dirs[0].clone()
}

/// Runs `name` in virtual time with `seed` (and `set`, `--set` values) and SIGKILLs it once
/// it reports step `k`.
fn killed_at(name: &str, seed: u64, k: u32, out: &Path) -> PathBuf {
    killed_with(name, &[], &[], seed, k, out)
}

/// As [`killed_at`], with `set` (`--set` values) and `extra` arguments to `gelrig run`.
pub(crate) fn killed_with(
    name: &str,
    set: &[&str],
    extra: &[&str],
    seed: u64,
    k: u32,
    out: &Path,
) -> PathBuf {
    let mut child = Command::new(gelrig())
        .arg("run")
        .arg(protocol(name))
        .args(set.iter().flat_map(|s| ["--set", s]))
        .args(extra)
        .args(["--plain", "--seed", &seed.to_string(), "--out"])
        .arg(out)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn gelrig");
    let stderr = child.stderr.take().expect("stderr");
    let needle = format!("step {k}/");
    for line in BufReader::new(stderr).lines().map_while(Result::ok) {
        // `step 3/20: …`, or `trial 2/3 · step 8/18: …` in grasp trials.
        if line.starts_with(&needle) || line.contains(&format!(" · {needle}")) {
            kill(Pid::from_raw(child.id() as i32), Signal::SIGKILL).expect("kill");
            break;
        }
    }
    let deadline = Instant::now() + Duration::from_secs(30);
    while child.try_wait().expect("wait").is_none() {
        assert!(Instant::now() < deadline, "gelrig did not die");
        std::thread::sleep(Duration::from_millis(10));
    }
    let dir = only_dir(out);
    assert_eq!(manifest(&dir).status, Status::Running, "killed mid-run");
    dir
}

pub(crate) fn resume(dir: &Path, extra: &[&str]) -> Output {
    Command::new(gelrig())
        .arg("resume")
        .arg(dir)
        .arg("--quiet")
        .args(extra)
        .output()
        .expect("gelrig resume")
}

fn reference(name: &str, seed: u64, out: &Path) -> PathBuf {
    reference_with(name, &[], seed, out)
}

/// As [`reference`], with more arguments to `gelrig run`.
pub(crate) fn reference_with(name: &str, extra: &[&str], seed: u64, out: &Path) -> PathBuf {
    let r = Command::new(gelrig())
        .arg("run")
        .arg(protocol(name))
        .args(extra)
        .args(["--quiet", "--seed", &seed.to_string(), "--out"])
        .arg(out)
        .output()
        .expect("gelrig run");
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    only_dir(out)
}

/// `gelrig report DIR`, and its `summary.json`.
fn report_summary(dir: &Path) -> serde_json::Value {
    let r = Command::new(gelrig())
        .arg("report")
        .arg(dir)
        .output()
        .expect("report");
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    serde_json::from_str(
        &std::fs::read_to_string(dir.join("report/summary.json")).expect("summary"),
    )
    .expect("json")
}

pub(crate) fn num(r: &std::collections::BTreeMap<String, String>, k: &str) -> f64 {
    r[k].parse().unwrap_or(f64::NAN)
}

#[test]
fn a_killed_run_resumed_has_every_step_and_the_same_quasistatic_values() {
    let mut worst_ratio: f64 = 0.0;
    // Seeds and kill steps drawn once (a fixed table, so a failure reproduces).
    for (seed, k) in [(1u64, 3u32), (2, 14)] {
        let tmp = tempfile::tempdir().expect("tmp");
        let dir = killed_at("box-normal-flat", seed, k, &tmp.path().join("killed"));
        let before = csv_rows(&dir.join("steps.csv")).len() as u32;
        let r = resume(&dir, &[]);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        let m = manifest(&dir);
        assert_eq!(m.status, Status::Completed);
        assert_eq!(m.resumed.len(), 1);
        let from = m.resumed[0].from_step;
        assert_eq!(from, before + 1, "continues at the first incomplete step");
        assert_eq!(m.resumed[0].previous_status, "interrupted");

        let whole = reference("box-normal-flat", seed, &tmp.path().join("ref"));
        let (got, want) = (
            csv_rows(&dir.join("steps.csv")),
            csv_rows(&whole.join("steps.csv")),
        );
        assert_eq!(got.len(), want.len(), "every step, once");
        for (g, w) in got.iter().zip(&want) {
            assert_eq!((&g["step"], &g["label"]), (&w["step"], &w["label"]));
            assert_eq!(g["target"], w["target"]);
            let step: u32 = g["step"].parse().expect("step");
            let (a, b) = (num(g, "fz_n"), num(w, "fz_n"));
            if step < from {
                // Recorded before the kill: the same seed in virtual time is the same run.
                assert_eq!(a, b, "step {step}: recorded before the kill");
            } else {
                // Two independent window means of the same equilibrium: their difference
                // has σ√2, σ the standard error of one window.
                let sigma = num(w, "window_std") / num(w, "window_samples").sqrt();
                let ratio = (a - b).abs() / (sigma * 2f64.sqrt());
                worst_ratio = worst_ratio.max(ratio);
                assert!(
                    ratio < 4.0,
                    "seed {seed}, step {step}: resumed Fz {a} N against {b} N uninterrupted ({ratio:.1} σ)"
                );
            }
        }
        // The journal says what the resume did.
        let journal = std::fs::read_to_string(dir.join("journal.jsonl")).expect("journal");
        assert!(journal.contains("\"event\":\"resume\""));
        assert!(journal.contains("\"event\":\"contact_rechecked\""));
        assert_eq!(
            journal.matches("\"event\":\"replay_step\"").count() as u32,
            from - 1,
            "every completed step replayed"
        );
        // The report reads it as one run.
        let summary = report_summary(&dir);
        assert_eq!(summary["run"]["resumed_at_steps"][0], from);
    }
    println!("resume: worst post-resume difference {worst_ratio:.2} σ of two window means");
}

#[test]
fn resume_refuses_a_completed_run_a_running_one_and_a_moved_origin() {
    let tmp = tempfile::tempdir().expect("tmp");
    let whole = reference("portable-normal", 4, &tmp.path().join("ref"));
    let r = resume(&whole, &[]);
    assert_eq!(r.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&r.stderr).contains("it completed every step"),
        "{}",
        String::from_utf8_lossy(&r.stderr)
    );

    let dir = killed_at("portable-normal", 4, 4, &tmp.path().join("killed"));
    // Someone holds the lock: the run is really in progress.
    let lock = std::fs::OpenOptions::new()
        .write(true)
        .open(dir.join("run.lock"))
        .expect("lock file");
    lock.try_lock().expect("take the lock");
    let r = resume(&dir, &[]);
    assert_eq!(r.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&r.stderr).contains("still running"),
        "{}",
        String::from_utf8_lossy(&r.stderr)
    );
    drop(lock);

    // The sensor moved by 0.3 mm since the run found contact.
    let steps_before = std::fs::read_to_string(dir.join("steps.csv")).expect("steps");
    let yaml = std::fs::read_to_string(dir.join("run.yaml")).expect("run.yaml");
    let mut m: serde_yaml::Value = serde_yaml::from_str(&yaml).expect("yaml");
    let origin = m["origins"]["normal"].as_f64().expect("origin");
    m["origins"]["normal"] = serde_yaml::Value::from(origin - 0.3);
    std::fs::write(
        dir.join("run.yaml"),
        serde_yaml::to_string(&m).expect("yaml"),
    )
    .expect("write");
    let r = resume(&dir, &[]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(1), "{err}");
    assert!(
        err.contains("resume refused") && err.contains("from the run's recorded origin"),
        "{err}"
    );
    assert_eq!(
        std::fs::read_to_string(dir.join("steps.csv")).expect("steps"),
        steps_before,
        "no step ran"
    );
    let m = manifest(&dir);
    assert_eq!(m.status, Status::Failed);
    assert_eq!(m.final_positions["normal"], 0.0, "retracted");

    // Told the shift is harmless, it resumes (the failed segment is the previous one); a
    // shift that large is the bench's, not the approach's: the new contact is the origin.
    let r = resume(&dir, &["--origin-tolerance", "0.5"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let m = manifest(&dir);
    assert_eq!(m.status, Status::Completed);
    assert_eq!(m.resumed.len(), 2);
    assert_eq!(m.resumed[1].previous_status, "failed");
    let rows = csv_rows(&dir.join("steps.csv"));
    assert_eq!(rows.len() as u32, m.steps_planned);
    let found = m.origins["normal"];
    assert!(
        (found - origin).abs() < 0.01,
        "the contact re-found: {found}"
    );
    let resumed_from = m.resumed[1].from_step;
    for r in rows
        .iter()
        .filter(|r| r["step"].parse::<u32>().expect("step") >= resumed_from)
    {
        assert_close_to_origin(r, found);
    }
}

/// A row's stage position is its depth from `origin`, within a step of the stage's
/// resolution.
fn assert_close_to_origin(row: &std::collections::BTreeMap<String, String>, origin: f64) {
    let (abs, depth) = (num(row, "position_abs"), num(row, "position"));
    assert!(
        (abs - (origin + depth)).abs() <= 0.0021,
        "step {}: at {abs}, depth {depth} from the origin {origin}",
        row["step"]
    );
}

#[test]
fn a_contact_within_the_approachs_jitter_keeps_the_recorded_origin() {
    // Two approaches to the same surface differ by the creep between two readings and the
    // stage's resolution: such a difference is not a moved bench, and the resumed steps must
    // go to the stage positions of the first segment (a re-found origin one resolution step
    // off put `box-normal-flat`'s resumed steps 2 µm shallow, 0.6 % of Fz).
    let tmp = tempfile::tempdir().expect("tmp");
    let dir = killed_at("portable-normal", 5, 3, &tmp.path().join("killed"));
    let yaml = std::fs::read_to_string(dir.join("run.yaml")).expect("run.yaml");
    let mut m: serde_yaml::Value = serde_yaml::from_str(&yaml).expect("yaml");
    let found_first = m["origins"]["normal"].as_f64().expect("origin");
    // One resolution step (0.002 mm) off, as a second approach can be.
    let recorded = found_first + 0.002;
    m["origins"]["normal"] = serde_yaml::Value::from(recorded);
    std::fs::write(
        dir.join("run.yaml"),
        serde_yaml::to_string(&m).expect("yaml"),
    )
    .expect("write");
    let r = resume(&dir, &[]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let m = manifest(&dir);
    assert_eq!(m.status, Status::Completed);
    assert_eq!(m.origins["normal"], recorded, "the recorded origin stays");
    let journal = std::fs::read_to_string(dir.join("journal.jsonl")).expect("journal");
    let recheck: serde_json::Value = journal
        .lines()
        .find(|l| l.contains("\"event\":\"contact_rechecked\""))
        .and_then(|l| serde_json::from_str(l).ok())
        .expect("contact_rechecked");
    let found = recheck["found"].as_f64().expect("found");
    assert!(
        (found - recorded).abs() > 1e-6,
        "the approach found another position"
    );
    assert!((found - recorded).abs() <= recheck["jitter"].as_f64().expect("jitter"));
    let kept = recheck["origin"].as_f64().expect("origin");
    assert!((kept - recorded).abs() < 1e-9, "{kept} against {recorded}");
    let from = m.resumed[0].from_step;
    let rows = csv_rows(&dir.join("steps.csv"));
    for r in rows
        .iter()
        .filter(|r| r["step"].parse::<u32>().expect("step") >= from)
    {
        assert_close_to_origin(r, recorded);
    }
}

#[test]
fn a_grasp_trial_cut_short_is_done_again_and_read_once() {
    // Three trials of six steps; killed in the second trial.
    let tmp = tempfile::tempdir().expect("tmp");
    let set = ["sequence.2.repeat.times=3"];
    let dir = killed_with("lifting-can", &set, &[], 5, 8, &tmp.path().join("killed"));
    let rows_before = csv_rows(&dir.join("steps.csv")).len();
    assert!(rows_before >= 8, "{rows_before}");
    let r = resume(&dir, &[]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let m = manifest(&dir);
    assert_eq!(m.status, Status::Completed);
    assert_eq!(
        m.resumed[0].from_step, 7,
        "trial 2 restarts at its first step"
    );
    // The file keeps both attempts of trial 2's completed steps; every step is in it.
    let rows = csv_rows(&dir.join("steps.csv"));
    let steps: std::collections::BTreeSet<u32> = rows
        .iter()
        .map(|r| r["step"].parse().expect("step"))
        .collect();
    assert_eq!(steps, (1..=18).collect());
    assert_eq!(
        rows.len(),
        18 + (rows_before - 6),
        "the abandoned attempt's rows stay"
    );
    // Frame numbers never collide.
    let frames = csv_rows(&dir.join("frames.csv"));
    let numbers: std::collections::BTreeSet<&String> = frames.iter().map(|f| &f["frame"]).collect();
    assert_eq!(numbers.len(), frames.len());
    // The report reads three trials, once each.
    let summary = report_summary(&dir);
    assert_eq!(
        summary["trial_stats"]["trials"], 3,
        "{}",
        summary["trial_stats"]
    );
    assert_eq!(summary["trials"].as_array().map(Vec::len), Some(3));
}

/// The simulator's truth of a run's steps (`sim_steps.csv`), by step.
pub(crate) fn sim_steps(
    dir: &Path,
) -> std::collections::BTreeMap<u32, std::collections::BTreeMap<String, String>> {
    csv_rows(&dir.join("sim_steps.csv"))
        .into_iter()
        .map(|r| (r["step"].parse().expect("step"), r))
        .collect()
}

#[test]
fn a_resumed_run_goes_on_writing_run_mcap_and_it_holds_the_whole_run() {
    // Recorded as MCAP as it goes, killed in its second trial: the resumed run's file is the
    // whole run (the earlier segment's records first), read back by the independent reader
    // like its CSVs.
    let tmp = tempfile::tempdir().expect("tmp");
    let set = ["sequence.2.repeat.times=2"];
    let dir = killed_with(
        "lifting-can",
        &set,
        &["--record", "mcap"],
        6,
        8,
        &tmp.path().join("killed"),
    );
    let before = std::fs::metadata(dir.join("run.mcap"))
        .expect("run.mcap")
        .len();
    let r = resume(&dir, &[]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert_eq!(manifest(&dir).status, Status::Completed);
    let after = std::fs::metadata(dir.join("run.mcap"))
        .expect("run.mcap")
        .len();
    assert!(
        after > before,
        "{after} bytes after the resume, {before} before"
    );
    if !crate::export::readers_available() {
        return;
    }
    let name = manifest(&dir).protocol;
    let j = crate::export::check_mcap(&dir, &dir.join("run.mcap"), &name, "6");
    assert_eq!(j["metadata"][0]["status"], "completed");
}
