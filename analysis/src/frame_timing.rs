//! A camera's timing from what a run recorded: frame intervals, dropped and duplicated
//! frames, how many force samples each exposure held, and — on a simulated bench — how far
//! frame times are from the true exposure.

/// One recorded frame, as the timing analysis reads it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameTime {
    /// Frame time on the run's timebase, ns.
    pub t_ns: u64,
    /// The camera's frame counter.
    pub seq: u64,
    /// Force samples inside its exposure (`None`: not matched).
    pub force_samples: Option<u32>,
    /// The true exposure midpoint (simulated bench), ns.
    pub truth_t_ns: Option<u64>,
}

/// The camera's timing over a run.
#[derive(Debug, Clone, PartialEq)]
pub struct CameraTiming {
    /// Intervals between consecutive frames of a stream, ms.
    pub intervals_ms: Vec<f64>,
    /// The stream's commonest step of the frame counter (1 when every frame is kept; k when
    /// a stream keeps every k-th frame of the camera).
    pub stride: u64,
    /// Frames missing from the streams: counter steps longer than the stride.
    pub dropped: u64,
    /// Frames recorded twice: the counter or the time did not advance.
    pub duplicated: u64,
    /// Frames matched to the force of their exposure.
    pub matched: usize,
    /// Of those, frames whose exposure held no force sample (interpolated).
    pub interpolated: usize,
    /// Median force samples per exposure.
    pub median_samples: Option<f64>,
    /// Frame time less the true exposure midpoint, ms (simulated bench).
    pub errors_ms: Vec<f64>,
}

/// Frames closer together than this belong to one stream (a record block); farther apart,
/// they are separate captures (a frame per step) whose counter gaps are not drops.
const STREAM_GAP_NS: u64 = 1_000_000_000;

/// The timing of `frames` (in recording order).
pub fn camera_timing(frames: &[FrameTime]) -> CameraTiming {
    let pairs: Vec<(&FrameTime, &FrameTime)> = frames
        .windows(2)
        .map(|w| (&w[0], &w[1]))
        .filter(|(a, b)| b.t_ns.saturating_sub(a.t_ns) < STREAM_GAP_NS)
        .collect();
    // The stride is the commonest step of the counter (the smaller on a tie): drops are the
    // exception, and a stream at a rate that does not divide the camera's alternates steps.
    let mut counts = std::collections::BTreeMap::<u64, usize>::new();
    for (a, b) in &pairs {
        if b.seq > a.seq {
            *counts.entry(b.seq - a.seq).or_default() += 1;
        }
    }
    let stride = counts
        .iter()
        .max_by(|x, y| x.1.cmp(y.1).then(y.0.cmp(x.0)))
        .map_or(1, |(s, _)| *s);
    let mut dropped = 0;
    let mut duplicated = 0;
    for (a, b) in &pairs {
        if b.seq <= a.seq || b.t_ns <= a.t_ns {
            duplicated += 1;
        } else if b.seq - a.seq > stride {
            dropped += (b.seq - a.seq) / stride - 1;
        }
    }
    let intervals_ms = pairs
        .iter()
        .map(|(a, b)| b.t_ns.saturating_sub(a.t_ns) as f64 * 1e-6)
        .collect();
    let matched: Vec<u32> = frames.iter().filter_map(|f| f.force_samples).collect();
    let mut samples: Vec<f64> = matched.iter().map(|&n| f64::from(n)).collect();
    CameraTiming {
        intervals_ms,
        stride,
        dropped,
        duplicated,
        matched: matched.len(),
        interpolated: matched.iter().filter(|&&n| n == 0).count(),
        median_samples: tracking::median(&mut samples),
        errors_ms: frames
            .iter()
            .filter_map(|f| f.truth_t_ns.map(|t| (f.t_ns as f64 - t as f64) * 1e-6))
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(t_ms: u64, seq: u64) -> FrameTime {
        FrameTime {
            t_ns: t_ms * 1_000_000,
            seq,
            force_samples: Some(3),
            truth_t_ns: Some(t_ms * 1_000_000 + 500_000),
        }
    }

    #[test]
    fn drops_and_duplicates_are_counted_within_streams() {
        // A 25 Hz stream keeping every frame: seq 10, 11, (12 dropped), 13, 13 again; then a
        // single frame a minute later, whose counter gap is not a drop.
        let frames = [
            frame(400, 10),
            frame(440, 11),
            frame(520, 13),
            frame(520, 13),
            frame(60_000, 1500),
        ];
        let t = camera_timing(&frames);
        assert_eq!(t.stride, 1);
        assert_eq!(t.dropped, 1);
        assert_eq!(t.duplicated, 1);
        assert_eq!(t.intervals_ms, vec![40.0, 80.0, 0.0]);
        assert_eq!(t.matched, 5);
        assert_eq!(t.median_samples, Some(3.0));
        assert!(t.errors_ms.iter().all(|e| (e + 0.5).abs() < 1e-9));
    }

    #[test]
    fn a_stream_that_keeps_every_kth_frame_is_not_dropping() {
        // 10 Hz from a 25 Hz camera: the counter steps by 2 or 3.
        let frames: Vec<FrameTime> = (0..20u64).map(|k| frame(100 * k, k * 5 / 2)).collect();
        let t = camera_timing(&frames);
        assert_eq!(t.dropped, 0, "{t:?}");
        assert_eq!(t.duplicated, 0);
    }
}
