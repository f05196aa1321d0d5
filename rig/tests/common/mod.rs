//! Helpers shared by the driver tests.

use std::time::{Duration, Instant};

use rig::device::Axis;

/// Polls `a` until it stops (at most 10 s) and returns where it stopped.
pub(crate) async fn wait_idle(a: &mut dyn Axis) -> f64 {
    let t0 = Instant::now();
    loop {
        let s = a.status().await.expect("status");
        if !s.moving {
            return s.position;
        }
        assert!(t0.elapsed() < Duration::from_secs(10), "never stopped");
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
}
