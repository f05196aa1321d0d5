//! Grasp trials that feel slip (thesis §6.3): the lifting-can protocols on the simulated
//! bench with the camera, the live tactile state against the simulator's truth, moves that
//! stop on touch, and the per-trial report.

use std::collections::BTreeSet;
use std::path::Path;

use rundir::write::Status;

use crate::support::{csv_rows, load_text, manifest, run_virtual, shipped_text};

fn edit(text: &str, from: &str, to: &str) -> String {
    assert!(text.contains(from), "fixture lacks {from:?}");
    text.replacen(from, to, 1)
}

/// A shipped grasp protocol cut to `trials` trials, dry-run with `seed` into `dir`.
fn run_trials(name: &str, times: &str, trials: u32, seed: u64, dir: &Path) -> std::path::PathBuf {
    let text = edit(
        &shipped_text(name),
        &format!("times: {times}"),
        &format!("times: {trials}"),
    );
    let loaded = load_text(dir, &text).unwrap();
    let (o, _) = run_virtual(&loaded, dir, seed, None);
    assert_eq!(o.status, Status::Completed, "{name}: {:?}", o.message);
    o.dir
}

fn labels_by_step(dir: &Path) -> std::collections::BTreeMap<(String, String), String> {
    csv_rows(&dir.join("steps.csv"))
        .into_iter()
        .map(|r| ((r["step"].clone(), r["trial"].clone()), r["label"].clone()))
        .collect()
}

#[test]
fn lifting_can_records_frames_and_a_tactile_state_only_inside_its_trials() {
    // Shared with `force_unseen`, which reads its second trial's hold.
    let dir = crate::support::shared_can(2, 3);
    let m = manifest(&dir);
    assert!(
        m.devices.iter().any(|d| d.role == "camera"),
        "{:?}",
        m.devices
    );
    let frames = csv_rows(&dir.join("frames.csv"));
    assert!(
        frames.iter().all(|r| r["trial"] != "0"),
        "frames outside a trial"
    );
    let trials: BTreeSet<&str> = frames.iter().map(|r| r["trial"].as_str()).collect();
    assert_eq!(trials.len(), 2);
    // 25 Hz on the run's timebase.
    let t: Vec<f64> = frames.iter().map(|r| r["t_ns"].parse().unwrap()).collect();
    let gaps: Vec<f64> = t.windows(2).map(|w| (w[1] - w[0]) * 1e-9).collect();
    let typical = {
        let mut g = gaps.clone();
        g.sort_by(f64::total_cmp);
        g[g.len() / 2]
    };
    assert!((typical - 0.04).abs() < 1e-6, "frame interval {typical}");
    // Every frame but each block's reference is judged.
    let tactile = csv_rows(&dir.join("tactile.csv"));
    assert_eq!(tactile.len(), frames.len() - 2);
    // The can's true state rides along: lifted 20 mm and held, never slipping.
    let labels = labels_by_step(&dir);
    let label = |r: &std::collections::BTreeMap<String, String>| {
        labels
            .get(&(r["step"].clone(), r["trial"].clone()))
            .cloned()
            .unwrap_or_default()
    };
    for r in &tactile {
        assert_ne!(r["true_sliding"], "true", "{r:?}");
        let l = label(r);
        if l == "hold" || l == "twist" || l == "swing" {
            // Margin > 80 %: no false alarm in holds or disturbances.
            assert_eq!(r["state"], "stick", "{l}: {r:?}");
            assert_eq!(r["gripping"], "true");
            let h: f64 = r["true_height_mm"].parse().unwrap();
            assert!(h > 19.0 && h < 20.5, "{l}: height {h}");
        }
    }
    // The twist shows as a turning contact; the hold as a steady shear along the lift.
    let rot = |l: &str| -> f64 {
        tactile
            .iter()
            .filter(|r| label(r) == l)
            .map(|r| r["rotation_deg"].parse::<f64>().unwrap().abs())
            .fold(0.0, f64::max)
    };
    assert!(
        rot("twist") > 1.0 && rot("hold") < 0.2,
        "{} {}",
        rot("twist"),
        rot("hold")
    );
    // The Nano17 behind the sponge reads the squeeze and the sponge side's share of the
    // weight (0.98 N shared with the gel through their stiffnesses).
    for r in csv_rows(&dir.join("steps.csv"))
        .iter()
        .filter(|r| r["label"] == "hold")
    {
        let fy: f64 = r["fy_n"].parse().unwrap();
        let fz: f64 = r["fz_n"].parse().unwrap();
        assert!(fy > 0.2 && fy < 0.8, "hold Fy {fy}");
        assert!(fz > 3.0 && fz < 5.5, "hold Fz {fz}");
    }
}

/// The "no alarm when the margin is ≥ 30 %", torque included: gripped lighter
/// (2.6 N), the 10 N·mm twist takes the gel to within a few per cent of turning the can, and
/// the markers may report that; wherever the gel's true margins along the lift and about its
/// normal are both at least 30 %, holds, twists and swings stay in `stick`.
#[test]
fn a_lighter_grip_alarms_only_where_the_true_margin_is_below_thirty_percent() {
    let tmp = tempfile::tempdir().unwrap();
    let text = edit(
        &edit(&shipped_text("lifting-can"), "times: 10", "times: 1"),
        "until: 5 N",
        "until: 3.0 N",
    );
    let loaded = load_text(tmp.path(), &text).unwrap();
    let (o, _) = run_virtual(&loaded, tmp.path(), 1, None);
    assert_eq!(o.status, Status::Completed, "{:?}", o.message);
    let labels = labels_by_step(&o.dir);
    let tactile = csv_rows(&o.dir.join("tactile.csv"));
    let num =
        |r: &std::collections::BTreeMap<String, String>, c: &str| -> f64 { r[c].parse().unwrap() };
    let disturbed: Vec<_> = tactile
        .iter()
        .filter(|r| {
            let l = labels
                .get(&(r["step"].clone(), r["trial"].clone()))
                .map(String::as_str);
            matches!(l, Some("hold" | "twist" | "swing"))
        })
        .collect();
    assert!(disturbed.len() >= 170, "{}", disturbed.len());
    assert!(disturbed.iter().all(|r| r["true_sliding"] == "false"));
    // The twist does come close to turning the can (so this exercises the torsional case)...
    let least = disturbed
        .iter()
        .map(|r| num(r, "true_twist_margin"))
        .fold(f64::INFINITY, f64::min);
    assert!(least < 0.3, "least torsional margin {least}");
    // ...and no frame with 30 % to spare either way alarms.
    for r in &disturbed {
        if num(r, "true_margin") >= 0.3 && num(r, "true_twist_margin") >= 0.3 {
            assert_eq!(r["state"], "stick", "{r:?}");
        }
    }
}

/// Over 10 seeds the warning's thresholds were never set on (they were set on seeds 1–10:
/// `analysis/src/tactile.rs`), at the shipped 25 frames/s, `incipient` comes before the can's
/// gross slip in every trial, at least 0.5 s ahead (measured on these seeds: 10 of 10, least
/// lead 0.68 s, median 1.00 s; `grasp_study -- 10 from 11`).
#[test]
fn loosening_in_the_air_warns_before_the_can_slips_on_ten_held_out_seeds() {
    let mut leads_s = Vec::new();
    for seed in 11..=20 {
        let tmp = tempfile::tempdir().unwrap();
        let dir = run_trials("lifting-can-slip", "3", 1, seed, tmp.path());
        let rows = csv_rows(&dir.join("tactile.csv"));
        let gross = rows
            .iter()
            .position(|r| r["true_sliding"] == "true")
            .unwrap_or_else(|| panic!("seed {seed}: the can never slipped"));
        let first = rows
            .iter()
            .position(|r| r["gripping"] == "true" && r["state"] != "stick")
            .filter(|k| *k < gross)
            .unwrap_or_else(|| panic!("seed {seed}: no warning before the slip"));
        let t = |k: usize| rows[k]["t_ns"].parse::<f64>().unwrap() * 1e-9;
        leads_s.push(t(gross) - t(first));
        // It dropped: back on the table before the lift came down.
        assert!(
            rows[gross..].iter().any(|r| r["true_on_table"] == "true"),
            "seed {seed}"
        );
    }
    println!("leads before gross slip, s: {leads_s:.2?}");
    assert!(
        leads_s.iter().all(|l| *l >= 0.5),
        "a warning less than 0.5 s ahead: {leads_s:.2?}"
    );
}

#[test]
fn regrip_on_incipient_slip_keeps_the_can_in_hand() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = run_trials("lifting-can-regrip", "3", 10, 5, tmp.path());
    let rows = csv_rows(&dir.join("tactile.csv"));
    assert!(
        rows.iter().all(|r| r["true_sliding"] != "true"),
        "the can slipped"
    );
    let journal = std::fs::read_to_string(dir.join("journal.jsonl")).unwrap();
    assert_eq!(journal.matches("\"tactile_stop\"").count(), 10);
    // Each loosening stopped short of its 2.5 mm, with the squeeze still up.
    for r in csv_rows(&dir.join("steps.csv"))
        .iter()
        .filter(|r| r["label"] == "loosen")
    {
        let p: f64 = r["position"].parse().unwrap();
        let fz: f64 = r["fz_n"].parse().unwrap();
        assert!(p > -2.4 && p < -0.05, "loosened to {p}");
        assert!(fz > 0.7, "squeeze at the stop {fz}");
    }
    let written = report::report(&dir, None).unwrap();
    let outcomes: Vec<&str> = written.summary["trials"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| t["outcome"].as_str().unwrap())
        .collect();
    assert_eq!(outcomes, ["held"; 10]);
}

#[test]
fn the_report_scores_each_trial_against_force_and_truth() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = run_trials("lifting-can-slip", "3", 2, 2, tmp.path());
    let written = report::report(&dir, None).unwrap();
    let s = &written.summary;
    assert!(written.sections.iter().any(|t| t == "Grasp trials"));
    let trials = s["trials"].as_array().unwrap();
    assert_eq!(trials.len(), 2);
    for t in trials {
        assert_eq!(t["outcome"], "dropped", "{t}");
        let squeeze = t["squeeze_n"].as_f64().unwrap();
        assert!(squeeze > 3.5 && squeeze < 5.5, "{t}");
        let tactile = t["tactile_onset_s"].as_f64().unwrap();
        let truth = t["true_onset_s"].as_f64().unwrap();
        let force = t["force_onset_s"].as_f64().unwrap();
        // The markers felt it first, the force sensor saw it after the can went.
        assert!(tactile < truth && truth <= force + 1e-9, "{t}");
        assert!((t["lead_s"].as_f64().unwrap() - (truth - tactile)).abs() < 1e-9);
        // μ̂ of the grasp at slip (weight share over squeeze): between the gel's 0.6 and
        // the sponge's 0.8 friction (both sides slide together).
        let mu = t["mu_hat"].as_f64().unwrap();
        assert!(mu > 0.4 && mu < 1.2, "{t}");
    }
    assert_eq!(s["trial_stats"]["warned_before_slip"], 2);
    assert!(dir.join("report").join("trial_001.svg").is_file());
}

/// Every diagnostic of a protocol that must not load, one per line.
fn refusal(dir: &Path, text: &str) -> String {
    let err = load_text(dir, text).unwrap_err();
    err.iter()
        .map(|d| d.to_string())
        .collect::<Vec<_>>()
        .join("\n")
}

#[test]
fn a_move_can_stop_on_touch_only_where_frames_are_tracked() {
    let tmp = tempfile::tempdir().unwrap();
    // Outside a record block with frames: refused, with the fix.
    let text = edit(
        &shipped_text("lifting-can-regrip"),
        "            frames: 25 Hz\n",
        "",
    );
    let all = refusal(tmp.path(), &text);
    assert!(
        all.contains("tactile slip state comes from continuous frames")
            && all.contains("frames: 25 Hz"),
        "{all}"
    );
    // An unknown level names what is allowed.
    let text = edit(
        &shipped_text("lifting-can-regrip"),
        "until: {slip: incipient}",
        "until: {slip: slipping}",
    );
    let all = refusal(tmp.path(), &text);
    assert!(all.contains("incipient") && all.contains("slip"), "{all}");
}
