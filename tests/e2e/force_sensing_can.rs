//! The GelSight read on the grasp's can: live beside the Nano17, in the jig it was calibrated
//! in, through the can's twist, and as a shape the calibration never saw (the unseen
//! can, calibrated on flat-circle and sphere runs).

use sensing::sensor::{SensorFile, calibrate};

use crate::force_sensing::{
    portable_runs, portable_sensor, portable_traction_sensor, reported_fz_pct, symmetric_sensor,
};
use crate::support::{csv_rows, run_virtual, shared_dry_run};

/// A step's Nano17 Fz and the mean of the GelSight's Fz over its frames (`steps.csv` and
/// `tactile.csv` rows).
fn step_forces(steps: &[Row], rows: &[Row], label: &str) -> (f64, f64) {
    let step = steps.iter().find(|s| s["label"] == label).unwrap();
    let gel: Vec<f64> = rows
        .iter()
        .filter(|r| r["step"] == step["step"])
        .map(|r| r["gelsight_fz_n"].parse().unwrap())
        .collect();
    assert!(!gel.is_empty(), "no frames in {label}");
    (
        step["fz_n"].parse().unwrap(),
        gel.iter().sum::<f64>() / gel.len() as f64,
    )
}

type Row = std::collections::BTreeMap<String, String>;

/// The lowering's GelSight Fz over the Nano17's, less one, in a control run of `text` whose
/// twist and swing are plain holds of the same length (same seed, same timing).
fn control_lowering_bias(tmp: &std::path::Path, text: &str) -> f64 {
    let control_text = text
        .replace(
            "- disturb: {torque: 10 N·mm, frequency: 2 Hz, duration: 2 s, label: twist}",
            "- hold: {duration: 2 s, label: twist}",
        )
        .replace(
            "- disturb: {force: 0.3 N, frequency: 2 Hz, duration: 2 s, label: swing}",
            "- hold: {duration: 2 s, label: swing}",
        );
    assert_ne!(
        control_text, text,
        "the shipped twist and swing blocks changed"
    );
    let control_dir = tmp.join("control");
    std::fs::create_dir_all(&control_dir).unwrap();
    portable_traction_sensor()
        .write(&control_dir.join("sensor.yaml"))
        .unwrap();
    let loaded = crate::support::load_text(&control_dir, &control_text).unwrap();
    let (c, _) = run_virtual(&loaded, &control_dir, 2, None);
    assert_eq!(
        c.status,
        rundir::write::Status::Completed,
        "{:?}",
        c.message
    );
    let c_rows = csv_rows(&c.dir.join("tactile.csv"));
    let c_steps = csv_rows(&c.dir.join("steps.csv"));
    let (c_nano, c_mean) = step_forces(&c_steps, &c_rows, "lower");
    c_mean / c_nano - 1.0
}

/// Read live or afterwards, the same frames give the same force: `gelrig track --sensor`
/// on the run's frames (the live path once counted the image edge's border markers, which
/// the calibration leaves out, and read 13 % off it).
fn live_reading_is_the_offline_one(run: &std::path::Path, sensor: &std::path::Path, rows: &[Row]) {
    let t = std::process::Command::new(crate::support::gelrig())
        .arg("track")
        .arg(run)
        .arg("--sensor")
        .arg(sensor)
        .output()
        .unwrap();
    assert!(t.status.success(), "{}", String::from_utf8_lossy(&t.stderr));
    let offline: std::collections::BTreeMap<String, f64> = csv_rows(&run.join("wrench.csv"))
        .iter()
        .map(|r| (r["frame"].clone(), r["fz_n"].parse().unwrap()))
        .collect();
    let mut compared = 0;
    for r in rows {
        if let Some(off) = offline.get(&r["frame"]) {
            let live: f64 = r["gelsight_fz_n"].parse().unwrap();
            assert!(
                (live - off).abs() <= 2e-3 + 1e-3 * off.abs(),
                "frame {}: live {live} N, afterwards {off} N",
                r["frame"]
            );
            compared += 1;
        }
    }
    assert!(
        compared * 10 >= rows.len() * 9,
        "{compared} of {} frames",
        rows.len()
    );
}

/// `record.gelsight_force` reads the GelSight's wrench live, frame by frame, beside the
/// Nano17: the grasp's squeeze shows in `tactile.csv`'s `gelsight_fz_n`. A protocol naming a
/// missing sensor file, or one without frames, is refused by validation.
#[test]
fn a_protocol_records_the_gelsights_force_beside_the_force_sensor() {
    let tmp = tempfile::tempdir().unwrap();
    portable_traction_sensor()
        .write(&tmp.path().join("sensor.yaml"))
        .unwrap();
    let text = crate::support::shipped_text("lifting-can")
        .replace("times: 10", "times: 1")
        .replace(
            "\nsequence:",
            "\nrecord: {gelsight_force: sensor.yaml}\nsequence:",
        );
    let loaded = crate::support::load_text(tmp.path(), &text).unwrap();
    let (o, _) = run_virtual(&loaded, tmp.path(), 2, None);
    assert_eq!(
        o.status,
        rundir::write::Status::Completed,
        "{:?}",
        o.message
    );
    // The run keeps the sensor it read with.
    let kept = SensorFile::read(&o.dir.join(runner::GELSIGHT_SENSOR_FILE)).unwrap();
    assert_eq!(kept, portable_traction_sensor());
    let rows = csv_rows(&o.dir.join("tactile.csv"));
    let steps = csv_rows(&o.dir.join("steps.csv"));
    let by_step = |label: &str| step_forces(&steps, &rows, label);
    let (nano, mean) = by_step("hold");
    let (twist_nano, twist_mean) = by_step("twist");
    eprintln!(
        "hold: GelSight {mean:.3} N, Nano17 {nano:.3} N; twist: {twist_mean:.3} N, {twist_nano:.3} N"
    );
    // Calibrated on a flat punch, read on a can lying across the pad: the squeeze within
    // half (BENCHMARKS: the can is outside the calibration; the unseen-shape target
    // is not met). The traction map reads the hold at 6.93 N against 5.02 N (+38 %, 28 Nov,
    // pressed with friction); the field moments, which this test used before, read it at
    // 11.8 N: a punch face catches the gel where it started, a curved contact catches it
    // already pushed outward, so the same force leaves a larger field under the can.
    assert!(
        (mean - nano).abs() < 0.5 * nano,
        "GelSight {mean} N vs Nano17 {nano} N"
    );
    // The twist's tractions are told apart from the squeeze: under the 10 N·mm twist at
    // 2 Hz the squeeze reads as it does in the hold, within 10 points of the Nano17's (+42 %
    // against +38 %; the field moments read 0–36 N there).
    assert!(
        ((twist_mean / twist_nano) - (mean / nano)).abs() < 0.1,
        "twist: GelSight {twist_mean} N vs Nano17 {twist_nano} N; hold {mean} N vs {nano} N"
    );
    // After the twist and the swing the reading has kept the gel's history: the lowering
    // reads as it does in a control run whose twist and swing are plain holds of the same
    // length (same seed, same timing), within 5 points of the Nano17's force. (Read by the
    // field moments, whose elastic reading swung 0–36 N at 2 Hz through the twist, the twist
    // taken into the load history left the lowering 9 points higher than the control's
    // before negative readings were kept out of it.) (The lowering's
    // bias itself is not the hold's: under the held grip the gel creeps deeper, and the can,
    // a shape the flat-punch calibration never saw, reads higher as it does.)
    let (lower_nano, lower_mean) = by_step("lower");
    let control_bias = control_lowering_bias(tmp.path(), &text);
    let bias = lower_mean / lower_nano - 1.0;
    assert!(
        (bias - control_bias).abs() < 0.05,
        "lowering: GelSight {lower_mean} N vs Nano17 {lower_nano} N ({:+.1} %); without the \
         twist and swing {:+.1} %",
        100.0 * bias,
        100.0 * control_bias
    );
    live_reading_is_the_offline_one(&o.dir, &tmp.path().join("sensor.yaml"), &rows);
    // Refusals at validation.
    let missing = text.replace("gelsight_force: sensor.yaml", "gelsight_force: none.yaml");
    let e = crate::support::load_text(tmp.path(), &missing).unwrap_err();
    assert!(
        e.iter().any(|d| d.to_string().contains("does not exist")),
        "{e:?}"
    );
    let no_frames = crate::support::shipped_text("box-normal-flat").replace(
        "record: {force: 20 Hz}",
        "record: {force: 20 Hz, gelsight_force: sensor.yaml}",
    );
    let e = crate::support::load_text(tmp.path(), &no_frames).unwrap_err();
    assert!(
        e.iter().any(|d| d.to_string().contains("records none")),
        "{e:?}"
    );
}

/// A grasp read from the field in the jig it was calibrated in (one normal run for the gel's
/// relaxation, a can trial for the contact), on a trial of another seed: with the gel's
/// memory the squeeze follows the Nano17 as it relaxes; read from the field alone it lags.
#[test]
fn a_grasp_calibrated_in_its_jig_reads_the_relaxing_squeeze() {
    let tmp = tempfile::tempdir().unwrap();
    let text = crate::support::shipped_text("lifting-can").replace("times: 10", "times: 2");
    let can = |seed: u64, dir: &str| {
        let loaded = crate::support::load_text(&tmp.path().join(dir), &text).unwrap();
        let (o, _) = run_virtual(&loaded, &tmp.path().join(dir), seed, None);
        assert_eq!(o.status, rundir::write::Status::Completed);
        o.dir
    };
    std::fs::create_dir_all(tmp.path().join("cal")).unwrap();
    std::fs::create_dir_all(tmp.path().join("test")).unwrap();
    let runs = vec![shared_dry_run("portable-normal"), can(1, "cal")];
    let sensor = calibrate(&runs, &crate::force_sensing::moments_on_every_feature()).unwrap();
    assert!(sensor.relaxation.is_some());
    let test = can(2, "test");
    let force = csv_rows(&test.join("force.csv"));
    let t: Vec<f64> = force.iter().map(|r| r["t_ns"].parse().unwrap()).collect();
    let fz: Vec<f64> = force.iter().map(|r| r["fz_n"].parse().unwrap()).collect();
    let nano_at = |x: f64| {
        let i = t.partition_point(|v| *v < x).clamp(1, t.len() - 1);
        let w = ((x - t[i - 1]) / (t[i] - t[i - 1])).clamp(0.0, 1.0);
        fz[i - 1] + w * (fz[i] - fz[i - 1])
    };
    let peak = fz.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    let rmse_pct = |s: &SensorFile| {
        let rows = sensing::sensor::read_wrench(s, &test).unwrap();
        let e: Vec<f64> = rows
            .iter()
            .filter_map(|r| Some(r.fz_n - nano_at(r.t_ns? as f64)))
            .collect();
        100.0 * (e.iter().map(|v| v * v).sum::<f64>() / e.len() as f64).sqrt() / peak
    };
    let with = rmse_pct(&sensor);
    let without = rmse_pct(&SensorFile {
        relaxation: None,
        ..sensor.clone()
    });
    // Set frictionless: 2.95 % of the peak with the memory, 13 % without (pressed with
    // friction, BENCHMARKS' three-trial jig study reads 4.2 % and 12.0 %). A history that started each grip
    // "at rest" (the grip's first reading taken as relaxed) and forgot the last grip read
    // 4.3 %: the can's strip is first seen at about a quarter of the squeeze, so the lift
    // and hold lost that part of the overshoot.
    assert!(with < 3.5, "Fz {with} % of peak with the gel's memory");
    assert!(without > 1.5 * with, "without {without} %, with {with} %");
}

/// Fitted by symmetry (`gelrig calibrate --symmetric`), a sensor calibrated on the portable
/// indentation runs reads the can's squeeze through its twist as through its hold: the
/// twist's field (10 N·mm at 2 Hz, three times any twist of the calibration) has no
/// feature Fz may read. Fitted on every feature, the twist swings the squeeze's reading
/// (measured 30 Nov, seed 2: its middle 80 % spans 36.5 N against the symmetric sensor's
/// 4.8 N and the hold's 2.1 N).
#[test]
fn a_symmetric_sensor_keeps_the_cans_twist_out_of_the_squeeze() {
    let runs = portable_runs();
    let symmetric = symmetric_sensor(&runs);
    let can = crate::support::shared_one_trial_can(2);
    let steps = csv_rows(&can.join("steps.csv"));
    let step_of = |label: &str| -> u32 {
        steps.iter().find(|s| s["label"] == label).unwrap()["step"]
            .parse()
            .unwrap()
    };
    // A step's Fz: its median, and the spread of its middle 80 % (10th to 90th percentile).
    let fz_of = |s: &SensorFile, label: &str| {
        let step = step_of(label);
        let mut v: Vec<f64> = sensing::sensor::read_wrench(s, &can)
            .unwrap()
            .iter()
            .filter(|r| r.step == step)
            .map(|r| r.fz_n)
            .collect();
        v.sort_by(f64::total_cmp);
        let at = |q: f64| v[((v.len() - 1) as f64 * q).round() as usize];
        (at(0.5), at(0.9) - at(0.1))
    };
    let ((twist, symmetric_spread), (hold, hold_spread)) =
        (fz_of(&symmetric, "twist"), fz_of(&symmetric, "hold"));
    let twist_spread = symmetric_spread;
    eprintln!(
        "symmetric: twist {twist:.2} N (spread {twist_spread:.2}), hold {hold:.2} N (spread \
         {hold_spread:.2})"
    );
    assert!(
        (twist - hold).abs() < 0.1 * hold,
        "symmetric: twist {twist} N against the hold's {hold} N"
    );
    // Fitted on every feature the twist's field swings the squeeze's reading at 2 Hz. (Its
    // median may stay near the hold's: the gel's memory averages the swings, since a
    // reading that would pull keeps the history.)
    let every = portable_sensor();
    let ((twist, twist_spread), (hold, hold_spread)) =
        (fz_of(&every, "twist"), fz_of(&every, "hold"));
    eprintln!(
        "every feature: twist {twist:.2} N (spread {twist_spread:.2}), hold {hold:.2} N \
         (spread {hold_spread:.2})"
    );
    assert!(
        twist_spread > 0.2 * hold
            && twist_spread > 3.0 * hold_spread
            && twist_spread > 4.0 * symmetric_spread,
        "every feature: the twist's Fz spreads {twist_spread} N (the hold's {hold_spread} N, at \
         {hold} N; the symmetric sensor's twist {symmetric_spread} N) — the twist no longer \
         leaks, and this test no longer shows what the symmetric fit keeps out"
    );
}

/// The unseen-shape test on the portable sensor: calibrated on flat-circle and
/// sphere runs (`portable-normal`, `portable-normal-sphere`, the flat punch's shear and
/// twist), the traction map and the field moments fitted by symmetry, and the scale fit,
/// read the squeeze of a can they never saw — a cylinder lying across the pad — within 5 %
/// of the calibrated span over a whole grasp trial (seed 2). Calibrated on the flat punch
/// alone the traction map reads it 5.1 % off and the symmetric moments 6.7 %: pressed with
/// friction a punch face catches the gel where it started, a curved contact catches it
/// already pushed outward, and only a calibration with a curved contact has seen that field
/// (BENCHMARKS.md).
#[test]
fn calibrated_on_flat_and_sphere_runs_the_sensor_reads_the_unseen_can() {
    let tmp = tempfile::tempdir().unwrap();
    let mut runs = portable_runs();
    runs.push(shared_dry_run("portable-normal-sphere"));
    let can = crate::support::shared_one_trial_can(2);
    let fz_pct = |s: &SensorFile, what: &str| {
        let path = tmp.path().join(format!("{what}.yaml"));
        s.write(&path).unwrap();
        reported_fz_pct(&can, s, &path, &tmp.path().join(format!("report-{what}")))
    };
    let traction = calibrate(
        &runs,
        &sensing::sensor::calibrate::CalibrateOptions {
            method: Some(sensing::sensor::calibrate::Method::Traction),
            symmetric: Some(true),
            ..Default::default()
        },
    )
    .unwrap();
    let moments = symmetric_sensor(&runs);
    let scale = calibrate(
        &runs,
        &sensing::sensor::calibrate::CalibrateOptions {
            method: Some(sensing::sensor::calibrate::Method::Scale),
            symmetric: Some(false),
            ..Default::default()
        },
    )
    .unwrap();
    let flat_only = symmetric_sensor(&portable_runs());
    let (t, m, s, f) = (
        fz_pct(&traction, "traction"),
        fz_pct(&moments, "moments"),
        fz_pct(&scale, "scale"),
        fz_pct(&flat_only, "flat-only"),
    );
    eprintln!(
        "the can's Fz, % of span: traction {t:.2}, moments {m:.2} (symmetric), scale {s:.2}; \
         moments on the flat runs alone {f:.2}"
    );
    // Measured 28 Nov: 2.97, 2.91 and 3.12 % (the can's seeds 3 and 4: 2.8–3.5, 2.9 and
    // 3.2 %).
    assert!(
        t < 5.0,
        "symmetric traction map: the can's Fz {t:.2} % of span"
    );
    assert!(m < 5.0, "symmetric moments: the can's Fz {m:.2} % of span");
    assert!(s < 5.0, "scale fit: the can's Fz {s:.2} % of span");
    // And the sphere is what does it: without it the same fit misses (6.7 %).
    assert!(
        f > 5.0,
        "moments without the sphere {f:.2} %, with it {m:.2} %"
    );
}
