//! The ATI CAN driver against its twin on the in-memory bus (this machine has no vcan):
//! little-endian short data, scaling from the settings, bias, status flags, frame loss.

use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use rig::device::{ForceRange, ForceSensor, STATUS_SATURATED, Wrench};
use rig::drivers::ati_can::{AtiCanSensor, AtiCanSettings};
use rig::drivers::can::{CanBus, MemBus, RawFrame};
use rig::twins::ati_can::AtiCanTwin;
use rig::{Clock, ClockMode, RigError, lock};

fn settings() -> AtiCanSettings {
    AtiCanSettings {
        base_id: 0x20,
        counts_per_n: 400.0,
        counts_per_nmm: 50.0,
        timeout: Duration::from_millis(100),
        retries: 2,
        range: ForceRange::NANO17,
    }
}

fn clock() -> Clock {
    Clock::new(ClockMode::Scaled { scale: 1.0 })
}

#[tokio::test]
async fn short_data_bias_and_status() {
    let bus = MemBus::new();
    let twin = AtiCanTwin::spawn(Box::new(bus.endpoint()), 0x20, 400.0, 50.0);
    *lock(&twin.load) = Wrench {
        fx_n: -1.5,
        fy_n: 0.25,
        fz_n: 12.0,
        tx_nmm: 3.0,
        ty_nmm: -4.0,
        tz_nmm: 20.0,
    };
    let mut s = AtiCanSensor::open(settings(), Box::new(bus.endpoint()), clock())
        .await
        .expect("opens");
    let x = s.read().await.expect("sample");
    let w = x.wrench;
    assert!(
        (w.fz_n - 12.0).abs() < 1.0 / 400.0 && (w.fx_n + 1.5).abs() < 1.0 / 400.0,
        "{w:?}"
    );
    assert!(
        (w.tz_nmm - 20.0).abs() < 1.0 / 50.0 && (w.ty_nmm + 4.0).abs() < 1.0 / 50.0,
        "{w:?}"
    );
    assert_eq!(x.status, 0);
    let seq = x.ft_seq;
    assert_eq!(s.read().await.expect("sample").ft_seq, seq + 1);
    s.bias().await.expect("bias");
    tokio::time::sleep(Duration::from_millis(5)).await;
    assert!(s.read().await.expect("sample").wrench.fz_n.abs() < 1e-9);
    lock(&twin.faults).status = 0x4000;
    let x = s.read().await.expect("sample");
    assert!(
        x.status & STATUS_SATURATED != 0 && x.status & 0x4000 != 0,
        "{:#x}",
        x.status
    );
}

#[tokio::test]
async fn missing_or_half_replies_are_bounded_errors() {
    let bus = MemBus::new();
    let twin = AtiCanTwin::spawn(Box::new(bus.endpoint()), 0x20, 400.0, 50.0);
    let mut s = AtiCanSensor::open(settings(), Box::new(bus.endpoint()), clock())
        .await
        .expect("opens");
    lock(&twin.faults).half_reply = true;
    let t0 = Instant::now();
    let e = s.read().await.expect_err("half replies");
    assert!(
        matches!(e, RigError::Timeout { .. }) && e.to_string().contains("no complete reply"),
        "{e}"
    );
    assert!(t0.elapsed() < Duration::from_secs(1));
    lock(&twin.faults).half_reply = false;
    // Every fifth frame lost on the bus (a request or one of the two reply frames): at
    // most two attempts in a row fail, so the retries still get complete replies.
    bus.drop_every.store(5, Ordering::Relaxed);
    for _ in 0..10 {
        s.read().await.expect("retried through loss");
    }
    bus.drop_every.store(0, Ordering::Relaxed);
    lock(&twin.faults).no_reply = true;
    assert!(matches!(s.read().await, Err(RigError::Timeout { .. })));
    // Nobody on the bus at all.
    let lonely = MemBus::new();
    assert!(
        AtiCanSensor::open(settings(), Box::new(lonely.endpoint()), clock())
            .await
            .is_err()
    );
    // Frames of other nodes are ignored.
    let ep = bus.endpoint();
    ep.send(RawFrame::new(0x7FF, &[1, 2, 3]))
        .await
        .expect("send");
}
