//! `gelrig shape FRAME…`: per frame a height map as NumPy `.npy` (float32, H×W, mm, positive
//! out of the gel, 0 on the untouched gel), a coloured picture of its depth, and a row of
//! `shape.csv`; optionally a PLY point cloud.

use std::io::Write;
use std::path::{Path, PathBuf};

use serde::Serialize;
use shape::{Depth, ModelKind, Rgb};

use super::{ShapeFile, ShapeFileError};
use crate::track::load_rgb;

/// One row of `shape.csv`.
#[derive(Debug, Clone, Serialize)]
pub struct ShapeRow {
    /// The frame's file name.
    pub file: String,
    /// Deepest point, mm.
    pub max_depth_mm: f64,
    /// Area deeper than 0.03 mm, mm².
    pub contact_area_mm2: f64,
    /// Depth-weighted centroid of that area, px (empty without contact).
    pub centroid_x_px: Option<f64>,
    /// See `centroid_x_px`.
    pub centroid_y_px: Option<f64>,
    /// Volume pressed below the surface, mm³.
    pub volume_mm3: f64,
}

fn werr(path: &Path) -> impl Fn(String) -> ShapeFileError + '_ {
    move |detail| ShapeFileError::Write {
        path: path.to_path_buf(),
        detail,
    }
}

/// Reads each of `frames` against `background` with `file`'s model (or `model`), writing
/// into `out`; returns the rows of `out/shape.csv`.
pub fn write_height_maps(
    file: &ShapeFile,
    model: Option<ModelKind>,
    background: &Path,
    frames: &[PathBuf],
    out: &Path,
    ply: bool,
) -> Result<Vec<ShapeRow>, ShapeFileError> {
    let (bw, bh, bg) = load_rgb(background).map_err(|e| ShapeFileError::Read {
        path: background.to_path_buf(),
        detail: e.to_string(),
        fix: "give a frame of the unpressed gel from the same session (--background)",
    })?;
    if (bw, bh) != (file.width_px, file.height_px) {
        return Err(ShapeFileError::Read {
            path: background.to_path_buf(),
            detail: format!(
                "{bw}×{bh} px; the shape file was calibrated on {}×{} px frames",
                file.width_px, file.height_px
            ),
            fix: "use the camera setting the sensor was calibrated at, or calibrate at this one",
        });
    }
    let map = file.model(model).prepare(bw, bh).ok_or_else(|| {
        shape::ShapeError::Calibration(
            "the shape file's model holds too little: calibrate again".into(),
        )
    })?;
    let mut depth = Depth::new(map, Rgb::new(bw, bh, &bg)?, file.mm_per_px)?;
    std::fs::create_dir_all(out).map_err(|e| werr(out)(e.to_string()))?;
    let mut rows = Vec::with_capacity(frames.len());
    for path in frames {
        let (w, h, px) = load_rgb(path).map_err(|e| ShapeFileError::Read {
            path: path.clone(),
            detail: e.to_string(),
            fix: "frames are PNG files of the calibrated camera",
        })?;
        let height = depth
            .height(Rgb::new(w, h, &px)?)
            .map_err(|e| ShapeFileError::Read {
                path: path.clone(),
                detail: e.to_string(),
                fix: "use frames of the camera setting the background was taken at",
            })?
            .to_vec();
        let stem = path
            .file_stem()
            .map_or_else(|| "frame".to_string(), |s| s.to_string_lossy().into_owned());
        let npy = out.join(format!("{stem}.height.npy"));
        write_npy(&npy, &height, w, h).map_err(|e| werr(&npy)(e.to_string()))?;
        let png = out.join(format!("{stem}.height.png"));
        depth_picture(&height, w, h)
            .save(&png)
            .map_err(|e| werr(&png)(e.to_string()))?;
        if ply {
            let p = out.join(format!("{stem}.ply"));
            write_ply(&p, &height, w, file.mm_per_px).map_err(|e| werr(&p)(e.to_string()))?;
        }
        let s = depth.stats();
        let centroid = s.centroid_px[0].is_finite().then_some(s.centroid_px);
        rows.push(ShapeRow {
            file: path
                .file_name()
                .map_or_else(String::new, |n| n.to_string_lossy().into_owned()),
            max_depth_mm: s.max_depth_mm,
            contact_area_mm2: s.contact_area_mm2,
            centroid_x_px: centroid.map(|c| c[0]),
            centroid_y_px: centroid.map(|c| c[1]),
            volume_mm3: s.volume_mm3,
        });
    }
    let csv_path = out.join("shape.csv");
    let mut wtr = csv::Writer::from_path(&csv_path).map_err(|e| werr(&csv_path)(e.to_string()))?;
    for r in &rows {
        wtr.serialize(r)
            .map_err(|e| werr(&csv_path)(e.to_string()))?;
    }
    wtr.flush().map_err(|e| werr(&csv_path)(e.to_string()))?;
    Ok(rows)
}

/// The height map as NumPy `.npy` (float32, H×W; `rundir::npy`), written whole then renamed.
fn write_npy(path: &Path, data: &[f32], w: usize, h: usize) -> std::io::Result<()> {
    let tmp = path.with_extension("npy.partial");
    std::fs::write(&tmp, rundir::npy::encode(data, &[h, w]))?;
    std::fs::rename(&tmp, path)
}

/// The depth as colour: untouched gel dark blue, deepest yellow (a viridis-like ramp scaled
/// to the frame's own deepest point; the scale is in `shape.csv`'s `max_depth_mm`).
fn depth_picture(height: &[f32], w: usize, h: usize) -> image::RgbImage {
    const STOPS: [[f32; 3]; 5] = [
        [68.0, 1.0, 84.0],
        [59.0, 82.0, 139.0],
        [33.0, 145.0, 140.0],
        [94.0, 201.0, 98.0],
        [253.0, 231.0, 37.0],
    ];
    let deepest = height.iter().fold(0f32, |a, v| a.max(-v)).max(1e-6);
    let mut img = image::RgbImage::new(w as u32, h as u32);
    for (i, p) in img.pixels_mut().enumerate() {
        let t = (-height[i] / deepest).clamp(0.0, 1.0) * 4.0;
        let k = (t.floor() as usize).min(3);
        let f = t - k as f32;
        let c = |j: usize| (STOPS[k][j] * (1.0 - f) + STOPS[k + 1][j] * f) as u8;
        *p = image::Rgb([c(0), c(1), c(2)]);
    }
    img
}

/// An ASCII PLY point cloud: one vertex per pixel, x right, y down, z the height, all mm.
fn write_ply(path: &Path, height: &[f32], w: usize, mm_per_px: f64) -> std::io::Result<()> {
    let tmp = path.with_extension("ply.partial");
    let mut f = std::io::BufWriter::new(std::fs::File::create(&tmp)?);
    writeln!(
        f,
        "ply\nformat ascii 1.0\ncomment gelrig shape: mm, z positive out of the gel\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nend_header",
        height.len()
    )?;
    for (i, z) in height.iter().enumerate() {
        let (x, y) = ((i % w) as f64 * mm_per_px, (i / w) as f64 * mm_per_px);
        writeln!(f, "{x:.4} {y:.4} {z:.5}")?;
    }
    f.into_inner().map_err(|e| e.into_error())?.sync_all()?;
    std::fs::rename(&tmp, path)
}
