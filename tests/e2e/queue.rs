//! `gelrig run A.yaml B.yaml …`: a queue of runs, checked whole before the first starts,
//! stopped at the first run that does not complete.

use std::path::Path;
use std::process::Command;

use crate::support::{gelrig, root, shipped_text};

fn write(dir: &Path, name: &str, text: &str) -> std::path::PathBuf {
    let rig = root().join("protocols/rigs/sim.yaml");
    let p = dir.join(format!("{name}.yaml"));
    let text = text.replace("rig: rigs/sim.yaml", &format!("rig: {}", rig.display()));
    std::fs::write(&p, text).unwrap();
    p
}

fn runs_in(dir: &Path) -> usize {
    std::fs::read_dir(dir).map_or(0, |d| {
        d.flatten()
            .filter(|e| e.path().join("run.yaml").is_file())
            .count()
    })
}

#[test]
fn a_queue_runs_in_order_and_stops_at_the_first_safety_abort() {
    let tmp = tempfile::tempdir().unwrap();
    let normal = shipped_text("portable-normal");
    let rotation = write(tmp.path(), "rotation", &shipped_text("portable-rotation"));
    let good = write(tmp.path(), "normal", &normal);
    // A limit the first loading steps exceed: the watchdog aborts the run.
    let strict = write(
        tmp.path(),
        "strict",
        &normal.replace("max_fz: 60 N", "max_fz: 6 N"),
    );
    assert_ne!(std::fs::read_to_string(&strict).unwrap(), normal, "fixture");

    let out = tmp.path().join("ok");
    let r = Command::new(gelrig())
        .arg("run")
        .args([&good, &rotation])
        .arg("--quiet")
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert_eq!(runs_in(&out), 2);
    assert_eq!(
        String::from_utf8_lossy(&r.stdout).lines().count(),
        2,
        "one run directory per line"
    );

    let out = tmp.path().join("stops");
    let r = Command::new(gelrig())
        .arg("run")
        .args([&good, &strict, &rotation])
        .arg("--quiet")
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(3), "{err}");
    assert!(
        err.contains("queue stopped: run 2 of 3") && err.contains("not run: portable-rotation"),
        "{err}"
    );
    assert_eq!(runs_in(&out), 2, "the third protocol did not run");

    // A broken protocol anywhere in the queue: nothing runs.
    let broken = write(
        tmp.path(),
        "broken",
        &normal.replace("max_fz: 60 N", "max_fz: sixty"),
    );
    let out = tmp.path().join("invalid");
    let r = Command::new(gelrig())
        .arg("run")
        .args([&good, &broken])
        .arg("--quiet")
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert_eq!(r.status.code(), Some(2));
    assert_eq!(runs_in(&out), 0, "nothing ran");
    // --name names one run.
    let r = Command::new(gelrig())
        .arg("run")
        .args([&good, &rotation])
        .args(["--name", "x", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert_eq!(r.status.code(), Some(2));
}
