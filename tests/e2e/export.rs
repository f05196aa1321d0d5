//! `gelrig export`: a grasp trial's run read back by independent readers — MCAP by Foxglove's
//! Python `mcap` and `mcap-ros2-support` (every force sample as a ROS 2 `WrenchStamped` with
//! its value in SI and its time, every frame as a `CompressedImage`, stage positions, steps,
//! attachments and metadata), Parquet by pandas (types, row counts, units, a campaign's `run`
//! column).

use std::process::{Command, Stdio};

use crate::support::{csv_rows, gelrig, load_text, root, run_virtual, shipped_text};

/// Whether the Python readers are here; prints the skip line (or fails under CI).
pub(crate) fn readers_available() -> bool {
    let ok = Command::new("python3")
        .args(["-c", "import mcap, mcap_ros2, pandas, pyarrow"])
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if !ok {
        testkit::skip(
            testkit::Need::Peers,
            "the MCAP and Parquet readers",
            "they need python3 with mcap, mcap-ros2-support, pandas and pyarrow; pip install them",
        );
    }
    ok
}

#[test]
fn an_exported_run_reads_back_in_the_independent_mcap_reader() {
    let tmp = tempfile::tempdir().unwrap();
    let text = shipped_text("lifting-can").replace("times: 10", "times: 1");
    let loaded = load_text(tmp.path(), &text).unwrap();
    let (o, _) = run_virtual(&loaded, tmp.path(), 3, None);
    let dir = o.dir;
    // Tracked, so its markers go in too.
    let t = Command::new(gelrig())
        .arg("track")
        .arg(&dir)
        .output()
        .unwrap();
    assert!(t.status.success(), "{}", String::from_utf8_lossy(&t.stderr));
    let out = tmp.path().join("trial.mcap");
    let e = Command::new(gelrig())
        .args(["export"])
        .arg(&dir)
        .args(["--format", "mcap", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(e.status.success(), "{}", String::from_utf8_lossy(&e.stderr));
    // Refused with the fix: not a run directory.
    let bad = Command::new(gelrig())
        .args(["export"])
        .arg(tmp.path())
        .output()
        .unwrap();
    assert_eq!(bad.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("run.yaml"));
    if !readers_available() {
        return;
    }
    let j = check_mcap(&dir, &out, "lifting-can", "3");
    // Markers: one ImageMarker per tracked frame, a line per measured marker from its
    // reference to where it is.
    let markers = csv_rows(&dir.join("markers.csv"));
    let mut frames_tracked: Vec<&str> = markers.iter().map(|r| r["frame"].as_str()).collect();
    frames_tracked.dedup();
    assert_eq!(j["counts"]["/camera/markers"], frames_tracked.len());
    let m = &j["first"]["/camera/markers"];
    assert_eq!(m["type"], 2, "LINE_LIST");
    let first_frame: Vec<_> = markers
        .iter()
        .filter(|r| r["frame"] == frames_tracked[0])
        .filter(|r| r["state"] == "tracked" || r["state"] == "merged")
        .collect();
    assert_eq!(m["n"].as_u64().unwrap() as usize, 2 * first_frame.len());
    if let Some(r) = first_frame.first() {
        let v = |c: &str| r[c].parse::<f64>().unwrap();
        assert!((m["p1"][0].as_f64().unwrap() - v("x_px")).abs() < 1e-9);
        assert!((m["p0"][1].as_f64().unwrap() - (v("y_px") - v("dy_px"))).abs() < 1e-9);
    }
}

#[test]
fn a_run_recorded_as_mcap_while_it_goes_reads_back_like_its_csvs() {
    let tmp = tempfile::tempdir().unwrap();
    let r = Command::new(gelrig())
        .args([
            "run",
            "lifting-can",
            "--set",
            "sequence.2.repeat.times=1",
            "--seed",
            "4",
        ])
        .args(["--record", "mcap", "--quiet", "--out"])
        .arg(tmp.path())
        .current_dir(root())
        .output()
        .unwrap();
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let dir = std::path::PathBuf::from(String::from_utf8_lossy(&r.stdout).trim());
    let mcap = dir.join("run.mcap");
    assert!(mcap.is_file(), "no run.mcap in {}", dir.display());
    // Without --record, none.
    let plain = Command::new(gelrig())
        .args(["run", "box-normal-flat", "--quiet", "--out"])
        .arg(tmp.path())
        .current_dir(root())
        .output()
        .unwrap();
    let plain_dir = std::path::PathBuf::from(String::from_utf8_lossy(&plain.stdout).trim());
    assert!(plain_dir.join("run.yaml").is_file() && !plain_dir.join("run.mcap").exists());
    if !readers_available() {
        return;
    }
    let j = check_mcap(&dir, &mcap, "lifting-can-df382d", "4");
    assert_eq!(j["metadata"][0]["status"], "completed");
}

/// Reads `mcap` with the independent readers and checks it against the run's CSVs: every
/// wrench (time, N, N·m), every frame (time, the recorded PNG's size), stage positions in
/// SI, steps and the grasp's tactile state as JSON, attachments and metadata.
pub(crate) fn check_mcap(
    dir: &std::path::Path,
    mcap: &std::path::Path,
    protocol: &str,
    seed: &str,
) -> serde_json::Value {
    let r = Command::new("python3")
        .arg(root().join("tests/peers/read_mcap.py"))
        .arg(mcap)
        .output()
        .unwrap();
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let j: serde_json::Value = serde_json::from_slice(&r.stdout).unwrap();
    let force = csv_rows(&dir.join("force.csv"));
    let frames = csv_rows(&dir.join("frames.csv"));
    let axes = csv_rows(&dir.join("axes.csv"));
    let steps = csv_rows(&dir.join("steps.csv"));
    assert_eq!(j["counts"]["/force"], force.len());
    assert_eq!(j["counts"]["/camera/image/compressed"], frames.len());
    assert_eq!(j["counts"]["/stages"], axes.len());
    assert_eq!(j["counts"]["/steps"], steps.len());
    let tactile = csv_rows(&dir.join("tactile.csv"));
    assert_eq!(j["counts"]["/tactile"], tactile.len());
    assert_eq!(
        j["first"]["/tactile"]["state"],
        tactile[0]["state"].as_str()
    );
    assert_eq!(
        j["first"]["/tactile"]["t_ns"].as_u64().unwrap().to_string(),
        tactile[0]["t_ns"]
    );
    // Every wrench: its time on the run's clock, forces in N, torques in N·m.
    for (row, m) in force.iter().zip(j["forces"].as_array().unwrap()) {
        let t: u64 = row["t_ns"].parse().unwrap();
        let m: Vec<f64> = m
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        assert_eq!(m[0] as u64, t);
        assert_eq!(m[1] as u64 * 1_000_000_000 + m[2] as u64, t);
        for (k, (col, scale)) in [
            ("fx_n", 1.0),
            ("fy_n", 1.0),
            ("fz_n", 1.0),
            ("tx_nmm", 1e-3),
            ("ty_nmm", 1e-3),
            ("tz_nmm", 1e-3),
        ]
        .iter()
        .enumerate()
        {
            let v: f64 = row[*col].parse().unwrap();
            assert!(
                (m[3 + k] - v * scale).abs() < 1e-12,
                "{col}: {} vs {v}",
                m[3 + k]
            );
        }
    }
    // Every frame: the PNG as recorded, at its time.
    for (row, m) in frames.iter().zip(j["images"].as_array().unwrap()) {
        let bytes = std::fs::metadata(dir.join(&row["file"])).unwrap().len();
        assert_eq!(m[0].as_u64().unwrap().to_string(), row["t_ns"]);
        assert_eq!(m[1], "png");
        assert_eq!(m[2].as_u64().unwrap(), bytes);
    }
    // Stage positions in SI (the lift axis in m), steps as JSON, the run's files attached.
    let first = &j["first"]["/stages"];
    let pos_mm: f64 = axes[0]["position"].parse().unwrap();
    assert!((first["pos"][0].as_f64().unwrap() - pos_mm / 1000.0).abs() < 1e-12);
    assert_eq!(j["first"]["/steps"]["label"], steps[0]["label"].as_str());
    assert_eq!(j["first"]["/steps"]["step"], 1);
    let atts: Vec<&str> = j["attachments"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap())
        .collect();
    assert_eq!(atts, ["protocol.yaml", "rig.yaml", "run.yaml"]);
    assert_eq!(j["metadata"][0]["protocol"], protocol);
    assert_eq!(j["metadata"][0]["seed"], seed);
    j
}

#[test]
fn parquet_tables_load_in_pandas_typed_with_units_and_a_campaign_has_a_run_column() {
    let tmp = tempfile::tempdir().unwrap();
    let text = shipped_text("lifting-can").replace("times: 10", "times: 1");
    let loaded = load_text(tmp.path(), &text).unwrap();
    let runs = tmp.path().join("runs");
    std::fs::create_dir_all(&runs).unwrap();
    let (a, _) = run_virtual(&loaded, &runs, 1, None);
    let (b, _) = run_virtual(&loaded, &runs, 2, None);
    // The live path wrote tactile.csv; tracking markers for the markers table.
    let t = Command::new(gelrig())
        .arg("track")
        .arg(&a.dir)
        .output()
        .unwrap();
    assert!(t.status.success(), "{}", String::from_utf8_lossy(&t.stderr));
    let export = |path: &std::path::Path, out: &std::path::Path| {
        let e = Command::new(gelrig())
            .arg("export")
            .arg(path)
            .args(["--format", "parquet", "--out"])
            .arg(out)
            .output()
            .unwrap();
        assert!(e.status.success(), "{}", String::from_utf8_lossy(&e.stderr));
    };
    let one = tmp.path().join("one");
    let campaign = tmp.path().join("campaign");
    export(&a.dir, &one);
    export(&runs, &campaign);
    if !readers_available() {
        return;
    }
    let read = |dir: &std::path::Path| -> serde_json::Value {
        let r = Command::new("python3")
            .arg(root().join("tests/peers/read_parquet.py"))
            .arg(dir)
            .output()
            .unwrap();
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        serde_json::from_slice(&r.stdout).unwrap()
    };
    let j = read(&one);
    for table in ["force", "axes", "steps", "frames", "markers", "tactile"] {
        let rows = csv_rows(&a.dir.join(format!("{table}.csv"))).len();
        assert_eq!(j[table]["rows"], rows, "{table}");
    }
    let dt = |t: &str, c: &str| j[t]["dtypes"][c].as_str().unwrap_or("").to_string();
    assert_eq!(dt("force", "t_ns"), "int64");
    assert_eq!(dt("force", "fz_n"), "float64");
    assert_eq!(dt("steps", "saturated"), "bool");
    assert_eq!(dt("markers", "state"), "category");
    assert_eq!(dt("tactile", "state"), "category");
    assert_eq!(j["force"]["units"]["fz_n"], "N");
    assert_eq!(j["force"]["units"]["tz_nmm"], "N·mm");
    assert_eq!(j["force"]["units"]["t_ns"], "ns");
    assert_eq!(j["markers"]["units"]["dx_px"], "px");
    // The campaign: one table per kind over both runs, with the run named in each row.
    let c = read(&campaign);
    let both = csv_rows(&a.dir.join("force.csv")).len() + csv_rows(&b.dir.join("force.csv")).len();
    assert_eq!(c["force"]["rows"], both);
    assert_eq!(c["force"]["dtypes"]["run"], "category");
    let names: Vec<String> = [&a.dir, &b.dir]
        .iter()
        .map(|d| d.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    let mut want = names.clone();
    want.sort();
    assert_eq!(c["force"]["runs"], serde_json::json!(want));
    // A folder with no runs is refused with exit 2.
    let e = Command::new(gelrig())
        .arg("export")
        .arg(tmp.path().join("one"))
        .args(["--format", "parquet"])
        .output()
        .unwrap();
    assert_eq!(e.status.code(), Some(2));
}
