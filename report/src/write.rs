//! The report on disk: plots (SVG + PNG), `report.md`, a self-contained `report.html`
//! and `summary.json`.

use std::fs;
use std::path::Path;

use serde_json::{Value, json};

use super::out::{Out, Section, num, werr};
use super::plots::{Chart, Series};
use super::results::Report;
use super::{ReportError, RunData, Written};

pub(super) fn write(
    data: &RunData,
    r: &Report,
    dir: &Path,
    gelsight: Option<(
        &sensing::sensor::SensorFile,
        &str,
        &[sensing::sensor::WrenchRow],
    )>,
) -> Result<Written, ReportError> {
    fs::create_dir_all(dir).map_err(|e| werr(dir)(e.to_string()))?;
    let mut out = Out {
        dir: dir.to_path_buf(),
        sections: Vec::new(),
    };
    let (run_md, run_json) = super::header::header(data);
    let mut summary = json!({ "run": run_json });
    out.sections.push(Section {
        title: "Run".into(),
        text: run_md,
        plots: Vec::new(),
    });
    force_time(data, &mut out)?;
    let main = r
        .blocks
        .iter()
        .enumerate()
        .max_by_key(|(_, b)| b.steps.len())
        .map(|(k, _)| k);
    let mut blocks_json = Vec::new();
    for (k, b) in r.blocks.iter().enumerate() {
        let j = super::block_sections::block_sections(data, r, b, k, &mut out)?;
        if Some(k) == main {
            summary["main_block"] = json!({"kind": b.kind.name(), "unit": b.unit,
                "force_unit": b.kind.force_unit()});
            for key in ["linearity", "hysteresis", "slip", "force_from_field"] {
                if let Some(v) = j.get(key) {
                    summary[key] = v.clone();
                }
            }
        }
        blocks_json.push(j);
    }
    summary["blocks"] = Value::Array(blocks_json);
    if let (Some(slope), Some(lin)) = (r.sim_slope, summary.get_mut("linearity")) {
        lin["sim_slope"] = num(slope);
    }
    super::relaxation::section(r, &mut out, &mut summary)?;
    if let Some((title, text, rows)) = super::contact::section(data) {
        out.sections.push(Section {
            title,
            text,
            plots: Vec::new(),
        });
        summary["contact"] = rows;
    }
    if let Some((title, text, rows, plots)) = super::depth::section(data, &out.dir)? {
        out.sections.push(Section { title, text, plots });
        summary["depth"] = rows;
    }
    let grasp = super::trials::analyse(data, &data.tactile);
    if let Some((title, text, json, charts)) = super::trials::section(data, &grasp, &data.tactile) {
        let mut plots = Vec::new();
        for (name, chart) in &charts {
            plots.push(out.plot(name, chart)?);
        }
        let mut text = text;
        let mut pictures = 0;
        for t in &grasp {
            let shots = super::snapshots::write(data, t, &out.dir)?;
            pictures += shots.len();
            plots.extend(shots.into_iter().map(|(file, _)| file));
        }
        if pictures > 0 {
            text.push_str(
                "\nField snapshots per trial (Fig. 6-20 to 6-24): the total field and the \
                 differential field (from the frame before) at the grip, the end of the lift, \
                 the hold, the disturbance's largest twist and the tactile warning \
                 (`trial_NNN_<moment>_<total|differential>.svg`; arrows magnified so the \
                 largest is 20 px).\n",
            );
        }
        out.sections.push(Section { title, text, plots });
        summary["trials"] = json["trials"].clone();
        summary["trial_stats"] = json["trial_stats"].clone();
    }
    if let Some((title, text, json, charts)) =
        gelsight.and_then(|(f, name, rows)| super::gelsight_force::section(data, f, name, rows))
    {
        let mut plots = Vec::new();
        for (name, chart) in &charts {
            plots.push(out.plot(name, chart)?);
        }
        out.sections.push(Section { title, text, plots });
        summary["gelsight_force"] = json;
    }
    if let Some((title, text, json, chart)) = super::camera_timing::section(data) {
        let plots = match &chart {
            Some(c) => vec![out.plot("frame_intervals", c)?],
            None => Vec::new(),
        };
        out.sections.push(Section { title, text, plots });
        summary["camera_timing"] = json;
    }
    if let Some(note) = &r.model_note {
        summary["notes"] = json!([note]);
    }
    let sections: Vec<String> = out.sections.iter().map(|s| s.title.clone()).collect();
    summary["sections"] = json!(sections);
    let p = dir.join("summary.json");
    let text = serde_json::to_string_pretty(&summary).map_err(|e| werr(&p)(e.to_string()))?;
    fs::write(&p, text).map_err(|e| werr(&p)(e.to_string()))?;
    let heading = super::html::Heading::run(data);
    super::html::write_md(&heading, &out)?;
    super::html::write_html(&heading, &out)?;
    Ok(Written {
        dir: dir.to_path_buf(),
        sections,
        summary,
    })
}

fn force_time(data: &RunData, out: &mut Out) -> Result<(), ReportError> {
    if data.force.is_empty() {
        return Ok(());
    }
    // At most ~4000 points per channel: every k-th sample.
    let k = (data.force.len() / 4000).max(1);
    // The line breaks where a resumed run's segment starts: nothing was recorded between.
    let breaks: Vec<u64> = data.manifest.resumed.iter().map(|s| s.t_start_ns).collect();
    let pts = |g: &dyn Fn(&super::ForceRow) -> f64| -> Vec<(f64, f64)> {
        let mut out = Vec::new();
        let mut last_t = 0;
        for r in data.force.iter().step_by(k) {
            if breaks.iter().any(|&b| last_t < b && b <= r.t_ns) {
                out.push((f64::NAN, f64::NAN));
            }
            last_t = r.t_ns;
            out.push((r.t_ns as f64 * 1e-9, g(r)));
        }
        out
    };
    let chart = Chart {
        title: "Force against time (shaded: steps)".into(),
        x_label: "time (s)".into(),
        y_label: "force (N), torque (N·mm)".into(),
        series: vec![
            Series::line("Fz", pts(&|r| r.fz_n), 0),
            Series::line("Fx", pts(&|r| r.fx_n), 1),
            Series::line("Fy", pts(&|r| r.fy_n), 2),
            Series::line("Tz", pts(&|r| r.tz_nmm), 3),
        ],
        bands: data
            .steps
            .iter()
            .map(|s| (s.t_start_ns as f64 * 1e-9, s.settle_end_ns as f64 * 1e-9))
            .collect(),
        ..Default::default()
    };
    let name = out.plot("force_time", &chart)?;
    out.sections.push(Section {
        title: "Force against time".into(),
        text: format!(
            "{} force samples over {} steps; shaded bands are the steps (move, settle, capture).\n",
            data.force.len(),
            data.steps.len()
        ),
        plots: vec![name],
    });
    Ok(())
}
