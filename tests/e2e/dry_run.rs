//! Dry runs on the simulated bench: every shipped protocol, the run directory, what is left
//! out, determinism, and every way a run can end early.

use std::collections::BTreeSet;
use std::process::Command;

use rundir::write::Status;

use crate::support::{
    col, csv_rows, gelrig, image_size, load_ok, load_text, manifest, protocol, run_virtual,
    runs_listing, shared_dry_run, shipped, shipped_text,
};

fn edit(text: &str, from: &str, to: &str) -> String {
    assert!(text.contains(from), "fixture lacks {from:?}");
    text.replacen(from, to, 1)
}

#[test]
fn every_shipped_protocol_dry_runs_to_completion() {
    // Through the shared runs (seed 1): the tests that read one of them find it done.
    for name in shipped() {
        let loaded = load_ok(&protocol(&name));
        let plan = &loaded.plan;
        let dir = &shared_dry_run(&name);
        let m = manifest(dir);
        assert_eq!(m.status, Status::Completed);
        assert_eq!(m.steps_completed, loaded.compiled.steps, "{name}");
        let steps = csv_rows(&dir.join("steps.csv"));
        assert_eq!(steps.len() as u32, loaded.compiled.steps, "{name}");
        // The run lasted within the planned range (steps end inside their planned window).
        let last_end_s = steps.last().unwrap()["t_end_ns"].parse::<f64>().unwrap() * 1e-9;
        let planned = plan.steps.last().unwrap().ends_s;
        assert!(
            last_end_s >= planned.min - 1.0 && last_end_s <= planned.max + 1.0,
            "{name}: {last_end_s} not in {planned:?}"
        );
        // Only what the protocol needs is opened.
        let opened: BTreeSet<String> = m.devices.iter().map(|d| d.role.clone()).collect();
        let mut needed: BTreeSet<String> = loaded
            .compiled
            .needs
            .axes
            .iter()
            .map(|a| a.to_string())
            .collect();
        if loaded.compiled.needs.force {
            needed.insert("force".into());
        }
        if loaded.compiled.needs.camera {
            needed.insert("camera".into());
        }
        if loaded.compiled.needs.disturber {
            needed.insert("disturber".into());
        }
        assert_eq!(opened, needed, "{name}");
        // Every pressing axis ends retracted.
        for (role, q) in &loaded.protocol.safety.retract {
            assert_eq!(
                m.final_positions.get(role.name()).copied(),
                Some(q.raw()),
                "{name}: {role}"
            );
        }
        for f in [
            "protocol.yaml",
            "rig.yaml",
            "run.yaml",
            "journal.jsonl",
            "steps.csv",
        ] {
            assert!(dir.join(f).is_file(), "{name}: {f}");
        }
        // The resolved protocol in the run directory loads again and expands identically.
        let again =
            experiments::load::load(&dir.join("protocol.yaml"), Some(&dir.join("rig.yaml")))
                .unwrap();
        assert_eq!(again.compiled.actions, loaded.compiled.actions, "{name}");
    }
}

#[test]
fn box_normal_flat_records_the_thesis_experiment() {
    let out = tempfile::tempdir().unwrap();
    let loaded = load_ok(&protocol("box-normal-flat"));
    let (outcome, _) = run_virtual(&loaded, out.path(), 0, None);
    assert_eq!(outcome.status, Status::Completed);
    let dir = &outcome.dir;
    let steps = csv_rows(&dir.join("steps.csv"));
    assert_eq!(steps.len(), 20);
    let phases: Vec<&str> = steps.iter().map(|r| r["phase"].as_str()).collect();
    assert_eq!(&phases[..10], &["load"; 10]);
    assert_eq!(&phases[10..], &["unload"; 10]);
    for key in [
        "step", "phase", "axis", "target", "position", "fx_n", "fy_n", "fz_n", "tx_nmm", "ty_nmm",
        "tz_nmm", "settle_s",
    ] {
        assert!(steps[0].contains_key(key), "steps.csv lacks {key}");
    }
    let target = col(&steps, "target");
    let position = col(&steps, "position");
    for (t, p) in target.iter().zip(&position) {
        assert!((t - p).abs() <= 0.002 + 1e-9, "position {p} vs target {t}");
    }
    assert!(
        col(&steps, "settle_s")
            .iter()
            .all(|s| (*s - 180.0).abs() < 1e-9)
    );
    let fz = col(&steps, "fz_n");
    // Force rises with every loading step and falls with every unloading step.
    assert!(fz[..10].windows(2).all(|w| w[1] > w[0]), "{fz:?}");
    assert!(fz[10..].windows(2).all(|w| w[1] < w[0]), "{fz:?}");
    // Viscoelastic hysteresis: at the same depth, unloading reads below loading (Fig. 6-5).
    for k in 0..9 {
        let (load, unload) = (fz[k], fz[18 - k]);
        assert!((target[k] - target[18 - k]).abs() < 1e-9);
        assert!(
            unload < load,
            "depth {}: unload {unload} ≥ load {load}",
            target[k]
        );
    }
    // The quasistatic value is the mean of the last 10 s of force.csv (thesis §4.3).
    let force = csv_rows(&dir.join("force.csv"));
    let window_end: f64 = steps[4]["settle_end_ns"].parse().unwrap();
    let in_window: Vec<f64> = force
        .iter()
        .filter(|r| {
            let t: f64 = r["t_ns"].parse().unwrap();
            t >= window_end - 10e9 - 1.0 && t <= window_end + 1.0
        })
        .map(|r| r["fz_n"].parse().unwrap())
        .collect();
    let mean = in_window.iter().sum::<f64>() / in_window.len() as f64;
    assert!((mean - fz[4]).abs() < 1e-5, "{mean} vs {}", fz[4]);
    assert_eq!(
        in_window.len(),
        steps[4]["window_samples"].parse::<usize>().unwrap()
    );
    // force.csv: 20 Hz, every column, monotonic time, recorded from the start.
    let t = col(&force, "t_ns");
    assert!(
        t.windows(2).all(|w| (w[1] - w[0] - 50e6).abs() < 1.0),
        "20 Hz"
    );
    for key in [
        "t_ns", "step", "fx_n", "fy_n", "fz_n", "tx_nmm", "ty_nmm", "tz_nmm",
    ] {
        assert!(force[0].contains_key(key), "force.csv lacks {key}");
    }
    // Frames: a reference before contact and one per step, decodable PNGs.
    let frames = csv_rows(&dir.join("frames.csv"));
    assert_eq!(frames.len(), 21);
    assert_eq!(frames[0]["step"], "0");
    for f in &frames {
        let img = image_size(&dir.join(&f["file"]));
        assert_eq!(img, (640, 480));
    }
    // No axes stream was asked for.
    assert!(!dir.join("axes.csv").exists());
    let m = manifest(dir);
    assert!(m.tare.is_some() && m.origins.contains_key("normal"));
}

#[test]
fn same_seed_same_data_other_seed_other_noise() {
    let loaded = load_ok(&protocol("portable-rotation"));
    let runs: Vec<_> = [7, 7, 8]
        .iter()
        .map(|seed| {
            let out = tempfile::tempdir().unwrap();
            let (o, _) = run_virtual(&loaded, out.path(), *seed, None);
            let force = std::fs::read(o.dir.join("force.csv")).unwrap();
            let steps = std::fs::read(o.dir.join("steps.csv")).unwrap();
            (force, steps, out)
        })
        .collect();
    assert_eq!(
        runs[0].0, runs[1].0,
        "force.csv differs between identical seeds"
    );
    assert_eq!(
        runs[0].1, runs[1].1,
        "steps.csv differs between identical seeds"
    );
    assert_ne!(
        runs[0].0, runs[2].0,
        "a different seed should change the noise"
    );
}

#[test]
fn a_safety_trip_aborts_retracts_and_keeps_the_data() {
    let dir = tempfile::tempdir().unwrap();
    let text = edit(
        &shipped_text("box-normal-flat"),
        "max_fz: 40 N",
        "max_fz: 3.5 N",
    );
    let loaded = load_text(dir.path(), &text).unwrap();
    let (o, _) = run_virtual(&loaded, dir.path(), 0, None);
    assert_eq!(o.status, Status::Aborted);
    let m = manifest(&o.dir);
    let reason = m.reason.clone().unwrap();
    assert!(reason.contains("exceeds max_fz 3.5 N"), "{reason}");
    assert_eq!(m.safety_events.len(), 1);
    assert_eq!(m.final_positions["normal"], 0.0, "normal axis retracted");
    // Steps before the trip are on disk; the trip happened during step 3, pressed with
    // friction (its force overshoots to about 4 N as it is pressed and settles at 3.47 N;
    // step 2 overshoots to about 3 N and settles at 2.33 N).
    let steps = csv_rows(&o.dir.join("steps.csv"));
    assert_eq!(steps.len(), 2, "{steps:?}");
    assert!(reason.contains("(step 3)"), "{reason}");
    let journal = std::fs::read_to_string(o.dir.join("journal.jsonl")).unwrap();
    assert!(journal.contains("\"event\":\"retract\""));
}

#[test]
fn an_interrupt_aborts_at_once_and_retracts() {
    let dir = tempfile::tempdir().unwrap();
    let loaded = load_ok(&protocol("box-shear-flat"));
    let (o, _) = run_virtual(&loaded, dir.path(), 0, Some(1000.0));
    assert_eq!(o.status, Status::Aborted);
    let m = manifest(&o.dir);
    assert_eq!(m.reason.as_deref(), Some("interrupted by the operator"));
    assert_eq!(m.final_positions["normal"], 0.0);
    assert_eq!(m.final_positions["shear"], 0.0);
    // 1000 s in: the preload (≈186 s) and four shear steps (180 s each) are done.
    assert_eq!(csv_rows(&o.dir.join("steps.csv")).len(), 5);
    // The normal axis left the elastomer before the shear axis moved back.
    let journal = std::fs::read_to_string(o.dir.join("journal.jsonl")).unwrap();
    assert!(journal.contains("\"errors\":[]"), "{journal}");
}

#[test]
fn an_approach_that_finds_no_contact_fails_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let text = edit(
        &shipped_text("box-normal-flat"),
        "max_travel: 2 mm",
        "max_travel: 0.5 mm",
    );
    let loaded = load_text(dir.path(), &text).unwrap();
    let (o, _) = run_virtual(&loaded, dir.path(), 0, None);
    assert_eq!(o.status, Status::Failed);
    let m = manifest(&o.dir);
    assert!(m.error.unwrap().contains("reached the end of the approach"));
    assert_eq!(m.final_positions["normal"], 0.0);
    assert_eq!(csv_rows(&o.dir.join("steps.csv")).len(), 0);
}

#[test]
fn settle_by_rate_converges_or_times_out_as_asked() {
    let dir = tempfile::tempdir().unwrap();
    let loaded = load_ok(&protocol("portable-normal"));
    let (o, _) = run_virtual(&loaded, dir.path(), 0, None);
    let steps = csv_rows(&o.dir.join("steps.csv"));
    for r in &steps {
        assert_eq!(r["settle_verdict"], "converged", "{r:?}");
        let s: f64 = r["settle_s"].parse().unwrap();
        assert!((60.0..=120.0).contains(&s), "{s}");
    }
    // A threshold below what the sensor noise can resolve is never met: on_timeout decides.
    let strict = edit(
        &shipped_text("portable-normal"),
        "below: 0.005 N/s",
        "below: 0.00001 N/s",
    );
    let loaded = load_text(dir.path(), &strict).unwrap();
    let (o, _) = run_virtual(&loaded, dir.path(), 0, None);
    assert_eq!(o.status, Status::Completed);
    let steps = csv_rows(&o.dir.join("steps.csv"));
    assert!(
        steps
            .iter()
            .all(|r| r["settle_verdict"] == "timeout" && r["settle_s"] == "120.0")
    );
    assert!(!manifest(&o.dir).warnings.is_empty());
    let abort = edit(&strict, "max: 120 s}", "max: 120 s, on_timeout: abort}");
    let loaded = load_text(dir.path(), &abort).unwrap();
    let (o, _) = run_virtual(&loaded, dir.path(), 0, None);
    assert_eq!(o.status, Status::Aborted);
    assert!(o.message.unwrap().contains("stayed above"));
}

#[test]
fn a_protocol_without_streams_or_frames_records_neither() {
    let dir = tempfile::tempdir().unwrap();
    let text = shipped_text("box-normal-flat")
        .replace("record: {force: 20 Hz}\n", "")
        .replace(", reference_frames: 1", "")
        .replace("frames: 1}", "frames: 0}");
    let loaded = load_text(dir.path(), &text).unwrap();
    assert!(!loaded.compiled.needs.camera);
    let (o, _) = run_virtual(&loaded, dir.path(), 0, None);
    assert_eq!(o.status, Status::Completed);
    assert!(!o.dir.join("force.csv").exists());
    assert!(!o.dir.join("frames").exists());
    let m = manifest(&o.dir);
    assert!(m.devices.iter().all(|d| d.role != "camera"));
    // The quasistatic values are still measured, from the safety monitor's samples.
    let steps = csv_rows(&o.dir.join("steps.csv"));
    assert!(col(&steps, "fz_n")[9] > 5.0);
}

#[test]
fn the_readme_command_runs_box_normal_flat() {
    let out = tempfile::tempdir().unwrap();
    let run = Command::new(gelrig())
        .args(["run"])
        .arg(protocol("box-normal-flat"))
        .arg("--out")
        .arg(out.path())
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let dir = std::path::PathBuf::from(String::from_utf8_lossy(&run.stdout).trim());
    assert!(dir.starts_with(out.path()));
    assert_eq!(manifest(&dir).status, Status::Completed);
    assert_eq!(csv_rows(&dir.join("steps.csv")).len(), 20);
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(
        err.contains("step 20/20"),
        "plain progress lines when not on a terminal: {err}"
    );
    let text = runs_listing(out.path());
    assert!(
        text.contains("completed") && text.contains("20/20"),
        "{text}"
    );
}
