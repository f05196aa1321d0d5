//! "GelSight force against the force sensor" (`gelrig report --sensor SENSOR.yaml`): the
//! wrench read from the run's marker field with a calibrated sensor, frame by frame, scored
//! against the force sensor (its step's force-window mean for a frame captured at a settled
//! step's end, else its mean over the frame's ±60 ms).
//!
//! Per channel: RMSE in the channel's unit and in % of the sensor's calibrated span (Fx and
//! Fy share the shear force's), bias (GelSight − force sensor), the largest error, and the
//! frames outside the calibrated range; time series overlaid and error against load.

use serde_json::{Value, json};

use super::RunData;
use super::plots::{Chart, Mark, Series};
use crate::sensor::calibrate::{span, stats};
use crate::sensor::{SensorFile, WrenchRow, reference_at};

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
         span (Fx and Fy: the shear force's). A frame outside the calibrated range is an \
         extrapolation.\n\n\
         | channel | RMSE | % of span | bias | largest error | frames outside the range |\n\
         |---|---|---|---|---|---|\n",
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
        text.push_str(&format!(
            "| {label} | {:.4} {unit} | {:.2} | {:+.4} {unit} | {:.4} {unit} | {outside} |\n",
            s.rmse, s.pct_range, s.bias, worst
        ));
        let short = key.split('_').next().unwrap_or(key);
        json_channels.insert(
            short.to_string(),
            json!({"rmse": s.rmse, "pct_range": s.pct_range, "bias": s.bias,
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
