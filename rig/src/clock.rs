//! The run's single timebase.
//!
//! Every sample, move and frame carries `t_ns` from one clock (ARCHITECTURE.md, "Time").
//! On a real bench it is CLOCK_MONOTONIC in nanoseconds, comparable with V4L2 buffer
//! timestamps. On the simulated bench the same code runs on *virtual* time: the runner is
//! driven by tokio's paused clock, which jumps straight to the next timer whenever every
//! task is waiting, so a protocol with twenty 3-minute settles finishes in about a second,
//! deterministically. A *scaled* clock runs k× faster than the wall, for watching a dry run
//! or interrupting it in a test.

use std::time::Duration;

use tokio::time::Instant;

/// How the clock relates to the wall.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(rename_all = "snake_case", tag = "kind")]
pub enum ClockMode {
    /// Paused tokio time that auto-advances: as fast as the computation allows. Requires a
    /// runtime built with `start_paused(true)`.
    Virtual,
    /// Real time divided by `scale`: `scale = 60` runs an hour in a minute.
    Scaled {
        /// Speed-up over the wall clock.
        scale: f64,
    },
    /// CLOCK_MONOTONIC, for real devices.
    Monotonic,
}

use serde::Serialize;

/// A cheaply cloneable handle to the run's clock.
#[derive(Debug, Clone)]
pub struct Clock {
    origin: Instant,
    origin_ns: u64,
    scale: f64,
    mode: ClockMode,
}

impl Clock {
    /// Builds a clock in `mode`, starting now.
    pub fn new(mode: ClockMode) -> Self {
        let (origin_ns, scale) = match mode {
            ClockMode::Virtual => (0, 1.0),
            ClockMode::Scaled { scale } => (0, scale.max(1e-9)),
            ClockMode::Monotonic => (monotonic_ns(), 1.0),
        };
        Self {
            origin: Instant::now(),
            origin_ns,
            scale,
            mode,
        }
    }

    /// Builds a clock in `mode` that reads `t0_ns` now: a resumed run continues on its own
    /// timebase. A real clock cannot be set: it keeps reading CLOCK_MONOTONIC, which the
    /// caller checks is past `t0_ns`.
    pub fn starting_at(mode: ClockMode, t0_ns: u64) -> Self {
        let mut c = Self::new(mode);
        if !matches!(mode, ClockMode::Monotonic) {
            c.origin_ns = t0_ns;
        }
        c
    }

    /// The clock's reading at a wall-clock `instant` (a device twin's record of when it
    /// sampled); for real and scaled clocks (a virtual clock's time is not the wall's).
    pub fn ns_at(&self, instant: std::time::Instant) -> u64 {
        let d = instant
            .saturating_duration_since(self.origin.into_std())
            .as_nanos() as f64
            * self.scale;
        self.origin_ns + d as u64
    }

    /// The clock's mode.
    pub fn mode(&self) -> ClockMode {
        self.mode
    }

    /// True unless the clock is real time: simulated devices may only run on such a clock.
    pub fn is_simulated(&self) -> bool {
        !matches!(self.mode, ClockMode::Monotonic)
    }

    /// Current time in ns on the run's timebase.
    pub fn now_ns(&self) -> u64 {
        let elapsed = self.origin.elapsed().as_nanos() as f64 * self.scale;
        self.origin_ns + elapsed as u64
    }

    /// Sleeps until the clock reads `t_ns` (returns at once if it already does). A wait
    /// longer than a year of wall time is cut to a year: nothing a run waits for is that far
    /// away, and an `Instant` that far out could overflow; the caller's loop wakes and waits
    /// again.
    pub async fn sleep_until_ns(&self, t_ns: u64) {
        const YEAR_NS: f64 = 365.0 * 86_400.0 * 1e9;
        let ahead_ns = (t_ns.saturating_sub(self.origin_ns) as f64 / self.scale)
            .min(self.origin.elapsed().as_nanos() as f64 + YEAR_NS);
        let deadline = self
            .origin
            .checked_add(Duration::from_nanos(ahead_ns.ceil() as u64))
            .unwrap_or_else(|| Instant::now() + Duration::from_secs(86_400));
        tokio::time::sleep_until(deadline).await;
    }

    /// Sleeps for `s` seconds of clock time.
    pub async fn sleep_s(&self, s: f64) {
        let target = self.now_ns() + (s.max(0.0) * 1e9) as u64;
        self.sleep_until_ns(target).await;
    }
}

/// CLOCK_MONOTONIC in ns (the V4L2 and host-stamping timebase, devices spec §4).
pub fn monotonic_ns() -> u64 {
    match nix::time::clock_gettime(nix::time::ClockId::CLOCK_MONOTONIC) {
        Ok(ts) => ts.tv_sec() as u64 * 1_000_000_000 + ts.tv_nsec() as u64,
        // CLOCK_MONOTONIC cannot fail on Linux; fall back to a still-monotonic source.
        Err(_) => std::time::Instant::now().elapsed().as_nanos() as u64,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test(start_paused = true)]
    async fn virtual_clock_jumps_through_sleeps() {
        let clock = Clock::new(ClockMode::Virtual);
        let wall = std::time::Instant::now();
        clock.sleep_s(3600.0).await;
        assert!(clock.now_ns() >= 3_600_000_000_000);
        assert!(wall.elapsed() < Duration::from_secs(1));
    }

    #[tokio::test]
    async fn scaled_clock_runs_faster_than_the_wall() {
        let clock = Clock::new(ClockMode::Scaled { scale: 1000.0 });
        clock.sleep_s(20.0).await;
        assert!(clock.now_ns() >= 20_000_000_000);
    }
}
