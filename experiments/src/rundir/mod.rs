//! The run directory as it is read back: its tables' row types, [`RunData`] (everything a
//! report or a calibration reads from a run), reading it — tracking its frames first when
//! `markers.csv` is missing — and the marker field of a frame. `report` and `sensor` both
//! read runs through here; neither reads the other's files.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use analysis::field::MarkerField;
use serde::Deserialize;

/// Why a run directory could not be read (or a report of it written). Whatever was written
/// before the failure stays.
#[derive(Debug, thiserror::Error)]
pub enum RunDirError {
    /// The run directory lacks a table every report needs.
    #[error("{path}: {detail}; fix: give a run directory made by `gelrig run`")]
    Missing {
        /// The missing or unreadable file.
        path: PathBuf,
        /// What went wrong.
        detail: String,
    },
    /// A table has a malformed row.
    #[error(
        "{path}, row {row}: {detail}; fix: the file was edited or truncated — restore it from the run"
    )]
    Malformed {
        /// The table.
        path: PathBuf,
        /// 1-based data row.
        row: usize,
        /// The parse error.
        detail: String,
    },
    /// The GelSight's force could not be read with the sensor file given.
    #[error("reading force from the field with {sensor}: {detail}")]
    Sensor {
        /// The sensor file.
        sensor: PathBuf,
        /// Why (names the fix).
        detail: String,
    },
    /// Writing the report failed.
    #[error("cannot write {path}: {detail}; fix: check that the folder is writable")]
    Write {
        /// The output.
        path: PathBuf,
        /// What went wrong.
        detail: String,
    },
}

/// One row of `steps.csv` (only what the report reads).
#[derive(Debug, Clone, Deserialize)]
pub(crate) struct StepRow {
    pub step: u32,
    pub trial: u32,
    #[serde(default)]
    pub label: String,
    pub phase: String,
    pub axis: String,
    pub position: Option<f64>,
    pub unit: String,
    pub fx_n: f64,
    pub fy_n: f64,
    pub fz_n: f64,
    pub tz_nmm: f64,
    pub settle_s: f64,
    pub force_window_s: f64,
    pub t_start_ns: u64,
    pub settle_end_ns: u64,
    /// End of the step (after its capture).
    #[serde(default)]
    pub t_end_ns: u64,
}

/// One row of `force.csv`.
#[derive(Debug, Clone, Copy, Deserialize)]
pub(crate) struct ForceRow {
    pub t_ns: u64,
    pub step: u32,
    #[serde(default)]
    pub trial: u32,
    pub fx_n: f64,
    pub fy_n: f64,
    pub fz_n: f64,
    #[serde(default)]
    pub tx_nmm: f64,
    #[serde(default)]
    pub ty_nmm: f64,
    pub tz_nmm: f64,
}

/// One row of `sim_steps.csv` (simulated runs).
#[derive(Debug, Clone, Deserialize)]
pub(crate) struct SimRow {
    pub step: u32,
    pub fz_eq_n: f64,
    pub fx_eq_n: f64,
    pub tz_eq_nmm: f64,
    pub shear_slips: u32,
    pub twist_slips: u32,
    pub shear_stick_fraction: Option<f64>,
    pub twist_stick_fraction: Option<f64>,
    /// Contact radius of the simulated contact, mm (older runs lack the column).
    #[serde(default)]
    pub contact_radius_mm: Option<f64>,
}

/// One row of `frames.csv`.
#[derive(Debug, Clone, Deserialize)]
pub(crate) struct FrameRow {
    pub frame: u64,
    #[serde(default)]
    pub t_ns: u64,
    pub step: u32,
    /// The camera's frame counter.
    #[serde(default)]
    pub seq: Option<u64>,
}

/// One row of `markers.csv`.
#[derive(Debug, Clone, Deserialize)]
pub(crate) struct MarkerRow {
    pub frame: u64,
    pub id: usize,
    pub x_px: f64,
    pub y_px: f64,
    pub dx_px: f64,
    pub dy_px: f64,
    pub state: String,
}

/// Everything read from a run directory.
#[derive(Debug, Clone)]
pub(crate) struct RunData {
    pub dir: PathBuf,
    pub protocol_name: String,
    /// `run.yaml`: how the run went.
    pub manifest: crate::record::Manifest,
    pub steps: Vec<StepRow>,
    pub force: Vec<ForceRow>,
    pub sim: Option<Vec<SimRow>>,
    pub frames: Vec<FrameRow>,
    /// Markers by frame number.
    pub markers: BTreeMap<u64, Vec<MarkerRow>>,
    /// Frame size, px, when frames exist.
    pub frame_size: Option<(usize, usize)>,
    /// The contact region per frame (`contact.csv`), when frames exist.
    pub contact: Vec<ContactRow>,
    /// The live tactile state per frame (`tactile.csv`), when the run tracked frames live.
    pub tactile: Vec<TactileCsvRow>,
}

impl RunData {
    /// The last frame of `step`: taken at the end of its settle, like its force window.
    pub(crate) fn last_frame_of(&self, step: u32) -> Option<u64> {
        self.frames
            .iter()
            .filter(|f| f.step == step)
            .map(|f| f.frame)
            .max()
    }
}

pub(crate) fn read_csv<T: for<'de> Deserialize<'de>>(path: &Path) -> Result<Vec<T>, RunDirError> {
    let mut r = csv::Reader::from_path(path).map_err(|e| RunDirError::Missing {
        path: path.to_path_buf(),
        detail: e.to_string(),
    })?;
    r.deserialize()
        .enumerate()
        .map(|(k, row)| {
            row.map_err(|e| RunDirError::Malformed {
                path: path.to_path_buf(),
                row: k + 1,
                detail: e.to_string(),
            })
        })
        .collect()
}

pub(crate) fn read_optional<T: for<'de> Deserialize<'de>>(
    path: &Path,
) -> Result<Option<Vec<T>>, RunDirError> {
    if path.is_file() {
        read_csv(path).map(Some)
    } else {
        Ok(None)
    }
}

/// Reads the run, tracking its frames into `markers.csv` first if that is missing.
pub(crate) fn read_run(dir: &Path) -> Result<RunData, RunDirError> {
    if !dir.is_dir() {
        return Err(RunDirError::Missing {
            path: dir.to_path_buf(),
            detail: "not a directory".into(),
        });
    }
    let manifest = crate::record::read_manifest(dir).map_err(|detail| RunDirError::Missing {
        path: dir.join("run.yaml"),
        detail,
    })?;
    let steps: Vec<StepRow> = read_csv(&dir.join("steps.csv"))?;
    let force: Vec<ForceRow> = read_optional(&dir.join("force.csv"))?.unwrap_or_default();
    let sim = read_optional(&dir.join("sim_steps.csv"))?;
    let frames: Vec<FrameRow> = read_optional(&dir.join("frames.csv"))?.unwrap_or_default();
    let mut markers = BTreeMap::new();
    let mut frame_size = None;
    let mut contact = Vec::new();
    if frames.len() > 1 {
        let path = dir.join("markers.csv");
        if !path.is_file() || !dir.join("contact.csv").is_file() {
            track_into_place(dir)?;
        }
        for m in read_csv::<MarkerRow>(&path)? {
            markers.entry(m.frame).or_insert_with(Vec::new).push(m);
        }
        frame_size = first_frame_size(dir);
        contact = read_optional(&dir.join("contact.csv"))?.unwrap_or_default();
    }
    Ok(RunData {
        dir: dir.to_path_buf(),
        protocol_name: manifest.protocol.clone(),
        manifest,
        steps,
        force,
        sim,
        frames,
        markers,
        frame_size,
        contact,
        tactile: read_tactile(dir)?,
    })
}

/// Tracks the run's frames into `markers.csv` and `contact.csv`: written in a folder of this
/// process's own and renamed into place when complete, so a second report or calibration
/// reading the same run meanwhile never sees a half-written table.
fn track_into_place(dir: &Path) -> Result<(), RunDirError> {
    let work = dir.join(format!(".tracking-{}", std::process::id()));
    let err = |path: PathBuf, detail: String| RunDirError::Missing { path, detail };
    std::fs::create_dir_all(&work).map_err(|e| err(work.clone(), e.to_string()))?;
    let markers = work.join("markers.csv");
    let tracked = crate::track::track(
        &crate::track::Input::RunDir {
            dir: dir.to_path_buf(),
            reference: None,
        },
        &markers,
        &crate::track::Options::default(),
    )
    .map_err(|e| {
        err(
            dir.join("markers.csv"),
            format!("tracking the run's frames failed: {e}"),
        )
    });
    let placed = tracked.and_then(|_| {
        for name in ["contact.csv", "markers.csv"] {
            std::fs::rename(work.join(name), dir.join(name))
                .map_err(|e| err(dir.join(name), e.to_string()))?;
        }
        Ok(())
    });
    let _ = std::fs::remove_dir_all(&work);
    placed
}

fn first_frame_size(dir: &Path) -> Option<(usize, usize)> {
    let rows: Vec<BTreeMap<String, String>> = read_csv(&dir.join("frames.csv")).ok()?;
    let file = rows.first()?.get("file")?;
    let (w, h) = image::image_dimensions(crate::record::run_file(dir, file).ok()?).ok()?;
    Some((w as usize, h as usize))
}

/// One row of `contact.csv` (as `gelrig track` writes it).
#[derive(Debug, Clone, Deserialize)]
pub(crate) struct ContactRow {
    pub frame: u64,
    pub area_px2: f64,
    #[serde(default)]
    pub cx_px: Option<f64>,
    #[serde(default)]
    pub cy_px: Option<f64>,
    pub area_mm2: Option<f64>,
    pub radius_mm: Option<f64>,
    pub radius_px: f64,
}

/// One row of `tactile.csv` (what the report reads).
#[derive(Debug, Clone, Deserialize)]
pub(crate) struct TactileCsvRow {
    pub frame: u64,
    pub t_ns: u64,
    pub step: u32,
    pub trial: u32,
    pub state: String,
    pub gripping: bool,
    #[serde(default)]
    pub stuck_fraction: f64,
    #[serde(default)]
    pub gelsight_fz_n: Option<f64>,
    pub rotation_deg: f64,
    #[serde(default)]
    pub true_sliding: Option<bool>,
    #[serde(default)]
    pub true_height_mm: Option<f64>,
}

/// Reads `tactile.csv` if the run has one.
pub(crate) fn read_tactile(dir: &Path) -> Result<Vec<TactileCsvRow>, RunDirError> {
    Ok(read_optional(&dir.join("tactile.csv"))?.unwrap_or_default())
}

/// The interior marker field of a frame.
pub(crate) fn frame_field(data: &RunData, frame: u64) -> Option<MarkerField> {
    Some(field_of_rows(data.markers.get(&frame)?))
}

/// The marker field of one frame's rows of `markers.csv`, by marker identity.
pub(crate) fn field_of_rows(rows: &[MarkerRow]) -> MarkerField {
    let mut sorted: Vec<&MarkerRow> = rows.iter().collect();
    sorted.sort_by_key(|m| m.id);
    MarkerField {
        reference_px: sorted
            .iter()
            .map(|m| [m.x_px - m.dx_px, m.y_px - m.dy_px])
            .collect(),
        displacement_px: sorted.iter().map(|m| [m.dx_px, m.dy_px]).collect(),
        measured: sorted
            .iter()
            .map(|m| m.state == "tracked" || m.state == "merged")
            .collect(),
    }
}
