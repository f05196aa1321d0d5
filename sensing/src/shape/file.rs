//! The shape file (`shape.yaml`): a GelSight calibrated as a shape sensor — both slope models,
//! which one to use, and each one's error on presses left out of its fit and its cost —
//! versioned, and refused with a reason when it does not fit the frames given.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use shape::ball::Circle;
use shape::local_linear::LocalLinear;
use shape::lut::Lut;
use shape::{HeldOut, ModelKind, SlopeModel};

use super::CirclesFrom;

/// `format:` of a shape file.
pub const FORMAT: &str = "gelrig-shape";
/// The version this build writes. Version 2 added the local-linear model's `flat_field`
/// (responses of the colour change relative to the background's light); version 1 files,
/// whose responses are of the raw change, are still read.
pub const VERSION: u32 = 2;

/// What reading or writing a shape file (or its inputs) refuses.
#[derive(Debug, thiserror::Error)]
pub enum ShapeFileError {
    /// A file that cannot be read or is not what it should be.
    #[error("{path}: {detail}; fix: {fix}")]
    Read {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        detail: String,
        /// What to do.
        fix: &'static str,
    },
    /// A file that cannot be written.
    #[error("cannot write {path}: {detail}")]
    Write {
        /// The file.
        path: PathBuf,
        /// Why.
        detail: String,
    },
    /// The shape chain's own refusal.
    #[error("{0}")]
    Shape(#[from] shape::ShapeError),
}

/// A model's held-out figures and its cost.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModelFigures {
    /// On presses left out of its fit.
    #[serde(flatten)]
    pub held_out: HeldOut,
    /// Median time from pixels to height map, ms per frame, one core (the calibrating
    /// machine's; BENCHMARKS for the command).
    pub ms_per_frame: f64,
}

/// A press the calibration used.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct UsedPress {
    /// File name.
    pub file: String,
    /// Its contact circle.
    #[serde(flatten)]
    pub circle: Circle,
}

/// The shape file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ShapeFile {
    /// [`FORMAT`].
    pub format: String,
    /// [`VERSION`].
    pub version: u32,
    /// Frame width, px.
    pub width_px: usize,
    /// Frame height, px.
    pub height_px: usize,
    /// Image scale, mm per px.
    pub mm_per_px: f64,
    /// The calibration ball's diameter, mm.
    pub ball_diameter_mm: f64,
    /// The model `gelrig shape` uses.
    pub chosen: ModelKind,
    /// Why: the rule that chose it.
    pub chosen_by: String,
    /// The local-linear model.
    pub local_linear: LocalLinear,
    /// The lookup table.
    pub lut: Lut,
    /// Each model's figures, local-linear first.
    pub figures: Vec<ModelFigures>,
    /// Where the presses' circles came from (files before it was kept: labels).
    #[serde(default = "labels")]
    pub circles_from: CirclesFrom,
    /// The presses fitted on.
    pub presses: Vec<UsedPress>,
    /// Presses left out, and why.
    #[serde(default)]
    pub left_out: Vec<UsedPressLeftOut>,
}

fn labels() -> CirclesFrom {
    CirclesFrom::Labels
}

/// A press the calibration left out.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct UsedPressLeftOut {
    /// File name.
    pub file: String,
    /// Why.
    pub reason: String,
}

impl ShapeFile {
    /// The chosen model, or `model` where given.
    pub fn model(&self, model: Option<ModelKind>) -> SlopeModel {
        match model.unwrap_or(self.chosen) {
            ModelKind::LocalLinear => SlopeModel::LocalLinear(self.local_linear.clone()),
            ModelKind::Lut => SlopeModel::Lut(self.lut.clone()),
        }
    }

    /// Writes the file atomically.
    pub fn write(&self, path: &Path) -> Result<(), ShapeFileError> {
        experiments::artifact::write_yaml(path, self).map_err(|detail| ShapeFileError::Write {
            path: path.to_path_buf(),
            detail,
        })
    }

    /// Reads and checks a shape file.
    pub fn read(path: &Path) -> Result<Self, ShapeFileError> {
        let err = |detail: String, fix: &'static str| ShapeFileError::Read {
            path: path.to_path_buf(),
            detail,
            fix,
        };
        const GIVE: &str = "give the shape.yaml that `gelrig shape calibrate --out` wrote";
        let text = std::fs::read_to_string(path).map_err(|e| err(e.to_string(), GIVE))?;
        #[derive(Deserialize)]
        struct Header {
            format: Option<String>,
            version: Option<u32>,
        }
        let h: Header =
            serde_yaml::from_str(&text).map_err(|e| err(format!("not a shape file: {e}"), GIVE))?;
        if h.format.as_deref() != Some(FORMAT) {
            return Err(err(
                format!("`format` is {:?}, not {FORMAT:?}", h.format),
                GIVE,
            ));
        }
        if !matches!(h.version, Some(1) | Some(VERSION)) {
            return Err(err(
                format!(
                    "shape file version {:?}; this gelrig reads versions 1 to {VERSION}",
                    h.version
                ),
                "use the gelrig that wrote it, or calibrate again with this one",
            ));
        }
        let s: Self = serde_yaml::from_str(&text).map_err(|e| {
            err(
                e.to_string(),
                "the file was edited or truncated: calibrate again, or restore it",
            )
        })?;
        // Version 1 predates the flat field: its responses are of the raw change.
        if s.version < 2 && s.local_linear.flat_field {
            return Err(err(
                "version 1 with `local_linear.flat_field: true` (version 1 predates the flat \
                 field: its responses are of the raw colour change)"
                    .into(),
                "calibrate again with this gelrig, or restore the file's `version: 2`",
            ));
        }
        let sane = s.width_px >= 2
            && s.height_px >= 2
            && s.mm_per_px.is_finite()
            && s.mm_per_px > 0.0
            && s.local_linear.responses.iter().all(|r| {
                r.at.iter()
                    .chain(r.channels.iter().flatten())
                    .all(|v| v.is_finite())
            })
            && s.lut.bins.iter().all(|b| {
                b.slope.iter().all(|v| v.is_finite())
                    && b.at.iter().all(|i| usize::from(*i) < shape::lut::BINS)
            });
        if !sane {
            return Err(err(
                "sizes, scale, responses or table out of range (or not numbers)".into(),
                "the file was edited or truncated: calibrate again, or restore it",
            ));
        }
        Ok(s)
    }
}
