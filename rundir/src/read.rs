//! Reading a run directory back: the tables' row types as readers see them (each a view of
//! the columns the writer's rows in [`crate::write`] define — a test checks every field here
//! is a column the writer writes), and reading a table whole with the row that failed named.

use std::path::{Path, PathBuf};

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
pub struct StepRow {
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
pub struct ForceRow {
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
pub struct SimRow {
    pub step: u32,
    #[serde(default)]
    pub trial: u32,
    /// The simulator's indentation depth at the step's end, mm (older runs lack it).
    #[serde(default)]
    pub depth_mm: Option<f64>,
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
pub struct FrameRow {
    pub frame: u64,
    /// The frame's file, relative to the run directory.
    #[serde(default)]
    pub file: Option<String>,
    #[serde(default)]
    pub t_ns: u64,
    pub step: u32,
    #[serde(default)]
    pub trial: u32,
    /// The camera's frame counter.
    #[serde(default)]
    pub seq: Option<u64>,
    /// The force during the exposure (tared, mean of the samples inside it), N; older runs
    /// and runs without a force sensor lack it.
    #[serde(default)]
    pub fz_n: Option<f64>,
    /// See `fz_n`.
    #[serde(default)]
    pub fx_n: Option<f64>,
    /// See `fz_n`.
    #[serde(default)]
    pub fy_n: Option<f64>,
    /// See `fz_n`, N·mm.
    #[serde(default)]
    pub tx_nmm: Option<f64>,
    /// See `fz_n`, N·mm.
    #[serde(default)]
    pub ty_nmm: Option<f64>,
    /// See `fz_n`, N·mm.
    #[serde(default)]
    pub tz_nmm: Option<f64>,
    /// Spread of Fz over the exposure, N.
    #[serde(default)]
    pub fz_sd_n: Option<f64>,
    /// Force samples inside the exposure (0: interpolated between the samples around it).
    #[serde(default)]
    pub force_samples: Option<u32>,
    /// The true exposure midpoint on a simulated bench, ns.
    #[serde(default)]
    pub sim_t_ns: Option<u64>,
}

/// One row of `markers.csv`.
#[derive(Debug, Clone, Deserialize)]
pub struct MarkerRow {
    pub frame: u64,
    pub id: usize,
    pub x_px: f64,
    pub y_px: f64,
    pub dx_px: f64,
    pub dy_px: f64,
    pub state: String,
}

pub fn read_csv<T: for<'de> Deserialize<'de>>(path: &Path) -> Result<Vec<T>, RunDirError> {
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

pub fn read_optional<T: for<'de> Deserialize<'de>>(
    path: &Path,
) -> Result<Option<Vec<T>>, RunDirError> {
    if path.is_file() {
        read_csv(path).map(Some)
    } else {
        Ok(None)
    }
}

/// One row of `contact.csv` (as `gelrig track` writes it).
#[derive(Debug, Clone, Deserialize)]
pub struct ContactRow {
    pub frame: u64,
    pub area_px2: f64,
    #[serde(default)]
    pub cx_px: Option<f64>,
    #[serde(default)]
    pub cy_px: Option<f64>,
    pub area_mm2: Option<f64>,
    pub radius_mm: Option<f64>,
    pub radius_px: f64,
    /// The region's central second moments per unit area, px² (absent before 27 Nov).
    #[serde(default)]
    pub sxx_px2: Option<f64>,
    #[serde(default)]
    pub syy_px2: Option<f64>,
    #[serde(default)]
    pub sxy_px2: Option<f64>,
}

/// One row of `depth.csv` (as `gelrig track --shape` writes it).
#[derive(Debug, Clone, Deserialize)]
pub struct DepthRow {
    pub frame: u64,
    pub max_depth_mm: f64,
    pub depth_area_mm2: f64,
    #[serde(default)]
    pub depth_cx_px: Option<f64>,
    #[serde(default)]
    pub depth_cy_px: Option<f64>,
    pub volume_mm3: f64,
}

/// One row of `tactile.csv` (what the report reads).
#[derive(Debug, Clone, Deserialize)]
pub struct TactileCsvRow {
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
pub fn read_tactile(dir: &Path) -> Result<Vec<TactileCsvRow>, RunDirError> {
    Ok(read_optional(&dir.join(crate::names::TACTILE))?.unwrap_or_default())
}

/// The events of `journal.jsonl` in order, each a JSON object with its `event` name. A line
/// that does not parse is skipped: the journal is appended line by line, so a killed run can
/// leave its last line torn, and what the writer finished stays readable.
pub fn read_journal(dir: &Path) -> Result<Vec<serde_json::Value>, RunDirError> {
    let path = dir.join(crate::names::JOURNAL);
    let text = std::fs::read_to_string(&path).map_err(|e| RunDirError::Missing {
        path: path.clone(),
        detail: e.to_string(),
    })?;
    Ok(text
        .lines()
        .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
        .filter(|v| v.get("event").is_some())
        .collect())
}

#[cfg(test)]
mod journal_tests {
    use super::read_journal;

    #[test]
    fn a_torn_last_line_is_skipped_and_the_rest_read_in_order() {
        let dir = tempfile::tempdir().expect("tmp");
        std::fs::write(
            dir.path().join("journal.jsonl"),
            "{\"event\":\"start\",\"t_ns\":0}\n{\"event\":\"contact\",\"force\":0.2}\n{\"event\":\"ste",
        )
        .expect("write");
        let events = read_journal(dir.path()).expect("read");
        assert_eq!(events.len(), 2);
        assert_eq!(events[1]["event"], "contact");
        let missing = read_journal(&dir.path().join("nowhere")).expect_err("no journal there");
        assert!(missing.to_string().contains("journal.jsonl"), "{missing}");
    }
}
