//! Force from the GelSight against the force sensor (BENCHMARKS.md, "Force from the
//! GelSight"): each sensor calibrated on dry runs of seed 1, then read on dry runs of seed 2
//! — the same protocols (same indenter, other noise) and protocols with indenters the
//! calibration never saw — with the per-frame cost of the reading.
//!
//! ```text
//! cargo run --release -p experiments --example force_study
//! ```

use std::path::{Path, PathBuf};
use std::time::Instant;

use experiments::protocol::load;
use experiments::runner::run_virtual_blocking;
use experiments::sensor::calibrate::CalibrateOptions;
use experiments::sensor::reader::Reader;
use experiments::sensor::{SensorFile, calibrate, load_frames};

fn dry_run(protocol: &Path, out: &Path, seed: u64) -> PathBuf {
    let loaded = load(protocol, None).unwrap_or_else(|d| panic!("{}", d[0]));
    run_virtual_blocking(&loaded, out, seed).expect("run").dir
}

/// Error against the traction map's cell (box sensor; calibrated on flat-circle and sphere
/// runs of seed 1, read on the ellipse and rectangle of seed 2) and its cost per frame.
fn cells(root: &Path, tmp: &Path) {
    let cal: Vec<PathBuf> = [
        "box-normal-flat",
        "box-normal-sphere",
        "box-shear-flat",
        "box-shear-sphere",
    ]
    .iter()
    .map(|p| dry_run(&root.join(format!("{p}.yaml")), &tmp.join("cal"), 1))
    .collect();
    let tests: Vec<PathBuf> = ["box-normal-ellipse", "box-normal-rectangle"]
        .iter()
        .map(|p| dry_run(&root.join(format!("{p}.yaml")), &tmp.join("test"), 2))
        .collect();
    println!(
        "| cell (mm) | support (chosen) | held-out Fz % | ellipse Fz % | rectangle Fz % | reading, ms/frame (median) |"
    );
    println!("|---|---|---|---|---|---|");
    for cell_mm in [0.75, 1.0, 1.5, 2.0] {
        let opts = CalibrateOptions {
            traction: true,
            cell_mm,
            support: None,
        };
        let sensor = calibrate(&cal, &opts).expect("calibrate");
        let path = tmp.join("cells.yaml");
        sensor.write(&path).expect("write");
        let reader = Reader::new(&sensor);
        let mut pct = Vec::new();
        let mut ms = Vec::new();
        for dir in &tests {
            let out = tmp.join("report");
            experiments::report::report_with_sensor(dir, Some(&out), Some((&sensor, &path)))
                .expect("report");
            let summary: serde_json::Value = serde_json::from_str(
                &std::fs::read_to_string(out.join("summary.json")).expect("summary"),
            )
            .expect("json");
            pct.push(
                summary["gelsight_force"]["fz"]["pct_range"]
                    .as_f64()
                    .unwrap_or(f64::NAN),
            );
            let frames = load_frames(dir).expect("frames");
            let map = reader
                .layout
                .match_markers(&frames[0].field.reference_px)
                .expect("layout");
            for f in &frames {
                let started = Instant::now();
                let r = reader.read(&f.field, f.contact, &map);
                std::hint::black_box(reader.model.predict(&r.features));
                ms.push(started.elapsed().as_secs_f64() * 1e3);
            }
        }
        ms.sort_by(f64::total_cmp);
        println!(
            "| {cell_mm} | {} | {:.2} | {:.2} | {:.2} | {:.2} |",
            sensor.traction.map_or(f64::NAN, |t| t.support),
            sensor.held_out.channels["fz_n"].pct_range,
            pct[0],
            pct[1],
            ms[ms.len() / 2]
        );
    }
}

fn main() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../protocols");
    let tmp = tempfile::tempdir().expect("tmp");
    if std::env::args().nth(1).as_deref() == Some("cells") {
        cells(&root, tmp.path());
        return;
    }
    let studies: [(&str, &[&str], &[&str]); 2] = [
        (
            "portable",
            &["portable-normal", "portable-shear", "portable-rotation"],
            &[
                "portable-normal",
                "portable-shear",
                "portable-rotation",
                "lifting-can",
            ],
        ),
        (
            "box",
            &[
                "box-normal-flat",
                "box-normal-sphere",
                "box-shear-flat",
                "box-shear-sphere",
            ],
            &[
                "box-normal-flat",
                "box-shear-sphere",
                "box-normal-ellipse",
                "box-normal-rectangle",
            ],
        ),
    ];
    println!(
        "| sensor | method | test run (seed 2) | seen indenter | Fx % | Fy % | Fz % | Tz % | reading, ms/frame (median) |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for (name, cal, test) in studies {
        let runs: Vec<PathBuf> = cal
            .iter()
            .map(|p| dry_run(&root.join(format!("{p}.yaml")), &tmp.path().join("cal"), 1))
            .collect();
        let tests: Vec<(&str, PathBuf)> = test
            .iter()
            .map(|p| {
                let mut file = root.join(format!("{p}.yaml"));
                if *p == "lifting-can" {
                    // One trial of the grasp, the can's cylinder lying across the pad.
                    let text = std::fs::read_to_string(&file).expect("protocol");
                    file = root.join(".lifting-can-1.yaml");
                    std::fs::write(&file, text.replace("times: 10", "times: 1")).expect("write");
                }
                let dir = dry_run(&file, &tmp.path().join("test"), 2);
                if *p == "lifting-can" {
                    let _ = std::fs::remove_file(&file);
                }
                (*p, dir)
            })
            .collect();
        for (method, opts) in [
            ("moments", CalibrateOptions::default()),
            (
                "traction",
                CalibrateOptions {
                    traction: true,
                    ..CalibrateOptions::default()
                },
            ),
        ] {
            let sensor: SensorFile = calibrate(&runs, &opts).expect("calibrate");
            let path = tmp.path().join(format!("{name}-{method}.yaml"));
            sensor.write(&path).expect("write");
            let held: Vec<String> = sensor
                .held_out
                .channels
                .values()
                .map(|s| format!("{:.2}", s.pct_range))
                .collect();
            let settings = sensor
                .traction
                .map(|t| format!(" (cell {} mm, support {})", t.cell_mm, t.support))
                .unwrap_or_default();
            println!(
                "| {name} | {method}{settings} | calibration, held out ({} frames) | yes | {} |  |",
                sensor.model.samples,
                held.join(" | ")
            );
            let reader = Reader::new(&sensor);
            for (p, dir) in &tests {
                let out = tmp.path().join("report");
                experiments::report::report_with_sensor(dir, Some(&out), Some((&sensor, &path)))
                    .expect("report");
                let summary: serde_json::Value = serde_json::from_str(
                    &std::fs::read_to_string(out.join("summary.json")).expect("summary"),
                )
                .expect("json");
                let g = &summary["gelsight_force"];
                let pct = |c: &str| g[c]["pct_range"].as_f64().unwrap_or(f64::NAN);
                // The reading alone, tracking done: match once, then each frame.
                let frames = load_frames(dir).expect("frames");
                let map = reader
                    .layout
                    .match_markers(&frames[0].field.reference_px)
                    .expect("layout");
                let mut ms: Vec<f64> = frames
                    .iter()
                    .map(|f| {
                        let started = Instant::now();
                        let r = reader.read(&f.field, f.contact, &map);
                        std::hint::black_box(reader.model.predict(&r.features));
                        started.elapsed().as_secs_f64() * 1e3
                    })
                    .collect();
                ms.sort_by(f64::total_cmp);
                println!(
                    "| {name} | {method} | {p} | {} | {:.2} | {:.2} | {:.2} | {:.2} | {:.3} |",
                    if cal.contains(p) { "yes" } else { "no" },
                    pct("fx"),
                    pct("fy"),
                    pct("fz"),
                    pct("tz"),
                    ms[ms.len() / 2]
                );
            }
        }
    }
}
