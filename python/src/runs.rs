//! Run directories from Python: the manifest, the status, a frame as a numpy array, the
//! report, the exports and the listing of a folder of runs. The tables themselves are read
//! by pyarrow in the Python package (no row loop).

use std::path::{Path, PathBuf};

use numpy::PyArray3;
use pyo3::prelude::*;

use crate::{frames, gelrig_err};

/// `run.yaml` as JSON text.
#[pyfunction]
pub(crate) fn read_manifest(dir: PathBuf) -> PyResult<String> {
    let m = gelrig::runs::read_manifest(&dir).map_err(gelrig_err)?;
    serde_json::to_string(&m).map_err(gelrig_err)
}

/// The run's status as `gelrig runs` shows it (`interrupted` for a killed run).
#[pyfunction]
pub(crate) fn run_status(dir: PathBuf) -> PyResult<String> {
    let m = gelrig::runs::read_manifest(&dir).map_err(gelrig_err)?;
    Ok(gelrig::runs::listing::effective_status(&dir, m.status).to_string())
}

/// The image at `path` as a `uint8` array of shape (height, width, 3), decoded as `gelrig
/// track` decodes it (bounded in size; grey and 16-bit images to RGB8).
#[pyfunction]
pub(crate) fn read_image(py: Python<'_>, path: PathBuf) -> PyResult<Bound<'_, PyArray3<u8>>> {
    let decoded = py.detach(|| gelrig::track::recorded::load_rgb(&path));
    let (w, h, rgb) = decoded.map_err(gelrig_err)?;
    frames::to_numpy(py, w, h, rgb)
}

/// Frame `index` of the run in `dir` as a `uint8` array of shape (height, width, 3).
#[pyfunction]
pub(crate) fn read_frame(
    py: Python<'_>,
    dir: PathBuf,
    index: u64,
) -> PyResult<Bound<'_, PyArray3<u8>>> {
    let path = dir.join(gelrig::runs::names::frame_png(index));
    if !path.is_file() {
        return Err(gelrig_err(format!(
            "{}: no such frame (frames are numbered as in frames.csv's `frame` column)",
            path.display()
        )));
    }
    read_image(py, path)
}

/// Writes the report of the run in `dir` (into `dir/report/`, or `out`), with the GelSight's
/// force read by `sensor` if given; returns the report folder and `summary.json` as text.
#[pyfunction]
#[pyo3(signature = (dir, out=None, sensor=None))]
pub(crate) fn report(
    py: Python<'_>,
    dir: PathBuf,
    out: Option<PathBuf>,
    sensor: Option<PathBuf>,
) -> PyResult<(PathBuf, String)> {
    let written = py.detach(|| -> Result<_, String> {
        let file = match &sensor {
            Some(p) => Some(gelrig::force::SensorFile::read(p).map_err(|e| e.to_string())?),
            None => None,
        };
        let with = file.as_ref().zip(sensor.as_deref());
        gelrig::reports::report_with_sensor(&dir, out.as_deref(), with).map_err(|e| e.to_string())
    });
    let w = written.map_err(gelrig_err)?;
    Ok((w.dir, w.summary.to_string()))
}

/// Exports the run (or a folder of runs, for Parquet) in `dir` as `format` (`parquet` or
/// `mcap`) into `out`; returns the files written.
#[pyfunction]
pub(crate) fn export(
    py: Python<'_>,
    dir: PathBuf,
    format: &str,
    out: PathBuf,
) -> PyResult<Vec<PathBuf>> {
    let format = format.to_ascii_lowercase();
    py.detach(|| match format.as_str() {
        "parquet" => gelrig::runs::export::export_parquet(&dir, &out)
            .map(|e| e.tables.into_iter().map(|(_, file, _)| file).collect())
            .map_err(|e| e.to_string()),
        "mcap" => gelrig::runs::export::export_mcap(&dir, &out)
            .map(|_| vec![out.clone()])
            .map_err(|e| e.to_string()),
        other => Err(format!("format `{other}`: give `parquet` or `mcap`")),
    })
    .map_err(gelrig_err)
}

/// The runs in `folder` as JSON text (a list of rows, as `gelrig runs` shows them).
#[pyfunction]
pub(crate) fn list_runs(folder: PathBuf) -> PyResult<String> {
    let runs = gelrig::runs::listing::list(Path::new(&folder)).map_err(gelrig_err)?;
    let rows: Vec<serde_json::Value> = runs
        .iter()
        .map(|r| {
            serde_json::json!({
                "dir": r.dir, "protocol": r.protocol, "status": r.status,
                "started": r.started, "steps": r.steps, "note": r.note,
                "duration_s": r.duration_s, "seed": r.seed, "rig": r.rig,
            })
        })
        .collect();
    Ok(serde_json::Value::Array(rows).to_string())
}
