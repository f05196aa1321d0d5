//! A device's sample clock on the host's timebase, from its sample counter and the times its
//! samples arrive.
//!
//! A force/torque sensor such as the ATI Net F/T counts its own samples (`ft_sequence`, at
//! a nominal 7 kHz on a crystal that drifts by tens of ppm) and sends them over a network
//! whose delay varies but is never negative. Host arrival time of sample `n` is
//! `a_n = t₀ + n·P·(1 + δ) + d_n` with `d_n ≥ d_min`: every arrival lies on or above the
//! line of the sensor's clock shifted by the least delay. The line is found as the **lower
//! envelope** of the arrivals — the edge of their lower convex hull that minimises the sum of
//! the arrivals' heights above it, the linear-programming estimate of Moon, Skelly & Towsley,
//! "Estimation and removal of clock skew from network delay measurements" (IEEE INFOCOM 1999,
//! §III), the idea of TICSync (Harrison & Newman, ICRA 2011) — refitted over a sliding window
//! so the drift is tracked (devices spec §4, item 2).
//!
//! What it cannot see: the least delay itself. A constant latency every packet shares is,
//! from arrival times alone, the same as a clock offset; the model's times are the samples'
//! times plus `d_min`. That part is calibrated per setup (an event both sensors see) or,
//! where the latency is known, subtracted ([`CounterClock::with_known_latency_ns`]).
//!
//! Cost: arrivals are reduced to the earliest-relative point of each bin of the counter, so
//! a fit works on a few thousand points whatever the sample rate.

use std::collections::VecDeque;

/// One bin's lowest arrival: counter value and arrival less the nominal clock, ns.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Point {
    seq: u64,
    /// `arrival − seq·P`, ns, relative to the first arrival.
    y_ns: f64,
}

/// The fitted line: `arrival ≈ base + seq·P + intercept + slope·(seq − seq0)`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Line {
    seq0: u64,
    intercept_ns: f64,
    slope_ns: f64,
}

/// A counter clock tracked against host arrival times.
#[derive(Debug, Clone)]
pub struct CounterClock {
    period_ns: f64,
    /// Samples per bin.
    bin: u64,
    /// Bins kept (the sliding window).
    bins_kept: usize,
    /// Arrival of the first sample less its nominal time: keeps the numbers small.
    base_ns: Option<f64>,
    points: VecDeque<Point>,
    /// The bin being filled.
    open: Option<Point>,
    line: Option<Line>,
    latency_ns: f64,
}

/// Bins a fit needs before the model is used: until then samples keep their arrival time.
pub const MIN_BINS: usize = 20;

impl CounterClock {
    /// A clock counting at `rate_hz`, binned every `bin_s` and fitted over the last
    /// `window_s` (devices spec: 10–30 s tracks the drift of a crystal).
    pub fn new(rate_hz: f64, bin_s: f64, window_s: f64) -> Self {
        let rate = if rate_hz.is_finite() && rate_hz > 0.0 {
            rate_hz
        } else {
            1.0
        };
        let bin = (rate * bin_s.max(1e-6)).round().max(1.0) as u64;
        let bins_kept = ((window_s / bin_s.max(1e-6)).round() as usize).max(MIN_BINS);
        Self {
            period_ns: 1e9 / rate,
            bin,
            bins_kept,
            base_ns: None,
            points: VecDeque::new(),
            open: None,
            line: None,
            latency_ns: 0.0,
        }
    }

    /// Subtracts a latency known from elsewhere (calibrated, or injected by a twin) from
    /// every time the model gives.
    pub fn with_known_latency_ns(mut self, latency_ns: f64) -> Self {
        self.latency_ns = latency_ns.max(0.0);
        self
    }

    /// Records that sample `seq` (unwrapped) arrived at host time `arrival_ns`.
    pub fn observe(&mut self, seq: u64, arrival_ns: u64) {
        let nominal = seq as f64 * self.period_ns;
        let base = *self.base_ns.get_or_insert(arrival_ns as f64 - nominal);
        let p = Point {
            seq,
            y_ns: arrival_ns as f64 - nominal - base,
        };
        match &mut self.open {
            Some(o) if o.seq / self.bin == seq / self.bin => {
                if p.y_ns < o.y_ns {
                    *o = p;
                }
            }
            _ => {
                if let Some(done) = self.open.replace(p) {
                    self.close(done);
                }
            }
        }
    }

    fn close(&mut self, p: Point) {
        // Counters only go forward; a late duplicate of an old bin is dropped.
        if self.points.back().is_some_and(|b| b.seq >= p.seq) {
            return;
        }
        self.points.push_back(p);
        while self.points.len() > self.bins_kept {
            self.points.pop_front();
        }
        if self.points.len() >= MIN_BINS {
            self.line = lower_envelope(self.points.make_contiguous());
        }
    }

    /// True once enough arrivals were seen to use the model.
    pub fn ready(&self) -> bool {
        self.line.is_some()
    }

    /// Host time of sample `seq`, ns: the model's once [`Self::ready`], else `None`.
    pub fn time_of(&self, seq: u64) -> Option<u64> {
        let (line, base) = (self.line?, self.base_ns?);
        let dx = seq as f64 - line.seq0 as f64;
        let t = base + seq as f64 * self.period_ns + line.intercept_ns + line.slope_ns * dx
            - self.latency_ns;
        (t.is_finite() && t >= 0.0).then_some(t.round() as u64)
    }

    /// The sensor's clock rate against the host's, ppm (positive: its samples come slower
    /// than nominal, i.e. its crystal runs slow).
    pub fn drift_ppm(&self) -> Option<f64> {
        self.line.map(|l| l.slope_ns / self.period_ns * 1e6)
    }
}

/// The edge of the lower convex hull of `points` (ascending `seq`) that minimises the sum
/// of the points' heights above it: the edge whose span holds the points' mean `seq`
/// (Moon et al. 1999: the objective is linear along the hull, so its minimum is there).
fn lower_envelope(points: &[Point]) -> Option<Line> {
    let seq0 = points.first()?.seq;
    let xy: Vec<(f64, f64)> = points
        .iter()
        .map(|p| ((p.seq - seq0) as f64, p.y_ns))
        .collect();
    // Andrew's monotone chain, lower half.
    let mut hull: Vec<(f64, f64)> = Vec::with_capacity(xy.len());
    for &p in &xy {
        while hull.len() >= 2 {
            let (a, b) = (hull[hull.len() - 2], hull[hull.len() - 1]);
            let cross = (b.0 - a.0) * (p.1 - a.1) - (b.1 - a.1) * (p.0 - a.0);
            if cross <= 0.0 {
                hull.pop();
            } else {
                break;
            }
        }
        hull.push(p);
    }
    if hull.len() < 2 {
        return None;
    }
    let mean_x = xy.iter().map(|p| p.0).sum::<f64>() / xy.len() as f64;
    let k = hull
        .windows(2)
        .position(|w| w[0].0 <= mean_x && mean_x <= w[1].0)
        .unwrap_or(hull.len() - 2);
    let (a, b) = (hull[k], hull[k + 1]);
    let slope = (b.1 - a.1) / (b.0 - a.0);
    Some(Line {
        seq0,
        intercept_ns: a.1 - slope * a.0,
        slope_ns: slope,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// A 7 kHz counter whose crystal is 50 ppm slow, sent in packets of 7 samples every
    /// 1 ms with 2 ms of latency and up to 10 ms more (±5 ms about its middle), 60 s.
    /// Per packet: its last sample, the model's error and the arrival stamp's error, ns.
    fn simulate(seed: u64, model: &mut CounterClock) -> Vec<(u64, f64, f64)> {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let period_true_ns = 1e9 / 7000.0 * (1.0 + 50e-6);
        let t0_ns = 5e9;
        let mut errors = Vec::new();
        for packet in 0..60_000u64 {
            let last = packet * 7 + 6;
            let t_last = t0_ns + last as f64 * period_true_ns;
            let arrival = t_last + 2e6 + rng.random_range(0.0..10e6);
            for k in packet * 7..=last {
                model.observe(k, arrival as u64);
            }
            if let Some(t) = model.time_of(last) {
                errors.push((last, t as f64 - t_last, arrival - t_last));
            }
        }
        errors
    }

    #[test]
    fn the_envelope_recovers_sample_times_within_a_millisecond_under_jitter_and_drift() {
        for seed in 0..3 {
            let mut m = CounterClock::new(7000.0, 0.01, 20.0).with_known_latency_ns(2e6);
            let errors = simulate(seed, &mut m);
            // After the first window, every sample's time is within 1 ms of its truth.
            let worst = errors
                .iter()
                .filter(|(seq, _, _)| *seq > 7000 * 20)
                .map(|(_, e, _)| e.abs())
                .fold(0.0, f64::max);
            assert!(worst < 1e6, "seed {seed}: worst {:.3} ms", worst * 1e-6);
            let ppm = m.drift_ppm().expect("fitted");
            assert!((ppm - 50.0).abs() < 5.0, "drift {ppm} ppm");
        }
    }

    #[test]
    fn without_the_known_latency_the_times_are_late_by_it() {
        let mut m = CounterClock::new(7000.0, 0.01, 20.0);
        let errors = simulate(7, &mut m);
        let late: Vec<f64> = errors
            .iter()
            .filter(|(seq, _, _)| *seq > 7000 * 20)
            .map(|(_, e, _)| *e)
            .collect();
        let mean = late.iter().sum::<f64>() / late.len() as f64;
        assert!(
            (mean - 2e6).abs() < 0.5e6,
            "mean lateness {:.3} ms",
            mean * 1e-6
        );
    }

    #[test]
    fn the_model_beats_stamping_on_arrival_by_an_order_of_magnitude() {
        let mut m = CounterClock::new(7000.0, 0.01, 20.0).with_known_latency_ns(2e6);
        let errors = simulate(3, &mut m);
        let rms = |f: &dyn Fn(&(u64, f64, f64)) -> f64| {
            (errors.iter().map(|e| f(e).powi(2)).sum::<f64>() / errors.len() as f64).sqrt()
        };
        let (model, arrival) = (rms(&|e| e.1), rms(&|e| e.2));
        assert!(
            arrival > 5e6,
            "arrival stamps are late by the delay: {arrival}"
        );
        assert!(
            model * 10.0 < arrival,
            "model {model} ns, arrival {arrival} ns"
        );
        assert!(m.points.len() <= m.bins_kept, "the window is bounded");
    }
}
