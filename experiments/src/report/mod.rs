//! `gelrig report`: a run directory turned into the thesis's results.
//!
//! This module does the I/O — read the run's tables, track its frames when `markers.csv`
//! is missing, build the reference fields from the run's own protocol — and hands numbers
//! to the pure analyses in [`analysis`]; [`write`] renders what comes back as
//! `report/report.html` (self-contained), `report/report.md`, SVG/PNG plots and
//! `report/summary.json`. Sections appear only where they apply: a run without frames has
//! no field sections, a run that never unloads no hysteresis, a normal-only run no slip.

pub(crate) mod analyse;
mod contact;
mod gelsight_force;
pub mod plots;
mod snapshots;
mod trials;
mod write;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::Deserialize;

pub use analyse::Report;

/// Why a report could not be made. Whatever was written before the failure stays.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    /// The run directory lacks a table every report needs.
    #[error("{path}: {detail}; fix: point gelrig report at a run directory made by `gelrig run`")]
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
    pub steps: Vec<StepRow>,
    pub force: Vec<ForceRow>,
    pub sim: Option<Vec<SimRow>>,
    pub frames: Vec<FrameRow>,
    /// Markers by frame number.
    pub markers: BTreeMap<u64, Vec<MarkerRow>>,
    /// Frame size, px, when frames exist.
    pub frame_size: Option<(usize, usize)>,
    /// The contact region per frame (`contact.csv`), when frames exist.
    pub contact: Vec<contact::ContactRow>,
    /// The live tactile state per frame (`tactile.csv`), when the run tracked frames live.
    pub tactile: Vec<trials::TactileCsvRow>,
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

pub(crate) fn read_csv<T: for<'de> Deserialize<'de>>(path: &Path) -> Result<Vec<T>, ReportError> {
    let mut r = csv::Reader::from_path(path).map_err(|e| ReportError::Missing {
        path: path.to_path_buf(),
        detail: e.to_string(),
    })?;
    r.deserialize()
        .enumerate()
        .map(|(k, row)| {
            row.map_err(|e| ReportError::Malformed {
                path: path.to_path_buf(),
                row: k + 1,
                detail: e.to_string(),
            })
        })
        .collect()
}

fn read_optional<T: for<'de> Deserialize<'de>>(path: &Path) -> Result<Option<Vec<T>>, ReportError> {
    if path.is_file() {
        read_csv(path).map(Some)
    } else {
        Ok(None)
    }
}

/// Reads the run, tracking its frames into `markers.csv` first if that is missing.
pub(crate) fn read_run(dir: &Path) -> Result<RunData, ReportError> {
    if !dir.is_dir() {
        return Err(ReportError::Missing {
            path: dir.to_path_buf(),
            detail: "not a directory".into(),
        });
    }
    let manifest = crate::record::read_manifest(dir).map_err(|detail| ReportError::Missing {
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
        protocol_name: manifest.protocol,
        steps,
        force,
        sim,
        frames,
        markers,
        frame_size,
        contact,
        tactile: trials::read_tactile(dir)?,
    })
}

/// Tracks the run's frames into `markers.csv` and `contact.csv`: written in a folder of this
/// process's own and renamed into place when complete, so a second report or calibration
/// reading the same run meanwhile never sees a half-written table.
fn track_into_place(dir: &Path) -> Result<(), ReportError> {
    let work = dir.join(format!(".tracking-{}", std::process::id()));
    let err = |path: PathBuf, detail: String| ReportError::Missing { path, detail };
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

/// Where the report went and its headline numbers.
#[derive(Debug, Clone)]
pub struct Written {
    /// The report folder.
    pub dir: PathBuf,
    /// Section titles present, in order.
    pub sections: Vec<String>,
    /// The summary that went into `summary.json`.
    pub summary: serde_json::Value,
}

/// Makes the report of `run_dir` into `run_dir/report/` (or `out`).
pub fn report(run_dir: &Path, out: Option<&Path>) -> Result<Written, ReportError> {
    report_with_sensor(run_dir, out, None)
}

/// [`report`], with a section "GelSight force against the force sensor" when a calibrated
/// sensor file (and its path, for the text) is given.
pub fn report_with_sensor(
    run_dir: &Path,
    out: Option<&Path>,
    sensor: Option<(&crate::sensor::SensorFile, &Path)>,
) -> Result<Written, ReportError> {
    let data = read_run(run_dir)?;
    let gelsight =
        match sensor {
            Some((file, path)) => {
                let frames = crate::sensor::run_frames(&data);
                let rows = crate::sensor::wrench::wrench_of_frames(file, &frames, run_dir)
                    .map_err(|e| ReportError::Sensor {
                        sensor: path.to_path_buf(),
                        detail: e.to_string(),
                    })?;
                let name = path
                    .file_name()
                    .map(|n| n.to_string_lossy().into_owned())
                    .unwrap_or_default();
                Some((file, name, rows))
            }
            None => None,
        };
    let model = analyse::reference_model(&data);
    let report = analyse::analyse(&data, model);
    let dir = out
        .map(Path::to_path_buf)
        .unwrap_or_else(|| run_dir.join("report"));
    write::write(
        &data,
        &report,
        &dir,
        gelsight
            .as_ref()
            .map(|(f, n, r)| (*f, n.as_str(), r.as_slice())),
    )
}
