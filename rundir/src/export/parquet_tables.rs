//! `gelrig export RUN_DIR|RUNS_DIR --format parquet`: every table of a run directory as a
//! Parquet file with typed columns and each column's unit in its field metadata — or, for a
//! folder of runs, one file per table across all of them with a `run` column, for analysing
//! a campaign in pandas.
//!
//! The types are read from the values (integers, numbers, true/false, text; text with few
//! distinct values becomes a dictionary, a pandas `category`), the units from the column
//! names, which carry them by the project's rule (`fz_n` N, `tz_nmm` N·mm, `t_ns` ns, `x_px`
//! px, `settle_s` s, …): a column added to a CSV arrives typed and with its unit, with no
//! list to keep in step here.

use std::collections::HashMap;
use std::fs::File;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use arrow_array::types::Int32Type;
use arrow_array::{
    ArrayRef, BooleanArray, DictionaryArray, Float64Array, Int64Array, RecordBatch, StringArray,
};
use arrow_schema::{DataType, Field, Schema};

use super::ExportError;
use crate::read::RunDirError;

/// The tables exported, where a run has them.
pub const TABLES: [&str; 9] = [
    "force",
    "axes",
    "steps",
    "frames",
    "markers",
    "contact",
    "tactile",
    "wrench",
    "sim_steps",
];

/// The unit a column's name carries, by its suffix.
pub fn unit_of(column: &str) -> Option<&'static str> {
    const SUFFIXES: [(&str, &str); 14] = [
        ("_ns", "ns"),
        ("_nmm", "N·mm"),
        ("_mm_s", "mm/s"),
        ("_mm2", "mm²"),
        ("_px2", "px²"),
        ("_n", "N"),
        ("_mm", "mm"),
        ("_px", "px"),
        ("_s", "s"),
        ("_deg", "deg"),
        ("_hz", "Hz"),
        ("_um", "µm"),
        ("_pct", "%"),
        ("_n_s", "N/s"),
    ];
    SUFFIXES
        .iter()
        .filter(|(s, _)| column.ends_with(s))
        .max_by_key(|(s, _)| s.len())
        .map(|(_, u)| *u)
}

/// What a column holds, read from its values.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Kind {
    Int,
    Float,
    Bool,
    Dictionary,
    Text,
}

fn kind_of(values: &[&str]) -> Kind {
    let present: Vec<&str> = values.iter().copied().filter(|v| !v.is_empty()).collect();
    if present.is_empty() {
        return Kind::Float;
    }
    if present.iter().all(|v| v.parse::<i64>().is_ok()) {
        return Kind::Int;
    }
    if present.iter().all(|v| v.parse::<f64>().is_ok()) {
        return Kind::Float;
    }
    if present.iter().all(|v| *v == "true" || *v == "false") {
        return Kind::Bool;
    }
    let mut distinct: Vec<&str> = present.clone();
    distinct.sort_unstable();
    distinct.dedup();
    if distinct.len() <= 64 && distinct.len() * 4 <= present.len().max(4) {
        Kind::Dictionary
    } else {
        Kind::Text
    }
}

/// A CSV table: its header and rows, each tagged with the run it came from.
struct Table {
    columns: Vec<String>,
    rows: Vec<(usize, HashMap<String, String>)>,
}

/// Puts each run's parameters (one value per run) on each of its rows, as the first
/// columns after `run`.
fn add_parameters(table: &mut Table, params: &[(String, Vec<String>)]) {
    if table.columns.is_empty() || params.is_empty() {
        return;
    }
    for (name, values) in params.iter().rev() {
        table.columns.insert(0, name.clone());
        for (run, row) in &mut table.rows {
            row.insert(name.clone(), values.get(*run).cloned().unwrap_or_default());
        }
    }
}

fn read_table(path: &Path, run: usize, into: &mut Table) -> Result<(), ExportError> {
    let mut r = csv::Reader::from_path(path).map_err(|e| RunDirError::Missing {
        path: path.to_path_buf(),
        detail: e.to_string(),
    })?;
    let header: Vec<String> = r
        .headers()
        .map_err(|e| RunDirError::Malformed {
            path: path.to_path_buf(),
            row: 0,
            detail: e.to_string(),
        })?
        .iter()
        .map(str::to_string)
        .collect();
    for c in &header {
        if !into.columns.contains(c) {
            into.columns.push(c.clone());
        }
    }
    for (k, rec) in r.records().enumerate() {
        let rec = rec.map_err(|e| RunDirError::Malformed {
            path: path.to_path_buf(),
            row: k + 1,
            detail: e.to_string(),
        })?;
        into.rows.push((
            run,
            header
                .iter()
                .cloned()
                .zip(rec.iter().map(str::to_string))
                .collect(),
        ));
    }
    Ok(())
}

/// The table's columns as Arrow arrays, with a `run` column first when `runs` names them.
fn batch(table: &Table, runs: Option<&[String]>) -> Result<RecordBatch, String> {
    let mut fields = Vec::new();
    let mut arrays: Vec<ArrayRef> = Vec::new();
    if let Some(names) = runs {
        fields.push(Field::new(
            "run",
            DataType::Dictionary(Box::new(DataType::Int32), Box::new(DataType::Utf8)),
            false,
        ));
        let col: DictionaryArray<Int32Type> = table
            .rows
            .iter()
            .map(|(r, _)| names.get(*r).map(String::as_str).unwrap_or(""))
            .collect();
        arrays.push(Arc::new(col));
    }
    for c in &table.columns {
        let values: Vec<&str> = table
            .rows
            .iter()
            .map(|(_, row)| row.get(c).map(String::as_str).unwrap_or(""))
            .collect();
        let kind = kind_of(&values);
        let (dt, array): (DataType, ArrayRef) = match kind {
            Kind::Int => (
                DataType::Int64,
                Arc::new(Int64Array::from(
                    values
                        .iter()
                        .map(|v| v.parse::<i64>().ok())
                        .collect::<Vec<_>>(),
                )),
            ),
            Kind::Float => (
                DataType::Float64,
                Arc::new(Float64Array::from(
                    values
                        .iter()
                        .map(|v| v.parse::<f64>().ok())
                        .collect::<Vec<_>>(),
                )),
            ),
            Kind::Bool => (
                DataType::Boolean,
                Arc::new(BooleanArray::from(
                    values
                        .iter()
                        .map(|v| (!v.is_empty()).then_some(*v == "true"))
                        .collect::<Vec<_>>(),
                )),
            ),
            Kind::Dictionary => (
                DataType::Dictionary(Box::new(DataType::Int32), Box::new(DataType::Utf8)),
                Arc::new(
                    values
                        .iter()
                        .map(|v| (!v.is_empty()).then_some(*v))
                        .collect::<DictionaryArray<Int32Type>>(),
                ),
            ),
            Kind::Text => (
                DataType::Utf8,
                Arc::new(StringArray::from(
                    values
                        .iter()
                        .map(|v| (!v.is_empty()).then_some(*v))
                        .collect::<Vec<_>>(),
                )),
            ),
        };
        let mut field = Field::new(c, dt, true);
        if let Some(u) = unit_of(c) {
            field = field.with_metadata(HashMap::from([("unit".to_string(), u.to_string())]));
        }
        fields.push(field);
        arrays.push(array);
    }
    RecordBatch::try_new(Arc::new(Schema::new(fields)), arrays).map_err(|e| e.to_string())
}

/// What a Parquet export wrote: each file and its rows.
#[derive(Debug, Clone, PartialEq)]
pub struct ParquetExport {
    /// The folder written.
    pub dir: PathBuf,
    /// Table name, file, rows.
    pub tables: Vec<(String, PathBuf, usize)>,
    /// The runs exported.
    pub runs: Vec<PathBuf>,
}

/// Exports `path` — a run directory, or a folder of them (a campaign, with a `run` column) —
/// as Parquet files into `out`.
pub fn export_parquet(path: &Path, out: &Path) -> Result<ParquetExport, ExportError> {
    let (runs, params, campaign) = runs_of(path)?;
    if runs.is_empty() {
        return Err(RunDirError::Missing {
            path: path.join(crate::names::MANIFEST),
            detail: "neither a run directory nor a folder of runs".into(),
        }
        .into());
    }
    let werr = |p: &Path, e: String| ExportError::Write {
        path: p.to_path_buf(),
        detail: e,
    };
    std::fs::create_dir_all(out).map_err(|e| werr(out, e.to_string()))?;
    let names: Vec<String> = runs
        .iter()
        .map(|r| {
            r.file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default()
        })
        .collect();
    let mut tables = Vec::new();
    for name in TABLES {
        let mut table = Table {
            columns: Vec::new(),
            rows: Vec::new(),
        };
        for (k, run) in runs.iter().enumerate() {
            let csv = run.join(format!("{name}.csv"));
            if csv.is_file() {
                read_table(&csv, k, &mut table)?;
            }
        }
        add_parameters(&mut table, &params);
        if table.columns.is_empty() {
            continue;
        }
        let batch = batch(&table, campaign.then_some(names.as_slice()))
            .map_err(|e| werr(out, format!("{name}: {e}")))?;
        let file = out.join(format!("{name}.parquet"));
        let f = File::create(&file).map_err(|e| werr(&file, e.to_string()))?;
        let mut w = parquet::arrow::ArrowWriter::try_new(f, batch.schema(), None)
            .map_err(|e| werr(&file, e.to_string()))?;
        w.write(&batch).map_err(|e| werr(&file, e.to_string()))?;
        w.close().map_err(|e| werr(&file, e.to_string()))?;
        tables.push((name.to_string(), file, table.rows.len()));
    }
    Ok(ParquetExport {
        dir: out.to_path_buf(),
        tables,
        runs,
    })
}

/// The runs an export covers: one run directory; a folder of runs; or a sweep's campaign
/// (its completed points' runs, with their parameters as columns). Also whether it is more
/// than one run's folder.
pub(crate) fn runs_of(path: &Path) -> Result<RunsOf, ExportError> {
    let campaign = !path.join(crate::names::MANIFEST).is_file();
    // A sweep's campaign: its completed points' runs, their parameters as columns.
    let swept = match crate::campaign_dir::campaign_runs(path) {
        Some(Ok(runs)) => Some(runs),
        Some(Err(detail)) => {
            return Err(RunDirError::Missing {
                path: path.join("campaign.csv"),
                detail,
            }
            .into());
        }
        None => None,
    };
    let params = swept
        .as_deref()
        .map(crate::campaign_dir::parameter_columns)
        .unwrap_or_default();
    let runs: Vec<PathBuf> = if let Some(swept) = &swept {
        swept.iter().map(|(d, _)| d.clone()).collect()
    } else if campaign {
        let mut v: Vec<PathBuf> = std::fs::read_dir(path)
            .map_err(|e| RunDirError::Missing {
                path: path.to_path_buf(),
                detail: e.to_string(),
            })?
            .filter_map(Result::ok)
            .map(|e| e.path())
            .filter(|p| p.join(crate::names::MANIFEST).is_file())
            .collect();
        v.sort();
        v
    } else {
        vec![path.to_path_buf()]
    };
    Ok((runs, params, campaign))
}

/// [`runs_of`]: the run directories, the parameter columns (one value per run), and whether
/// the path is a folder of runs rather than one.
pub(crate) type RunsOf = (Vec<PathBuf>, Vec<(String, Vec<String>)>, bool);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn units_come_from_the_names_and_types_from_the_values() {
        assert_eq!(unit_of("tz_nmm"), Some("N·mm"));
        assert_eq!(unit_of("fz_n"), Some("N"));
        assert_eq!(unit_of("t_ns"), Some("ns"));
        assert_eq!(unit_of("true_slip_mm_s"), Some("mm/s"));
        assert_eq!(unit_of("contact_area_mm2"), Some("mm²"));
        assert_eq!(unit_of("state"), None);
        assert_eq!(kind_of(&["1", "", "3"]), Kind::Int);
        assert_eq!(kind_of(&["1", "2.5"]), Kind::Float);
        assert_eq!(kind_of(&["true", "false"]), Kind::Bool);
        assert_eq!(kind_of(&["stick"; 10]), Kind::Dictionary);
        assert_eq!(kind_of(&["a/1.png", "a/2.png"]), Kind::Text);
    }
}
