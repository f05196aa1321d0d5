//! The contact size seen on the camera's frames, step by step (the thesis measured contact
//! diameters on its images, §5.1: 5.60 mm at 1.0 mm of the 12.68 mm sphere; 43.6 mm² at the
//! deepest step), against the simulator's contact radius on dry runs.

use serde_json::{Value, json};

use super::RunData;

/// The section's title, markdown and `summary.json` entry, when any step shows contact.
pub(super) fn section(data: &RunData) -> Option<(String, String, Value)> {
    // A region on a step without load is the gel's slow recovery (a residual imprint), not
    // contact: a normal step at or above the contact point, or any other step under 2 % of
    // the largest normal force, is shown without a size.
    let max_fz = data.steps.iter().map(|s| s.fz_n.abs()).fold(0.0, f64::max);
    let loaded = |s: &super::StepRow| match (s.axis.as_str(), s.position) {
        ("normal", Some(depth)) => depth > 0.0,
        _ => s.fz_n.abs() >= 0.02 * max_fz,
    };
    let mut rows = Vec::new();
    for s in &data.steps {
        let Some(frame) = data.last_frame_of(s.step) else {
            continue;
        };
        let Some(c) = data.contact.iter().find(|c| c.frame == frame) else {
            continue;
        };
        let sim = data
            .sim
            .as_ref()
            .and_then(|v| v.iter().find(|r| r.step == s.step))
            .and_then(|r| r.contact_radius_mm);
        rows.push((s, c, sim));
    }
    if !rows.iter().any(|(s, c, _)| c.area_px2 > 0.0 && loaded(s)) {
        return None;
    }
    let mm = rows.iter().all(|(_, c, _)| c.radius_mm.is_some());
    let unit = if mm { "mm" } else { "px" };
    let mut text = format!(
        "Contact region per step from the frames (contact.csv, the step's last frame): \
         the colour change against the untouched gel, its edge where the surface tilts \
         most. Equivalent radius √(area/π), {unit}.\n\n"
    );
    let with_sim = rows.iter().any(|(_, _, s)| s.is_some());
    text.push_str(&format!(
        "| step | position | area ({unit}²) | radius ({unit}) | diameter ({unit}) |{}\n|---|---|---|---|---|{}\n",
        if with_sim { " simulator's radius (mm) | difference |" } else { "" },
        if with_sim { "---|---|" } else { "" },
    ));
    let mut json_rows = Vec::new();
    for (s, c, sim) in &rows {
        let (area, radius) = if mm {
            (c.area_mm2.unwrap_or(0.0), c.radius_mm.unwrap_or(0.0))
        } else {
            (c.area_px2, c.radius_px)
        };
        let position = s
            .position
            .map(|p| format!("{p:.3} {}", s.unit))
            .unwrap_or_else(|| "—".into());
        if !loaded(s) {
            text.push_str(&format!(
                "| {} | {position} | — | no load (a residual imprint) | — |{}\n",
                s.step,
                if with_sim { " — | — |" } else { "" }
            ));
            continue;
        }
        let extra = match sim {
            Some(a) if with_sim && mm && *a > 0.0 && radius > 0.0 => {
                format!(" {a:.3} | {:+.1} % |", 100.0 * (radius / a - 1.0))
            }
            Some(a) if with_sim => format!(" {a:.3} | — |"),
            _ if with_sim => " — | — |".into(),
            _ => String::new(),
        };
        text.push_str(&format!(
            "| {} | {position} | {area:.2} | {radius:.3} | {:.3} |{extra}\n",
            s.step,
            2.0 * radius
        ));
        json_rows.push(json!({
            "step": s.step, "frame": c.frame, "position": s.position,
            "area": area, "radius": radius, "unit": unit, "sim_radius_mm": sim,
        }));
    }
    Some((
        "Contact size from the image".into(),
        text,
        Value::Array(json_rows),
    ))
}
