//! `gelrig shape calibrate`: a directory of ball presses into a shape file, with each model's
//! held-out figures and its cost per frame measured on the presses.

use std::path::Path;
use std::time::Instant;

use shape::{ModelKind, Press, Rgb, calibrate};

use super::file::{FORMAT, ModelFigures, ShapeFile, UsedPress, UsedPressLeftOut, VERSION};
use super::{ShapeFileError, read_presses};

/// Calibrates on the presses in `dir` (ball `ball_diameter_mm`, image `mm_per_px`).
pub fn calibrate_dir(
    dir: &Path,
    ball_diameter_mm: f64,
    mm_per_px: f64,
) -> Result<ShapeFile, ShapeFileError> {
    let read = read_presses(dir)?;
    let (w, h, bg) = &read.background;
    let background = Rgb::new(*w, *h, bg)?;
    let presses: Vec<Press<'_>> = read
        .presses
        .iter()
        .map(|(name, px, circle)| {
            Ok(Press {
                name: name.clone(),
                frame: Rgb::new(*w, *h, px)?,
                circle: *circle,
            })
        })
        .collect::<Result<_, shape::ShapeError>>()?;
    let ball_px = ball_diameter_mm / 2.0 / mm_per_px;
    let cal = calibrate(background, &presses, ball_px, mm_per_px)?;
    let mut file = ShapeFile {
        format: FORMAT.into(),
        version: VERSION,
        width_px: *w,
        height_px: *h,
        mm_per_px,
        ball_diameter_mm,
        chosen: cal.chosen,
        chosen_by: "the smaller root-mean-square error of the cap height on presses left out \
                    of the fit, one at a time"
            .into(),
        local_linear: cal.local_linear,
        lut: cal.lut,
        figures: Vec::new(),
        circles_from: read.circles_from,
        presses: presses
            .iter()
            .map(|p| UsedPress {
                file: p.name.clone(),
                circle: p.circle,
            })
            .collect(),
        left_out: read
            .left_out
            .into_iter()
            .map(|(file, reason)| UsedPressLeftOut { file, reason })
            .collect(),
    };
    for held_out in cal.held_out {
        let ms_per_frame = cost_ms(&file, held_out.model, background, &presses)?;
        file.figures.push(ModelFigures {
            held_out,
            ms_per_frame,
        });
    }
    Ok(file)
}

/// Median time of a model's height map over the presses, ms (after one warm-up frame).
fn cost_ms(
    file: &ShapeFile,
    model: ModelKind,
    background: Rgb<'_>,
    presses: &[Press<'_>],
) -> Result<f64, ShapeFileError> {
    let map = file
        .model(Some(model))
        .prepare(file.width_px, file.height_px)
        .ok_or_else(|| {
            shape::ShapeError::Calibration(format!("the {} model holds too little", model.name()))
        })?;
    let mut depth = shape::Depth::new(map, background, file.mm_per_px)?;
    depth.height(presses[0].frame)?;
    let mut times = Vec::with_capacity(presses.len());
    for p in presses {
        let t = Instant::now();
        depth.height(p.frame)?;
        times.push(t.elapsed().as_secs_f64() * 1e3);
    }
    times.sort_by(f64::total_cmp);
    Ok(times[times.len() / 2])
}
