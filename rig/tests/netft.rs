//! The production Net F/T driver against its twin over loopback UDP and TCP: scaling read
//! from the box, bias, saturation, sequence wrap, and injected loss, reordering,
//! duplication, an unreachable box and a stopped stream.

use std::time::{Duration, Instant};

use rig::device::{ForceRange, ForceSensor, STATUS_SATURATED, Wrench};
use rig::drivers::netft::{NetFtSensor, NetFtSettings};
use rig::drivers::netft_rdt::CalInfo;
use rig::twins::netft::{NetFtTwin, TwinParams};
use rig::{Clock, ClockMode, RigError, lock};

const NANO17: ForceRange = ForceRange {
    fz_n: 70.0,
    fxy_n: 50.0,
    torque_nmm: 500.0,
    force_resolution_n: 1.0 / 80.0,
    torque_resolution_nmm: 1.0 / 16.0,
};

fn params() -> TwinParams {
    TwinParams {
        rate_hz: 500.0,
        // Counts per N and per N·m that are not 1e6: hard-coded scaling would be wrong.
        cal: CalInfo {
            force_unit: 2,
            torque_unit: 3,
            counts_per_force: 1_500_000,
            counts_per_torque: 2_000_000,
        },
        range: NANO17,
        first_seq: (1, 0),
    }
}

fn twin(first_seq: (u32, u32)) -> NetFtTwin {
    NetFtTwin::spawn(TwinParams {
        first_seq,
        ..params()
    })
    .expect("loopback sockets")
}

fn settings(t: &NetFtTwin) -> NetFtSettings {
    NetFtSettings {
        rdt: t.rdt_addr(),
        calibration: t.calibration_addr(),
        timeout: Duration::from_millis(300),
        retries: 3,
        range: NANO17,
        latency_s: 0.0,
    }
}

fn clock() -> Clock {
    Clock::new(ClockMode::Scaled { scale: 1.0 })
}

/// Reads until `pred` holds or a second passes.
async fn read_until(
    s: &mut NetFtSensor,
    pred: impl Fn(&rig::ForceSample) -> bool,
) -> rig::ForceSample {
    let t0 = Instant::now();
    loop {
        let x = s.read().await.expect("sample");
        if pred(&x) {
            return x;
        }
        assert!(
            t0.elapsed() < Duration::from_secs(2),
            "never reached: {x:?}"
        );
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
}

#[tokio::test]
async fn scaled_samples_bias_and_saturation() {
    let t = twin((1, 0));
    *lock(&t.load) = Wrench {
        fx_n: 0.5,
        fy_n: 0.0,
        fz_n: 2.25,
        tx_nmm: 0.0,
        ty_nmm: 0.0,
        tz_nmm: 12.0,
    };
    let mut s = NetFtSensor::open(settings(&t), clock())
        .await
        .expect("opens");
    assert!(
        s.info().identity.contains("1500000"),
        "{}",
        s.info().identity
    );
    let x = read_until(&mut s, |x| x.wrench.fz_n > 2.0).await;
    assert!(
        (x.wrench.fz_n - 2.25).abs() < 1e-6 && (x.wrench.fx_n - 0.5).abs() < 1e-6,
        "{x:?}"
    );
    // N·m on the wire, N·mm in gelrig.
    assert!((x.wrench.tz_nmm - 12.0).abs() < 1e-3, "{x:?}");
    assert_eq!(x.status & STATUS_SATURATED, 0);
    s.bias().await.expect("bias");
    read_until(&mut s, |x| x.wrench.fz_n.abs() < 1e-6).await;
    *lock(&t.load) = Wrench {
        fz_n: 80.0,
        ..Default::default()
    };
    let x = read_until(&mut s, |x| x.status & STATUS_SATURATED != 0).await;
    assert!(x.wrench.fz_n > 70.0);
    assert_eq!(
        s.stats().lost + s.stats().out_of_order,
        0,
        "{:?}",
        s.stats()
    );
}

#[tokio::test]
async fn loss_reordering_duplicates_and_the_counter_wrap_are_counted() {
    // Start 100 records before both counters wrap.
    let t = twin((u32::MAX - 100, u32::MAX - 1400));
    let mut s = NetFtSensor::open(settings(&t), clock())
        .await
        .expect("opens");
    {
        let mut f = lock(t.faults());
        f.drop_every = 10;
        f.reorder_every = 7;
        f.duplicate_every = 13;
    }
    let first = s.read().await.expect("sample").ft_seq;
    let t0 = Instant::now();
    while t0.elapsed() < Duration::from_millis(800) {
        s.read().await.expect("sample");
    }
    let last = s.read().await.expect("sample").ft_seq;
    assert!(
        last > first && last > u32::MAX as u64,
        "ft_seq unwrapped past 2^32: {first} → {last}"
    );
    let st = s.stats();
    assert!(st.lost > 0 && st.out_of_order > 0, "{st:?}");
    // About a tenth of the records dropped (reordered ones count once as lost, once late).
    let ratio = st.lost as f64 / (st.received + st.lost) as f64;
    assert!((0.05..0.3).contains(&ratio), "{st:?}");
}

#[tokio::test]
async fn an_unreachable_box_or_a_stopped_stream_is_a_timeout_not_a_hang() {
    let t = twin((1, 0));
    lock(t.faults()).ignore_requests = true;
    let t0 = Instant::now();
    let e = NetFtSensor::open(settings(&t), clock())
        .await
        .err()
        .expect("no stream");
    assert!(matches!(e, RigError::Timeout { .. }), "{e}");
    assert!(t0.elapsed() < Duration::from_secs(2));
    lock(t.faults()).ignore_requests = false;

    let mut s = NetFtSensor::open(settings(&t), clock())
        .await
        .expect("opens");
    s.read().await.expect("sample");
    lock(t.faults()).silent = true;
    tokio::time::sleep(Duration::from_millis(50)).await;
    let _ = s.read().await; // drains what was queued
    let e = s.read().await.expect_err("stopped");
    assert!(e.to_string().contains("stream stopped"), "{e}");

    // Nothing listening for calibration at all.
    let mut bad = settings(&t);
    bad.calibration = "127.0.0.1:1".parse().expect("addr");
    let e = NetFtSensor::open(bad, clock())
        .await
        .err()
        .expect("refused");
    assert!(
        matches!(e, RigError::Io { .. } | RigError::Timeout { .. }),
        "{e}"
    );
}

/// One record whose sequence number jumps by 2³¹ − 1, then normal records carrying 55 N:
/// the jump is reported (not swallowed), and the next reads carry the new load — the driver
/// never takes the real records for stale ones and repeats the last good 0 N sample.
#[tokio::test]
async fn a_sequence_jump_is_reported_and_never_blinds_the_reader() {
    let t = twin((1, 0));
    let mut s = NetFtSensor::open(settings(&t), clock())
        .await
        .expect("opens");
    let x = s.read().await.expect("sample");
    assert!(x.wrench.fz_n.abs() < 1e-9);
    lock(t.faults()).jump_once = Some(0x7fff_ffff);
    *lock(&t.load) = Wrench {
        fz_n: 55.0,
        ..Default::default()
    };
    let mut jumped = None;
    let mut loaded = None;
    let t0 = Instant::now();
    while t0.elapsed() < Duration::from_secs(2) && loaded.is_none() {
        match s.read().await {
            Ok(x) if x.wrench.fz_n > 50.0 => loaded = Some(x),
            Ok(_) => {}
            Err(e) => jumped = Some(e),
        }
    }
    let e = jumped.expect("the jump was reported");
    assert!(
        matches!(&e, RigError::Garbled { detail, .. } if detail.contains("jumped")),
        "{e}"
    );
    assert!(loaded.is_some(), "never read the 55 N after the jump");
    assert_eq!(s.stats().jumps, 1, "{:?}", s.stats());
}

/// Empty and 35-byte datagrams are reported as not whole records, and never make `read`
/// return an old sample again: each sample comes from a record newer than the last.
#[tokio::test]
async fn short_datagrams_are_reported_and_samples_are_never_repeated() {
    let t = twin((1, 0));
    let mut s = NetFtSensor::open(settings(&t), clock())
        .await
        .expect("opens");
    for n in [0usize, 35] {
        let before = s.read().await.expect("sample").ft_seq;
        lock(t.faults()).short_once = Some(n);
        let t0 = Instant::now();
        let mut reported = false;
        let mut last = before;
        while t0.elapsed() < Duration::from_millis(500) {
            match s.read().await {
                Ok(x) => {
                    assert!(
                        x.ft_seq > last,
                        "sample repeated: {} after {last}",
                        x.ft_seq
                    );
                    last = x.ft_seq;
                }
                Err(e) => {
                    assert!(e.to_string().contains(&format!("{n} bytes")), "{e}");
                    reported = true;
                }
            }
        }
        assert!(reported, "a {n}-byte datagram went unreported");
    }
    assert_eq!(s.stats().malformed, 2, "{:?}", s.stats());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn samples_are_stamped_when_taken_through_latency_jitter_and_drift() {
    // 2 ms of latency (known to the driver, as if calibrated), ±5 ms of jitter (0–10 ms
    // extra), a crystal 50 ppm slow.
    let t = twin((1, 0));
    {
        let mut f = lock(t.faults());
        f.latency_ms = 2.0;
        f.jitter_ms = 5.0;
        f.drift_ppm = 50.0;
    }
    let clock = clock();
    let mut s = NetFtSensor::open(
        NetFtSettings {
            latency_s: 0.002,
            ..settings(&t)
        },
        clock.clone(),
    )
    .await
    .expect("open");
    let t0 = clock.now_ns();
    let mut seen = Vec::new();
    let start = Instant::now();
    while start.elapsed() < Duration::from_secs(5) {
        s.read().await.expect("sample");
        seen.extend(s.take_received());
        // The runner reads at tens of Hz: stamps must not depend on when it reads.
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    let truth: std::collections::HashMap<u32, u64> = t
        .sample_times()
        .into_iter()
        .map(|(ft, at)| (ft, clock.ns_at(at)))
        .collect();
    let error_ms = |x: &rig::ForceSample| {
        truth
            .get(&(x.ft_seq as u32))
            .map(|&s| (x.t_ns as f64 - s as f64) * 1e-6)
    };
    let part = |from_s: f64, to_s: f64| -> Vec<f64> {
        seen.iter()
            .filter(|x| {
                let at = (x.t_ns.saturating_sub(t0)) as f64 * 1e-9;
                at >= from_s && at < to_s
            })
            .filter_map(error_ms)
            .collect()
    };
    let (early, late) = (part(0.0, 1.5), part(3.0, 10.0));
    assert!(
        early.len() > 300 && late.len() > 300,
        "{} {}",
        early.len(),
        late.len()
    );
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    // Stamped on arrival (before the model has 2 s of records): late by the jitter.
    assert!(
        mean(&early) > 1.0,
        "arrival stamps: {:.2} ms late",
        mean(&early)
    );
    let worst = late.iter().fold(0.0f64, |a, e| a.max(e.abs()));
    assert!(worst < 1.0, "model stamps: worst {worst:.3} ms");
    let timing = s.timing().expect("the driver reports its timing");
    let drift = timing.drift_ppm.expect("fitted");
    // Over 3 s the slope is loose (60 s: within 3 ppm, BENCHMARKS.md); its sign is not.
    assert!(drift > 0.0 && drift < 150.0, "drift {drift:.1} ppm");
    println!(
        "net f/t clock: arrival stamps {:.2} ms late on average; model stamps worst {worst:.3} ms, \
         drift {drift:.1} ppm",
        mean(&early)
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_7_khz_stream_read_at_20_hz_loses_no_record() {
    // The box's highest rate, read the way the runner reads it; every record is kept for
    // matching frames (the full 60 s is `examples/sync_study.rs`, BENCHMARKS.md).
    let t = NetFtTwin::spawn(TwinParams {
        rate_hz: 7000.0,
        ..params()
    })
    .expect("loopback sockets");
    let mut s = NetFtSensor::open(settings(&t), clock())
        .await
        .expect("open");
    let mut kept = 0usize;
    let start = Instant::now();
    while start.elapsed() < Duration::from_secs(3) {
        s.read().await.expect("sample");
        let got = s.take_received();
        // In order. (The box's counter may skip where the twin itself fell behind — a box
        // drops samples it cannot send — so its gaps are not the driver's losses; the
        // packet counter's are, in `stats`.)
        assert!(
            got.windows(2).all(|w| w[1].ft_seq > w[0].ft_seq),
            "out of order"
        );
        kept += got.len();
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    let st = s.stats();
    assert_eq!(
        st.lost + st.out_of_order + st.jumps + st.malformed,
        0,
        "{st:?}"
    );
    // 21 000 sent at full rate; a debug build's twin under load sends fewer.
    assert!(kept > 10_000, "{kept} records in 3 s, {st:?}");
}
