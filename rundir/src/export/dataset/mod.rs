//! `gelrig export CAMPAIGN --format dataset`: every recorded frame of a run, a folder of runs
//! or a sweep's campaign as one row of a learning dataset — the frame's PNG and its labels —
//! in Parquet shards that Hugging Face `datasets` loads as they are (the image columns carry
//! its `Image` feature in the schema's `huggingface` metadata), with a dataset card.
//!
//! The labels are what the run recorded and the simulator knew: the wrench during the
//! exposure (`frames.csv`), the step's axis and position (`steps.csv`), the simulator's depth,
//! contact radius and forces at the step's end (`sim_steps.csv`), the indenter as the
//! protocol gives it, the sweep's parameters, and every marker's true centre and its
//! displacement from the first frame (`sim_markers.csv`). Layout and units: the card the
//! export writes (`README.md`), and docs/reference/dataset.md.

use std::collections::HashMap;
use std::fs::File;
use std::path::{Path, PathBuf};

use super::ExportError;
use super::parquet_tables::runs_of;
use card::card_text;
use columns::batch;

mod card;
mod columns;
mod maps;
use crate::read::{FrameRow, SimRow, StepRow, read_csv, read_optional};

/// Frames per Parquet shard: about 50 MB of 640×480 PNGs, and what the export holds in memory
/// at once (about five times that).
pub const SHARD_ROWS: usize = 100;

/// What [`export_dataset`] wrote.
#[derive(Debug, Clone)]
pub struct DatasetExport {
    /// The dataset's folder.
    pub dir: PathBuf,
    /// The shards, each with its rows.
    pub shards: Vec<(PathBuf, usize)>,
    /// Runs read.
    pub runs: usize,
    /// Frames written.
    pub frames: usize,
}

/// One frame's row, before it becomes columns.
pub(super) struct Row {
    png: Vec<u8>,
    file: String,
    run: String,
    params: Vec<String>,
    ints: [Option<i64>; 5],
    floats: Vec<Option<f64>>,
    texts: [String; 3],
    markers: [Vec<f32>; 4],
    maps: Option<maps::FrameMaps>,
}

pub(super) const INTS: [&str; 5] = ["frame", "step", "t_ns", "maps_width", "maps_height"];
pub(super) const FLOATS: [&str; 21] = [
    "fx_n",
    "fy_n",
    "fz_n",
    "tx_nmm",
    "ty_nmm",
    "tz_nmm",
    "position",
    "sim_depth_mm",
    "sim_contact_radius_mm",
    "sim_fz_n",
    "sim_fx_n",
    "sim_tz_nmm",
    "sim_frame_depth_mm",
    "sim_frame_shear_n",
    "sim_frame_torque_nmm",
    "sim_centre_x_mm",
    "sim_centre_y_mm",
    "sim_rotation_rad",
    "sim_frame_fz_n",
    "sim_contact_area_mm2",
    "maps_cell_mm",
];
/// The label columns with no list above.
const OTHER_COLUMNS: [&str; 6] = [
    "image",
    "run",
    "pressure_kpa",
    "shear_x_kpa",
    "shear_y_kpa",
    "contact_mask",
];

/// A sweep parameter's column: its name, or `sweep.NAME` where a label has that name (a
/// sweep over whole indenters has a parameter `indenter`, and the label `indenter` is the
/// protocol's; two columns of one name are refused by every Parquet reader).
pub(super) fn param_column(name: &str) -> String {
    let taken = INTS.contains(&name)
        || FLOATS.contains(&name)
        || TEXTS.contains(&name)
        || MARKERS.contains(&name)
        || OTHER_COLUMNS.contains(&name);
    match taken {
        true => format!("sweep.{name}"),
        false => name.to_string(),
    }
}

pub(super) const TEXTS: [&str; 3] = ["position_unit", "axis", "indenter"];
pub(super) const MARKERS: [&str; 4] =
    ["marker_x_px", "marker_y_px", "marker_dx_px", "marker_dy_px"];

/// Writes the dataset of `path` (a run, a folder of runs, a campaign) into `out`.
pub fn export_dataset(path: &Path, out: &Path) -> Result<DatasetExport, ExportError> {
    let (runs, params, _) = runs_of(path)?;
    let werr = |p: &Path, e: String| ExportError::Write {
        path: p.to_path_buf(),
        detail: e,
    };
    let data = out.join("data");
    std::fs::create_dir_all(&data).map_err(|e| werr(&data, e.to_string()))?;
    // Shards are written as the frames are read: at most one shard's frames in memory.
    let total: usize = runs.iter().map(|r| frame_count(r)).sum();
    if total == 0 {
        return Err(crate::read::RunDirError::Missing {
            path: path.join(crate::names::FRAMES),
            detail: "no frames: a dataset is made of a run's recorded frames".into(),
        }
        .into());
    }
    let names: Vec<String> = params.iter().map(|(n, _)| param_column(n)).collect();
    let count = total.div_ceil(SHARD_ROWS);
    let mut shards = Vec::new();
    let mut pending: Vec<Row> = Vec::with_capacity(SHARD_ROWS);
    let mut frames = 0;
    let flush =
        |rows: &mut Vec<Row>, shards: &mut Vec<(PathBuf, usize)>| -> Result<(), ExportError> {
            let file = data.join(format!("train-{:05}-of-{count:05}.parquet", shards.len()));
            write_shard(&file, rows, &names).map_err(|e| werr(&file, e))?;
            shards.push((file, rows.len()));
            rows.clear();
            Ok(())
        };
    for (k, run) in runs.iter().enumerate() {
        let values: Vec<String> = params
            .iter()
            .map(|(_, v)| v.get(k).cloned().unwrap_or_default())
            .collect();
        for row in run_rows(run, &values)? {
            pending.push(row);
            frames += 1;
            if pending.len() == SHARD_ROWS {
                flush(&mut pending, &mut shards)?;
            }
        }
    }
    if !pending.is_empty() {
        flush(&mut pending, &mut shards)?;
    }
    let card = out.join("README.md");
    std::fs::write(&card, card_text(frames, runs.len(), &names))
        .map_err(|e| werr(&card, e.to_string()))?;
    Ok(DatasetExport {
        dir: out.to_path_buf(),
        shards,
        runs: runs.len(),
        frames,
    })
}

/// Frames of a run with a file (what [`run_rows`] will give), from `frames.csv`.
fn frame_count(run: &Path) -> usize {
    read_csv::<FrameRow>(&run.join(crate::names::FRAMES))
        .map(|f| f.iter().filter(|r| r.file.is_some()).count())
        .unwrap_or(0)
}

/// One shard: the rows as a record batch, written as Parquet.
fn write_shard(file: &Path, rows: &[Row], names: &[String]) -> Result<(), String> {
    let batch = batch(rows, names)?;
    let f = File::create(file).map_err(|e| e.to_string())?;
    // Snappy: the maps are mostly zeros beyond the contact.
    let props = parquet::file::properties::WriterProperties::builder()
        .set_compression(parquet::basic::Compression::SNAPPY)
        .build();
    let mut w = parquet::arrow::ArrowWriter::try_new(f, batch.schema(), Some(props))
        .map_err(|e| e.to_string())?;
    w.write(&batch).map_err(|e| e.to_string())?;
    w.close().map_err(|e| e.to_string())?;
    Ok(())
}

/// Every frame of one run as rows.
fn run_rows(run: &Path, params: &[String]) -> Result<Vec<Row>, ExportError> {
    let frames: Vec<FrameRow> = read_csv(&run.join(crate::names::FRAMES))?;
    let steps: Vec<StepRow> = read_optional(&run.join(crate::names::STEPS))?.unwrap_or_default();
    let sim: Vec<SimRow> = read_optional(&run.join(crate::names::SIM_STEPS))?.unwrap_or_default();
    let markers = sim_markers(&run.join(crate::names::SIM_MARKERS));
    let sim_frames = maps::sim_frames(run)?;
    let first: Option<&Vec<[f32; 2]>> = frames.first().and_then(|f| markers.get(&f.frame));
    let indenter = indenter_json(&run.join(crate::names::PROTOCOL));
    let name = run
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let mut rows = Vec::with_capacity(frames.len());
    for f in &frames {
        let Some(file) = &f.file else { continue };
        let png_path = crate::write::run_file(run, file).map_err(|detail| {
            crate::read::RunDirError::Missing {
                path: run.join(file),
                detail: detail.to_string(),
            }
        })?;
        let png = std::fs::read(&png_path).map_err(|e| crate::read::RunDirError::Missing {
            path: png_path.clone(),
            detail: e.to_string(),
        })?;
        let step = steps
            .iter()
            .find(|s| s.step == f.step && s.trial == f.trial);
        let truth = sim.iter().find(|s| s.step == f.step && s.trial == f.trial);
        let mut m: [Vec<f32>; 4] = Default::default();
        if let Some(now) = markers.get(&f.frame) {
            for (i, p) in now.iter().enumerate() {
                let start = first.and_then(|r| r.get(i)).copied().unwrap_or(*p);
                m[0].push(p[0]);
                m[1].push(p[1]);
                m[2].push(p[0] - start[0]);
                m[3].push(p[1] - start[1]);
            }
        }
        let sf = sim_frames.get(&f.frame);
        let frame_maps = sf.map(|s| maps::read_maps(run, s)).transpose()?;
        rows.push(Row {
            png,
            file: format!("{name}/{file}"),
            run: name.clone(),
            params: params.to_vec(),
            ints: [
                Some(f.frame as i64),
                Some(i64::from(f.step)),
                Some(f.t_ns as i64),
                frame_maps.as_ref().map(|m| m.width as i64),
                frame_maps.as_ref().map(|m| m.height as i64),
            ],
            floats: vec![
                f.fx_n,
                f.fy_n,
                f.fz_n,
                f.tx_nmm,
                f.ty_nmm,
                f.tz_nmm,
                step.and_then(|s| s.position),
                truth.and_then(|s| s.depth_mm),
                truth.and_then(|s| s.contact_radius_mm),
                truth.map(|s| s.fz_eq_n),
                truth.map(|s| s.fx_eq_n),
                truth.map(|s| s.tz_eq_nmm),
                sf.map(|s| s.depth_mm),
                sf.map(|s| s.shear_n),
                sf.map(|s| s.torque_nmm),
                sf.map(|s| s.centre_x_mm),
                sf.map(|s| s.centre_y_mm),
                sf.map(|s| s.rotation_rad),
                sf.map(|s| s.fz_n),
                sf.map(|s| s.contact_area_mm2),
                sf.map(|s| s.cell_mm),
            ],
            texts: [
                step.map(|s| s.unit.clone()).unwrap_or_default(),
                step.map(|s| s.axis.clone()).unwrap_or_default(),
                indenter.clone(),
            ],
            markers: m,
            maps: frame_maps,
        });
    }
    Ok(rows)
}

/// `sim_markers.csv` by frame: each marker's true centre, in id order.
fn sim_markers(path: &Path) -> HashMap<u64, Vec<[f32; 2]>> {
    #[derive(serde::Deserialize)]
    struct M {
        frame: u64,
        x_px: f32,
        y_px: f32,
    }
    let mut out: HashMap<u64, Vec<[f32; 2]>> = HashMap::new();
    if let Ok(mut r) = csv::Reader::from_path(path) {
        for m in r.deserialize::<M>().flatten() {
            out.entry(m.frame).or_default().push([m.x_px, m.y_px]);
        }
    }
    out
}

/// The protocol's `indenter:` as JSON (`{"shape":"sphere","diameter":"12.68 mm"}`).
fn indenter_json(protocol: &Path) -> String {
    std::fs::read_to_string(protocol)
        .ok()
        .and_then(|t| serde_yaml::from_str::<serde_yaml::Value>(&t).ok())
        .and_then(|v| v.get("indenter").cloned())
        .and_then(|i| serde_json::to_string(&i).ok())
        .unwrap_or_default()
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_parameter_named_as_a_label_gets_its_own_column() {
        assert_eq!(super::param_column("indenter"), "sweep.indenter");
        assert_eq!(super::param_column("pressure_kpa"), "sweep.pressure_kpa");
        assert_eq!(
            super::param_column("indenter.diameter_mm"),
            "indenter.diameter_mm"
        );
        assert_eq!(super::param_column("seed"), "seed");
    }
}
