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
use experiments::sensor::{SensorFile, calibrate, read_wrench};

fn dry_run(protocol: &Path, out: &Path, seed: u64) -> PathBuf {
    let loaded = load(protocol, None).unwrap_or_else(|d| panic!("{}", d[0]));
    run_virtual_blocking(&loaded, out, seed).expect("run").dir
}

fn main() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../protocols");
    let tmp = tempfile::tempdir().expect("tmp");
    let studies: [(&str, &[&str], &[&str]); 2] = [
        (
            "portable",
            &["portable-normal", "portable-shear", "portable-rotation"],
            &["portable-normal", "portable-shear", "portable-rotation"],
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
        "| sensor | test run (seed 2) | seen indenter | Fx % | Fy % | Fz % | Tz % | reading, µs/frame |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    for (name, cal, test) in studies {
        let runs: Vec<PathBuf> = cal
            .iter()
            .map(|p| dry_run(&root.join(format!("{p}.yaml")), &tmp.path().join("cal"), 1))
            .collect();
        let sensor: SensorFile = calibrate(&runs).expect("calibrate");
        let path = tmp.path().join(format!("{name}.yaml"));
        sensor.write(&path).expect("write");
        let held: Vec<String> = sensor
            .held_out
            .channels
            .values()
            .map(|s| format!("{:.2}", s.pct_range))
            .collect();
        println!(
            "| {name} | calibration, held out ({} frames) | yes | {} |  |",
            sensor.model.samples,
            held.join(" | ")
        );
        for p in test {
            let dir = dry_run(&root.join(format!("{p}.yaml")), &tmp.path().join("test"), 2);
            let started = Instant::now();
            let rows = read_wrench(&sensor, &dir).expect("read");
            let per_frame_us = 1e6 * started.elapsed().as_secs_f64() / rows.len().max(1) as f64;
            experiments::report::report_with_sensor(&dir, None, Some((&sensor, &path)))
                .expect("report");
            let summary: serde_json::Value = serde_json::from_str(
                &std::fs::read_to_string(dir.join("report/summary.json")).expect("summary"),
            )
            .expect("json");
            let g = &summary["gelsight_force"];
            let pct = |c: &str| g[c]["pct_range"].as_f64().unwrap_or(f64::NAN);
            println!(
                "| {name} | {p} | {} | {:.2} | {:.2} | {:.2} | {:.2} | {:.0} (tracking included) |",
                if cal.contains(p) { "yes" } else { "no" },
                pct("fx"),
                pct("fy"),
                pct("fz"),
                pct("tz"),
                per_frame_us
            );
        }
    }
}
