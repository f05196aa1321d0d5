//! The GelSight's force on what it was not calibrated on: `gelrig calibrate` with no method
//! flags chooses by the error on indenters left out of the fit, and a reading outside the
//! calibration says so and carries an uncertainty that covers its error. Calibrations on seed
//! 1, readings on seed 3 (the choice rules were set looking at seed 1 alone).

use std::path::{Path, PathBuf};
use std::process::Command;

use sensing::sensor::calibrate::{CalibrateOptions, Method};
use sensing::sensor::{SensorFile, calibrate, read_wrench};

use crate::support::{csv_rows, gelrig, load_ok, protocol, run_virtual, shared_dry_run};

/// A shipped protocol dry-run with `seed` into `dir`.
fn dry(name: &str, seed: u64, dir: &Path) -> PathBuf {
    let (o, _) = run_virtual(&load_ok(&protocol(name)), dir, seed, None);
    assert_eq!(o.status, rundir::write::Status::Completed, "{name}");
    o.dir
}

/// `gelrig calibrate RUNS… --out OUT` with no method flags; its stdout (it must succeed).
fn calibrate_cli(runs: &[PathBuf], out: &Path) -> String {
    let o = Command::new(gelrig())
        .arg("calibrate")
        .args(runs)
        .arg("--out")
        .arg(out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// Per channel, the error in % of the calibrated span that `gelrig report --sensor` gives
/// for `run`.
fn reported(run: &Path, sensor: &SensorFile, path: &Path) -> serde_json::Value {
    let out = run.join("report-unseen");
    report::report_with_sensor(run, Some(&out), Some((sensor, path))).unwrap();
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    summary["gelsight_force"].clone()
}

#[test]
fn with_no_flags_calibrate_chooses_by_indenters_left_out_and_reads_unseen_punches() {
    let tmp = tempfile::tempdir().unwrap();
    let runs: Vec<PathBuf> = [
        "box-normal-flat",
        "box-shear-flat",
        "box-normal-sphere",
        "box-shear-sphere",
    ]
    .iter()
    .map(|n| shared_dry_run(n))
    .collect();
    let out = tmp.path().join("box.yaml");
    let stdout = calibrate_cli(&runs, &out);
    assert!(
        stdout.contains("chosen by the error leave one indenter out"),
        "{stdout}"
    );
    assert!(stdout.contains("on shapes it never saw"), "{stdout}");
    let sensor = SensorFile::read(&out).unwrap();
    let choice = sensor
        .chosen_by
        .as_ref()
        .expect("the choice is in the file");
    assert_eq!(choice.by, "leave one indenter out");
    assert!(choice.candidates.len() >= 3, "{:?}", choice.candidates);
    // Candidates best first, the chosen one first.
    assert!(
        choice
            .candidates
            .windows(2)
            .all(|w| w[0].score <= w[1].score)
    );
    let unseen = sensor
        .unseen_shape
        .as_ref()
        .expect("the unseen-shape error");
    assert_eq!(unseen.shapes.len(), 3, "flat 9.5 mm, flat 12.68 mm, sphere");
    assert!(unseen.channels["fz_n"].pct_range < 5.0, "{unseen:?}");
    // Tz is the Nano17's noise on these runs (nothing twists): not scored.
    assert_eq!(choice.scored, ["fx_n", "fy_n", "fz_n"]);
    // Held-out seed: the same shapes within 2 % of span, the unseen ones within 3 % (the
    // issue's target 5 %; published 1.00 / 2.24 / 2.42 %, BENCHMARKS.md).
    for (name, limit) in [
        ("box-normal-flat", 2.0),
        ("box-shear-flat", 2.0),
        ("box-shear-sphere", 2.0),
        ("box-normal-ellipse", 3.0),
        ("box-normal-rectangle", 3.0),
        ("box-normal-triangle", 3.0),
    ] {
        let dir = dry(name, 3, &tmp.path().join(name));
        let g = reported(&dir, &sensor, &out);
        for c in ["fx", "fy", "fz"] {
            let pct = g[c]["pct_range"].as_f64().unwrap();
            assert!(
                pct <= limit,
                "{name} {c}: {pct:.2} % of span (limit {limit} %)"
            );
            // Every error is also stated against the run's own range and the reading (a
            // dash where the run does not move the channel).
            assert!(g[c].get("pct_run_range").is_some(), "{name} {c}: {g}");
            assert!(g[c].get("pct_reading").is_some(), "{name} {c}: {g}");
        }
    }
}

#[test]
fn a_single_indenter_says_its_unseen_shape_error_is_unknown() {
    let tmp = tempfile::tempdir().unwrap();
    // The portable sensor's flat punch, pressed, sheared and twisted: one indenter.
    let runs: Vec<PathBuf> = ["portable-normal", "portable-shear", "portable-rotation"]
        .iter()
        .map(|n| shared_dry_run(n))
        .collect();
    let out = tmp.path().join("one.yaml");
    let stdout = calibrate_cli(&runs, &out);
    assert!(
        stdout.contains("on shapes it never saw: unknown"),
        "{stdout}"
    );
    let sensor = SensorFile::read(&out).unwrap();
    assert!(sensor.unseen_shape.is_none());
    assert!(
        sensor
            .chosen_by
            .as_ref()
            .is_some_and(|c| c.by.contains("unseen-shape error is unknown"))
    );
}

/// One loaded frame of a can run, read by a sensor file beside the Nano17.
struct CanFrame {
    fz_n: f64,
    fz_sd_n: f64,
    /// The Nano17's Fz over the frame's ±60 ms.
    nano_fz_n: f64,
    label: String,
    trial: String,
    outside_calibration: String,
}

/// The can's frames where the Nano17 reads 0.5 N or more.
fn can_frames(sensor: &SensorFile, dir: &Path) -> Vec<CanFrame> {
    let rows = read_wrench(sensor, dir).unwrap();
    let force = csv_rows(&dir.join("force.csv"));
    let t: Vec<u64> = force.iter().map(|r| r["t_ns"].parse().unwrap()).collect();
    let fz: Vec<f64> = force.iter().map(|r| r["fz_n"].parse().unwrap()).collect();
    let steps = csv_rows(&dir.join("steps.csv"));
    rows.iter()
        .filter_map(|r| {
            let at = r.t_ns?;
            let (lo, hi) = (
                t.partition_point(|&x| x + 60_000_000 < at),
                t.partition_point(|&x| x <= at + 60_000_000),
            );
            if hi <= lo {
                return None;
            }
            let nano_fz_n = fz[lo..hi].iter().sum::<f64>() / (hi - lo) as f64;
            let step = steps
                .iter()
                .find(|s| s["step"].parse::<u32>().ok() == Some(r.step));
            let (label, trial) = step.map_or_else(Default::default, |s| {
                (s["label"].clone(), s["trial"].clone())
            });
            (nano_fz_n >= 0.5).then(|| CanFrame {
                fz_n: r.fz_n,
                fz_sd_n: r.fz_sd_n,
                nano_fz_n,
                label,
                trial,
                outside_calibration: r.outside_calibration.clone(),
            })
        })
        .collect()
}

/// The hold's squeeze as read over the Nano17's: the ratio of the medians, over the hold
/// frames of `trial` (every trial's where `None`).
fn hold_ratio(frames: &[CanFrame], trial: Option<&str>) -> f64 {
    let hold: Vec<&CanFrame> = frames
        .iter()
        .filter(|f| f.label == "hold" && trial.is_none_or(|t| f.trial == t))
        .collect();
    assert!(!hold.is_empty(), "no hold frames in trial {trial:?}");
    median(hold.iter().map(|f| f.fz_n).collect())
        / median(hold.iter().map(|f| f.nano_fz_n).collect())
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

#[test]
fn an_unseen_can_reads_within_two_stated_uncertainties_and_says_it_is_unseen() {
    let tmp = tempfile::tempdir().unwrap();
    let runs: Vec<PathBuf> = [
        "portable-normal",
        "portable-shear",
        "portable-rotation",
        "portable-normal-sphere",
    ]
    .iter()
    .map(|n| shared_dry_run(n))
    .collect();
    let can = crate::support::shared_one_trial_can(3);
    let default = calibrate(&runs, &CalibrateOptions::default()).unwrap();
    let moments = calibrate(
        &runs,
        &CalibrateOptions {
            method: Some(Method::Moments),
            symmetric: Some(true),
            ..Default::default()
        },
    )
    .unwrap();
    // With a strip among the calibration's contacts (the shipped `portable-normal-dowel`),
    // the default's traction map fits its elongation term.
    let mut with_dowel = runs.clone();
    with_dowel.push(shared_dry_run("portable-normal-dowel"));
    let dowel = calibrate(&with_dowel, &CalibrateOptions::default()).unwrap();
    assert_eq!(
        dowel.features.last().map(String::as_str),
        Some("traction_fz_elongation"),
        "the dowel's calibration reads {:?} by {:?}",
        dowel.features,
        dowel.method
    );
    assert_eq!(
        default.features.len(),
        4,
        "round contacts only: no elongation term"
    );
    // Fz reads the term (a symmetric fit gives it to Fz alone); the file says its version.
    let weights: Vec<f64> = dowel
        .model()
        .channels
        .iter()
        .map(|c| c.weights[4])
        .collect();
    assert!(
        weights[2].abs() > 1e-6 && [0, 1, 3].iter().all(|&c| weights[c] == 0.0),
        "the elongation term's weights per channel: {weights:?}"
    );
    assert_eq!((default.version, dowel.version), (4, 5));
    // Both kinds of file read back as written; a term renamed by hand is refused.
    for (file, sensor) in [("round.yaml", &default), ("dowel.yaml", &dowel)] {
        let path = tmp.path().join(file);
        sensor.write(&path).unwrap();
        assert_eq!(&SensorFile::read(&path).unwrap(), sensor, "{file}");
    }
    let edited = std::fs::read_to_string(tmp.path().join("dowel.yaml"))
        .unwrap()
        .replace("- traction_fz_elongation", "- traction_fz_long");
    std::fs::write(tmp.path().join("edited.yaml"), edited).unwrap();
    let refused = SensorFile::read(&tmp.path().join("edited.yaml"))
        .unwrap_err()
        .to_string();
    assert!(
        refused.contains("without the elongation term") && refused.contains("edited.yaml"),
        "{refused}"
    );
    // A file that says it is version 4 cannot hold the term: edited, and refused so.
    let older = std::fs::read_to_string(tmp.path().join("dowel.yaml"))
        .unwrap()
        .replacen("version: 5", "version: 4", 1);
    std::fs::write(tmp.path().join("older.yaml"), older).unwrap();
    let refused = SensorFile::read(&tmp.path().join("older.yaml"))
        .unwrap_err()
        .to_string();
    assert!(refused.contains("came with version 5"), "{refused}");
    // The dowel's calibration reads two trials: on seed 3 the second trial's hold is where
    // the can read high (1.120 of the Nano17's with the dowel pressed in 0.10 mm steps,
    // against 1.067 in the first; ten trials 1.112) — its contact region runs longer there.
    let two_trials = crate::support::shared_can(2, 3);
    for (name, sensor, can) in [
        ("default", &default, &can),
        ("moments --symmetric", &moments, &can),
        ("default, with the dowel", &dowel, &two_trials),
    ] {
        let frames = can_frames(sensor, can);
        assert!(frames.len() > 200, "{name}: {} loaded frames", frames.len());
        let within = frames
            .iter()
            .filter(|f| (f.fz_n - f.nano_fz_n).abs() <= 2.0 * f.fz_sd_n)
            .count() as f64
            / frames.len() as f64;
        let flagged = frames
            .iter()
            .filter(|f| {
                f.outside_calibration.contains("shape")
                    && f.outside_calibration.contains("view_edge")
            })
            .count() as f64
            / frames.len() as f64;
        let trials: std::collections::BTreeSet<&str> = frames
            .iter()
            .filter(|f| f.label == "hold")
            .map(|f| f.trial.as_str())
            .collect();
        let ratios: Vec<f64> = trials
            .iter()
            .map(|t| hold_ratio(&frames, Some(t)))
            .collect();
        let ratio = hold_ratio(&frames, None);
        eprintln!(
            "{name}: {:.1} % of frames within 2σ, hold read {ratio:.3} of the Nano17's \
             (per trial {ratios:.3?}), {:.0} % flagged shape and view edge",
            100.0 * within,
            100.0 * flagged
        );
        // Measured on seeds 2–4 (29 Nov–2 Dec): 99.0–100 % within 2σ for all three; the
        // hold 1.18–1.19 (default on the four runs: a symmetric traction map, 2 mm cells,
        // support 1.1), 0.90–0.91 (moments, symmetric) and, over ten trials, 1.004 / 1.047 /
        // 1.004 (default with the dowel: the same map with its elongation term; every trial
        // 0.99–1.07). On round indenters alone the traction map reads the can's strip 18 %
        // high, and no leave-one-out on them can see it (BENCHMARKS, "Force from the
        // GelSight").
        assert!(within >= 0.95, "{name}: {:.1} % within 2σ", 100.0 * within);
        if name != "default, with the dowel" {
            // Only round contacts in the calibration: the can's strip is an unseen shape.
            assert!(flagged >= 0.8, "{name}: {:.0} % flagged", 100.0 * flagged);
        }
        if name != "default" {
            for r in ratios.iter().chain([&ratio]) {
                assert!(
                    (r - 1.0).abs() <= 0.10,
                    "{name}: the hold read {ratio:.3} of the Nano17's (per trial {ratios:.3?})"
                );
            }
        }
    }
}
