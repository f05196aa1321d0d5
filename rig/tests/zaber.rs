//! The production Zaber driver against its twin over a real pseudo-terminal: motion,
//! limits, reference state, checksums, and every injected fault (a clear error or a
//! bounded retry; never a hang, never a panic).

use std::time::{Duration, Instant};

use rig::device::{Axis, AxisInfo};
use rig::drivers::zaber::{ZaberAxis, ZaberSettings};
use rig::twins::zaber::{TwinParams, ZaberTwin};
use rig::units::AxisUnit;

mod common;
use common::wait_idle;
use rig::{RigError, lock};

const MICROSTEP_MM: f64 = 0.047625e-3;

fn twin(require_checksum: bool) -> ZaberTwin {
    // 0–25 mm of travel in microsteps.
    ZaberTwin::spawn(TwinParams {
        device: 1,
        limits: (0, (25.0 / MICROSTEP_MM) as i64),
        require_checksum,
        time_scale: 1.0,
    })
    .expect("a pty")
}

fn info() -> AxisInfo {
    AxisInfo {
        role: "normal".into(),
        unit: AxisUnit::Mm,
        travel_min: 0.0,
        travel_max: 25.0,
        max_speed: 5.0,
        resolution: 0.002,
        identity: String::new(),
    }
}

fn settings(t: &ZaberTwin, checksum: bool) -> ZaberSettings {
    ZaberSettings {
        port: t.path().to_string(),
        device: 1,
        axis: 1,
        microstep: MICROSTEP_MM,
        checksum,
        timeout: Duration::from_millis(150),
        retries: 2,
    }
}

#[tokio::test]
async fn homes_moves_and_reports_position_over_a_pty() {
    let t = twin(true);
    let mut a = ZaberAxis::open(settings(&t, true), info())
        .await
        .expect("opens");
    assert!(a.info().identity.contains("50081"), "{}", a.info().identity);
    let s = a.status().await.expect("status");
    assert!(!s.referenced, "WR until homed");
    // Moving before homing is refused as not referenced.
    let e = a.move_to(1.0, 2.0).await.expect_err("not homed");
    assert!(matches!(e, RigError::NotReferenced { .. }), "{e}");
    a.home().await.expect("home");
    wait_idle(&mut a).await;
    assert!(a.status().await.expect("status").referenced);
    a.move_to(0.42, 2.0).await.expect("move");
    assert!(
        a.status().await.expect("status").moving,
        "BUSY right after the move"
    );
    let p = wait_idle(&mut a).await;
    assert!((p - 0.42).abs() < MICROSTEP_MM, "{p}");
    // Outside travel or too fast: refused before anything is sent.
    assert!(matches!(
        a.move_to(30.0, 1.0).await,
        Err(RigError::OutOfTravel { .. })
    ));
    assert!(matches!(
        a.move_to(1.0, 50.0).await,
        Err(RigError::BadSpeed { .. })
    ));
    // A stop mid-move leaves the axis between start and target, flagged interrupted.
    a.move_to(5.0, 5.0).await.expect("move");
    tokio::time::sleep(Duration::from_millis(100)).await;
    a.stop().await.expect("stop");
    assert_eq!(a.last_warning.as_deref(), Some("NI"));
    let p = wait_idle(&mut a).await;
    assert!(p > 0.42 && p < 5.0, "{p}");
    assert!(
        t.transcript()
            .iter()
            .any(|l| l.starts_with("> /1 1 ") && l.contains(':')),
        "checksummed commands"
    );
}

#[tokio::test]
async fn a_device_requiring_checksums_rejects_a_driver_without_them() {
    let t = twin(true);
    let e = ZaberAxis::open(settings(&t, false), info())
        .await
        .err()
        .expect("rejected");
    assert!(
        matches!(&e, RigError::Rejected { reason, .. } if reason == "BADDATA"),
        "{e}"
    );
}

#[tokio::test]
async fn injected_faults_give_clear_errors_or_bounded_retries() {
    let t = twin(false);
    let mut a = ZaberAxis::open(settings(&t, true), info())
        .await
        .expect("opens");
    a.home().await.expect("home");
    wait_idle(&mut a).await;

    // No reply: a timeout after the retries, in bounded time.
    lock(t.faults()).no_reply = true;
    let t0 = Instant::now();
    let e = a.status().await.expect_err("no reply");
    assert!(matches!(e, RigError::Timeout { .. }), "{e}");
    assert!(t0.elapsed() < Duration::from_secs(2), "{:?}", t0.elapsed());
    assert!(e.to_string().contains("gelrig probe"));
    lock(t.faults()).no_reply = false;

    // One garbled reply: retried, and the command succeeds.
    lock(t.faults()).garble_next = 1;
    a.status().await.expect("recovers after one garbled reply");
    // Every reply garbled: a garbled-reply error naming the problem.
    lock(t.faults()).garble_next = 10;
    let e = a.status().await.expect_err("garbled");
    assert!(matches!(e, RigError::Garbled { .. }), "{e}");
    lock(t.faults()).garble_next = 0;

    // Replies slower than the timeout: late replies are not mistaken for later ones.
    lock(t.faults()).delay = Duration::from_millis(400);
    let e = a.status().await.expect_err("too slow");
    assert!(matches!(e, RigError::Timeout { .. }), "{e}");
    lock(t.faults()).delay = Duration::ZERO;
    tokio::time::sleep(Duration::from_millis(1500)).await;
    a.move_to(0.1, 1.0)
        .await
        .expect("move after the late replies drained");
    let p = wait_idle(&mut a).await;
    assert!((p - 0.1).abs() < MICROSTEP_MM, "{p}");

    // Unplugged: an error, not a hang.
    lock(t.faults()).disconnect = true;
    tokio::time::sleep(Duration::from_millis(50)).await;
    let t0 = Instant::now();
    let e = a.status().await.expect_err("disconnected");
    assert!(t0.elapsed() < Duration::from_secs(2));
    match &e {
        RigError::Timeout { .. } => {}
        RigError::Io { .. } => assert!(e.to_string().contains("disconnected; fix"), "{e}"),
        _ => panic!("{e}"),
    }
}

#[tokio::test]
async fn a_wrong_port_path_is_a_clear_error() {
    let mut s = settings(&twin(false), false);
    s.port = "/dev/pts/does-not-exist".into();
    let e = ZaberAxis::open(s, info())
        .await
        .err()
        .expect("no such port");
    assert!(e.to_string().contains("rig file"), "{e}");
}
