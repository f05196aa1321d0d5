//! `gelrig track --shape`: the contact read from depth (the GelSight's lights, through a
//! shape calibration) beside the colour-change region, one row a frame in `depth.csv`.
//! The height maps come from the `shape` crate; the untouched reference frame is the
//! background they are read against.

use std::fs;
use std::path::{Path, PathBuf};

use serde::Serialize;
use shape::{Depth, Rgb, SlopeModel};

use super::{TrackFailure, r4, write_err};

/// What `--shape` needs of a shape file: its model, its frame size and its scale.
#[derive(Debug, Clone, PartialEq)]
pub struct ShapeReading {
    /// The slope model to read with.
    pub model: SlopeModel,
    /// The calibration's frame size, px.
    pub size_px: (usize, usize),
    /// The calibration's image scale, mm per px.
    pub mm_per_px: f64,
    /// The file it came from, for messages.
    pub path: PathBuf,
}

/// One row of `depth.csv`.
#[derive(Debug, Serialize)]
struct DepthRow {
    frame: u64,
    max_depth_mm: f64,
    /// Area deeper than 0.03 mm (`shape::depth::CONTACT_DEPTH_MM`), mm².
    depth_area_mm2: f64,
    depth_cx_px: Option<f64>,
    depth_cy_px: Option<f64>,
    volume_mm3: f64,
}

/// Reads each frame's height map and writes its row.
pub(super) struct DepthOut {
    depth: Depth,
    csv: csv::Writer<fs::File>,
    path: PathBuf,
}

impl DepthOut {
    /// For frames like `reference` (the untouched gel): `depth.csv` beside `out`.
    pub(super) fn new(
        reading: &ShapeReading,
        reference: Rgb<'_>,
        out: &Path,
    ) -> Result<Self, TrackFailure> {
        let (w, h) = reading.size_px;
        if (reference.width, reference.height) != (w, h) {
            return Err(TrackFailure::Usage {
                detail: format!(
                    "--shape {} was calibrated on {w}×{h} px frames, these are {}×{} px; fix: \
                     calibrate the shape sensor on frames of this camera setting (gelrig shape \
                     calibrate)",
                    reading.path.display(),
                    reference.width,
                    reference.height
                ),
            });
        }
        let unusable = |detail: String| TrackFailure::Usage {
            detail: format!(
                "--shape {}: {detail}; fix: calibrate again (gelrig shape calibrate)",
                reading.path.display()
            ),
        };
        let map = reading
            .model
            .prepare(w, h)
            .ok_or_else(|| unusable("its model holds too little to read frames".into()))?;
        let depth =
            Depth::new(map, reference, reading.mm_per_px).map_err(|e| unusable(e.to_string()))?;
        let path = out.with_file_name(rundir::names::DEPTH);
        let csv = csv::Writer::from_path(&path).map_err(|e| write_err(&path)(e.to_string()))?;
        Ok(Self { depth, csv, path })
    }

    /// Where the rows go.
    pub(super) fn path(&self) -> &Path {
        &self.path
    }

    /// Reads frame `frame` (RGB, the reference's size) and writes its row.
    pub(super) fn frame(&mut self, frame: u64, rgb: Rgb<'_>) -> Result<(), TrackFailure> {
        let usage = |e: shape::ShapeError| TrackFailure::Usage {
            detail: format!("frame {frame}: {e}"),
        };
        self.depth.height(rgb).map_err(usage)?;
        let s = self.depth.stats();
        let centroid = |v: f64| v.is_finite().then(|| r4(v));
        let row = DepthRow {
            frame,
            max_depth_mm: r4(s.max_depth_mm),
            depth_area_mm2: r4(s.contact_area_mm2),
            depth_cx_px: centroid(s.centroid_px[0]),
            depth_cy_px: centroid(s.centroid_px[1]),
            volume_mm3: r4(s.volume_mm3),
        };
        let werr = write_err(&self.path);
        self.csv.serialize(row).map_err(|e| werr(e.to_string()))?;
        self.csv.flush().map_err(|e| werr(e.to_string()))
    }
}
