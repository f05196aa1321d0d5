//! When a simulated camera's frames are exposed, when they reach the host, and the time the
//! host gives them.
//!
//! A USB camera's frames are exposed on its own crystal (a frame period off by tens of ppm),
//! read out at the end of the exposure and delivered after a latency that varies by
//! milliseconds (USB scheduling, the driver, the host). A host that stamps frames on arrival
//! is late by all of that, differently for each frame. The simulated camera injects each part
//! ([`Injected`]) and stamps frames as a careful driver would: the frame counter is the
//! camera's clock, fitted against the arrival times by the same lower envelope as the force
//! sensor's ([`CounterClock`]), less the exposure's second half and a latency calibrated per
//! setup. The true exposure midpoint goes with the frame ([`rig::Frame::truth_t_ns`]) so the
//! error can be measured.

use rand::{Rng, SeedableRng};

use rig::clock_sync::CounterClock;

/// Timing faults a simulated camera injects.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Injected {
    /// Delay every frame has from the end of its exposure to the host, s.
    pub latency_s: f64,
    /// Extra delay of each frame, uniform in 0…2× this, s ("± jitter" about its middle).
    pub jitter_s: f64,
    /// The camera's crystal runs this many ppm slow: its frames come that much further
    /// apart in host time.
    pub drift_ppm: f64,
}

/// One frame's times on the run's timebase, ns.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FrameTimes {
    /// The camera's frame counter.
    pub seq: u64,
    /// The true midpoint of the exposure.
    pub exposure_mid_ns: u64,
    /// When the frame reaches the host.
    pub arrival_ns: u64,
}

/// A camera's frame schedule and the host's model of it.
#[derive(Debug, Clone)]
pub struct FrameTiming {
    /// The camera's frame period in host time, ns (drift included).
    period_ns: f64,
    exposure_ns: f64,
    injected: Injected,
    rng: rand::rngs::StdRng,
    /// The last frame delivered (frames arrive in order).
    last: Option<FrameTimes>,
    model: CounterClock,
    /// Frames needed before the model is used (the lower envelope of a few frames is only
    /// as good as the least-delayed of them).
    min_frames: u64,
    seen: u64,
    last_t_ns: u64,
    latency_known_ns: f64,
    stamped_on_arrival: u64,
}

impl FrameTiming {
    /// A camera at `fps` exposing for `exposure_s`, with `injected` faults; the host knows
    /// the latency `latency_known_s` (calibrated) and the exposure.
    pub fn new(
        fps: f64,
        exposure_s: f64,
        injected: Injected,
        latency_known_s: f64,
        seed: u64,
    ) -> Self {
        let fps = if fps.is_finite() && fps > 0.0 {
            fps
        } else {
            1.0
        };
        let period_ns = 1e9 / fps * (1.0 + injected.drift_ppm * 1e-6);
        let exposure_ns = (exposure_s.max(0.0) * 1e9).min(period_ns);
        let latency_known_ns = latency_known_s.max(0.0) * 1e9;
        Self {
            period_ns,
            exposure_ns,
            injected,
            rng: rand::rngs::StdRng::seed_from_u64(seed ^ 0x5EED_CA3E),
            last: None,
            // One frame per bin; 500 frames (20 s at 25 Hz) in the window.
            model: CounterClock::new(fps, 1.0 / fps, 500.0 / fps)
                .with_known_latency_ns(latency_known_ns + exposure_ns / 2.0),
            min_frames: 100,
            seen: 0,
            last_t_ns: 0,
            latency_known_ns,
            stamped_on_arrival: 0,
        }
    }

    /// The exposure, s.
    pub fn exposure_s(&self) -> f64 {
        self.exposure_ns * 1e-9
    }

    /// The next frame for a capture asked at `now_ns`, and when it arrives: the frame after
    /// the last one delivered while it is still fresh in the driver's queue (it arrived
    /// less than a frame period ago: a stream read at the camera's rate, a little late,
    /// drops nothing), else the first whose exposure starts at or after `now_ns`.
    pub fn next_after(&mut self, now_ns: u64) -> FrameTimes {
        let mut seq = (now_ns as f64 / self.period_ns).ceil() as u64;
        if let Some(l) = self.last {
            let queued = l.seq + 1;
            let queued_arrival = (queued as f64 + 1.0) * self.period_ns
                + self.exposure_ns
                + self.injected.latency_s.max(0.0) * 1e9;
            if queued < seq && queued_arrival >= now_ns as f64 {
                seq = queued;
            }
            seq = seq.max(l.seq + 1);
        }
        let start_ns = seq as f64 * self.period_ns;
        let jitter_ns = if self.injected.jitter_s > 0.0 {
            self.rng
                .random_range(0.0..2.0 * self.injected.jitter_s * 1e9)
        } else {
            0.0
        };
        let arrival =
            start_ns + self.exposure_ns + self.injected.latency_s.max(0.0) * 1e9 + jitter_ns;
        let times = FrameTimes {
            seq,
            exposure_mid_ns: (start_ns + self.exposure_ns / 2.0).round() as u64,
            // In order: a frame cannot overtake the one before it.
            arrival_ns: (arrival.round() as u64).max(self.last.map_or(0, |l| l.arrival_ns)),
        };
        self.last = Some(times);
        times
    }

    /// The time the host gives frame `seq`, which arrived at `arrival_ns`: the model's once
    /// it has seen enough frames (never after the arrival, never before the frame before),
    /// else the arrival less the known latency and half the exposure.
    pub fn stamp(&mut self, seq: u64, arrival_ns: u64) -> u64 {
        self.model.observe(seq, arrival_ns);
        self.seen += 1;
        let on_arrival =
            || arrival_ns.saturating_sub((self.latency_known_ns + self.exposure_ns / 2.0) as u64);
        let t = match self.model.time_of(seq) {
            Some(t) if self.seen >= self.min_frames => t.min(arrival_ns),
            _ => {
                self.stamped_on_arrival += 1;
                on_arrival()
            }
        }
        .max(self.last_t_ns);
        self.last_t_ns = t;
        t
    }

    /// How frames are put on the timebase, for the manifest.
    pub fn report(&self) -> rig::DeviceTiming {
        rig::DeviceTiming {
            method: "the camera's frame counter against arrival times (lower envelope)".into(),
            latency_s: self.latency_known_ns * 1e-9,
            drift_ppm: self.model.drift_ppm(),
            stamped_on_arrival: self.stamped_on_arrival,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 25 Hz, 10 ms exposure, 2 ms latency, ±5 ms jitter, 50 ppm slow, for 60 s.
    fn errors_ms(seed: u64) -> (Vec<f64>, Vec<f64>) {
        let injected = Injected {
            latency_s: 0.002,
            jitter_s: 0.005,
            drift_ppm: 50.0,
        };
        let mut t = FrameTiming::new(25.0, 0.01, injected, 0.002, seed);
        let (mut early, mut late) = (Vec::new(), Vec::new());
        let mut now = 1_000_000_000u64;
        for k in 0..1500 {
            let f = t.next_after(now);
            now = f.arrival_ns;
            let stamp = t.stamp(f.seq, f.arrival_ns);
            let e = (stamp as f64 - f.exposure_mid_ns as f64) * 1e-6;
            if k < 100 { &mut early } else { &mut late }.push(e);
        }
        (early, late)
    }

    #[test]
    fn frames_are_stamped_at_their_exposure_through_latency_jitter_and_drift() {
        for seed in 1..4 {
            let (early, late) = errors_ms(seed);
            let mean = early.iter().sum::<f64>() / early.len() as f64;
            // On arrival: late by the jitter (5 ms on average).
            assert!(mean > 3.0, "arrival stamps {mean:.2} ms late");
            let worst = late.iter().fold(0.0f64, |a, e| a.max(e.abs()));
            assert!(worst < 0.5, "model stamps: worst {worst:.3} ms");
        }
    }

    #[test]
    fn frames_come_in_order_at_the_drifted_period() {
        let injected = Injected {
            latency_s: 0.0,
            jitter_s: 0.0,
            drift_ppm: 100.0,
        };
        let mut t = FrameTiming::new(25.0, 0.01, injected, 0.0, 1);
        let a = t.next_after(0);
        let b = t.next_after(a.arrival_ns);
        assert_eq!(b.seq, a.seq + 1);
        let period = (b.exposure_mid_ns - a.exposure_mid_ns) as f64;
        assert!((period - 40e6 * 1.0001).abs() < 2.0, "{period}");
        // Asking again for a time already passed gives the next frame, never the same one.
        assert_eq!(t.next_after(0).seq, b.seq + 1);
    }
}
