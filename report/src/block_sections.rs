//! The report sections of one block of steps: linearity, hysteresis, slip and displacement
//! field, each with its plots and its part of the block's `summary.json` entry.

use std::fmt::Write as _;

use analysis::hysteresis::Hysteresis;
use analysis::linearity::LineFit;
use serde_json::{Value, json};

use super::out::{Out, Section, f, num};
use super::plots::{Chart, Mark, Series};
use super::results::{Block, BlockStep, FieldForce, Kind, Linearity, Report, Slip};
use super::{ReportError, RunData};

/// One block as its sections see it: the block, its place in the run, the prefix of its
/// plot files and its (load, force) points, loading and unloading apart.
struct BlockView<'a> {
    b: &'a Block,
    /// Index of the block in the run (shown 1-based).
    k: usize,
    /// `block<N>_<kind>`: the prefix of the block's plot files.
    tag: String,
    /// (load, force) of the loading steps.
    load_pts: Vec<(f64, f64)>,
    /// (load, force) of the unloading steps.
    unload_pts: Vec<(f64, f64)>,
}

impl<'a> BlockView<'a> {
    /// The view of block `b`, the `k`-th of the run (0-based).
    fn new(b: &'a Block, k: usize) -> Self {
        let points = |unloading: bool| -> Vec<(f64, f64)> {
            b.steps
                .iter()
                .filter(|s| s.unloading == unloading)
                .map(|s| (s.load, s.force))
                .collect()
        };
        BlockView {
            b,
            k,
            tag: format!("block{}_{}", k + 1, b.kind.name()),
            load_pts: points(false),
            unload_pts: points(true),
        }
    }

    /// A section title such as `Linearity — normal (block 1)`.
    fn title(&self, what: &str) -> String {
        format!("{what} — {} (block {})", self.b.kind.name(), self.k + 1)
    }
}

/// The sections of block `b` (the `k`-th of the run), pushed onto `out`; the block's entry
/// of `summary.json`.
pub(super) fn block_sections(
    data: &RunData,
    r: &Report,
    b: &Block,
    k: usize,
    out: &mut Out,
) -> Result<Value, ReportError> {
    let v = BlockView::new(b, k);
    let mut j = json!({"kind": b.kind.name(), "unit": b.unit.as_str(), "force_unit": b.kind.force_unit(),
        "steps": b.steps.iter().map(|s| s.step).collect::<Vec<_>>()});
    if let Some(lin) = &b.linearity {
        j["linearity"] = linearity_section(r, &v, lin, out)?;
    }
    if let Some(h) = &b.hysteresis {
        j["hysteresis"] = hysteresis_section(&v, h, out)?;
    }
    if let Some(s) = &b.slip {
        j["slip"] = slip_section(&v, s, out)?;
    }
    if let Some(force_from_field) = field_section(data, &v, out)? {
        j["force_from_field"] = force_from_field;
    }
    Ok(j)
}

/// The linearity section (force against load, its fits, and marker displacement against
/// force when frames exist); its `summary.json` entry.
fn linearity_section(
    r: &Report,
    v: &BlockView<'_>,
    lin: &Linearity,
    out: &mut Out,
) -> Result<Value, ReportError> {
    let name = out.plot(&format!("{}_force_load", v.tag), &force_load_chart(v, lin))?;
    let text = linearity_text(r, v, lin);
    let mut plots = vec![name];
    if v.b.displacement_px.iter().any(Option::is_some) {
        plots.push(out.plot(
            &format!("{}_displacement_force", v.tag),
            &displacement_force_chart(v),
        )?);
    }
    let json = linearity_json(lin);
    out.sections.push(Section {
        title: v.title("Linearity"),
        text,
        plots,
    });
    Ok(json)
}

/// Force against load: the loading (and unloading) points, the fitted line over the linear
/// range, the power law where one was fitted, and where the linear range ends.
fn force_load_chart(v: &BlockView<'_>, lin: &Linearity) -> Chart {
    let b = v.b;
    let unit = b.unit.as_str();
    let fu = b.kind.force_unit();
    let (x0, x1) = v
        .load_pts
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |a, p| {
            (a.0.min(p.0), a.1.max(p.0))
        });
    // The line over the loads it was fitted on (the linear range), not beyond.
    let fit_end = lin.range.as_ref().map_or(x1, |rg| rg.end_x.min(x1));
    let line = |l: &LineFit| {
        vec![
            (x0.min(0.0), l.slope * x0.min(0.0) + l.intercept),
            (fit_end, l.slope * fit_end + l.intercept),
        ]
    };
    let mut series = vec![
        Series {
            name: "loading".into(),
            points: v.load_pts.clone(),
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
    if !v.unload_pts.is_empty() {
        series.insert(
            1,
            Series {
                name: "unloading".into(),
                points: v.unload_pts.clone(),
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
    Chart {
        title: format!("{} force against load", b.kind.name()),
        x_label: format!("{} ({unit})", b.kind.load_name()),
        y_label: b.kind.force_label().into(),
        series,
        markers,
        ..Default::default()
    }
}

/// The linearity section's text: the table of fits, the linear range, the power law, the
/// simulator's slope (main block only) and the displacement–force slope.
fn linearity_text(r: &Report, v: &BlockView<'_>, lin: &Linearity) -> String {
    let b = v.b;
    let unit = b.unit.as_str();
    let fu = b.kind.force_unit();
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
    if let Some(rg) = &lin.range {
        let _ = writeln!(
            text,
            "Linear range (within {} % of the first three steps' slope {} {fu}/{unit}): up to **{} {unit}** ({} of {} loading steps).\n",
            rg.tolerance * 100.0,
            f(rg.initial_slope, 3),
            f(rg.end_x, 3),
            rg.points,
            v.load_pts.len()
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
    text
}

/// Mean and largest marker displacement (px) against force, loading, and the mean
/// unloading when the block unloads.
fn displacement_force_chart(v: &BlockView<'_>) -> Chart {
    let b = v.b;
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
    if !v.unload_pts.is_empty() {
        series.push(Series {
            name: "mean, unloading".into(),
            points: pts(|d| d.0, true),
            mark: Mark::LinePoints,
            colour: 1,
        });
    }
    Chart {
        title: "marker displacement against force".into(),
        x_label: b.kind.force_label().into(),
        y_label: "marker displacement (px)".into(),
        series,
        ..Default::default()
    }
}

/// The block's `linearity` entry of `summary.json`.
fn linearity_json(lin: &Linearity) -> Value {
    let rg = lin.range.as_ref();
    json!({
        "slope": num(lin.with_intercept.slope), "intercept": num(lin.with_intercept.intercept), "r2": num(lin.with_intercept.r2),
        "slope_through_origin": num(lin.through_origin.slope), "r2_through_origin": num(lin.through_origin.r2),
        "slope_all": num(lin.all.slope), "r2_all": num(lin.all.r2),
        "linear_range": rg.map(|r| num(r.end_x)), "linear_range_points": rg.map(|r| r.points),
        "initial_slope": rg.map(|r| num(r.initial_slope)), "tolerance": rg.map(|r| r.tolerance),
        "residuals": lin.with_intercept.residuals.iter().map(|v| num(*v)).collect::<Vec<_>>(),
        "power_law": lin.power_law.as_ref().map(|p| json!({"k": num(p.k), "n": num(p.n), "d0": num(p.d0), "r2": num(p.r2)})),
        "displacement_px_per_force": lin.displacement_vs_force.as_ref().map(|d| num(d.slope)),
    })
}

/// The hysteresis section: the loop's numbers (force–load, and displacement–force when
/// frames exist) and the loop itself; its `summary.json` entry.
fn hysteresis_section(
    v: &BlockView<'_>,
    h: &Hysteresis,
    out: &mut Out,
) -> Result<Value, ReportError> {
    let b = v.b;
    let unit = b.unit.as_str();
    let fu = b.kind.force_unit();
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
    let name = out.plot(
        &format!("{}_hysteresis", v.tag),
        &Chart {
            title: "hysteresis loop".into(),
            x_label: format!("{} ({unit})", b.kind.load_name()),
            y_label: b.kind.force_label().into(),
            series: vec![
                Series {
                    name: "loading".into(),
                    points: v.load_pts.clone(),
                    mark: Mark::LinePoints,
                    colour: 0,
                },
                Series {
                    name: "unloading".into(),
                    points: v.unload_pts.clone(),
                    mark: Mark::LinePoints,
                    colour: 1,
                },
            ],
            ..Default::default()
        },
    )?;
    let json = json!({"loop_area": num(h.loop_area), "max_gap": num(h.max_gap), "max_gap_at": num(h.max_gap_at),
        "residual_at_zero": num(h.residual_at_zero),
        "displacement_force": b.displacement_hysteresis.as_ref().map(|d| json!({"loop_area": num(d.loop_area), "max_gap": num(d.max_gap), "residual_at_zero": num(d.residual_at_zero)}))});
    out.sections.push(Section {
        title: v.title("Hysteresis"),
        text,
        plots: vec![name],
    });
    Ok(json)
}

/// The slip cues, in the order of [`analysis::slip::SlipReport::first_by_cue`].
const SLIP_CUES: [&str; 3] = ["force", "central line", "contact centre"];

/// The step number of the `i`-th loading step, if any.
fn step_of(load: &[&BlockStep], i: Option<usize>) -> Option<u32> {
    i.and_then(|i| load.get(i)).map(|s| s.step)
}

/// The slip section: each loading step's state by cue, when slip began, μ, and the states
/// over force against load; its `summary.json` entry.
fn slip_section(v: &BlockView<'_>, s: &Slip, out: &mut Out) -> Result<Value, ReportError> {
    let b = v.b;
    let load: Vec<&BlockStep> = b.steps.iter().filter(|s| !s.unloading).collect();
    let mut text = slip_table(b, &load, s);
    let onset = step_of(&load, s.report.onset);
    let incipient = step_of(&load, s.report.incipient);
    let agreed = cues_agreeing(&load, s, incipient);
    slip_findings(&mut text, b.kind, &load, s, (incipient, onset), &agreed);
    let name = out.plot(&format!("{}_slip", v.tag), &slip_chart(b, &load, s))?;
    let json = json!({"onset_step": onset, "incipient_step": incipient, "mu": s.mu.map(num), "mu_note": s.mu_note,
        "sim_onset_step": s.sim_onset_step, "cues_agreed": agreed,
        "first_step_by_cue": {"force": step_of(&load, s.report.first_by_cue[0]), "central_line": step_of(&load, s.report.first_by_cue[1]), "contact": step_of(&load, s.report.first_by_cue[2])},
        "steps": load.iter().zip(&s.report.steps).map(|(st, v)| json!({"step": st.step, "state": v.state.as_str(), "force": v.force.as_str(),
            "central_line": v.central_line.map(|c| c.as_str()), "contact": v.contact.map(|c| c.as_str())})).collect::<Vec<_>>()});
    out.sections.push(Section {
        title: v.title("Slip"),
        text,
        plots: vec![name],
    });
    Ok(json)
}

/// The table of each loading step's slip state, cue by cue.
fn slip_table(b: &Block, load: &[&BlockStep], s: &Slip) -> String {
    let unit = b.unit.as_str();
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
    text
}

/// The cues whose first slipping step is within one step of the incipient step.
fn cues_agreeing(load: &[&BlockStep], s: &Slip, incipient: Option<u32>) -> Vec<&'static str> {
    let all: Vec<Option<u32>> = s
        .report
        .first_by_cue
        .iter()
        .map(|i| step_of(load, *i))
        .collect();
    SLIP_CUES
        .iter()
        .zip(&all)
        .filter(|(_, v)| v.is_some() && v.zip(incipient).is_some_and(|(a, b)| a.abs_diff(b) <= 1))
        .map(|(c, _)| *c)
        .collect()
}

/// The slip section's findings below its table: when (incipient) slip began, the first
/// step of each cue, the cues that agree, μ (or why there is none) and the simulator's
/// onset.
fn slip_findings(
    text: &mut String,
    kind: Kind,
    load: &[&BlockStep],
    s: &Slip,
    (incipient, onset): (Option<u32>, Option<u32>),
    agreed: &[&str],
) {
    let firsts: Vec<String> = s
        .report
        .first_by_cue
        .iter()
        .zip(SLIP_CUES)
        .map(|(i, c)| {
            format!(
                "{c}: {}",
                step_of(load, *i).map_or("never".into(), |s| format!("step {s}"))
            )
        })
        .collect();
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
                if kind == Kind::Rotation {
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
}

/// Force against load of the loading steps, one series per slip state.
fn slip_chart(b: &Block, load: &[&BlockStep], s: &Slip) -> Chart {
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
    Chart {
        title: "slip state per step".into(),
        x_label: format!("{} ({})", b.kind.load_name(), b.unit),
        y_label: b.kind.force_label().into(),
        series,
        ..Default::default()
    }
}

/// The displacement-field section: profiles, force from the field and the field pictures,
/// when the block has any of them; the `force_from_field` entry of `summary.json`, when
/// there is one.
///
/// Rotation blocks have no radial profiles nor a force-from-field fit, but their twist
/// field is the picture that matters.
fn field_section(
    data: &RunData,
    v: &BlockView<'_>,
    out: &mut Out,
) -> Result<Option<Value>, ReportError> {
    let b = v.b;
    let field_pics = super::field_figures::figures(data, b, out)?;
    if b.profiles.is_empty() && b.field_force.is_none() && field_pics.is_empty() {
        return Ok(None);
    }
    let mut plots = Vec::new();
    let mut text = String::new();
    let mut json = None;
    if !b.profiles.is_empty() {
        plots.push(out.plot(&format!("{}_profiles", v.tag), &profiles_chart(b))?);
    }
    if let Some(ff) = &b.field_force {
        plots.push(out.plot(
            &format!("{}_force_from_field", v.tag),
            &force_from_field_chart(b, ff),
        )?);
        text.push_str(&force_from_field_text(b, ff));
        json = Some(force_from_field_json(ff));
    }
    if b.kind == Kind::Rotation && !field_pics.is_empty() {
        text.push_str(
            "The twist field at chosen steps: the markers turn about the contact's centre \
             (thesis Fig. 6-16).\n",
        );
    }
    plots.extend(field_pics);
    out.sections.push(Section {
        title: v.title("Displacement field"),
        text,
        plots,
    });
    Ok(json)
}

/// Displacement profiles (mm) of about six of the block's steps: radial for a normal
/// block, along the central line for the others.
fn profiles_chart(b: &Block) -> Chart {
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
    Chart {
        title: title.into(),
        x_label: x.into(),
        y_label: "displacement (mm)".into(),
        series,
        ..Default::default()
    }
}

/// Recorded force per step against the force read from the field, calibration steps and
/// predicted steps apart.
fn force_from_field_chart(b: &Block, ff: &FieldForce) -> Chart {
    let p = &ff.prediction;
    let recorded: Vec<(f64, f64)> = b.steps.iter().map(|s| (s.step as f64, s.force)).collect();
    let from_field = |calibration: bool| -> Vec<(f64, f64)> {
        b.steps
            .iter()
            .zip(&p.predicted)
            .zip(&p.calibration)
            .filter(|(_, c)| **c == calibration)
            .map(|((s, v), _)| (s.step as f64, *v))
            .collect()
    };
    Chart {
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
                points: from_field(true),
                mark: Mark::Points,
                colour: 2,
            },
            Series {
                name: "from field (predicted)".into(),
                points: from_field(false),
                mark: Mark::Points,
                colour: 3,
            },
        ],
        ..Default::default()
    }
}

/// How the force was read from the field, and how well it predicts the recorded force.
fn force_from_field_text(b: &Block, ff: &FieldForce) -> String {
    let p = &ff.prediction;
    let fu = b.kind.force_unit();
    let mut text = String::new();
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
    text
}

/// The block's `force_from_field` entry of `summary.json`.
fn force_from_field_json(ff: &FieldForce) -> Value {
    let p = &ff.prediction;
    json!({"rmse_n": num(p.rmse), "rmse_pct": num(p.rmse_pct), "map": format!("{:?}", p.map).to_lowercase(), "gain": num(p.gain), "bias": num(p.bias),
        "scales": ff.scales.iter().map(|v| num(*v)).collect::<Vec<_>>(), "predicted": p.predicted.iter().map(|v| num(*v)).collect::<Vec<_>>(),
        "calibration": p.calibration})
}
