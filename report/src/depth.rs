//! The contact read from depth (`gelrig track --shape`: the GelSight's lights through a ball
//! calibration, docs/explanation/shape.md), step by step beside the colour-change region,
//! with the height maps of chosen steps.

use std::fs;
use std::path::Path;

use serde_json::{Value, json};

use super::out::werr;
use super::{ReportError, RunData};

/// Height-map pictures shown at most: evenly over the steps that have one, the deepest
/// always among them.
const MAX_PICTURES: usize = 6;

/// A section: title, markdown, `summary.json` entry, and the pictures' names.
type DepthSection = (String, String, Value, Vec<String>);

/// The section, when the run has `depth.csv`; its pictures are copied into `out`.
pub(super) fn section(data: &RunData, out: &Path) -> Result<Option<DepthSection>, ReportError> {
    if data.depth.is_empty() {
        return Ok(None);
    }
    let mut text = String::from(
        "The contact read from the gel's shape (`gelrig track --shape`: depth.csv, the \
         step's last frame): the deepest point of the height map, the area deeper than \
         0.03 mm, and the volume pressed in, beside the colour-change region of the section \
         above. Depth is read from the untouched gel far from the contact; the lights barely see \
         the gentle rise of the gel piled up around an indenter, so the deepest point reads \
         near the cap's depth below the contact's edge rather than the stage's depth \
         (docs/explanation/shape.md gives the figures).\n\n| step | position | deepest (mm) | area by depth (mm²) | area by \
         colour change (mm²) | volume (mm³) |\n|---|---|---|---|---|---|\n",
    );
    let mut rows = Vec::new();
    let mut pictured = Vec::new();
    for s in &data.steps {
        let Some(frame) = data.last_frame_of(s.step) else {
            continue;
        };
        let Some(d) = data.depth.iter().find(|d| d.frame == frame) else {
            continue;
        };
        let colour = data
            .contact
            .iter()
            .find(|c| c.frame == frame)
            .and_then(|c| c.area_mm2);
        let position = s
            .position
            .map(|p| format!("{p:.3} {}", s.unit))
            .unwrap_or_else(|| "—".into());
        text.push_str(&format!(
            "| {} | {position} | {:.3} | {:.2} | {} | {:.3} |\n",
            s.step,
            d.max_depth_mm,
            d.depth_area_mm2,
            colour.map_or_else(|| "—".into(), |a| format!("{a:.2}")),
            d.volume_mm3
        ));
        rows.push(json!({
            "step": s.step, "frame": frame, "position": s.position,
            "max_depth_mm": d.max_depth_mm, "depth_area_mm2": d.depth_area_mm2,
            "colour_area_mm2": colour, "volume_mm3": d.volume_mm3,
        }));
        if let Some(png) = picture_of(data, frame) {
            pictured.push((s.step, d.max_depth_mm, png));
        }
    }
    if rows.is_empty() {
        return Ok(None);
    }
    let mut plots = Vec::new();
    let mut shown = Vec::new();
    for (step, deepest_mm, png) in chosen(&pictured) {
        let name = format!("depth_step_{step:03}");
        let dest = out.join(format!("{name}.png"));
        fs::copy(png, &dest).map_err(|e| werr(&dest)(e.to_string()))?;
        plots.push(name);
        shown.push(format!("step {step} ({deepest_mm:.3} mm deep)"));
    }
    if !plots.is_empty() {
        text.push_str(&format!(
            "\nHeight maps, in order: {} (`depth_step_NNN.png`; brightest is deepest, each \
             picture scaled to its own deepest point): evenly over the steps, the deepest among \
             them.\n",
            shown.join(", ")
        ));
    }
    Ok(Some((
        "Contact depth from the lights".into(),
        text,
        Value::Array(rows),
        plots,
    )))
}

/// `RUN/depth/<frame file's stem>.height.png`, where `gelrig track --shape` wrote it.
fn picture_of(data: &RunData, frame: u64) -> Option<std::path::PathBuf> {
    let file = data
        .frames
        .iter()
        .find(|f| f.frame == frame)?
        .file
        .as_ref()?;
    let stem = Path::new(file).file_stem()?.to_string_lossy().into_owned();
    let png = data
        .dir
        .join(rundir::names::DEPTH_DIR)
        .join(format!("{stem}.height.png"));
    png.is_file().then_some(png)
}

/// At most [`MAX_PICTURES`] of the pictured steps: evenly spaced, the deepest among them.
fn chosen<T: Clone>(pictured: &[(u32, f64, T)]) -> Vec<(u32, f64, T)> {
    let n = pictured.len();
    if n <= MAX_PICTURES {
        return pictured.to_vec();
    }
    let mut picks: Vec<usize> = (0..MAX_PICTURES)
        .map(|k| k * (n - 1) / (MAX_PICTURES - 1))
        .collect();
    if let Some(deepest) = (0..n).max_by(|a, b| pictured[*a].1.total_cmp(&pictured[*b].1))
        && !picks.contains(&deepest)
    {
        // The pick nearest the deepest gives way to it.
        if let Some(slot) = picks.iter_mut().min_by_key(|p| p.abs_diff(deepest)) {
            *slot = deepest;
        }
        picks.sort_unstable();
    }
    picks.into_iter().map(|k| pictured[k].clone()).collect()
}

#[cfg(test)]
mod tests {
    use super::chosen;

    #[test]
    fn at_most_six_pictures_evenly_with_the_deepest() {
        let steps: Vec<(u32, f64, ())> = (0..20)
            .map(|k| (k, if k == 9 { 5.0 } else { k as f64 / 10.0 }, ()))
            .collect();
        let got: Vec<u32> = chosen(&steps).iter().map(|s| s.0).collect();
        assert_eq!(got.len(), 6);
        assert!(
            got.contains(&9) && got.contains(&0) && got.contains(&19),
            "{got:?}"
        );
        let few: Vec<(u32, f64, ())> = (0..4).map(|k| (k, 0.0, ())).collect();
        assert_eq!(chosen(&few).len(), 4);
    }
}
