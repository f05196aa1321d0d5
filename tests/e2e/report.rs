//! `gelrig report` on dry runs of the shipped protocols, against the simulator's truth:
//! stiffness, relaxation times, slip onset, force from field, and which sections appear.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use serde_json::Value;

use crate::support::{col, csv_rows, gelrig, load_text, run_virtual, shared_dry_run, shipped_text};

/// Copies a shared dry run so the report writes into a private folder.
fn private_copy(name: &str, into: &Path) -> PathBuf {
    let src = shared_dry_run(name);
    let dst = into.join(name);
    crate::support::copy_run_dir(&src, &dst);
    dst
}

fn report(run: &Path) -> (Output, Value) {
    let o = Command::new(gelrig())
        .arg("report")
        .arg(run)
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "{}\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    let text = std::fs::read_to_string(run.join("report/summary.json")).unwrap();
    (o, serde_json::from_str(&text).unwrap())
}

fn sections(s: &Value) -> Vec<String> {
    s["sections"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap().to_string())
        .collect()
}

fn has(s: &Value, prefix: &str) -> bool {
    sections(s).iter().any(|t| t.starts_with(prefix))
}

/// The report folder is complete and its HTML needs nothing outside itself.
fn check_files(run: &Path) {
    let dir = run.join("report");
    for f in [
        "report.html",
        "report.md",
        "summary.json",
        "force_time.svg",
        "force_time.png",
    ] {
        assert!(dir.join(f).is_file(), "{f} missing");
    }
    let html = std::fs::read_to_string(dir.join("report.html")).unwrap();
    let srcs = html.matches("src=\"").count();
    assert!(srcs > 0, "no embedded pictures");
    assert_eq!(
        html.matches("src=\"data:").count(),
        srcs,
        "an image is not embedded"
    );
    assert!(!html.contains("<script src") && !html.contains("<link"));
    // Every plot the markdown names exists.
    let md = std::fs::read_to_string(dir.join("report.md")).unwrap();
    for line in md.lines().filter(|l| l.starts_with("![")) {
        let file = line.split("](").nth(1).unwrap().trim_end_matches(')');
        assert!(dir.join(file).is_file(), "{file}");
    }
}

/// Slope of the simulator's fully relaxed force against load over the first `k` loading
/// steps, read straight from `sim_steps.csv` and `steps.csv`.
fn sim_slope(run: &Path, channel: &str, k: usize) -> f64 {
    let steps = csv_rows(&run.join("steps.csv"));
    let sim = csv_rows(&run.join("sim_steps.csv"));
    let (mut x, mut y) = (Vec::new(), Vec::new());
    for (s, t) in steps.iter().zip(&sim) {
        if s["phase"] == "load" && x.len() < k {
            x.push(s["position"].parse::<f64>().unwrap());
            y.push(t[channel].parse::<f64>().unwrap().abs());
        }
    }
    let n = x.len() as f64;
    let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let sxy: f64 = x.iter().zip(&y).map(|(a, b)| (a - mx) * (b - my)).sum();
    let sxx: f64 = x.iter().map(|a| (a - mx).powi(2)).sum();
    sxy / sxx
}

/// The simulator's slip onset: the first loading step that fully slips or keeps under
/// 10 % of the contact stuck.
fn sim_onset(run: &Path, stick: &str, slips: &str) -> u64 {
    let steps = csv_rows(&run.join("steps.csv"));
    let sim = csv_rows(&run.join("sim_steps.csv"));
    steps
        .iter()
        .zip(&sim)
        .find(|(s, t)| {
            s["phase"] == "load"
                && (t[slips].parse::<u32>().unwrap() > 0
                    || t[stick].parse::<f64>().is_ok_and(|f| f < 0.1))
        })
        .map(|(s, _)| s["step"].parse().unwrap())
        .expect("the simulator slips")
}

#[test]
fn box_normal_flat_recovers_stiffness_relaxation_and_force_from_field() {
    let tmp = tempfile::tempdir().unwrap();
    let run = private_copy("box-normal-flat", tmp.path());
    let (_, s) = report(&run);
    check_files(&run);
    // Stiffness: the recorded quasistatic force against depth vs the simulator's
    // equilibrium, within 2 %.
    let lin = &s["linearity"];
    let points = lin["linear_range_points"].as_u64().unwrap() as usize;
    let truth = sim_slope(&run, "fz_eq_n", points);
    let slope = lin["slope"].as_f64().unwrap();
    assert!(
        (slope / truth - 1.0).abs() < 0.02,
        "slope {slope} vs {truth}"
    );
    assert!(lin["r2"].as_f64().unwrap() > 0.999);
    assert_eq!(points, 10, "a flat punch is linear to 20 % of thickness");
    // Relaxation: the box gel's Prony times (docs/explanation/reports.md: 1.5, 15, 60 s), within 5 %.
    let taus: Vec<f64> = s["relaxation"]["shared_tau_s"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    assert_eq!(taus.len(), 3, "{taus:?}");
    for (got, want) in taus.iter().zip([1.5, 15.0, 60.0]) {
        assert!((got / want - 1.0).abs() < 0.05, "τ {got} vs {want}");
    }
    assert_eq!(
        s["relaxation"]["tau_s"].as_array().unwrap().len(),
        20,
        "one entry per step"
    );
    // Force from field within 5 % RMS.
    let ff = s["force_from_field"]["rmse_pct"].as_f64().unwrap();
    assert!(ff < 5.0, "force from field {ff} %");
    assert!(s["force_from_field"]["rmse_n"].as_f64().unwrap() > 0.0);
    // Loads and unloads: hysteresis; normal only: no slip.
    assert!(s["hysteresis"]["loop_area"].as_f64().unwrap() > 0.0);
    assert!(s.get("slip").is_none());
    assert!(has(&s, "Hysteresis") && !has(&s, "Slip") && has(&s, "Displacement field"));
    // Contact size from the frames: the 9.5 mm punch, every loaded step; the rendered edge is
    // smoothed by the field grid, so the image reads it 8 % wide (docs/explanation/tracking.md); the unloaded last
    // step (a residual imprint) has no size.
    assert!(has(&s, "Contact size"), "{:?}", sections(&s));
    let contact = s["contact"].as_array().expect("a contact table");
    assert_eq!(contact.len(), 19, "the 19 loaded steps");
    for r in contact {
        let radius = r["radius"].as_f64().unwrap();
        assert_eq!(r["unit"], "mm");
        assert!(radius > 4.75 && radius < 1.1 * 4.75, "{r}");
    }
    // Settle error falls with the wait, against the fit and against the truth.
    let e: Vec<f64> = s["settle"]["median_abs_error_vs_truth"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    assert!(e.first().unwrap() > &(10.0 * e.last().unwrap()), "{e:?}");
}

#[test]
fn shear_and_torsion_find_slip_within_one_step_of_the_simulator() {
    let tmp = tempfile::tempdir().unwrap();
    let run = private_copy("box-shear-flat", tmp.path());
    let (_, s) = report(&run);
    check_files(&run);
    let onset = s["slip"]["onset_step"].as_u64().unwrap();
    let truth = sim_onset(&run, "shear_stick_fraction", "shear_slips");
    assert!(
        onset.abs_diff(truth) <= 1,
        "onset {onset} vs simulator {truth}"
    );
    let mu = s["slip"]["mu"].as_f64().unwrap();
    assert!((mu - 0.6).abs() < 0.06, "μ {mu} (static 0.6, kinetic 0.54)");
    let ff = s["force_from_field"]["rmse_pct"].as_f64().unwrap();
    assert!(ff < 5.0, "force from field {ff} %");
    let points = s["linearity"]["linear_range_points"].as_u64().unwrap() as usize;
    let truth = sim_slope(&run, "fx_eq_n", points);
    let slope = s["linearity"]["slope"].as_f64().unwrap();
    assert!(
        (slope / truth - 1.0).abs() < 0.02,
        "shear stiffness {slope} vs {truth}"
    );
    // No unloading: no hysteresis.
    assert!(s.get("hysteresis").is_none() && !has(&s, "Hysteresis"));
    assert!(has(&s, "Slip"));

    let run = private_copy("portable-rotation", tmp.path());
    let (_, s) = report(&run);
    let onset = s["slip"]["onset_step"].as_u64().unwrap();
    let truth = sim_onset(&run, "twist_stick_fraction", "twist_slips");
    assert!(
        onset.abs_diff(truth) <= 1,
        "torsional onset {onset} vs simulator {truth}"
    );
    assert!(s["slip"]["mu"].as_f64().is_some());
}

#[test]
fn sections_appear_only_where_they_apply() {
    let tmp = tempfile::tempdir().unwrap();
    // No frames: no field sections, no force from field.
    let text = shipped_text("box-normal-flat")
        .replace("frames: 1}", "frames: 0}")
        .replace("reference_frames: 1", "reference_frames: 0");
    let loaded = load_text(tmp.path(), &text).unwrap_or_else(|d| panic!("{d:?}"));
    let (outcome, _) = run_virtual(&loaded, &tmp.path().join("runs"), 1, None);
    let (_, s) = report(&outcome.dir);
    assert!(!has(&s, "Displacement field"), "{:?}", sections(&s));
    assert!(!has(&s, "Contact size"), "{:?}", sections(&s));
    assert!(s.get("force_from_field").is_none());
    assert!(has(&s, "Linearity") && has(&s, "Hysteresis") && has(&s, "Relaxation"));
    // Grasp trials: no quasistatic steps; the force record and the trials.
    let run = private_copy("lifting-can-regrip", tmp.path());
    let (_, s) = report(&run);
    assert!(
        !has(&s, "Linearity") && has(&s, "Grasp trials"),
        "{:?}",
        sections(&s)
    );
    for key in ["linearity", "hysteresis", "slip", "force_from_field"] {
        assert!(s.get(key).is_none(), "{key}");
    }
}

#[test]
fn bad_run_directories_are_refused_with_the_fix() {
    let tmp = tempfile::tempdir().unwrap();
    let refused = |dir: &Path, needle: &str| {
        let o = Command::new(gelrig())
            .arg("report")
            .arg(dir)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert!(err.contains(needle) && err.contains("fix:"), "{err}");
        assert!(!err.contains("panicked"));
    };
    refused(&tmp.path().join("nothing"), "not a directory");
    let run = private_copy("box-normal-flat", tmp.path());
    // A garbled row names the file and the row.
    let steps = run.join("steps.csv");
    let mut text = std::fs::read_to_string(&steps).unwrap();
    text = text.replacen("\n3,", "\nthree,", 1);
    std::fs::write(&steps, text).unwrap();
    refused(&run, "row 3");
    std::fs::remove_file(&steps).unwrap();
    refused(&run, "steps.csv");
    // The forces are still intact: nothing the report does touches recorded data.
    assert!(!col(&csv_rows(&run.join("force.csv")), "fz_n").is_empty());
}
