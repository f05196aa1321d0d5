//! The force a frame saw: the samples inside its exposure.
//!
//! The camera and the force sensor sample on their own clocks (25 Hz and up to 7 kHz);
//! both are put on the run's timebase by their drivers (clock models, `rig::clock_sync`).
//! A frame is matched to the force samples whose times fall inside its exposure — their
//! mean and the spread of Fz — or, when the sensor is read more slowly than the exposure
//! is long, to the force interpolated at the exposure midpoint between the samples around
//! it.

use rig::{ForceSample, Wrench};
use rundir::write::FrameForce;

/// The exposure window of a frame exposed around `t_ns`: its exposure when the camera
/// reports one (0: an instant), else half a frame period either side.
pub(super) fn window_ns(t_ns: u64, exposure_s: Option<f64>, fps: f64) -> (u64, u64) {
    let half_ns = match exposure_s {
        Some(e) if e.is_finite() && e >= 0.0 => e * 0.5e9,
        _ => 0.5e9 / fps.max(1e-3),
    } as u64;
    (t_ns.saturating_sub(half_ns), t_ns + half_ns)
}

/// Matches `samples` (untared, oldest first, covering the window and one either side) to
/// the window `[from_ns, to_ns]` around `mid_ns`; `None` if they do not reach it.
pub(super) fn match_window(
    samples: &[ForceSample],
    tare: &Wrench,
    (from_ns, to_ns): (u64, u64),
    mid_ns: u64,
) -> Option<FrameForce> {
    let inside: Vec<[f64; 6]> = samples
        .iter()
        .filter(|s| (from_ns..=to_ns).contains(&s.t_ns))
        .map(|s| s.wrench.minus(tare).as_array())
        .collect();
    if !inside.is_empty() {
        let n = inside.len() as f64;
        let mean: [f64; 6] = std::array::from_fn(|k| inside.iter().map(|w| w[k]).sum::<f64>() / n);
        let fz_sd_n = (inside.len() >= 2).then(|| {
            let v = inside.iter().map(|w| (w[2] - mean[2]).powi(2)).sum::<f64>() / (n - 1.0);
            v.sqrt()
        });
        return Some(FrameForce {
            wrench: Wrench::from_array(mean),
            fz_sd_n,
            samples: inside.len() as u32,
        });
    }
    let before = samples.iter().rev().find(|s| s.t_ns <= mid_ns)?;
    let after = samples.iter().find(|s| s.t_ns >= mid_ns)?;
    let (a, b) = (
        before.wrench.minus(tare).as_array(),
        after.wrench.minus(tare).as_array(),
    );
    let span = after.t_ns.saturating_sub(before.t_ns) as f64;
    let u = if span > 0.0 {
        (mid_ns - before.t_ns) as f64 / span
    } else {
        0.0
    };
    Some(FrameForce {
        wrench: Wrench::from_array(std::array::from_fn(|k| a[k] + u * (b[k] - a[k]))),
        fz_sd_n: None,
        samples: 0,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(t_ms: u64, fz_n: f64) -> ForceSample {
        ForceSample {
            t_ns: t_ms * 1_000_000,
            ft_seq: t_ms,
            wrench: Wrench {
                fz_n,
                ..Wrench::default()
            },
            status: 0,
        }
    }

    #[test]
    fn samples_inside_the_exposure_are_averaged() {
        let s: Vec<_> = (0..100).map(|k| sample(k, k as f64)).collect();
        let tare = Wrench {
            fz_n: 1.0,
            ..Wrench::default()
        };
        let w = window_ns(50_000_000, Some(0.01), 25.0);
        let m = match_window(&s, &tare, w, 50_000_000).expect("covered");
        // 45..=55 ms: 11 samples, mean 50, less the tare.
        assert_eq!(m.samples, 11);
        assert!((m.wrench.fz_n - 49.0).abs() < 1e-12);
        let sd = m.fz_sd_n.expect("spread");
        assert!((sd - (11.0f64 * 12.0 / 12.0).sqrt()).abs() < 1e-9, "{sd}");
    }

    #[test]
    fn a_slow_stream_is_interpolated_at_the_midpoint() {
        // 20 Hz samples, a 10 ms exposure between them.
        let s = vec![sample(0, 0.0), sample(50, 5.0)];
        let w = window_ns(20_000_000, Some(0.01), 25.0);
        let m = match_window(&s, &Wrench::default(), w, 20_000_000).expect("covered");
        assert_eq!(m.samples, 0);
        assert!((m.wrench.fz_n - 2.0).abs() < 1e-12);
        // Samples that stop before the exposure do not reach it.
        assert!(match_window(&s[..1], &Wrench::default(), w, 20_000_000).is_none());
        // No exposure reported: half a frame period either side.
        assert_eq!(
            window_ns(100_000_000, None, 25.0),
            (80_000_000, 120_000_000)
        );
    }
}
