//! The simulator's per-frame truth a dataset run recorded (`record: {traction_maps: N}`):
//! `sim_frames.csv` (the contact's state and loads under each frame) and the maps it names
//! (`sim_maps/NNNNNN.npy`, float32 (4, H, W): pressure, shear x, shear y in kPa, contact).

use std::collections::HashMap;
use std::path::Path;

use image::ImageEncoder;
use image::codecs::png::PngEncoder;

use crate::export::ExportError;
use crate::read::{RunDirError, read_optional};

/// One row of `sim_frames.csv`.
#[derive(Debug, Clone, serde::Deserialize)]
pub(super) struct SimFrame {
    pub(super) frame: u64,
    pub(super) maps: String,
    pub(super) depth_mm: f64,
    pub(super) shear_n: f64,
    pub(super) torque_nmm: f64,
    pub(super) centre_x_mm: f64,
    pub(super) centre_y_mm: f64,
    pub(super) rotation_rad: f64,
    pub(super) fz_n: f64,
    pub(super) contact_area_mm2: f64,
    pub(super) cell_mm: f64,
}

/// One frame's maps, as the dataset stores them.
pub(super) struct FrameMaps {
    pub(super) width: usize,
    pub(super) height: usize,
    pub(super) pressure_kpa: Vec<f32>,
    pub(super) shear_x_kpa: Vec<f32>,
    pub(super) shear_y_kpa: Vec<f32>,
    /// The contact mask as an 8-bit grey PNG (255 in contact).
    pub(super) mask_png: Vec<u8>,
}

/// `sim_frames.csv` of `run` by frame (empty for a run that recorded no maps).
pub(super) fn sim_frames(run: &Path) -> Result<HashMap<u64, SimFrame>, ExportError> {
    let rows: Vec<SimFrame> =
        read_optional(&run.join(crate::names::SIM_FRAMES))?.unwrap_or_default();
    Ok(rows.into_iter().map(|r| (r.frame, r)).collect())
}

/// The maps `row` names, read and checked.
pub(super) fn read_maps(run: &Path, row: &SimFrame) -> Result<FrameMaps, ExportError> {
    let bad = |path: &Path, detail: String| -> ExportError {
        RunDirError::Missing {
            path: path.to_path_buf(),
            detail,
        }
        .into()
    };
    let path = crate::write::run_file(run, &row.maps)
        .map_err(|d| bad(&run.join(&row.maps), d.to_string()))?;
    let bytes = std::fs::read(&path).map_err(|e| bad(&path, e.to_string()))?;
    let (shape, data) = crate::npy::decode(&bytes).map_err(|e| bad(&path, e))?;
    let [4, height, width] = shape[..] else {
        return Err(bad(
            &path,
            format!("traction maps of shape {shape:?}, not (4, H, W)"),
        ));
    };
    let cells = width * height;
    let channel = |k: usize| data[k * cells..(k + 1) * cells].to_vec();
    let mask: Vec<u8> = data[3 * cells..]
        .iter()
        .map(|&v| if v > 0.5 { 255 } else { 0 })
        .collect();
    let mut mask_png = Vec::new();
    PngEncoder::new(&mut mask_png)
        .write_image(
            &mask,
            width as u32,
            height as u32,
            image::ExtendedColorType::L8,
        )
        .map_err(|e| bad(&path, e.to_string()))?;
    Ok(FrameMaps {
        width,
        height,
        pressure_kpa: channel(0),
        shear_x_kpa: channel(1),
        shear_y_kpa: channel(2),
        mask_png,
    })
}
