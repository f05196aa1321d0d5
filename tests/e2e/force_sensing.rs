//! The GelSight as a force sensor: calibrate on runs with frames and a force sensor, then
//! read force and torque from the field of runs it never saw (other seeds), through the
//! library and the `gelrig` binary; the sensor file round-trips and is refused where it
//! does not belong.

use std::path::{Path, PathBuf};
use std::process::Command;

use experiments::sensor::{SensorFile, calibrate};

use crate::support::{csv_rows, gelrig, load_ok, protocol, run_virtual, shared_dry_run};

/// A shipped protocol dry-run with `seed` into `dir`.
fn dry(name: &str, seed: u64, dir: &Path) -> PathBuf {
    let (o, _) = run_virtual(&load_ok(&protocol(name)), dir, seed, None);
    assert_eq!(o.status, experiments::record::Status::Completed, "{name}");
    o.dir
}

/// The portable sensor calibrated on normal, shear and rotation runs of seed 1, once per
/// test process (calibrating tracks the runs' frames into their directories, which the
/// tests share).
fn portable_sensor() -> SensorFile {
    static SENSOR: std::sync::OnceLock<SensorFile> = std::sync::OnceLock::new();
    SENSOR
        .get_or_init(|| {
            let runs: Vec<PathBuf> = ["portable-normal", "portable-shear", "portable-rotation"]
                .iter()
                .map(|n| shared_dry_run(n))
                .collect();
            calibrate(&runs).unwrap()
        })
        .clone()
}

#[test]
fn calibrated_on_one_seed_the_field_reads_force_on_another_within_two_percent() {
    let tmp = tempfile::tempdir().unwrap();
    let sensor = portable_sensor();
    assert_eq!(sensor.sensor, "portable");
    assert_eq!(sensor.calibrated_on.len(), 3);
    // Its own held-out error is in the file, and small for the loads it was calibrated on.
    for c in ["fx_n", "fz_n"] {
        let s = sensor.held_out.channels[c];
        assert!(s.pct_range < 2.0, "{c}: {s:?}");
    }
    // Round trip through the file.
    let path = tmp.path().join("portable.yaml");
    sensor.write(&path).unwrap();
    let back = SensorFile::read(&path).unwrap();
    assert_eq!(back, sensor);
    // Runs of another seed (other camera and force noise) in the report.
    for (name, channels) in [
        ("portable-normal", &["fz"][..]),
        ("portable-shear", &["fx", "fz"][..]),
        ("portable-rotation", &["tz", "fz"][..]),
    ] {
        let dir = dry(name, 2, &tmp.path().join(name));
        experiments::report::report_with_sensor(&dir, None, Some((&back, &path))).unwrap();
        let summary: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(dir.join("report/summary.json")).unwrap(),
        )
        .unwrap();
        let g = &summary["gelsight_force"];
        for c in channels {
            let pct = g[c]["pct_range"].as_f64().unwrap();
            assert!(pct < 2.5, "{name} {c}: {pct} % ({g})");
        }
        assert!(
            summary["sections"]
                .as_array()
                .unwrap()
                .iter()
                .any(|s| s == "GelSight force against the force sensor")
        );
    }
}

#[test]
fn track_with_a_sensor_writes_the_wrench_of_every_frame() {
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("portable.yaml");
    portable_sensor().write(&path).unwrap();
    let dir = dry("portable-normal", 3, &tmp.path().join("run"));
    let out = tmp.path().join("markers.csv");
    let o = Command::new(gelrig())
        .arg("track")
        .arg(&dir)
        .arg("--out")
        .arg(&out)
        .arg("--sensor")
        .arg(&path)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let rows = csv_rows(&tmp.path().join("wrench.csv"));
    let frames = csv_rows(&dir.join("frames.csv"));
    assert_eq!(rows.len(), frames.len());
    let steps = csv_rows(&dir.join("steps.csv"));
    // The deepest step's frame reads the force sensor's Fz within 2 % of its value.
    let deepest = steps
        .iter()
        .max_by(|a, b| {
            let f = |r: &std::collections::BTreeMap<String, String>| -> f64 {
                r["fz_n"].parse().unwrap()
            };
            f(a).total_cmp(&f(b))
        })
        .unwrap();
    let row = rows.iter().find(|r| r["step"] == deepest["step"]).unwrap();
    let (got, want): (f64, f64) = (
        row["fz_n"].parse().unwrap(),
        deepest["fz_n"].parse().unwrap(),
    );
    let sd: f64 = row["fz_sd_n"].parse().unwrap();
    assert!((got - want).abs() < 0.02 * want, "{got} vs {want}");
    assert!(sd > 0.0 && sd < 0.05 * want, "sd {sd}");
    for c in [
        "t_ns",
        "fx_n",
        "fy_n",
        "tz_nmm",
        "tz_sd_nmm",
        "measured_share",
    ] {
        assert!(row.contains_key(c), "{c}");
    }
}

#[test]
fn a_sensor_file_is_refused_where_it_does_not_belong() {
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("portable.yaml");
    portable_sensor().write(&path).unwrap();
    // Another gel (the box sensor's grid) is another marker layout.
    let box_run = dry("box-normal-flat", 1, &tmp.path().join("box"));
    let o = Command::new(gelrig())
        .arg("report")
        .arg(&box_run)
        .arg("--out")
        .arg(tmp.path().join("report"))
        .arg("--sensor")
        .arg(&path)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("calibrate one for this setup"), "{err}");
    // A newer format version, a truncated file and a file of something else: each named.
    let text = std::fs::read_to_string(&path).unwrap();
    for (bad, says) in [
        (text.replace("version: 1", "version: 9"), "version Some(9)"),
        (text[..text.len() / 2].to_string(), "edited or truncated"),
        (
            "format: gelrig-protocol\n".to_string(),
            "not \"gelrig-sensor\"",
        ),
    ] {
        let p = tmp.path().join("bad.yaml");
        std::fs::write(&p, bad).unwrap();
        let e = SensorFile::read(&p).unwrap_err().to_string();
        assert!(
            e.contains(says) && e.contains("bad.yaml") && e.contains("fix:"),
            "{e}"
        );
    }
    // Calibrating on a run without frames says what it lacks.
    let tmp2 = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(protocol("box-normal-flat"))
        .unwrap()
        .replace("frames: 1", "frames: 0");
    let p = tmp2.path().join("noframes.yaml");
    std::fs::write(&p, text).unwrap();
    let loaded =
        crate::support::load_text(tmp2.path(), &std::fs::read_to_string(&p).unwrap()).unwrap();
    let (o, _) = run_virtual(&loaded, tmp2.path(), 1, None);
    let e = calibrate(&[o.dir]).unwrap_err().to_string();
    assert!(e.contains("no tracked frames") && e.contains("fix:"), "{e}");
}
