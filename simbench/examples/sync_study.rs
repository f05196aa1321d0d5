//! Frame-to-force synchronization, end to end over loopback: the production Net F/T driver
//! against its twin streaming at 7 kHz with 2 ms latency, ±5 ms jitter and 50 ppm drift,
//! and a simulated camera at 25 Hz (10 ms exposure) with the same faults, on one clock.
//! Each frame is matched to the force samples its driver stamps inside its exposure; the
//! error of the frame-to-force offset is measured against the twin's and the camera's truth.
//! Also counts the records the driver lost (target: none at 7 kHz for 60 s).
//!
//! `cargo run --release -p simbench --example sync_study -- [SECONDS=60]`

use std::collections::HashMap;
use std::time::Duration;

use rig::device::{ForceRange, ForceSensor};
use rig::drivers::netft::{NetFtSensor, NetFtSettings};
use rig::drivers::netft_rdt::CalInfo;
use rig::twins::netft::{NetFtTwin, TwinParams};
use rig::{Clock, ClockMode, ForceSample, lock};
use simbench::frame_timing::{FrameTiming, Injected};

/// The `q` quantile of `v` (nearest rank; NaN when empty).
fn quantile(v: &[f64], q: f64) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    s.get(((s.len().max(1) - 1) as f64 * q).round() as usize)
        .copied()
        .unwrap_or(f64::NAN)
}

/// The camera's exposure, s.
const EXPOSURE_S: f64 = 0.01;

/// The Net F/T twin at 7 kHz with 2 ms latency, ±5 ms jitter and 50 ppm drift.
fn start_twin() -> NetFtTwin {
    let twin = NetFtTwin::spawn(TwinParams {
        rate_hz: 7000.0,
        cal: CalInfo {
            force_unit: 2,
            torque_unit: 3,
            counts_per_force: 1_000_000,
            counts_per_torque: 1_000_000,
        },
        range: ForceRange::NANO17,
        first_seq: (1, 0),
    })
    .expect("loopback sockets");
    {
        let mut f = lock(twin.faults());
        f.latency_ms = 2.0;
        f.jitter_ms = 5.0;
        f.drift_ppm = 50.0;
    }
    twin
}

/// The production driver on the twin, told of its 2 ms latency.
async fn open_sensor(twin: &NetFtTwin, clock: &Clock) -> NetFtSensor {
    NetFtSensor::open(
        NetFtSettings {
            rdt: twin.rdt_addr(),
            calibration: twin.calibration_addr(),
            timeout: Duration::from_millis(500),
            retries: 3,
            range: ForceRange::NANO17,
            latency_s: 0.002,
        },
        clock.clone(),
    )
    .await
    .expect("open the driver")
}

/// The simulated camera's timing: 25 Hz, with its own latency, jitter and −30 ppm drift.
fn camera_timing() -> FrameTiming {
    FrameTiming::new(
        25.0,
        EXPOSURE_S,
        Injected {
            latency_s: 0.002,
            jitter_s: 0.005,
            drift_ppm: -30.0,
        },
        0.002,
        7,
    )
}

/// Frames until `end_ns`, reading the sensor after each: every force sample received, and
/// each frame's (stamp, true exposure midpoint, arrival), ns.
async fn record(
    clock: &Clock,
    sensor: &mut NetFtSensor,
    camera: &mut FrameTiming,
    end_ns: u64,
) -> (Vec<ForceSample>, Vec<(u64, u64, u64)>) {
    let mut samples: Vec<ForceSample> = Vec::new();
    // (frame stamp, true exposure midpoint, frame arrival)
    let mut frames: Vec<(u64, u64, u64)> = Vec::new();
    while clock.now_ns() < end_ns {
        let f = camera.next_after(clock.now_ns());
        // Stamped at its arrival, as the kernel stamps a buffer (the task wakes a timer
        // tick later).
        clock.sleep_until_ns(f.arrival_ns).await;
        let arrival = f.arrival_ns;
        frames.push((camera.stamp(f.seq, arrival), f.exposure_mid_ns, arrival));
        // The runner reads the sensor at its own pace; every record is kept.
        let _ = sensor.read().await.expect("a sample");
        samples.extend(sensor.take_received());
    }
    tokio::time::sleep(Duration::from_millis(100)).await;
    samples.extend(sensor.take_received());
    (samples, frames)
}

/// Per frame after `from_ns`, ms: the frame-to-force offset error, the frame's own time
/// error, and the offset error had the frame been stamped on arrival.
struct Errors {
    offset_ms: Vec<f64>,
    frame_ms: Vec<f64>,
    arrival_ms: Vec<f64>,
}

/// The [`Errors`] of `frames` against the force `samples`, with the twin's true sample
/// times (`truth`, by sequence number, ns), for frames stamped from `from_ns` on.
fn errors(
    frames: &[(u64, u64, u64)],
    samples: &[ForceSample],
    truth: &HashMap<u32, u64>,
    from_ns: u64,
) -> Errors {
    // The frame's time error less the mean time error of the force samples matched to it.
    let half = (EXPOSURE_S * 0.5e9) as u64;
    let mut offset_ms = Vec::new();
    let mut frame_ms = Vec::new();
    let mut arrival_ms = Vec::new();
    for &(stamp, mid, arrival) in frames {
        if stamp < from_ns {
            continue;
        }
        let inside: Vec<f64> = samples
            .iter()
            .filter(|s| s.t_ns + half >= stamp && s.t_ns <= stamp + half)
            .filter_map(|s| {
                truth
                    .get(&(s.ft_seq as u32))
                    .map(|&t| s.t_ns as f64 - t as f64)
            })
            .collect();
        if inside.is_empty() {
            continue;
        }
        let force_err = inside.iter().sum::<f64>() / inside.len() as f64;
        let frame_err = stamp as f64 - mid as f64;
        offset_ms.push((frame_err - force_err).abs() * 1e-6);
        frame_ms.push(frame_err.abs() * 1e-6);
        // What stamping the frame on arrival (less the known latency) would have given.
        arrival_ms.push(
            (arrival as f64 - 0.002e9 - EXPOSURE_S * 0.5e9 - mid as f64 - force_err).abs() * 1e-6,
        );
    }
    Errors {
        offset_ms,
        frame_ms,
        arrival_ms,
    }
}

#[tokio::main(flavor = "multi_thread", worker_threads = 2)]
async fn main() {
    let seconds: f64 = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(60.0);
    let twin = start_twin();
    let clock = Clock::new(ClockMode::Scaled { scale: 1.0 });
    let mut sensor = open_sensor(&twin, &clock).await;
    let mut camera = camera_timing();
    let t0 = clock.now_ns();
    let end = t0 + (seconds * 1e9) as u64;
    let (samples, frames) = record(&clock, &mut sensor, &mut camera, end).await;
    let stats = sensor.stats();
    let truth: HashMap<u32, u64> = twin
        .sample_times()
        .into_iter()
        .map(|(ft, at)| (ft, clock.ns_at(at)))
        .collect();
    // Frame-to-force offset error per frame, after 5 s (both models ready).
    let Errors {
        offset_ms,
        frame_ms,
        arrival_ms,
    } = errors(&frames, &samples, &truth, t0 + 5_000_000_000);
    let timing = sensor.timing().expect("timing");
    println!(
        "{seconds} s: force records received {}, lost {}, out of order {}, jumps {}, malformed {}",
        stats.received, stats.lost, stats.out_of_order, stats.jumps, stats.malformed
    );
    println!(
        "force clock drift {:.1} ppm (injected 50); camera drift {:.1} ppm (injected -30)",
        timing.drift_ppm.unwrap_or(f64::NAN),
        camera.report().drift_ppm.unwrap_or(f64::NAN)
    );
    println!(
        "frame-to-force offset error over {} frames: median {:.3} ms, p99 {:.3} ms, worst {:.3} ms",
        offset_ms.len(),
        quantile(&offset_ms, 0.5),
        quantile(&offset_ms, 0.99),
        offset_ms.iter().fold(0.0f64, |a, &b| a.max(b))
    );
    println!(
        "  frame times alone: worst {:.3} ms; frames stamped on arrival instead: median {:.3} ms, worst {:.3} ms",
        frame_ms.iter().fold(0.0f64, |a, &b| a.max(b)),
        quantile(&arrival_ms, 0.5),
        arrival_ms.iter().fold(0.0f64, |a, &b| a.max(b))
    );
}
