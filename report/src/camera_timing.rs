//! The report's camera timing: the frame interval histogram, dropped and duplicated frames,
//! how each frame was matched to the force of its exposure, how each device's times were put
//! on the run's timebase, and — on a simulated bench — the frame times' error against the
//! true exposure.

use analysis::frame_timing::{CameraTiming, FrameTime, camera_timing};
use serde_json::{Value, json};

use super::RunData;
use super::out::{f, num};
use super::plots::{Chart, Series};

/// Histogram bins of the frame intervals: `(centre_ms, count)`, 1 ms wide (wider when the
/// intervals spread over more than 200 ms).
fn histogram(intervals_ms: &[f64]) -> Vec<(f64, f64)> {
    let (lo, hi) = intervals_ms
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    if !lo.is_finite() || !hi.is_finite() {
        return Vec::new();
    }
    let width = ((hi - lo) / 200.0).max(1.0).ceil();
    let start = (lo / width).floor() * width;
    let n = (((hi - start) / width).floor() as usize + 1).min(10_000);
    let mut counts = vec![0.0; n];
    for &v in intervals_ms {
        let k = (((v - start) / width).floor() as usize).min(n - 1);
        counts[k] += 1.0;
    }
    // Drawn as steps: each bin's count across its width.
    counts
        .iter()
        .enumerate()
        .flat_map(|(k, &c)| {
            let x0 = start + k as f64 * width;
            [(x0, c), (x0 + width, c)]
        })
        .collect()
}

fn quantile(v: &[f64], q: f64) -> f64 {
    let mut s: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
    if s.is_empty() {
        return f64::NAN;
    }
    s.sort_by(f64::total_cmp);
    s[((s.len() - 1) as f64 * q).round() as usize]
}

fn timing_lines(data: &RunData) -> String {
    let mut text = String::new();
    for (role, t) in &data.manifest.timing {
        text.push_str(&format!(
            "\nThe {role}'s times: {}; latency subtracted {} ms; clock drift {}; the first {} \
             stamped on arrival, before the model had seen enough.\n",
            t.method,
            f(t.latency_s * 1e3, 2),
            t.drift_ppm
                .map_or("not fitted".to_string(), |d| format!("{} ppm", f(d, 1))),
            t.stamped_on_arrival
        ));
    }
    text
}

/// The section's title, markdown, `summary.json` entry and chart, when the run has frames.
pub(super) fn section(data: &RunData) -> Option<(String, String, Value, Option<Chart>)> {
    if data.frames.len() < 2 {
        return None;
    }
    let frames: Vec<FrameTime> = data
        .frames
        .iter()
        .map(|r| FrameTime {
            t_ns: r.t_ns,
            seq: r.seq.unwrap_or(r.frame),
            force_samples: r.force_samples,
            truth_t_ns: r.sim_t_ns,
        })
        .collect();
    let t: CameraTiming = camera_timing(&frames);
    let mut text = String::new();
    if t.intervals_ms.is_empty() {
        text.push_str(&format!(
            "{} frames, each captured on its own (no frame streams): no intervals to show.\n",
            frames.len()
        ));
    } else {
        text.push_str(&format!(
            "{} frames; {} intervals within frame streams: median {} ms, 1st–99th percentile \
             {}–{} ms. The camera's counter steps by {} per recorded frame; {} frame(s) \
             dropped, {} duplicated.\n",
            frames.len(),
            t.intervals_ms.len(),
            f(quantile(&t.intervals_ms, 0.5), 2),
            f(quantile(&t.intervals_ms, 0.01), 2),
            f(quantile(&t.intervals_ms, 0.99), 2),
            t.stride,
            t.dropped,
            t.duplicated
        ));
    }
    if t.matched > 0 {
        text.push_str(&format!(
            "\nEach frame is matched to the force samples inside its exposure (`frames.csv` \
             `fx_n` … `tz_nmm`, `fz_sd_n`, `force_samples`): {} of {} frames matched, median {} \
             sample(s) per exposure; {} exposure(s) held none and carry the force interpolated \
             at their midpoint.\n",
            t.matched,
            frames.len(),
            t.median_samples.map_or("—".into(), |m| f(m, 0)),
            t.interpolated
        ));
    }
    let timing = timing_lines(data);
    if !timing.is_empty() {
        text.push_str(&timing);
        text.push_str(
            "\nA constant latency is invisible in arrival times (it looks like a clock \
             offset): the frame-to-force offset is right only as far as the latencies \
             subtracted are right — calibrate them per setup with an event both devices see.\n",
        );
    }
    // The frames stamped on arrival (before the camera's clock model had seen enough) are
    // the first ones; the rest are the model's.
    let on_arrival = data
        .manifest
        .timing
        .get("camera")
        .map_or(0, |c| c.stamped_on_arrival as usize)
        .min(t.errors_ms.len());
    let all: Vec<f64> = t.errors_ms.iter().map(|e| e.abs()).collect();
    let (early, abs) = all.split_at(on_arrival);
    let worst = |v: &[f64]| v.iter().fold(0.0, |a: f64, &b| a.max(b));
    if !abs.is_empty() {
        text.push_str(&format!(
            "\nSimulated bench: frame times against the true exposure midpoint — median |error| \
             {} ms, 99th percentile {} ms, worst {} ms ({} frames).\n",
            f(quantile(abs, 0.5), 3),
            f(quantile(abs, 0.99), 3),
            f(worst(abs), 3),
            abs.len()
        ));
    }
    if !early.is_empty() {
        text.push_str(&format!(
            "\nThe first {} frames, stamped on arrival before the clock model had seen enough: \
             median |error| {} ms, worst {} ms.\n",
            early.len(),
            f(quantile(early, 0.5), 3),
            f(worst(early), 3)
        ));
    }
    let json = json!({
        "frames": frames.len(),
        "interval_median_ms": num(quantile(&t.intervals_ms, 0.5)),
        "dropped": t.dropped,
        "duplicated": t.duplicated,
        "matched": t.matched,
        "interpolated": t.interpolated,
        "frame_time_error_ms": if abs.is_empty() { Value::Null } else { json!({
            "median_abs": num(quantile(abs, 0.5)),
            "p99_abs": num(quantile(abs, 0.99)),
            "worst_abs": num(worst(abs)),
            "stamped_on_arrival": early.len(),
            "on_arrival_worst_abs": num(worst(early)),
        })},
    });
    let chart = (!t.intervals_ms.is_empty()).then(|| Chart {
        title: "Frame intervals within frame streams".into(),
        x_label: "interval (ms)".into(),
        y_label: "frames".into(),
        series: vec![Series::line(
            "frame intervals",
            histogram(&t.intervals_ms),
            0,
        )],
        legend_upper_right: true,
        ..Default::default()
    });
    Some(("Camera timing".into(), text, json, chart))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_histogram_counts_every_interval_once() {
        let v = [40.0, 40.2, 39.9, 80.1, 40.0];
        let h = histogram(&v);
        // Step pairs: each bin appears twice.
        let total: f64 = h.iter().step_by(2).map(|p| p.1).sum();
        assert_eq!(total, 5.0);
        assert!(histogram(&[]).is_empty());
    }
}
