//! The MCAP writer of a run directory ([`super`] lists the topics).

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use serde::Deserialize;

use crate::read::{ForceRow, RunDirError, read_csv, read_optional};
use crate::ros2::{Ros2Mcap, Topic, rotary_axes, si};

/// Why a run could not be exported.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// The run directory could not be read.
    #[error(transparent)]
    Run(#[from] RunDirError),
    /// The output could not be written.
    #[error(
        "cannot write {path}: {detail}; fix: check the folder exists, is writable and has room"
    )]
    Write {
        /// The output file.
        path: PathBuf,
        /// What went wrong.
        detail: String,
    },
}

/// What an export wrote.
#[derive(Debug, Clone, PartialEq)]
pub struct Exported {
    /// The file written.
    pub path: PathBuf,
    /// Messages per topic.
    pub messages: BTreeMap<String, usize>,
}

/// One row of `axes.csv`.
#[derive(Debug, Deserialize)]
struct AxesRow {
    t_ns: u64,
    axis: String,
    position: Option<f64>,
}

/// One row of `frames.csv`.
#[derive(Debug, Deserialize)]
struct FrameFileRow {
    frame: u64,
    t_ns: u64,
    file: String,
}

/// A CSV row as JSON: integers stay integers, numbers numbers, `true`/`false` booleans, an
/// empty cell null, the rest text.
fn json_row(row: &BTreeMap<String, String>) -> serde_json::Map<String, serde_json::Value> {
    row.iter()
        .map(|(k, v)| {
            let value = if v.is_empty() {
                serde_json::Value::Null
            } else if let Ok(i) = v.parse::<i64>() {
                serde_json::Value::from(i)
            } else if let Some(x) = v.parse::<f64>().ok().filter(|x| x.is_finite()) {
                serde_json::Value::from(x)
            } else if v == "true" || v == "false" {
                serde_json::Value::from(v == "true")
            } else {
                serde_json::Value::from(v.clone())
            };
            (k.clone(), value)
        })
        .collect()
}

/// One row of `markers.csv` (as `gelrig track` writes it): the marker's position now and
/// its displacement from the reference.
#[derive(Debug, Deserialize)]
struct MarkerRow {
    frame: u64,
    x_px: f64,
    y_px: f64,
    dx_px: f64,
    dy_px: f64,
    state: String,
}

/// Writes `run_dir` as MCAP to `out`.
pub fn export_mcap(run_dir: &Path, out: &Path) -> Result<Exported, ExportError> {
    if !run_dir.join(crate::names::MANIFEST).is_file() {
        return Err(RunDirError::Missing {
            path: run_dir.join(crate::names::MANIFEST),
            detail: "not a run directory".into(),
        }
        .into());
    }
    let werr = |e: String| ExportError::Write {
        path: out.to_path_buf(),
        detail: e,
    };
    let m = |e: mcap::McapError| werr(e.to_string());
    let file = File::create(out).map_err(|e| werr(e.to_string()))?;
    let mut w = Ros2Mcap::create(BufWriter::new(file)).map_err(m)?;
    write_records(run_dir, &mut w).map_err(|e| match e {
        RecordsError::Read(e) => e.into(),
        RecordsError::Mcap(e) => m(e),
    })?;
    // The run's own files, and what it was.
    for name in [
        crate::names::PROTOCOL,
        crate::names::RIG,
        crate::names::MANIFEST,
    ] {
        if let Ok(bytes) = std::fs::read(run_dir.join(name)) {
            w.attach(name, bytes).map_err(m)?;
        }
    }
    if let Ok(manifest) = crate::manifest::read_manifest(run_dir) {
        w.run_metadata(manifest.headline()).map_err(m)?;
    }
    let messages = w.finish().map_err(m)?;
    Ok(Exported {
        path: out.to_path_buf(),
        messages,
    })
}

/// Why the run's records could not be written as MCAP messages.
pub(crate) enum RecordsError {
    /// A table or frame of the run could not be read.
    Read(RunDirError),
    /// The MCAP writer failed.
    Mcap(mcap::McapError),
}

impl From<RunDirError> for RecordsError {
    fn from(e: RunDirError) -> Self {
        RecordsError::Read(e)
    }
}

impl From<mcap::McapError> for RecordsError {
    fn from(e: mcap::McapError) -> Self {
        RecordsError::Mcap(e)
    }
}

/// Writes every record of `run_dir` as it stands (force, frames, markers, stage positions,
/// steps, tactile states) to `w`: the export's messages, and what a resumed run writes
/// first when it records `run.mcap` as it goes.
pub(crate) fn write_records<W: std::io::Write + std::io::Seek>(
    run_dir: &Path,
    w: &mut Ros2Mcap<W>,
) -> Result<(), RecordsError> {
    for r in read_optional::<ForceRow>(&run_dir.join(crate::names::FORCE))?.unwrap_or_default() {
        let v = [r.fx_n, r.fy_n, r.fz_n, r.tx_nmm, r.ty_nmm, r.tz_nmm];
        w.wrench(r.t_ns, v)?;
    }
    // Frames: the PNG bytes as recorded.
    let frames: Vec<FrameFileRow> =
        read_optional(&run_dir.join(crate::names::FRAMES))?.unwrap_or_default();
    for f in &frames {
        let path = run_dir.join(&f.file);
        let bytes = std::fs::read(&path).map_err(|e| RunDirError::Missing {
            path: path.clone(),
            detail: format!("frame {}: {e}", f.frame),
        })?;
        w.png(f.t_ns, &bytes)?;
    }
    // Markers, where the run was tracked: each frame's displacement lines at its time.
    let markers: Vec<MarkerRow> =
        read_optional(&run_dir.join(crate::names::MARKERS))?.unwrap_or_default();
    let time_of: BTreeMap<u64, u64> = frames.iter().map(|f| (f.frame, f.t_ns)).collect();
    for chunk in markers.chunk_by(|a, b| a.frame == b.frame) {
        let frame = chunk[0].frame;
        let lines: Vec<[f64; 4]> = chunk
            .iter()
            .filter(|r| r.state == "tracked" || r.state == "merged")
            .map(|r| [r.x_px - r.dx_px, r.y_px - r.dy_px, r.dx_px, r.dy_px])
            .collect();
        let t = time_of.get(&frame).copied().unwrap_or(0);
        w.markers(t, frame, &lines)?;
    }
    // Stage positions, SI: m for linear axes, rad for rotary ones.
    let rig_yaml = std::fs::read_to_string(run_dir.join(crate::names::RIG)).unwrap_or_default();
    let rotary = rotary_axes(&rig_yaml);
    for r in read_optional::<AxesRow>(&run_dir.join(crate::names::AXES))?.unwrap_or_default() {
        if let Some(p) = r.position {
            w.joint(r.t_ns, &r.axis, si(p, rotary.contains(&r.axis)))?;
        }
    }
    // Steps at their ends and grasp frames' tactile state, each row as JSON.
    for (file, topic, time_column) in [
        (crate::names::STEPS, Topic::Steps, "t_end_ns"),
        (crate::names::TACTILE, Topic::Tactile, "t_ns"),
    ] {
        let path = run_dir.join(file);
        if !path.is_file() {
            continue;
        }
        let rows: Vec<BTreeMap<String, String>> = read_csv(&path)?;
        for row in &rows {
            let t = row
                .get(time_column)
                .and_then(|v| v.parse::<u64>().ok())
                .unwrap_or(0);
            let text = serde_json::Value::Object(json_row(row)).to_string();
            w.json(topic, t, &text)?;
        }
    }
    Ok(())
}
