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
use std::sync::Arc;

use arrow_array::builder::{BinaryBuilder, Float32Builder, ListBuilder, StringBuilder};
use arrow_array::{
    Array, ArrayRef, Float64Array, Int64Array, RecordBatch, StringArray, StructArray,
};
use arrow_schema::{DataType, Field, Fields, Schema};

use super::ExportError;
use super::parquet_tables::runs_of;
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
struct Row {
    png: Vec<u8>,
    file: String,
    run: String,
    params: Vec<String>,
    ints: [Option<i64>; 3],
    floats: Vec<Option<f64>>,
    texts: [String; 3],
    markers: [Vec<f32>; 4],
}

const INTS: [&str; 3] = ["frame", "step", "t_ns"];
const FLOATS: [&str; 12] = [
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
];
const TEXTS: [&str; 3] = ["position_unit", "axis", "indenter"];
const MARKERS: [&str; 4] = ["marker_x_px", "marker_y_px", "marker_dx_px", "marker_dy_px"];

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
    let names: Vec<String> = params.iter().map(|(n, _)| n.clone()).collect();
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
    let mut w =
        parquet::arrow::ArrowWriter::try_new(f, batch.schema(), None).map_err(|e| e.to_string())?;
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
        rows.push(Row {
            png,
            file: format!("{name}/{file}"),
            run: name.clone(),
            params: params.to_vec(),
            ints: [
                Some(f.frame as i64),
                Some(i64::from(f.step)),
                Some(f.t_ns as i64),
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
            ],
            texts: [
                step.map(|s| s.unit.clone()).unwrap_or_default(),
                step.map(|s| s.axis.clone()).unwrap_or_default(),
                indenter.clone(),
            ],
            markers: m,
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

/// Columns being built: their fields, arrays and `datasets` features.
#[derive(Default)]
struct Columns {
    fields: Vec<Field>,
    arrays: Vec<ArrayRef>,
    features: serde_json::Map<String, serde_json::Value>,
}

fn value(dtype: &str) -> serde_json::Value {
    serde_json::json!({"dtype": dtype, "_type": "Value"})
}

impl Columns {
    fn push(&mut self, name: &str, array: ArrayRef, feature: serde_json::Value) {
        self.fields
            .push(Field::new(name, array.data_type().clone(), true));
        self.arrays.push(array);
        self.features.insert(name.into(), feature);
    }

    fn text(&mut self, name: &str, values: Vec<&str>) {
        self.push(name, Arc::new(StringArray::from(values)), value("string"));
    }

    fn floats(&mut self, name: &str, values: Vec<Option<f64>>) {
        self.push(name, Arc::new(Float64Array::from(values)), value("float64"));
    }
}

/// The rows as one record batch, with the `huggingface` features in the schema's metadata.
fn batch(rows: &[Row], params: &[String]) -> Result<RecordBatch, String> {
    let mut c = Columns::default();
    // The frame, as the `Image` feature stores one: {bytes, path}.
    let mut bytes = BinaryBuilder::new();
    let mut paths = StringBuilder::new();
    for r in rows {
        bytes.append_value(&r.png);
        paths.append_value(&r.file);
    }
    let image_fields = Fields::from(vec![
        Field::new("bytes", DataType::Binary, true),
        Field::new("path", DataType::Utf8, true),
    ]);
    let image = StructArray::new(
        image_fields,
        vec![
            Arc::new(bytes.finish()) as ArrayRef,
            Arc::new(paths.finish()),
        ],
        None,
    );
    c.push(
        "image",
        Arc::new(image),
        serde_json::json!({"_type": "Image"}),
    );
    c.text("run", rows.iter().map(|r| r.run.as_str()).collect());
    for (k, p) in params.iter().enumerate() {
        let vals: Vec<&str> = rows.iter().map(|r| r.params[k].as_str()).collect();
        if vals.iter().all(|v| v.parse::<f64>().is_ok()) {
            c.floats(p, vals.iter().map(|v| v.parse::<f64>().ok()).collect());
        } else {
            c.text(p, vals);
        }
    }
    for (k, name) in INTS.iter().enumerate() {
        let ints = Int64Array::from(rows.iter().map(|r| r.ints[k]).collect::<Vec<_>>());
        c.push(name, Arc::new(ints), value("int64"));
    }
    for (k, name) in FLOATS.iter().enumerate() {
        c.floats(name, rows.iter().map(|r| r.floats[k]).collect());
    }
    for (k, name) in TEXTS.iter().enumerate() {
        c.text(name, rows.iter().map(|r| r.texts[k].as_str()).collect());
    }
    for (k, name) in MARKERS.iter().enumerate() {
        let mut list = ListBuilder::new(Float32Builder::new());
        for r in rows {
            list.values().append_slice(&r.markers[k]);
            list.append(true);
        }
        let feature = serde_json::json!({"feature": value("float32"), "_type": "Sequence"});
        c.push(name, Arc::new(list.finish()), feature);
    }
    let meta = serde_json::json!({"info": {"features": c.features}}).to_string();
    let schema =
        Schema::new(c.fields).with_metadata(HashMap::from([("huggingface".to_string(), meta)]));
    RecordBatch::try_new(Arc::new(schema), c.arrays).map_err(|e| e.to_string())
}

/// The dataset card: what, how it was made, the columns and their units, and the licence of
/// the generator's assumptions.
fn card_text(frames: usize, runs: usize, params: &[String]) -> String {
    let params_text = if params.is_empty() {
        "none (a run or a folder of runs)".to_string()
    } else {
        params
            .iter()
            .map(|p| format!("`{p}`"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    format!(
        "---\nconfigs:\n- config_name: default\n  data_files:\n  - split: train\n    path: data/train-*.parquet\ntask_categories:\n- image-to-image\n- tabular-regression\ntags:\n- tactile\n- gelsight\n- simulation\n---\n\n\
# gelrig tactile dataset\n\n\
{frames} frames of {runs} runs written by `gelrig export --format dataset`: each row a \
GelSight frame (PNG) and what the run recorded and the simulated bench knew at that frame.\n\n\
Load it with `datasets.load_dataset(\"parquet\", data_files=\"data/*.parquet\")` or from this \
folder (`load_dataset(\"path/to/folder\")`); pandas and pyarrow read the shards too.\n\n\
## How it was made\n\n\
Dry runs of gelrig protocols on its simulated bench: a bonded viscoelastic gel layer pressed, \
sheared and twisted by a rigid indenter (the contact mechanics checked against finite \
elements: docs/benchmarks/pressing.md), its camera frames rendered with markers, shading and \
sensor noise, a Nano17-like force sensor sampled through the exposure. The gel's values of \
each protocol are assumed, not measured (the protocol file states them); the renderer is not \
a calibrated photometric model of any real sensor.\n\n\
Swept parameters (one column each; a quantity with one unit is a number column named with \
the unit): {params_text}.\n\n\
## Columns\n\n\
| column | what | unit |\n|---|---|---|\n\
| `image` | the frame (PNG; the `Image` feature) and its path in the run | — |\n\
| `run` | the run directory's name | — |\n\
| `frame`, `step`, `t_ns` | frame number, protocol step, time on the run's clock | —, —, ns |\n\
| `fx_n` … `tz_nmm` | the force sensor during the exposure (tared) | N, N·mm |\n\
| `axis`, `position`, `position_unit` | the step's axis and where it ended | the step's unit |\n\
| `sim_depth_mm` | the simulator's indentation depth at the step's end | mm |\n\
| `sim_contact_radius_mm` | the simulated contact's radius (equivalent, √(area/π)) | mm |\n\
| `sim_fz_n`, `sim_fx_n`, `sim_tz_nmm` | the simulator's equilibrium wrench at the step's end | N, N·mm |\n\
| `indenter` | the protocol's indenter, as JSON | — |\n\
| `marker_x_px`, `marker_y_px` | every marker's true centre in this frame, in id order | px |\n\
| `marker_dx_px`, `marker_dy_px` | its displacement from the run's first frame | px |\n\n\
Pressure and shear-traction maps and a contact mask per frame are not in this version.\n\n\
## Licence\n\n\
The frames and labels are generated; gelrig is MIT OR Apache-2.0, and so is what it \
generates. The assumptions behind them (gel values, indenters, the renderer) are the \
protocols'.\n"
    )
}
