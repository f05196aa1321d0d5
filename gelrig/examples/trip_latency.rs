//! Trip latency of the safety watchdog: from the force crossing `max_fz` to the stop
//! command sent, on the simulated bench in virtual time and over the wire twins in real
//! time (BENCHMARKS.md, "Safety watchdog").
//!
//! The protocol (`tests/fixtures/trip-latency.yaml`) presses a 9.5 mm flat punch into the
//! box sensor at 0.5 mm/s until |Fz| passes 10 N. The crossing time is interpolated
//! between the last sample below the limit and the first above it (force recorded at the
//! monitor's rate, so the recorded samples are the ones the watchdog judged); the stop time
//! is the watchdog's own record (`safety_trip.t_stop_sent_ns` in the journal). Latency =
//! stop − crossing; overshoot = |Fz| of the tripping sample − max_fz.
//!
//! ```text
//! cargo run --release -p gelrig --example trip_latency -- [TRIALS]
//! ```

use std::path::{Path, PathBuf};

use experiments::load::load;
use experiments::protocol::plant_spec;
use rig::ClockMode;
use runner::{Cancel, Launch, run};
use simbench::bench::{ServeOptions, serve};

struct Trial {
    latency_ms: f64,
    overshoot_n: f64,
    wall_us: f64,
}

/// The trip of a run directory: latency from the interpolated crossing, overshoot, and the
/// watchdog's own wall time from judgement to the last stop sent.
fn measure(dir: &Path, limit_n: f64) -> Option<Trial> {
    let journal = std::fs::read_to_string(dir.join(rundir::names::JOURNAL)).ok()?;
    let trip: serde_json::Value = journal
        .lines()
        .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
        .find(|v| v["event"] == "safety_trip")?;
    let (t1, f1) = (
        trip["t_sample_ns"].as_u64()?,
        trip["reading"][2].as_f64()?.abs(),
    );
    let t_stop = trip["t_stop_sent_ns"].as_u64()?;
    // The last judged sample below the limit: recorded, since force is recorded at the
    // monitor's rate and phase.
    let mut r = csv::Reader::from_path(dir.join(rundir::names::FORCE)).ok()?;
    let (t0, f0) = r
        .deserialize::<(u64, u32, u32, f64, f64, f64, f64, f64, f64, u64, u32)>()
        .filter_map(Result::ok)
        .map(|r| (r.0, r.5.abs()))
        .filter(|(t, _)| *t < t1)
        .last()?;
    let cross = if f1 > f0 && f0 <= limit_n {
        t0 as f64 + (limit_n - f0) / (f1 - f0) * (t1 - t0) as f64
    } else {
        t1 as f64
    };
    Some(Trial {
        latency_ms: (t_stop as f64 - cross) * 1e-6,
        overshoot_n: f1 - limit_n,
        wall_us: trip["detect_to_stop_wall_us"].as_f64()?,
    })
}

fn quantile(v: &mut [f64], q: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * q).round() as usize]
}

fn report(what: &str, trials: &[Trial]) {
    let col = |f: fn(&Trial) -> f64| trials.iter().map(f).collect::<Vec<f64>>();
    let (mut lat, mut over, mut wall) = (
        col(|t| t.latency_ms),
        col(|t| t.overshoot_n),
        col(|t| t.wall_us),
    );
    println!(
        "| {what} | {} | {:.1} / {:.1} / {:.1} | {:.3} / {:.3} | {:.0} / {:.0} |",
        trials.len(),
        quantile(&mut lat, 0.5),
        quantile(&mut lat, 0.9),
        quantile(&mut lat, 1.0),
        quantile(&mut over, 0.5),
        quantile(&mut over, 1.0),
        quantile(&mut wall, 0.5),
        quantile(&mut wall, 1.0),
    );
}

/// The fixture with `record: {force: <monitor rate>}` and the monitor rate set.
fn fixture(dir: &Path, monitor_hz: u32) -> PathBuf {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let text = std::fs::read_to_string(root.join("tests/fixtures/trip-latency.yaml"))
        .expect("the fixture");
    let text = text
        .replace(
            "rig: ../../protocols/rigs/sim.yaml",
            &format!("rig: {}", root.join("protocols/rigs/sim.yaml").display()),
        )
        .replace(
            "  retract: {normal: 0 mm}",
            &format!("  retract: {{normal: 0 mm}}\n  monitor_rate: {monitor_hz} Hz"),
        )
        .replace(
            "sequence:",
            &format!("record: {{force: {monitor_hz} Hz}}\nsequence:"),
        );
    let p = dir.join(format!("trip-{monitor_hz}.yaml"));
    std::fs::write(&p, text).expect("write the protocol");
    p
}

fn main() {
    let trials: u64 = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(10);
    let tmp = tempfile::tempdir().expect("temp dir");
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    println!(
        "| bench | trials | crossing → stop sent, ms (median / p90 / max) | overshoot past max_fz, N (median / max) | judgement → last stop sent, wall µs (median / max) |"
    );
    println!("|---|---|---|---|---|");
    for monitor_hz in [50, 200] {
        let p = fixture(tmp.path(), monitor_hz);
        let loaded = load(&p, None).unwrap_or_else(|d| panic!("{d:?}"));
        let mut results = Vec::new();
        for seed in 0..trials {
            let rt = tokio::runtime::Builder::new_current_thread()
                .enable_all()
                .start_paused(true)
                .build()
                .expect("runtime");
            let out = rt
                .block_on(run(
                    Launch::new(&loaded).out(tmp.path().join("sim")).seed(seed),
                    Cancel::new(),
                ))
                .expect("run directory");
            results.extend(measure(&out.dir, 10.0));
        }
        report(
            &format!("simulated, virtual time, monitor {monitor_hz} Hz"),
            &results,
        );
    }
    // Over the wire: Zaber (pty) and Net F/T (UDP) twins in real time, driven by the
    // production drivers; the twins' `twins:` marker removed so the run is on the
    // monotonic clock exactly as on a lab bench.
    for monitor_hz in [50, 200] {
        let p = fixture(tmp.path(), monitor_hz);
        let sim = load(&p, None).unwrap_or_else(|d| panic!("{d:?}"));
        let wire_rig = root.join("protocols/rigs/sim-wire.yaml");
        let (rig, _) = experiments::protocol::load_rig(&wire_rig).expect("sim-wire rig");
        let mut results = Vec::new();
        for seed in 0..trials {
            let rt = tokio::runtime::Builder::new_multi_thread()
                .worker_threads(2)
                .enable_all()
                .build()
                .expect("runtime");
            let spec = plant_spec(&sim.protocol, &sim.compiled).expect("plant");
            let served = rt
                .block_on(serve(
                    &rig,
                    ServeOptions {
                        time_scale: 1.0,
                        plant: Some((spec, sim.compiled.needs.axes.clone())),
                        seed,
                        drive_latency: std::time::Duration::ZERO,
                        overshoot_steps: 0.0,
                    },
                ))
                .expect("twins");
            let mut bound = served.bound.clone();
            bound.twins = None;
            let bound_path = tmp.path().join("bound.yaml");
            std::fs::write(&bound_path, serde_yaml::to_string(&bound).expect("yaml"))
                .expect("write the rig");
            let loaded = load(&p, Some(&bound_path)).unwrap_or_else(|d| panic!("{d:?}"));
            let out = rt
                .block_on(run(
                    Launch::new(&loaded)
                        .out(tmp.path().join("wire"))
                        .seed(seed)
                        .clock(ClockMode::Monotonic),
                    Cancel::new(),
                ))
                .expect("run directory");
            drop(served);
            results.extend(measure(&out.dir, 10.0));
        }
        report(
            &format!("wire twins (Zaber pty, Net F/T UDP), real time, monitor {monitor_hz} Hz"),
            &results,
        );
    }
}
