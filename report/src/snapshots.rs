//! Field snapshots of a grasp trial, as the thesis shows them (Fig. 6-20 to 6-24): the
//! total marker field (from the untouched gel) and the differential field (from the frame
//! before) at the grip, at the end of the lift, in the hold, at the disturbance's largest
//! twist, and at the tactile warning.

use std::fs;
use std::path::Path;

use tracking::field::MarkerField;
use tracking::field::picture::{Quiver, quiver_svg};

use super::trials::TrialResult;
use super::{ReportError, RunData};

/// One snapshot's pictures: (file name, caption).
pub(super) type Pictures = Vec<(String, String)>;

/// The moments of trial `t` worth a picture: (name, frame).
fn moments(data: &RunData, t: &TrialResult) -> Vec<(&'static str, u64)> {
    let rows: Vec<_> = data.tactile.iter().filter(|r| r.trial == t.trial).collect();
    let steps: Vec<_> = data.steps.iter().filter(|s| s.trial == t.trial).collect();
    let mut out = Vec::new();
    if let Some(r) = rows.iter().find(|r| r.gripping) {
        out.push(("grip", r.frame));
    }
    let lift = steps
        .iter()
        .find(|s| s.axis == "lift" && s.position.is_some_and(|p| p > 0.0));
    if let Some(f) = lift.and_then(|s| data.last_frame_of(s.step)) {
        out.push(("lift", f));
    }
    let frames_of = |step: u32| -> Vec<u64> {
        data.frames
            .iter()
            .filter(|f| f.step == step)
            .map(|f| f.frame)
            .collect()
    };
    if let Some(s) = steps.iter().find(|s| s.phase == "hold") {
        let fs = frames_of(s.step);
        if let Some(f) = fs.get(fs.len() / 2) {
            out.push(("hold", *f));
        }
    }
    if let Some(s) = steps.iter().find(|s| s.phase == "disturb") {
        let twist = rows
            .iter()
            .filter(|r| r.step == s.step)
            .max_by(|a, b| a.rotation_deg.abs().total_cmp(&b.rotation_deg.abs()));
        if let Some(r) = twist {
            out.push(("disturbance", r.frame));
        }
    }
    if let Some(onset) = t.tactile_onset_s {
        let at = (onset * 1e9).round() as u64;
        if let Some(r) = rows.iter().find(|r| r.t_ns == at) {
            out.push(("warning", r.frame));
        }
    }
    out
}

/// The difference of two frames' fields, marker by marker (measured in both).
fn differential(now: &MarkerField, before: &MarkerField) -> MarkerField {
    let n = now.len().min(before.len());
    MarkerField {
        reference_px: now.reference_px[..n].to_vec(),
        displacement_px: (0..n)
            .map(|i| {
                let (a, b) = (now.displacement_px[i], before.displacement_px[i]);
                [a[0] - b[0], a[1] - b[1]]
            })
            .collect(),
        measured: (0..n)
            .map(|i| now.measured[i] && before.measured[i])
            .collect(),
    }
}

fn picture(field: &MarkerField, size: (usize, usize), path: &Path) -> Result<f64, ReportError> {
    let max = field
        .measured_ids()
        .map(|i| field.displacement_px[i][0].hypot(field.displacement_px[i][1]))
        .fold(0.0, f64::max);
    let magnify = (20.0 / max.max(1e-3)).clamp(1.0, 50.0);
    let q = Quiver {
        frame_px: size,
        zoom: 1.0,
        magnify,
        spacing_px: super::field_analysis::spacing_px(field),
    };
    let svg = quiver_svg(field, &q, None).map_err(|e| ReportError::Write {
        path: path.to_path_buf(),
        detail: e.to_string(),
    })?;
    fs::write(path, svg).map_err(|e| ReportError::Write {
        path: path.to_path_buf(),
        detail: e.to_string(),
    })?;
    Ok(magnify)
}

/// Writes trial `t`'s snapshots into `dir`; their file names and captions.
pub(super) fn write(data: &RunData, t: &TrialResult, dir: &Path) -> Result<Pictures, ReportError> {
    let Some(size) = data.frame_size else {
        return Ok(Vec::new());
    };
    let mut out = Vec::new();
    for (name, frame) in moments(data, t) {
        let Some(total) = sensing::run_data::frame_field(data, frame) else {
            continue;
        };
        let file = format!("trial_{:03}_{name}_total.svg", t.trial);
        let m = picture(&total, size, &dir.join(&file))?;
        out.push((
            file,
            format!(
                "trial {}, {name} (frame {frame}): total field, arrows ×{m:.0}",
                t.trial
            ),
        ));
        if let Some(before) = frame
            .checked_sub(1)
            .and_then(|f| sensing::run_data::frame_field(data, f))
        {
            let file = format!("trial_{:03}_{name}_differential.svg", t.trial);
            let m = picture(&differential(&total, &before), size, &dir.join(&file))?;
            out.push((
                file,
                format!(
                    "trial {}, {name} (frame {frame}): differential field (from frame {}), arrows ×{m:.0}",
                    t.trial,
                    frame - 1
                ),
            ));
        }
    }
    Ok(out)
}
