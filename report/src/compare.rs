//! `gelrig report RUN_A RUN_B … --out DIR`: the same quantities of several runs side by side
//! — a dry run against the wire twins, two seeds, two gels — with their differences.
//!
//! Each run gets its own report as usual (in its `report/`); the comparison overlays the
//! main block's force against load (loading and unloading, so the hysteresis loops compare)
//! and tabulates the headline numbers with each run's difference from the first.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use serde_json::{Value, json};

use super::analyse;
use super::html::{Heading, esc};
use super::out::{Out, Section, f, num};
use super::plots::{Chart, Mark, Series};
use super::results::Block;
use super::{ReportError, Written, read_run};

/// One number compared across runs: its label and where it sits in a run's summary.
struct Metric {
    /// Its label, with units from the first run's main block (`force`, `load`).
    label: &'static str,
    get: fn(&Value) -> Option<f64>,
}

/// `label` with `{force}` and `{load}` replaced by the units of `summary`'s main block.
fn with_units(label: &str, summary: &Value) -> String {
    let b = &summary["main_block"];
    label
        .replace("{force}", b["force_unit"].as_str().unwrap_or("force unit"))
        .replace("{load}", b["unit"].as_str().unwrap_or("load unit"))
}

const METRICS: [Metric; 8] = [
    Metric {
        label: "stiffness ({force}/{load})",
        get: |s| s["linearity"]["slope"].as_f64(),
    },
    Metric {
        label: "R² over the linear range",
        get: |s| s["linearity"]["r2"].as_f64(),
    },
    Metric {
        label: "linear range ({load})",
        get: |s| s["linearity"]["linear_range"].as_f64(),
    },
    Metric {
        label: "hysteresis: largest load–unload gap ({force})",
        get: |s| s["hysteresis"]["max_gap"].as_f64(),
    },
    Metric {
        label: "friction coefficient μ",
        get: |s| s["slip"]["mu"].as_f64(),
    },
    Metric {
        label: "slip onset (step)",
        get: |s| s["slip"]["onset_step"].as_f64(),
    },
    Metric {
        label: "force from field, RMSE (%)",
        get: |s| s["force_from_field"]["rmse_pct"].as_f64(),
    },
    Metric {
        label: "slowest pooled τ (s)",
        get: |s| {
            s["relaxation"]["shared_tau_s"]
                .as_array()
                .and_then(|t| t.last())
                .and_then(Value::as_f64)
        },
    },
];

/// One run compared: its folder, protocol name, written report and main block.
type Reported = (PathBuf, String, Written, Option<Block>);

fn run_name(k: usize) -> String {
    format!("run {}", k + 1)
}

/// The table of the runs compared.
fn runs_table(reports: &[Reported]) -> String {
    let mut text =
        String::from("| | run | protocol | status | rig | seed |\n|---|---|---|---|---|---|\n");
    for (k, (dir, protocol, w, _)) in reports.iter().enumerate() {
        let run = &w.summary["run"];
        let _ = writeln!(
            text,
            "| {} | `{}` | {} | {} | {} | {} |",
            run_name(k),
            dir.display(),
            esc(protocol),
            run["status"].as_str().unwrap_or("—"),
            if run["simulated"] == true {
                "simulated"
            } else {
                "devices"
            },
            run["seed"]
        );
    }
    text
}

/// The headline numbers of every run and each run's difference from the first, as a table
/// and as JSON.
fn metrics_table(reports: &[Reported]) -> (String, serde_json::Map<String, Value>) {
    let mut text = String::from("| quantity |");
    for k in 0..reports.len() {
        let _ = write!(text, " {} |", run_name(k));
    }
    for k in 1..reports.len() {
        let _ = write!(text, " {} − run 1 (%) |", run_name(k));
    }
    text.push('\n');
    text.push_str(&"|---".repeat(2 * reports.len()));
    text.push_str("|\n");
    let mut metrics_json = serde_json::Map::new();
    for m in &METRICS {
        let values: Vec<Option<f64>> = reports.iter().map(|r| (m.get)(&r.2.summary)).collect();
        if values.iter().all(Option::is_none) {
            continue;
        }
        let label = with_units(m.label, &reports[0].2.summary);
        let _ = write!(text, "| {label} |");
        for v in &values {
            let _ = write!(text, " {} |", v.map_or("—".into(), |v| f(v, 4)));
        }
        let diffs: Vec<Option<f64>> = values
            .iter()
            .skip(1)
            .map(|v| match (values[0], *v) {
                (Some(a), Some(b)) if a != 0.0 => Some(100.0 * (b - a) / a.abs()),
                _ => None,
            })
            .collect();
        for d in &diffs {
            let _ = write!(text, " {} |", d.map_or("—".into(), |d| format!("{d:+.2}")));
        }
        text.push('\n');
        metrics_json.insert(
            label,
            json!({"values": values.iter().map(|v| v.map(num)).collect::<Vec<_>>(),
                   "difference_pct_from_first": diffs.iter().map(|v| v.map(num)).collect::<Vec<_>>()}),
        );
    }
    (text, metrics_json)
}

/// Force against load of each run's main block, loading and unloading.
fn force_load_series(kinds: &[Option<&Block>]) -> Vec<Series> {
    let mut series = Vec::new();
    for (k, b) in kinds.iter().enumerate() {
        let Some(b) = b else { continue };
        let pts = |unloading: bool| -> Vec<(f64, f64)> {
            b.steps
                .iter()
                .filter(|s| s.unloading == unloading)
                .map(|s| (s.load, s.force))
                .collect()
        };
        series.push(Series {
            name: format!("{} loading", run_name(k)),
            points: pts(false),
            mark: Mark::LinePoints,
            colour: k,
        });
        let unload = pts(true);
        if !unload.is_empty() {
            series.push(Series {
                name: format!("{} unloading", run_name(k)),
                points: unload,
                mark: Mark::Points,
                colour: k,
            });
        }
    }
    series
}

/// Reports every run of `runs` and compares them into `out`.
pub fn compare(runs: &[PathBuf], out: &Path) -> Result<Written, ReportError> {
    let mut reports: Vec<Reported> = Vec::new();
    for dir in runs {
        let data = read_run(dir)?;
        let model = analyse::reference_model(&data);
        let report = analyse::analyse(&data, model);
        let written = super::write::write(&data, &report, &dir.join("report"), None)?;
        let main = report.blocks.iter().max_by_key(|b| b.steps.len()).cloned();
        reports.push((dir.clone(), data.protocol_name.clone(), written, main));
    }
    std::fs::create_dir_all(out).map_err(|e| super::out::werr(out)(e.to_string()))?;
    let mut o = Out {
        dir: out.to_path_buf(),
        sections: Vec::new(),
    };
    o.sections.push(Section {
        title: "Runs compared".into(),
        text: runs_table(&reports),
        plots: Vec::new(),
    });
    let (mut text, metrics_json) = metrics_table(&reports);
    let kinds: Vec<Option<&Block>> = reports.iter().map(|r| r.3.as_ref()).collect();
    let series = force_load_series(&kinds);
    let mut plots = Vec::new();
    let first = kinds.iter().flatten().next();
    let same_kind = kinds
        .iter()
        .flatten()
        .all(|b| first.is_some_and(|f| f.kind == b.kind && f.unit == b.unit));
    if let Some(b) = first.filter(|_| same_kind && !series.is_empty()) {
        plots.push(o.plot(
            "compare_force_load",
            &Chart {
                title: format!(
                    "{} force against {}, each run",
                    b.kind.name(),
                    b.kind.load_name()
                ),
                x_label: format!("{} ({})", b.kind.load_name(), b.unit),
                y_label: b.kind.force_label().into(),
                series,
                ..Default::default()
            },
        )?);
    } else if !series.is_empty() {
        text.push_str(
            "\nThe runs' main blocks load different axes: their force–load curves are not \
             overlaid.\n",
        );
    }
    o.sections.push(Section {
        title: "Headline numbers and differences".into(),
        text,
        plots,
    });
    let summary = json!({
        "runs": reports.iter().map(|r| r.2.summary["run"].clone()).collect::<Vec<_>>(),
        "metrics": metrics_json,
    });
    let p = out.join("summary.json");
    let body =
        serde_json::to_string_pretty(&summary).map_err(|e| super::out::werr(&p)(e.to_string()))?;
    std::fs::write(&p, body).map_err(|e| super::out::werr(&p)(e.to_string()))?;
    let heading = Heading {
        title: format!("Comparison of {} runs", reports.len()),
        what: reports
            .iter()
            .enumerate()
            .map(|(k, r)| format!("{}: `{}`", run_name(k), r.0.display()))
            .collect::<Vec<_>>()
            .join("; "),
    };
    super::html::write_md(&heading, &o)?;
    super::html::write_html(&heading, &o)?;
    Ok(Written {
        dir: out.to_path_buf(),
        sections: o.sections.iter().map(|s| s.title.clone()).collect(),
        summary,
    })
}
