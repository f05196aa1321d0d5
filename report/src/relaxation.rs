//! The report's "Relaxation and settling": each step's force against time with its fit and
//! F∞ (the thesis's Fig. 4-5a), a table with a trust flag that says when the time constants
//! are not identified, the pooled time constants, and the settle error against settle time.

use std::fmt::Write as _;

use serde_json::{Value, json};

use super::ReportError;
use super::out::{Out, Section, f, num};
use super::plots::{Chart, Mark, Series, step_colour};
use super::results::{Kind, Report, StepRelax};

/// Per-step time constants that scatter by more than this factor across the steps of one
/// kind (fitted with the same number of terms) are not identified: a well-determined τ
/// agrees from step to step within tens of percent (the gel's τ does not depend on the step).
const SCATTER_RATIO: f64 = 2.5;

/// Why the steps of `kind` cannot be trusted for their time constants, if they cannot:
/// for each group of steps fitted with the same number of terms (three or more steps), the
/// first τ whose values scatter by more than [`SCATTER_RATIO`]. A fit that its own checks
/// already flag (time constants not separable, ill-conditioned: a step unloaded to a few
/// tens of mN at the contact origin) is left out: its τ are not a measurement of the gel,
/// and counting them would call every well-determined step's τ unidentified.
fn scatter(relaxation: &[StepRelax], kind: Kind) -> Option<String> {
    for terms in 1..=3usize {
        let group: Vec<&StepRelax> = relaxation
            .iter()
            .filter(|s| s.kind == kind && s.fit.terms == terms && s.fit.confident())
            .collect();
        if group.len() < 3 {
            continue;
        }
        for i in 0..terms {
            let taus: Vec<f64> = group
                .iter()
                .filter_map(|s| s.fit.taus_s.get(i).copied())
                .collect();
            let (lo, hi) = taus
                .iter()
                .fold((f64::INFINITY, 0.0f64), |(l, h), t| (l.min(*t), h.max(*t)));
            if lo > 0.0 && hi / lo > SCATTER_RATIO {
                return Some(format!(
                    "τ not identified: τ{} of the {terms}-term fits scatters from {} to {} s across \
                     steps",
                    i + 1,
                    f(lo, 2),
                    f(hi, 2)
                ));
            }
        }
    }
    None
}

pub(super) fn section(r: &Report, out: &mut Out, summary: &mut Value) -> Result<(), ReportError> {
    if r.relaxation.is_empty() {
        return Ok(());
    }
    let kinds: Vec<Kind> = [Kind::Normal, Kind::Shear, Kind::Rotation]
        .into_iter()
        .filter(|k| r.relaxation.iter().any(|s| s.kind == *k))
        .collect();
    let scatters: Vec<(Kind, Option<String>)> = kinds
        .iter()
        .map(|k| (*k, scatter(&r.relaxation, *k)))
        .collect();
    let scatter_of = |k: Kind| scatters.iter().find(|s| s.0 == k).and_then(|s| s.1.clone());
    let trusted = |s: &StepRelax| s.fit.confident() && scatter_of(s.kind).is_none();
    let mut text = String::from(
        "F(t) = F∞ + Σ Aᵢ·exp(−t/τᵢ), 0–3 terms chosen by BIC, fitted by variable projection from \
         the end of each move; the thesis's value is the mean of the last force window. Forces in \
         N, torques in N·mm.\n\n| step | channel | terms | F∞ | σ(F∞) | τ (s) | last-window mean | \
         truth | trust |\n|---|---|---|---|---|---|---|---|---|\n",
    );
    for s in &r.relaxation {
        let taus: Vec<String> = s.fit.taus_s.iter().map(|t| f(*t, 2)).collect();
        let mut issues = s.fit.issues.clone();
        if let Some(why) = scatter_of(s.kind) {
            issues.push(why);
        }
        let _ = writeln!(
            text,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            s.step,
            s.kind.force_label(),
            s.fit.terms,
            f(s.fit.f_inf, 4),
            f(s.fit.sigma_f_inf, 4),
            if taus.is_empty() {
                "—".into()
            } else {
                taus.join(", ")
            },
            f(s.fit.window_mean, 4),
            s.truth.map_or("—".into(), |t| f(t, 4)),
            if issues.is_empty() {
                "confident".into()
            } else {
                issues.join("; ")
            }
        );
    }
    if let Some(sh) = &r.shared {
        let _ = writeln!(
            text,
            "\nTime constants shared by all relaxing steps (pooled variable projection): **τ = {} s**.",
            sh.taus_s
                .iter()
                .map(|t| f(*t, 3))
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    for (k, why) in &scatters {
        if let Some(why) = why {
            let _ = writeln!(
                text,
                "\n**{} steps: {why}.** Read F∞ from the pooled fit or wait longer; the \
                 per-step τ are not the gel's.",
                k.name()
            );
        }
    }
    let mut plots = Vec::new();
    for kind in &kinds {
        if let Some(chart) = force_time_chart(r, *kind) {
            plots.push(out.plot(&format!("relaxation_{}", kind.name()), &chart)?);
        }
    }
    let settle_json = settle(r, out, &mut text, &mut plots)?;
    summary["relaxation"] = json!({
        "tau_s": r.relaxation.iter().map(|s| s.fit.taus_s.clone()).collect::<Vec<_>>(),
        "shared_tau_s": r.shared.as_ref().map(|s| s.taus_s.clone()),
        "tau_identified": scatters.iter().map(|(k, w)| (k.name().to_string(), json!(w.is_none()))).collect::<serde_json::Map<_, _>>(),
        "steps": r.relaxation.iter().map(|s| json!({"step": s.step, "kind": s.kind.name(), "unit": s.kind.force_unit(),
            "terms": s.fit.terms, "f_inf": num(s.fit.f_inf), "sigma_f_inf": num(s.fit.sigma_f_inf),
            "tau_s": s.fit.taus_s, "amplitudes": s.fit.amplitudes, "window_mean": num(s.fit.window_mean), "truth": s.truth.map(num),
            "confident": trusted(s), "issues": s.fit.issues.iter().cloned().chain(scatter_of(s.kind)).collect::<Vec<_>>()})).collect::<Vec<_>>(),
    });
    summary["settle"] = settle_json;
    out.sections.push(Section {
        title: "Relaxation and settling".into(),
        text,
        plots,
    });
    Ok(())
}

/// Every relaxing step of `kind`: its force against time since the end of its move (dots),
/// its fit over the same span (line) and F∞ (a short level over the last fifth), one
/// sequential colour per step — Fig. 4-5a of the thesis.
fn force_time_chart(r: &Report, kind: Kind) -> Option<Chart> {
    let steps: Vec<&StepRelax> = r
        .relaxation
        .iter()
        .filter(|s| s.kind == kind && s.fit.terms >= 1 && !s.t_s.is_empty())
        .collect();
    let n = steps.len();
    if n == 0 {
        return None;
    }
    let mut series = Vec::new();
    for (i, s) in steps.iter().enumerate() {
        let colour = step_colour(i, n);
        let every = (s.t_s.len() / 300).max(1);
        let edge = i == 0 || i + 1 == n;
        series.push(Series {
            name: if edge {
                format!("step {}", s.step)
            } else {
                String::new()
            },
            points: s
                .t_s
                .iter()
                .zip(&s.f)
                .step_by(every)
                .map(|(t, v)| (*t, *v))
                .collect(),
            mark: Mark::Points,
            colour,
        });
        if let Some(fit) = &s.fit.fit {
            series.push(Series {
                name: if i == 0 { "fit".into() } else { String::new() },
                points: s
                    .t_s
                    .iter()
                    .step_by(every)
                    .map(|t| (*t, fit.eval(*t)))
                    .collect(),
                mark: Mark::Line,
                colour,
            });
        }
        let end = s.t_s.last().copied().unwrap_or(0.0);
        series.push(Series {
            name: if i == 0 { "F∞".into() } else { String::new() },
            points: vec![(0.8 * end, s.fit.f_inf), (end, s.fit.f_inf)],
            mark: Mark::Line,
            colour: 3,
        });
    }
    Some(Chart {
        title: format!(
            "relaxation of each {} step, with its fit and F∞ (step order: dark to light)",
            kind.name()
        ),
        x_label: "time since the end of the move (s)".into(),
        y_label: kind.force_label().into(),
        series,
        legend_upper_right: kind == Kind::Normal,
        ..Default::default()
    })
}

/// The settle error against settle time: table, plot and its `summary.json` entry.
fn settle(
    r: &Report,
    out: &mut Out,
    text: &mut String,
    plots: &mut Vec<String>,
) -> Result<Value, ReportError> {
    let Some(sc) = &r.settle else {
        return Ok(Value::Null);
    };
    let _ = writeln!(
        text,
        "\n**Settle error against settle time** (mean of a {} s window ending at the wait, against F∞; median over steps; N or N·mm):\n\n| wait (s) | against F∞ | % of relaxation | against the simulator's equilibrium |\n|---|---|---|---|",
        10
    );
    for (k, w) in sc.waits_s.iter().enumerate() {
        let _ = writeln!(
            text,
            "| {} | {} | {} | {} |",
            w,
            f(sc.median_abs_vs_fit[k], 4),
            f(sc.median_pct_vs_fit[k], 2),
            sc.median_abs_vs_truth
                .as_ref()
                .map_or("—".into(), |v| f(v[k], 4))
        );
    }
    if !sc.rules.is_empty() {
        let _ = writeln!(
            text,
            "\nThe same records replayed through the other settle rules (each stopped at the \
             record's end at the latest; the value it would have recorded — the window mean, F∞ \
             for the adaptive rule — against {}; medians over steps; docs/reference/protocol.md, \"Choosing a settle \
             rule\"):\n\n| rule | settle time (s) | error | settled before the record's end |\n|---|---|---|---|",
            if sc.median_abs_vs_truth.is_some() {
                "the simulator's equilibrium"
            } else {
                "each step's fitted F∞"
            }
        );
        for o in &sc.rules {
            let _ = writeln!(
                text,
                "| `{}` | {} | {} | {} of {} |",
                o.rule,
                f(o.median_settle_s, 1),
                f(o.median_abs_error, 4),
                o.settled,
                o.steps
            );
        }
    }
    let mut series = vec![Series {
        name: "against fitted F∞".into(),
        points: sc
            .waits_s
            .iter()
            .copied()
            .zip(sc.median_abs_vs_fit.iter().copied())
            .collect(),
        mark: Mark::LinePoints,
        colour: 0,
    }];
    if let Some(t) = &sc.median_abs_vs_truth {
        series.push(Series {
            name: "against the simulator's equilibrium".into(),
            points: sc.waits_s.iter().copied().zip(t.iter().copied()).collect(),
            mark: Mark::LinePoints,
            colour: 3,
        });
    }
    for (k, o) in sc.rules.iter().enumerate() {
        series.push(Series {
            name: o.rule.split(':').next().unwrap_or("rule").to_string() + " rule (median)",
            points: vec![(o.median_settle_s, o.median_abs_error)],
            mark: Mark::Points,
            colour: 1 + k,
        });
    }
    plots.push(out.plot(
        "settle_error",
        &Chart {
            title: "quasistatic error against settle time".into(),
            x_label: "settle time (s)".into(),
            y_label: "median |error| (N or N·mm)".into(),
            series,
            log_y: true,
            legend_upper_right: true,
            ..Default::default()
        },
    )?);
    Ok(
        json!({"waits_s": sc.waits_s, "median_abs_error_vs_fit": sc.median_abs_vs_fit.iter().map(|v| num(*v)).collect::<Vec<_>>(),
        "median_pct_of_relaxation": sc.median_pct_vs_fit.iter().map(|v| num(*v)).collect::<Vec<_>>(),
        "median_abs_error_vs_truth": sc.median_abs_vs_truth.as_ref().map(|v| v.iter().map(|x| num(*x)).collect::<Vec<_>>()),
        "rules": sc.rules.iter().map(|o| json!({"rule": o.rule, "median_settle_s": num(o.median_settle_s),
            "median_abs_error": num(o.median_abs_error), "settled": o.settled, "steps": o.steps})).collect::<Vec<_>>()}),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use analysis::relaxation::StepRelaxation;

    fn step(k: u32, taus_s: Vec<f64>, issues: Vec<String>) -> StepRelax {
        StepRelax {
            step: k,
            kind: Kind::Normal,
            fit: StepRelaxation {
                terms: taus_s.len(),
                f_inf: 1.0,
                sigma_f_inf: 0.001,
                amplitudes: vec![0.2; taus_s.len()],
                taus_s,
                window_mean: 1.0,
                rms: 0.001,
                issues,
                fit: None,
            },
            t_s: Vec::new(),
            f: Vec::new(),
            truth: None,
            start_s: 0.0,
        }
    }

    #[test]
    fn an_ill_conditioned_fit_does_not_make_the_well_determined_steps_unidentified() {
        let good: Vec<StepRelax> = (1..=4)
            .map(|k| step(k, vec![1.4 + 0.05 * k as f64, 15.0], Vec::new()))
            .collect();
        assert_eq!(scatter(&good, Kind::Normal), None);
        // The contact origin's step: coincident τ with cancelling amplitudes, flagged by
        // its own fit.
        let mut with_bad = good;
        with_bad.push(step(
            5,
            vec![10.96, 10.96],
            vec!["ill-conditioned fit".into()],
        ));
        assert_eq!(scatter(&with_bad, Kind::Normal), None);
        // A confident step whose τ is off by more than the ratio still says so.
        with_bad.push(step(6, vec![5.0, 15.0], Vec::new()));
        let why = scatter(&with_bad, Kind::Normal).expect("scatter found");
        assert!(why.contains("τ1"), "{why}");
    }
}
