//! `gelrig track --detect-only`: the markers of each frame on its own, with no reference and
//! no identities — to check a camera's focus and exposure, or to look at a single frame.

use std::fs;
use std::path::{Path, PathBuf};

use serde::Serialize;
use tracking::{Reference, RgbView, TrackParams};

use super::decode::DecodeAhead;
use super::{TrackFailure, r4, write_err};

/// One row of `detections.csv`.
#[derive(Debug, Serialize)]
struct DetectionRow {
    frame: u64,
    id: usize,
    x_px: f64,
    y_px: f64,
    area_px: u32,
    border: bool,
}

/// What a detection pass found.
#[derive(Debug, Clone, PartialEq)]
pub struct Detections {
    /// Frames read.
    pub frames: usize,
    /// Markers found per frame (fewest, most).
    pub per_frame: (usize, usize),
    /// Median marker spacing over the frames, px.
    pub spacing_px: f64,
    /// Where the table went.
    pub csv: PathBuf,
}

/// Detects the markers of every frame independently (each frame is its own background,
/// measured with the markers masked) and writes `out`, flushed frame by frame.
pub fn detect_only(frames: &[PathBuf], out: &Path) -> Result<Detections, TrackFailure> {
    if let Some(parent) = out.parent().filter(|p| !p.as_os_str().is_empty()) {
        fs::create_dir_all(parent).map_err(|e| write_err(parent)(e.to_string()))?;
    }
    let mut csv = csv::Writer::from_path(out).map_err(|e| write_err(out)(e.to_string()))?;
    let workers = std::thread::available_parallelism().map_or(1, |n| n.get());
    let list: Vec<(u64, PathBuf)> = frames
        .iter()
        .enumerate()
        .map(|(k, p)| (k as u64, p.clone()))
        .collect();
    let (mut fewest, mut most, mut spacings) = (usize::MAX, 0, Vec::new());
    for decoded in DecodeAhead::new(list, workers) {
        let (w, h, rgb) = decoded.image?;
        let frame_err = |source| TrackFailure::Frame {
            path: decoded.path.clone(),
            source,
        };
        let view = RgbView::new(w, h, &rgb).map_err(frame_err)?;
        let seen = Reference::of_any_frame(view, &TrackParams::default()).map_err(frame_err)?;
        for (id, m) in seen.markers().iter().enumerate() {
            csv.serialize(DetectionRow {
                frame: decoded.frame,
                id,
                x_px: r4(m.x),
                y_px: r4(m.y),
                area_px: m.area_px,
                border: m.border,
            })
            .map_err(|e| write_err(out)(e.to_string()))?;
        }
        csv.flush().map_err(|e| write_err(out)(e.to_string()))?;
        fewest = fewest.min(seen.markers().len());
        most = most.max(seen.markers().len());
        spacings.push(seen.spacing_px());
    }
    spacings.sort_by(f64::total_cmp);
    Ok(Detections {
        frames: frames.len(),
        per_frame: (fewest.min(most), most),
        spacing_px: spacings.get(spacings.len() / 2).copied().unwrap_or(0.0),
        csv: out.to_path_buf(),
    })
}
