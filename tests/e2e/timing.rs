//! Frames and force on one timebase: a dry grasp trial whose simulated camera exposes on a
//! drifting clock and delivers late and jittered; its frames are stamped from the camera's
//! counter, matched to the force of their exposure, and the report says how far off they
//! are from the true exposure.

use crate::support::{csv_rows, run_virtual, shipped_text, sim_rig};

#[test]
fn frames_are_stamped_at_their_exposure_and_carry_its_force() {
    let tmp = tempfile::tempdir().unwrap();
    let rig = std::fs::read_to_string(sim_rig()).unwrap().replace(
        "camera: {driver: sim, width: 640, height: 480, fps: 25 Hz}",
        "camera:\n  driver: sim\n  width: 640\n  height: 480\n  fps: 25 Hz\n  exposure: 10 ms\n  \
         latency: 2 ms\n  simulate: {latency: 2 ms, jitter: 5 ms, drift_ppm: 50}",
    );
    assert!(
        rig.contains("simulate:"),
        "the shipped rig's camera line changed"
    );
    let rig_path = tmp.path().join("rig.yaml");
    std::fs::write(&rig_path, rig).unwrap();
    let text = shipped_text("lifting-can").replace("times: 10", "times: 2");
    let p = tmp.path().join("protocol.yaml");
    std::fs::write(&p, text).unwrap();
    let loaded = experiments::load::load(&p, Some(&rig_path)).unwrap();
    let (o, _) = run_virtual(&loaded, tmp.path(), 3, None);
    assert_eq!(
        o.status,
        rundir::write::Status::Completed,
        "{:?}",
        o.message
    );
    let frames = csv_rows(&o.dir.join("frames.csv"));
    assert!(frames.len() > 300, "{} frames", frames.len());
    let err_ms = |r: &std::collections::BTreeMap<String, String>| {
        let t: f64 = r["t_ns"].parse().unwrap();
        let truth: f64 = r["sim_t_ns"].parse().unwrap();
        (t - truth) * 1e-6
    };
    // Before the model has 100 frames: stamped on arrival, late by the jitter (0–10 ms).
    let early: Vec<f64> = frames[1..60].iter().map(err_ms).collect();
    let mean = early.iter().sum::<f64>() / early.len() as f64;
    assert!(mean > 2.0, "arrival stamps {mean:.2} ms late on average");
    // After: at the exposure midpoint.
    let late: Vec<f64> = frames[150..].iter().map(err_ms).collect();
    let worst = late.iter().fold(0.0f64, |a, e| a.max(e.abs()));
    assert!(worst < 1.0, "model stamps: worst {worst:.3} ms");
    // Every frame carries the force of its exposure; the squeeze is in it.
    let fz: Vec<f64> = frames.iter().map(|r| r["fz_n"].parse().unwrap()).collect();
    assert!(fz.iter().all(|v| v.is_finite()));
    assert!(
        fz.iter().any(|&v| v > 4.0),
        "the 5 N squeeze is in frames.csv"
    );
    // The report's timing section says the same, and the manifest how it was done.
    let written = report::report(&o.dir, None).unwrap();
    assert!(written.sections.iter().any(|s| s == "Camera timing"));
    let t = &written.summary["camera_timing"];
    assert_eq!(t["duplicated"], 0);
    assert_eq!(t["dropped"], 0, "{t}");
    let e = &t["frame_time_error_ms"];
    assert!(e["worst_abs"].as_f64().unwrap() < 1.0, "{e}");
    assert_eq!(e["stamped_on_arrival"], 99, "{e}");
    assert!(e["on_arrival_worst_abs"].as_f64().unwrap() > 2.0, "{e}");
    let manifest = crate::support::manifest(&o.dir);
    let cam = &manifest.timing["camera"];
    assert!((cam.latency_s - 0.002).abs() < 1e-12);
    let drift = cam.drift_ppm.expect("fitted");
    assert!((drift - 50.0).abs() < 10.0, "drift {drift} ppm");
}
