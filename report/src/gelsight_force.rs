//! "GelSight force against the force sensor" (`gelrig report --sensor SENSOR.yaml`): the
//! wrench read from the run's marker field with a calibrated sensor, frame by frame, scored
//! against the force sensor (its step's force-window mean for a frame captured at a settled
//! step's end, else its mean over the frame's ±60 ms).
//!
//! Per channel: RMSE in the channel's unit, in % of the sensor's calibrated span (Fx and Fy
//! share the shear force's), in % of this run's own range and of the reading (a squeeze of
//! 5 N read 1 N off is 3 % of a 34 N span but 20 % of the squeeze), bias (GelSight − force
//! sensor), the largest error, the share of frames within two of their stated standard
//! uncertainties, and the frames outside the calibrated range or judged outside the
//! calibration; time series overlaid and error against load.

use serde_json::{Value, json};

use super::RunData;
use super::plots::{Chart, Mark, Series};
use sensing::sensor::calibrate::{span, stats};
use sensing::sensor::{SensorFile, WrenchRow, reference_at};

/// Title, markdown, `summary.json` value and charts of the section.
pub(super) type ForceSection = (String, String, Value, Vec<(String, Chart)>);

const NAMES: [(&str, &str, &str); 4] = [
    ("fx_n", "Fx", "N"),
    ("fy_n", "Fy", "N"),
    ("fz_n", "Fz", "N"),
    ("tz_nmm", "Tz", "N·mm"),
];

fn channel(r: &WrenchRow, c: usize) -> f64 {
    [r.fx_n, r.fy_n, r.fz_n, r.tz_nmm][c]
}

/// A share in %, or a dash where the run does not give one.
fn shown(v: f64, digits: usize) -> String {
    if v.is_finite() {
        format!("{v:.digits$}")
    } else {
        "—".into()
    }
}

fn channel_sd(r: &WrenchRow, c: usize) -> f64 {
    [r.fx_sd_n, r.fy_sd_n, r.fz_sd_n, r.tz_sd_nmm][c]
}

/// The error as a share of the run's own: RMSE over the run's range of the force sensor's
/// readings (where the run moves the channel by a tenth of `span`, the calibrated span, or
/// more), and the RMS of error over reading where the reading is a tenth of `span` or more,
/// both in % (NaN where the run gives neither).
fn own_shares(pairs: &[(&WrenchRow, [f64; 4])], c: usize, span: f64) -> (f64, f64) {
    let (lo, hi) = pairs
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), (_, w)| {
            (l.min(w[c]), h.max(w[c]))
        });
    let range = hi - lo;
    let errors: Vec<f64> = pairs.iter().map(|(r, w)| channel(r, c) - w[c]).collect();
    let rmse = (errors.iter().map(|e| e * e).sum::<f64>() / errors.len().max(1) as f64).sqrt();
    let rel: Vec<f64> = pairs
        .iter()
        .filter(|(_, w)| span > 0.0 && w[c].abs() >= 0.1 * span)
        .map(|(r, w)| (channel(r, c) - w[c]) / w[c])
        .collect();
    let pct_reading = if rel.is_empty() {
        f64::NAN
    } else {
        100.0 * (rel.iter().map(|v| v * v).sum::<f64>() / rel.len() as f64).sqrt()
    };
    let pct_own = if span > 0.0 && range >= 0.1 * span {
        100.0 * rmse / range
    } else {
        f64::NAN
    };
    (pct_own, pct_reading)
}

/// The section, or `None` when no frame has a force reading beside it.
pub(super) fn section(
    data: &RunData,
    sensor: &SensorFile,
    sensor_name: &str,
    rows: &[WrenchRow],
) -> Option<ForceSection> {
    // Frames with a force reading, the reference (frame 0) left out: it is zero by definition.
    let pairs: Vec<(&WrenchRow, [f64; 4])> = rows
        .iter()
        .filter(|r| r.frame > 0)
        .filter_map(|r| Some((r, reference_at(data, r.step, r.t_ns?)?)))
        .collect();
    if pairs.is_empty() {
        return None;
    }
    let mut text = format!(
        "The wrench read from the marker field with `{sensor_name}` (method `{}`, calibrated \
         {} on {} frames of {}; its own held-out error {}), against the force sensor at \
         each of {} frames. Error = GelSight − force sensor; % of the sensor's calibrated \
         span (Fx and Fy: the shear force's), of this run's own range (where it moves the \
         channel by a tenth of the span or more), and of the reading (where it is a tenth of \
         the span or more); within 2σ: the share of frames \
         whose error is within two of their stated standard uncertainties. A frame outside \
         the calibrated range is an extrapolation; {} of the frames were judged outside the \
         calibration (their uncertainties widened: `wrench.csv`'s `outside_calibration`).\n\n\
         | channel | RMSE | % of span | % of the run's range | % of the reading | within 2σ | bias | largest error | frames outside the range |\n\
         |---|---|---|---|---|---|---|---|---|\n",
        sensor.method,
        sensor.created.get(..10).unwrap_or(&sensor.created),
        sensor.model.samples,
        sensor
            .calibrated_on
            .iter()
            .map(|r| r.protocol.as_str())
            .collect::<Vec<_>>()
            .join(", "),
        sensor
            .held_out
            .channels
            .iter()
            .map(|(c, s)| format!("{c} {:.2} %", s.pct_range))
            .collect::<Vec<_>>()
            .join(", "),
        pairs.len(),
        pairs
            .iter()
            .filter(|(r, _)| !r.outside_calibration.is_empty())
            .count(),
    );
    let mut json_channels = serde_json::Map::new();
    let mut charts = Vec::new();
    for (c, (key, label, unit)) in NAMES.iter().enumerate() {
        let errors: Vec<f64> = pairs.iter().map(|(r, w)| channel(r, c) - w[c]).collect();
        let s = stats(&errors, span(&sensor.ranges, key));
        let worst = errors.iter().fold(0.0f64, |a, e| a.max(e.abs()));
        let outside = sensor.ranges.get(*key).map_or(0, |r| {
            let margin = 0.05 * (r[1] - r[0]);
            pairs
                .iter()
                .filter(|(_, w)| w[c] < r[0] - margin || w[c] > r[1] + margin)
                .count()
        });
        let (pct_own, pct_reading) = own_shares(&pairs, c, span(&sensor.ranges, key));
        let within = pairs
            .iter()
            .filter(|(r, w)| (channel(r, c) - w[c]).abs() <= 2.0 * channel_sd(r, c))
            .count() as f64
            / pairs.len() as f64;
        text.push_str(&format!(
            "| {label} | {:.4} {unit} | {:.2} | {} | {} | {:.1} % | {:+.4} {unit} | {:.4} {unit} \
             | {outside} |\n",
            s.rmse,
            s.pct_range,
            shown(pct_own, 2),
            shown(pct_reading, 1),
            100.0 * within,
            s.bias,
            worst
        ));
        let short = key.split('_').next().unwrap_or(key);
        let finite = |v: f64| if v.is_finite() { json!(v) } else { Value::Null };
        json_channels.insert(
            short.to_string(),
            json!({"rmse": s.rmse, "pct_range": s.pct_range, "pct_run_range": finite(pct_own),
                   "pct_reading": finite(pct_reading), "within_2sd": within, "bias": s.bias,
                   "max_abs_error": worst, "frames_outside_range": outside}),
        );
        let t = |r: &WrenchRow| r.t_ns.unwrap_or(0) as f64 * 1e-9;
        let k = (data.force.len() / 3000).max(1);
        charts.push((
            format!("gelsight_{short}"),
            Chart {
                title: format!("{label}: GelSight against the force sensor"),
                x_label: "time (s)".into(),
                y_label: format!("{label} ({unit})"),
                series: vec![
                    Series::line(
                        "force sensor",
                        data.force
                            .iter()
                            .step_by(k)
                            .map(|r| (r.t_ns as f64 * 1e-9, [r.fx_n, r.fy_n, r.fz_n, r.tz_nmm][c]))
                            .collect(),
                        0,
                    ),
                    Series {
                        name: "GelSight (frames)".into(),
                        points: pairs.iter().map(|(r, _)| (t(r), channel(r, c))).collect(),
                        mark: Mark::Points,
                        colour: 1,
                    },
                ],
                ..Chart::default()
            },
        ));
    }
    // Error against load for the normal force (the thesis's Fig. 4-15 view).
    charts.push((
        "gelsight_fz_error".into(),
        Chart {
            title: "Fz error against load".into(),
            x_label: "force sensor Fz (N)".into(),
            y_label: "GelSight − force sensor (N)".into(),
            series: vec![Series {
                name: "Fz error".into(),
                points: pairs.iter().map(|(r, w)| (w[2], r.fz_n - w[2])).collect(),
                mark: Mark::Points,
                colour: 3,
            }],
            ..Chart::default()
        },
    ));
    text.push_str(
        "\nA simulated run's figures are the simulated bench's: a real gel adds what the \
         simulator leaves out (large strain, marker imprint shading, temperature).\n",
    );
    Some((
        "GelSight force against the force sensor".into(),
        text,
        Value::Object(json_channels),
        charts,
    ))
}
