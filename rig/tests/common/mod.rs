//! Helpers shared by the driver tests.

use std::time::{Duration, Instant};

use rig::device::Axis;

/// Polls `a` until it stops (at most 10 s) and returns where it stopped.
pub(crate) async fn wait_idle(a: &mut dyn Axis) -> f64 {
    poll_until_idle(a, Duration::from_millis(20)).await
}

/// Polls `a` back to back, as a runner waiting on a move does, until it reports rest (at
/// most 10 s); returns the position that status carried.
#[allow(dead_code)] // not every test binary uses it
pub(crate) async fn rest_position(a: &mut dyn Axis) -> f64 {
    poll_until_idle(a, Duration::ZERO).await
}

async fn poll_until_idle(a: &mut dyn Axis, pause: Duration) -> f64 {
    let t0 = Instant::now();
    loop {
        let s = a.status().await.expect("status");
        if !s.moving {
            return s.position;
        }
        assert!(t0.elapsed() < Duration::from_secs(10), "never stopped");
        if !pause.is_zero() {
            tokio::time::sleep(pause).await;
        }
    }
}
