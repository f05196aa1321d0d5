//! How a twin's stage moves: like a drive, not like an ideal one.
//!
//! Real controllers take milliseconds to show motion after a trigger (the command is parsed,
//! the profile planned, the motor energised), come to rest a little past or short of the
//! target, and raise in-position only once the position has settled. A twin whose stage is
//! busy at once and lands exactly hides every bug in a driver's or a runner's idea of "the
//! move is done" (a drive raising BUSY 20 ms after the trigger once let a run record 0.28 deg
//! for a 1 deg step). [`Timing`] makes each of those explicit and injectable; every twin
//! (Zaber, SMC100, Modbus) moves through a [`Motion`].

use std::time::{Duration, Instant};

/// How a twin's stage behaves around a move.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Timing {
    /// After a move is accepted the stage shows rest at its old position for this long,
    /// wall time, before it reports itself moving.
    pub delay_before_busy: Duration,
    /// After the motion ends, in-position is raised only after this long.
    pub settle_to_in_position: Duration,
    /// The stage comes to rest this far past the target, in the device's units (steps,
    /// microsteps or mm; negative: short of it).
    pub overshoot: f64,
}

/// What a stage reports at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reading {
    /// Position, device units.
    pub position: f64,
    /// The drive reports motion.
    pub busy: bool,
    /// The drive reports in-position.
    pub in_position: bool,
}

/// One move of a twin's stage, at constant speed (scaled by the twin's time scale).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Motion {
    from: f64,
    to: f64,
    start: Instant,
    /// Device units per wall second.
    speed: f64,
    timing: Timing,
}

impl Motion {
    /// At rest at `position`.
    pub fn at_rest(position: f64) -> Self {
        Self {
            from: position,
            to: position,
            start: Instant::now(),
            speed: 1.0,
            timing: Timing::default(),
        }
    }

    /// A move from `from` to `to` at `speed` (device units per wall second) starting now.
    pub fn new(from: f64, to: f64, speed: f64, timing: Timing) -> Self {
        Self {
            from,
            to,
            start: Instant::now(),
            speed: speed.abs().max(1e-12),
            timing,
        }
    }

    /// Where the move ends up (the target and any overshoot).
    pub fn end(&self) -> f64 {
        if self.from == self.to {
            self.to
        } else {
            self.to + self.timing.overshoot * (self.to - self.from).signum()
        }
    }

    /// The stage's report at `now`.
    pub fn at(&self, now: Instant) -> Reading {
        let t = now.saturating_duration_since(self.start);
        let delay = self.timing.delay_before_busy;
        if t < delay {
            return Reading {
                position: self.from,
                busy: false,
                in_position: self.from == self.to,
            };
        }
        let end = self.end();
        let d = end - self.from;
        let moving_s = (t - delay).as_secs_f64();
        let travelled = self.speed * moving_s;
        if travelled < d.abs() {
            return Reading {
                position: self.from + d.signum() * travelled,
                busy: true,
                in_position: false,
            };
        }
        let arrived_s = moving_s - d.abs() / self.speed;
        Reading {
            position: end,
            busy: false,
            in_position: arrived_s >= self.timing.settle_to_in_position.as_secs_f64(),
        }
    }

    /// Stops where the stage is at `now` (a stop cancels any pending start).
    pub fn stopped(&self, now: Instant) -> Self {
        Self::at_rest(self.at(now).position)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn late_busy_overshoot_and_settling() {
        let timing = Timing {
            delay_before_busy: Duration::from_millis(50),
            settle_to_in_position: Duration::from_millis(30),
            overshoot: 1.0,
        };
        let m = Motion::new(0.0, 100.0, 1000.0, timing);
        let t0 = m.start;
        let at = |ms: u64| m.at(t0 + Duration::from_millis(ms));
        // Not yet moving: rest at the old position, not in position.
        let r = at(20);
        assert!(!r.busy && !r.in_position && r.position == 0.0, "{r:?}");
        // Moving.
        let r = at(100);
        assert!(r.busy && (r.position - 50.0).abs() < 1e-9, "{r:?}");
        // 101 units at 1000/s: motion ends at 151 ms; in position 30 ms later.
        let r = at(160);
        assert!(!r.busy && !r.in_position && r.position == 101.0, "{r:?}");
        let r = at(190);
        assert!(r.in_position && r.position == 101.0, "{r:?}");
        // A stop freezes it.
        let s = m.stopped(t0 + Duration::from_millis(100));
        assert!(!s.at(t0 + Duration::from_secs(1)).busy);
    }
}
