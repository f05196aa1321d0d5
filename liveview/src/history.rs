//! A channel history whose memory does not grow with the run: min/max buckets whose width
//! doubles whenever they fill (the decimation the interop spec asks for: live plots slow
//! past ~1,000 points and viewers have used GiB for kHz data).
//!
//! Every sample lands in the newest bucket; when there are `cap` buckets, neighbours are
//! merged pairwise and the bucket width doubles. Extremes survive every merge, so a spike
//! of one sample in a ten-hour run is still on the plot; the mean of a bucket is kept too.

use serde::Serialize;

/// Channels per sample (Fx, Fy, Fz, Tz).
pub const CHANNELS: usize = 4;

#[derive(Debug, Clone, Copy)]
struct Bucket {
    t0_ns: u64,
    t1_ns: u64,
    n: u64,
    min: [f64; CHANNELS],
    max: [f64; CHANNELS],
    sum: [f64; CHANNELS],
}

impl Bucket {
    fn new(t_ns: u64, v: &[f64; CHANNELS]) -> Self {
        Self {
            t0_ns: t_ns,
            t1_ns: t_ns,
            n: 1,
            min: *v,
            max: *v,
            sum: *v,
        }
    }

    fn add(&mut self, t_ns: u64, v: &[f64; CHANNELS]) {
        self.merge(&Bucket::new(t_ns, v));
    }

    fn merge(&mut self, o: &Bucket) {
        self.t1_ns = self.t1_ns.max(o.t1_ns);
        self.n += o.n;
        for c in 0..CHANNELS {
            self.min[c] = self.min[c].min(o.min[c]);
            self.max[c] = self.max[c].max(o.max[c]);
            self.sum[c] += o.sum[c];
        }
    }
}

/// Decimated history of a four-channel stream.
#[derive(Debug, Clone)]
pub struct History {
    cap: usize,
    width_ns: u64,
    buckets: Vec<Bucket>,
    samples: u64,
}

/// The history as the page plots it: per bucket its start time (s) and, per channel, the
/// bucket's minimum, maximum and mean.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Series {
    /// Start of each bucket, s on the run's timebase.
    pub t_s: Vec<f64>,
    /// Per channel, the bucket minima.
    pub min: [Vec<f64>; CHANNELS],
    /// Per channel, the bucket maxima.
    pub max: [Vec<f64>; CHANNELS],
    /// Per channel, the bucket means.
    pub mean: [Vec<f64>; CHANNELS],
    /// Samples the buckets hold.
    pub samples: u64,
    /// Width of a bucket, s.
    pub bucket_s: f64,
}

impl History {
    /// At most `cap` buckets (rounded up to an even number ≥ 4), the first `width_ns` wide.
    pub fn new(cap: usize, width_ns: u64) -> Self {
        let cap = cap.max(4).next_multiple_of(2);
        Self {
            cap,
            width_ns: width_ns.max(1),
            buckets: Vec::with_capacity(cap),
            samples: 0,
        }
    }

    /// Adds a sample at `t_ns` (samples arrive in time order; a late one joins the newest
    /// bucket rather than reordering history).
    pub fn push(&mut self, t_ns: u64, v: [f64; CHANNELS]) {
        if v.iter().any(|x| !x.is_finite()) {
            return;
        }
        self.samples += 1;
        match self.buckets.last_mut() {
            Some(b) if t_ns < b.t0_ns.saturating_add(self.width_ns) => b.add(t_ns, &v),
            _ => {
                if self.buckets.len() == self.cap {
                    self.halve();
                }
                // Buckets start on the grid of their width, so merged pairs stay aligned.
                let mut b = Bucket::new(t_ns, &v);
                b.t0_ns = t_ns - t_ns % self.width_ns;
                self.buckets.push(b);
            }
        }
    }

    /// Merges neighbouring buckets that share a cell of twice the width.
    fn halve(&mut self) {
        self.width_ns = self.width_ns.saturating_mul(2);
        let w = self.width_ns;
        let mut out: Vec<Bucket> = Vec::with_capacity(self.cap);
        for b in &self.buckets {
            let cell = b.t0_ns - b.t0_ns % w;
            match out.last_mut() {
                Some(last) if last.t0_ns == cell => last.merge(b),
                _ => {
                    let mut nb = *b;
                    nb.t0_ns = cell;
                    out.push(nb);
                }
            }
        }
        self.buckets = out;
        // A gap-free stream halves the count; a sparse one may not, so keep halving.
        if self.buckets.len() >= self.cap {
            self.halve();
        }
    }

    /// Buckets held.
    pub fn len(&self) -> usize {
        self.buckets.len()
    }

    /// No sample yet.
    pub fn is_empty(&self) -> bool {
        self.buckets.is_empty()
    }

    /// Samples seen.
    pub fn samples(&self) -> u64 {
        self.samples
    }

    /// The plotted series.
    pub fn series(&self) -> Series {
        let r = |x: f64| (x * 1e5).round() / 1e5;
        let per = |f: &dyn Fn(&Bucket, usize) -> f64| -> [Vec<f64>; CHANNELS] {
            std::array::from_fn(|c| self.buckets.iter().map(|b| r(f(b, c))).collect())
        };
        Series {
            t_s: self
                .buckets
                .iter()
                .map(|b| (b.t0_ns as f64 * 1e-9 * 1e4).round() / 1e4)
                .collect(),
            min: per(&|b, c| b.min[c]),
            max: per(&|b, c| b.max[c]),
            mean: per(&|b, c| b.sum[c] / b.n as f64),
            samples: self.samples,
            bucket_s: self.width_ns as f64 * 1e-9,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ten_hours_at_a_kilohertz_stay_within_the_cap_and_keep_the_spike() {
        let mut h = History::new(1000, 1_000_000);
        let hours = 10u64;
        let n = hours * 3600 * 1000;
        let spike_at = n / 3 + 17;
        let mut global = [f64::INFINITY, f64::NEG_INFINITY];
        for i in 0..n {
            let v = if i == spike_at {
                7.5
            } else {
                ((i % 1000) as f64 * 1e-3).sin()
            };
            global = [global[0].min(v), global[1].max(v)];
            h.push(i * 1_000_000, [0.0, 0.0, v, -v]);
            assert!(h.len() <= 1000, "{} buckets at sample {i}", h.len());
        }
        let s = h.series();
        assert_eq!(s.samples, n);
        assert!(s.t_s.len() > 250, "too few buckets: {}", s.t_s.len());
        let max = s.max[2].iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let min = s.min[3].iter().copied().fold(f64::INFINITY, f64::min);
        assert_eq!(max, 7.5);
        assert_eq!(min, -7.5);
        assert!((s.min[2].iter().copied().fold(f64::INFINITY, f64::min) - global[0]).abs() < 1e-5);
        // Bucket starts increase strictly and cover the run.
        assert!(s.t_s.windows(2).all(|w| w[0] < w[1]));
        assert!(s.t_s[0] == 0.0 && *s.t_s.last().unwrap_or(&0.0) > 35_000.0);
    }

    #[test]
    fn the_mean_of_a_bucket_is_the_mean_of_its_samples() {
        let mut h = History::new(4, 10);
        for (t, v) in [(0, 1.0), (5, 3.0), (10, 10.0)] {
            h.push(t, [v; 4]);
        }
        let s = h.series();
        assert_eq!(s.mean[0], vec![2.0, 10.0]);
        assert_eq!(s.min[1], vec![1.0, 10.0]);
        assert_eq!(s.max[1], vec![3.0, 10.0]);
    }

    #[test]
    fn sparse_samples_with_gaps_still_fit() {
        let mut h = History::new(8, 1);
        for i in 0..10_000u64 {
            h.push(i * i * 1000, [i as f64; 4]);
            assert!(h.len() <= 8);
        }
        assert_eq!(h.samples(), 10_000);
    }

    #[test]
    fn non_finite_samples_are_not_plotted() {
        let mut h = History::new(8, 1);
        h.push(0, [f64::NAN, 0.0, 0.0, 0.0]);
        assert!(h.is_empty());
    }
}
