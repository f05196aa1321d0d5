//! The report on disk: plots (SVG + PNG), `report.md`, a self-contained `report.html`
//! and `summary.json`.

use std::fmt::Write as _;
use std::fs;
use std::path::Path;

use serde_json::{Value, json};

use super::out::{Out, Section, f, num, werr};
use super::plots::{Chart, Mark, Series};
use super::results::{Block, Kind, Report};
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
        let j = block_sections(data, r, b, k, &mut out)?;
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

fn block_sections(
    data: &RunData,
    r: &Report,
    b: &Block,
    k: usize,
    out: &mut Out,
) -> Result<Value, ReportError> {
    let unit = b.unit.as_str();
    let fu = b.kind.force_unit();
    let tag = format!("block{}_{}", k + 1, b.kind.name());
    let mut j = json!({"kind": b.kind.name(), "unit": unit, "force_unit": fu,
        "steps": b.steps.iter().map(|s| s.step).collect::<Vec<_>>()});
    let load_pts: Vec<(f64, f64)> = b
        .steps
        .iter()
        .filter(|s| !s.unloading)
        .map(|s| (s.load, s.force))
        .collect();
    let unload_pts: Vec<(f64, f64)> = b
        .steps
        .iter()
        .filter(|s| s.unloading)
        .map(|s| (s.load, s.force))
        .collect();
    // Linearity.
    if let Some(lin) = &b.linearity {
        let (x0, x1) = load_pts
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |a, p| {
                (a.0.min(p.0), a.1.max(p.0))
            });
        // The line over the loads it was fitted on (the linear range), not beyond.
        let fit_end = lin.range.as_ref().map_or(x1, |rg| rg.end_x.min(x1));
        let line = |l: &analysis::linearity::LineFit| {
            vec![
                (x0.min(0.0), l.slope * x0.min(0.0) + l.intercept),
                (fit_end, l.slope * fit_end + l.intercept),
            ]
        };
        let mut series = vec![
            Series {
                name: "loading".into(),
                points: load_pts.clone(),
                mark: Mark::Points,
                colour: 0,
            },
            Series {
                name: format!("fit, slope {} {fu}/{unit}", f(lin.with_intercept.slope, 3)),
                points: line(&lin.with_intercept),
                mark: Mark::Line,
                colour: 3,
            },
        ];
        if !unload_pts.is_empty() {
            series.insert(
                1,
                Series {
                    name: "unloading".into(),
                    points: unload_pts.clone(),
                    mark: Mark::Points,
                    colour: 1,
                },
            );
        }
        if let Some(p) = &lin.power_law {
            let curve: Vec<(f64, f64)> = (0..=60)
                .map(|i| x0 + (x1 - x0) * i as f64 / 60.0)
                .map(|d| (d, p.k * (d + p.d0).powf(p.n)))
                .collect();
            series.push(Series {
                name: format!("F = {}·(d + {})^{}", f(p.k, 2), f(p.d0, 3), f(p.n, 2)),
                points: curve,
                mark: Mark::Line,
                colour: 2,
            });
        }
        let markers = lin
            .range
            .as_ref()
            .map(|rg| {
                vec![(
                    rg.end_x,
                    format!("linear range ends ({} %)", rg.tolerance * 100.0),
                )]
            })
            .unwrap_or_default();
        let name = out.plot(
            &format!("{tag}_force_load"),
            &Chart {
                title: format!("{} force against load", b.kind.name()),
                x_label: format!("{} ({unit})", b.kind.load_name()),
                y_label: b.kind.force_label().into(),
                series,
                markers,
                ..Default::default()
            },
        )?;
        let rg = lin.range.as_ref();
        let mut text = format!(
            "| fit | slope ({fu}/{unit}) | intercept ({fu}) | R² |\n|---|---|---|---|\n| linear range, with intercept | {} | {} | {} |\n| linear range, through origin | {} | 0 | {} |\n| every loading step, with intercept | {} | {} | {} |\n\n",
            f(lin.with_intercept.slope, 4),
            f(lin.with_intercept.intercept, 4),
            f(lin.with_intercept.r2, 5),
            f(lin.through_origin.slope, 4),
            f(lin.through_origin.r2, 5),
            f(lin.all.slope, 4),
            f(lin.all.intercept, 4),
            f(lin.all.r2, 5)
        );
        if let Some(rg) = rg {
            let _ = writeln!(
                text,
                "Linear range (within {} % of the first three steps' slope {} {fu}/{unit}): up to **{} {unit}** ({} of {} loading steps).\n",
                rg.tolerance * 100.0,
                f(rg.initial_slope, 3),
                f(rg.end_x, 3),
                rg.points,
                load_pts.len()
            );
        }
        if let Some(p) = &lin.power_law {
            let _ = writeln!(
                text,
                "Power law F = k·(d + d0)ⁿ: k = {}, n = {}, d0 = {} {unit} (contact found after the indenter had entered by d0), R² = {}.\n",
                f(p.k, 3),
                f(p.n, 3),
                f(p.d0, 4),
                f(p.r2, 5)
            );
        }
        if let Some(slope) = r
            .sim_slope
            .filter(|_| b.steps.len() == r.blocks.iter().map(|b| b.steps.len()).max().unwrap_or(0))
        {
            let _ = writeln!(
                text,
                "Simulator's equilibrium slope over the same range: {} {fu}/{unit} (recovered {:+.2} %).\n",
                f(slope, 4),
                100.0 * (lin.with_intercept.slope / slope - 1.0)
            );
        }
        if let Some(d) = &lin.displacement_vs_force {
            let _ = writeln!(
                text,
                "Mean marker displacement against force: {} px per {fu}, R² = {}.\n",
                f(d.slope, 4),
                f(d.r2, 4)
            );
        }
        let mut plots = vec![name];
        if b.displacement_px.iter().any(Option::is_some) {
            let pts = |g: fn((f64, f64)) -> f64, unloading: bool| -> Vec<(f64, f64)> {
                b.steps
                    .iter()
                    .zip(&b.displacement_px)
                    .filter(|(s, _)| s.unloading == unloading)
                    .filter_map(|(s, d)| d.map(|d| (s.force, g(d))))
                    .collect()
            };
            let mut series = vec![
                Series {
                    name: "mean, loading".into(),
                    points: pts(|d| d.0, false),
                    mark: Mark::LinePoints,
                    colour: 0,
                },
                Series {
                    name: "max, loading".into(),
                    points: pts(|d| d.1, false),
                    mark: Mark::LinePoints,
                    colour: 2,
                },
            ];
            if !unload_pts.is_empty() {
                series.push(Series {
                    name: "mean, unloading".into(),
                    points: pts(|d| d.0, true),
                    mark: Mark::LinePoints,
                    colour: 1,
                });
            }
            plots.push(out.plot(
                &format!("{tag}_displacement_force"),
                &Chart {
                    title: "marker displacement against force".into(),
                    x_label: b.kind.force_label().into(),
                    y_label: "marker displacement (px)".into(),
                    series,
                    ..Default::default()
                },
            )?);
        }
        j["linearity"] = json!({
            "slope": num(lin.with_intercept.slope), "intercept": num(lin.with_intercept.intercept), "r2": num(lin.with_intercept.r2),
            "slope_through_origin": num(lin.through_origin.slope), "r2_through_origin": num(lin.through_origin.r2),
            "slope_all": num(lin.all.slope), "r2_all": num(lin.all.r2),
            "linear_range": rg.map(|r| num(r.end_x)), "linear_range_points": rg.map(|r| r.points),
            "initial_slope": rg.map(|r| num(r.initial_slope)), "tolerance": rg.map(|r| r.tolerance),
            "residuals": lin.with_intercept.residuals.iter().map(|v| num(*v)).collect::<Vec<_>>(),
            "power_law": lin.power_law.as_ref().map(|p| json!({"k": num(p.k), "n": num(p.n), "d0": num(p.d0), "r2": num(p.r2)})),
            "displacement_px_per_force": lin.displacement_vs_force.as_ref().map(|d| num(d.slope)),
        });
        out.sections.push(Section {
            title: format!("Linearity — {} (block {})", b.kind.name(), k + 1),
            text,
            plots,
        });
    }
    // Hysteresis.
    if let Some(h) = &b.hysteresis {
        let mut text = format!(
            "| | loop area | max gap | at | residual at zero {} |\n|---|---|---|---|---|\n| force–{} | {} {fu}·{unit} | {} {fu} | {} {unit} | {} {fu} |\n",
            b.kind.load_name(),
            b.kind.load_name(),
            f(h.loop_area, 5),
            f(h.max_gap, 4),
            f(h.max_gap_at, 3),
            f(h.residual_at_zero, 4)
        );
        if let Some(d) = &b.displacement_hysteresis {
            let _ = writeln!(
                text,
                "| displacement–force | {} px·{fu} | {} {fu} | {} px | {} px |",
                f(d.loop_area, 4),
                f(d.max_gap, 4),
                f(d.max_gap_at, 3),
                f(d.residual_at_zero, 4)
            );
        }
        let mut loop_pts = load_pts.clone();
        loop_pts.extend(unload_pts.iter().copied());
        let name = out.plot(
            &format!("{tag}_hysteresis"),
            &Chart {
                title: "hysteresis loop".into(),
                x_label: format!("{} ({unit})", b.kind.load_name()),
                y_label: b.kind.force_label().into(),
                series: vec![
                    Series {
                        name: "loading".into(),
                        points: load_pts.clone(),
                        mark: Mark::LinePoints,
                        colour: 0,
                    },
                    Series {
                        name: "unloading".into(),
                        points: unload_pts.clone(),
                        mark: Mark::LinePoints,
                        colour: 1,
                    },
                ],
                ..Default::default()
            },
        )?;
        j["hysteresis"] = json!({"loop_area": num(h.loop_area), "max_gap": num(h.max_gap), "max_gap_at": num(h.max_gap_at),
            "residual_at_zero": num(h.residual_at_zero),
            "displacement_force": b.displacement_hysteresis.as_ref().map(|d| json!({"loop_area": num(d.loop_area), "max_gap": num(d.max_gap), "residual_at_zero": num(d.residual_at_zero)}))});
        out.sections.push(Section {
            title: format!("Hysteresis — {} (block {})", b.kind.name(), k + 1),
            text,
            plots: vec![name],
        });
    }
    // Slip.
    if let Some(s) = &b.slip {
        let load: Vec<&super::results::BlockStep> =
            b.steps.iter().filter(|s| !s.unloading).collect();
        let mut text = format!(
            "| step | {} ({unit}) | {} | (a) force | (b) central line | (c) contact | state |\n|---|---|---|---|---|---|---|\n",
            b.kind.load_name(),
            b.kind.force_label()
        );
        let opt = |v: Option<analysis::slip::State>| v.map_or("—", |s| s.as_str());
        for (st, v) in load.iter().zip(&s.report.steps) {
            let _ = writeln!(
                text,
                "| {} | {} | {} | {} | {} | {} | **{}** |",
                st.step,
                f(st.load, 3),
                f(st.force, 3),
                v.force.as_str(),
                opt(v.central_line),
                opt(v.contact),
                v.state.as_str()
            );
        }
        let step_of = |i: Option<usize>| i.and_then(|i| load.get(i)).map(|s| s.step);
        let onset = step_of(s.report.onset);
        let incipient = step_of(s.report.incipient);
        let cues = ["force", "central line", "contact centre"];
        let firsts: Vec<String> = s
            .report
            .first_by_cue
            .iter()
            .zip(cues)
            .map(|(i, c)| {
                format!(
                    "{c}: {}",
                    step_of(*i).map_or("never".into(), |s| format!("step {s}"))
                )
            })
            .collect();
        let agreed: Vec<&str> = {
            let all: Vec<Option<u32>> = s.report.first_by_cue.iter().map(|i| step_of(*i)).collect();
            cues.iter()
                .zip(&all)
                .filter(|(_, v)| {
                    v.is_some() && v.zip(incipient).is_some_and(|(a, b)| a.abs_diff(b) <= 1)
                })
                .map(|(c, _)| *c)
                .collect()
        };
        let _ = writeln!(
            text,
            "\nIncipient slip from step {}, slip from step {}. First step each cue saw slip: {}. Cues agreeing (within one step) on the incipient step: {}.",
            incipient.map_or("—".into(), |v| v.to_string()),
            onset.map_or("—".into(), |v| v.to_string()),
            firsts.join(", "),
            if agreed.is_empty() {
                "none".into()
            } else {
                agreed.join(", ")
            }
        );
        match (s.mu, &s.mu_note) {
            (Some(mu), _) => {
                let _ = writeln!(
                    text,
                    "\nFriction coefficient estimate μ = **{}** (largest tangential/normal ratio up to the slip onset{}).",
                    f(mu, 3),
                    if b.kind == Kind::Rotation {
                        ", via T = μPaπ/4"
                    } else {
                        ""
                    }
                );
            }
            (None, Some(n)) => {
                let _ = writeln!(text, "\nμ: {n}.");
            }
            _ => {}
        }
        if let Some(sim) = s.sim_onset_step {
            let _ = writeln!(text, "\nSimulator's slip onset: step {sim}.");
        }
        let colour_of = |st: analysis::slip::State| st as usize;
        let mut series = Vec::new();
        for st in [
            analysis::slip::State::Stick,
            analysis::slip::State::Incipient,
            analysis::slip::State::Slip,
        ] {
            let pts: Vec<(f64, f64)> = load
                .iter()
                .zip(&s.report.steps)
                .filter(|(_, v)| v.state == st)
                .map(|(s, _)| (s.load, s.force))
                .collect();
            if !pts.is_empty() {
                series.push(Series {
                    name: st.as_str().into(),
                    points: pts,
                    mark: Mark::Points,
                    colour: [2, 1, 3][colour_of(st)],
                });
            }
        }
        let name = out.plot(
            &format!("{tag}_slip"),
            &Chart {
                title: "slip state per step".into(),
                x_label: format!("{} ({unit})", b.kind.load_name()),
                y_label: b.kind.force_label().into(),
                series,
                ..Default::default()
            },
        )?;
        j["slip"] = json!({"onset_step": onset, "incipient_step": incipient, "mu": s.mu.map(num), "mu_note": s.mu_note,
            "sim_onset_step": s.sim_onset_step, "cues_agreed": agreed,
            "first_step_by_cue": {"force": step_of(s.report.first_by_cue[0]), "central_line": step_of(s.report.first_by_cue[1]), "contact": step_of(s.report.first_by_cue[2])},
            "steps": load.iter().zip(&s.report.steps).map(|(st, v)| json!({"step": st.step, "state": v.state.as_str(), "force": v.force.as_str(),
                "central_line": v.central_line.map(|c| c.as_str()), "contact": v.contact.map(|c| c.as_str())})).collect::<Vec<_>>()});
        out.sections.push(Section {
            title: format!("Slip — {} (block {})", b.kind.name(), k + 1),
            text,
            plots: vec![name],
        });
    }
    // Fields: profiles and force from field.
    // Rotation blocks have no radial profiles nor a force-from-field fit, but their twist
    // field is the picture that matters.
    let field_pics = super::field_figures::figures(data, b, out)?;
    if !b.profiles.is_empty() || b.field_force.is_some() || !field_pics.is_empty() {
        let mut plots = Vec::new();
        let mut text = String::new();
        if !b.profiles.is_empty() {
            let every = (b.profiles.len() / 6).max(1);
            let series: Vec<Series> = b
                .profiles
                .iter()
                .step_by(every)
                .enumerate()
                .map(|(i, (step, p))| Series {
                    name: format!("step {step}"),
                    points: p.clone(),
                    mark: Mark::LinePoints,
                    colour: i,
                })
                .collect();
            let (title, x) = if b.kind == Kind::Normal {
                (
                    "radial displacement profile u_r(r)",
                    "distance from the contact centre (mm)",
                )
            } else {
                (
                    "shear-direction displacement on the central line",
                    "position on the central line (mm)",
                )
            };
            plots.push(out.plot(
                &format!("{tag}_profiles"),
                &Chart {
                    title: title.into(),
                    x_label: x.into(),
                    y_label: "displacement (mm)".into(),
                    series,
                    ..Default::default()
                },
            )?);
        }
        if let Some(ff) = &b.field_force {
            let p = &ff.prediction;
            let recorded: Vec<(f64, f64)> =
                b.steps.iter().map(|s| (s.step as f64, s.force)).collect();
            let pred: Vec<(f64, f64)> = b
                .steps
                .iter()
                .zip(&p.predicted)
                .zip(&p.calibration)
                .filter(|(_, c)| !**c)
                .map(|((s, v), _)| (s.step as f64, *v))
                .collect();
            let cal: Vec<(f64, f64)> = b
                .steps
                .iter()
                .zip(&p.predicted)
                .zip(&p.calibration)
                .filter(|(_, c)| **c)
                .map(|((s, v), _)| (s.step as f64, *v))
                .collect();
            plots.push(out.plot(
                &format!("{tag}_force_from_field"),
                &Chart {
                    title: "force from the displacement field".into(),
                    x_label: "step".into(),
                    y_label: b.kind.force_label().into(),
                    series: vec![
                        Series {
                            name: "recorded".into(),
                            points: recorded,
                            mark: Mark::LinePoints,
                            colour: 0,
                        },
                        Series {
                            name: "from field (calibration steps)".into(),
                            points: cal,
                            mark: Mark::Points,
                            colour: 2,
                        },
                        Series {
                            name: "from field (predicted)".into(),
                            points: pred,
                            mark: Mark::Points,
                            colour: 3,
                        },
                    ],
                    ..Default::default()
                },
            )?);
            let _ = writeln!(
                text,
                "Force from the field (thesis §4.3–4.4): weighted least-squares scale of the measured {} against the reference field of this contact from `mechanics`, thesis reliability weights; scale→force calibrated on every other step ({} of {}), predicted on the rest: **RMSE {} {fu} ({} %)**; gain {} {fu} per unit scale.",
                if b.kind == Kind::Normal {
                    "radial field"
                } else {
                    "pure-shear field along the shear direction"
                },
                p.calibration.iter().filter(|c| **c).count(),
                p.calibration.len(),
                f(p.rmse, 4),
                f(p.rmse_pct, 2),
                f(p.gain, 4)
            );
            j["force_from_field"] = json!({"rmse_n": num(p.rmse), "rmse_pct": num(p.rmse_pct), "map": format!("{:?}", p.map).to_lowercase(), "gain": num(p.gain), "bias": num(p.bias),
                "scales": ff.scales.iter().map(|v| num(*v)).collect::<Vec<_>>(), "predicted": p.predicted.iter().map(|v| num(*v)).collect::<Vec<_>>(),
                "calibration": p.calibration});
        }
        if b.kind == Kind::Rotation && !field_pics.is_empty() {
            text.push_str(
                "The twist field at chosen steps: the markers turn about the contact's centre \
                 (thesis Fig. 6-16).\n",
            );
        }
        plots.extend(field_pics);
        out.sections.push(Section {
            title: format!("Displacement field — {} (block {})", b.kind.name(), k + 1),
            text,
            plots,
        });
    }
    Ok(j)
}
