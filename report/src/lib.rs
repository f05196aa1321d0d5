//! `gelrig report`: a run directory turned into the thesis's results.
//!
//! The run is read through [`sensing::run_data`] (which tracks its frames when `markers.csv` is
//! missing); this module builds the reference fields from the run's own protocol and hands
//! numbers to the pure analyses in [`analysis`]; [`write`] renders what comes back as
//! `report/report.html` (self-contained), `report/report.md`, SVG/PNG plots and
//! `report/summary.json`. Sections appear only where they apply: a run without frames has
//! no field sections, a run that never unloads no hysteresis, a normal-only run no slip.

pub(crate) mod analyse;
mod block_sections;
mod camera_timing;
mod compare;
mod contact;
mod depth;
mod field_analysis;
mod field_figures;
mod gelsight_force;
mod header;
mod headline;
mod html;
mod out;
pub mod plots;
mod relaxation;
mod results;
mod settle_study;
mod snapshots;
mod trials;
mod write;

use std::path::{Path, PathBuf};

pub use compare::compare;
pub use headline::headline;
pub use results::Report;
pub use rundir::read::RunDirError as ReportError;
pub(crate) use sensing::run_data::{ForceRow, RunData, StepRow, read_run};

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
    sensor: Option<(&sensing::sensor::SensorFile, &Path)>,
) -> Result<Written, ReportError> {
    let data = read_run(run_dir)?;
    let gelsight =
        match sensor {
            Some((file, path)) => {
                let frames = sensing::sensor::run_frames(&data);
                let rows = sensing::sensor::wrench::wrench_of_frames(file, &frames, run_dir)
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
