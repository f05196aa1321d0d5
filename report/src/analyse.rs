//! From run tables to results: which analyses apply, and their numbers.

use analysis::hysteresis::hysteresis;
use analysis::linearity::{fit_line, fit_power_law, linear_range};
use analysis::relaxation::{SharedFit, analyse_step, fit_shared};
use analysis::slip;
use mechanics::Indenter;

use super::RunData;
use super::field_analysis::{analyse_fields, indenter_radius_mm, slip_block, slip_thresholds};
use super::results::{Block, BlockStep, Kind, Linearity, RefModel, Report, Slip, StepRelax};

/// Minimum settle for a step to count as quasistatic, s.
const QUASISTATIC_S: f64 = 5.0;

pub(crate) fn reference_model(data: &RunData) -> Result<RefModel, String> {
    let protocol = data.dir.join(rundir::names::PROTOCOL);
    let rig = data.dir.join(rundir::names::RIG);
    let loaded = experiments::load::load(&protocol, Some(&rig)).map_err(|d| {
        format!(
            "the run's protocol does not load ({})",
            d.first().map(|d| d.to_string()).unwrap_or_default()
        )
    })?;
    let spec = experiments::protocol::plant_spec(&loaded.protocol, &loaded.compiled)?;
    Ok(RefModel { spec })
}

fn channel(kind: Kind, fx: f64, fy: f64, fz: f64, tz: f64, dir: f64) -> f64 {
    match kind {
        Kind::Normal => fz,
        Kind::Shear => fx * dir.cos() + fy * dir.sin(),
        Kind::Rotation => tz,
    }
}

fn blocks(data: &RunData) -> Vec<Block> {
    let mut out: Vec<Block> = Vec::new();
    let mut last: Option<(String, u32, usize)> = None;
    for (row, s) in data.steps.iter().enumerate() {
        let kind = match s.axis.as_str() {
            "normal" => Kind::Normal,
            "shear" => Kind::Shear,
            "rotation" => Kind::Rotation,
            _ => {
                last = None;
                continue;
            }
        };
        let Some(load) = s.position else { continue };
        if s.settle_s < QUASISTATIC_S {
            last = None;
            continue;
        }
        let step = BlockStep {
            row,
            step: s.step,
            load,
            force: 0.0,
            normal_n: s.fz_n,
            unloading: s.phase == "unload",
        };
        match &last {
            Some((axis, trial, _)) if *axis == s.axis && *trial == s.trial => {
                if let Some(b) = out.last_mut() {
                    b.steps.push(step);
                }
            }
            _ => {
                out.push(Block {
                    kind,
                    unit: s.unit.clone(),
                    steps: vec![step],
                    force_direction_rad: 0.0,
                    sign: 1.0,
                    before: row.checked_sub(1),
                    linearity: None,
                    hysteresis: None,
                    displacement_hysteresis: None,
                    slip: None,
                    field_force: None,
                    displacement_px: Vec::new(),
                    profiles: Vec::new(),
                });
            }
        }
        last = Some((s.axis.clone(), s.trial, row));
    }
    for b in &mut out {
        let rows: Vec<&super::StepRow> = b.steps.iter().map(|s| &data.steps[s.row]).collect();
        let (sx, sy) = rows
            .iter()
            .fold((0.0, 0.0), |a, r| (a.0 + r.fx_n, a.1 + r.fy_n));
        b.force_direction_rad = sy.atan2(sx);
        let raw: Vec<f64> = rows
            .iter()
            .map(|r| {
                channel(
                    b.kind,
                    r.fx_n,
                    r.fy_n,
                    r.fz_n,
                    r.tz_nmm,
                    b.force_direction_rad,
                )
            })
            .collect();
        let mean = raw.iter().sum::<f64>() / raw.len().max(1) as f64;
        b.sign = if mean < 0.0 { -1.0 } else { 1.0 };
        for (s, v) in b.steps.iter_mut().zip(raw) {
            s.force = b.sign * v;
        }
    }
    out
}

/// Samples of one step on the block's channel, t from the end of the move.
/// A step's relaxation record: t from the end of the move, s; the channel; the move's end,
/// s on the run's clock.
fn step_record(data: &RunData, b: &Block, s: &BlockStep) -> (Vec<f64>, Vec<f64>, f64) {
    let row = &data.steps[s.row];
    let samples: Vec<(f64, f64)> = data
        .force
        .iter()
        .filter(|f| f.step == s.step && f.t_ns >= row.t_start_ns && f.t_ns <= row.settle_end_ns)
        .map(|f| {
            (
                (f.t_ns - row.t_start_ns) as f64 * 1e-9,
                b.sign
                    * channel(
                        b.kind,
                        f.fx_n,
                        f.fy_n,
                        f.fz_n,
                        f.tz_nmm,
                        b.force_direction_rad,
                    ),
            )
        })
        .collect();
    if samples.len() < 10 {
        return (Vec::new(), Vec::new(), 0.0);
    }
    // The move ends at the peak of the ramp (the maximum of a loading step, the minimum
    // of an unloading one) within the first fifth of the step; relaxation is fitted from
    // there. The samples before the ramp still sit at the previous step's level.
    let dir = if samples[samples.len() - 1].1 >= samples[0].1 {
        1.0
    } else {
        -1.0
    };
    let head = (samples.len() / 5).max(1);
    let k0 = (0..head)
        .max_by(|&a, &b| (dir * samples[a].1).total_cmp(&(dir * samples[b].1)))
        .unwrap_or(0);
    // The sample after the peak: the peak sample itself may fall just before the move ends.
    let k0 = (k0 + 1).min(samples.len() - 1);
    let t0 = samples[k0].0;
    let (t, f) = samples[k0..].iter().map(|(t, f)| (t - t0, *f)).unzip();
    (t, f, row.t_start_ns as f64 * 1e-9 + t0)
}

fn sim_truth(data: &RunData, b: &Block, step: u32) -> Option<f64> {
    let r = data.sim.as_ref()?.iter().find(|r| r.step == step)?;
    Some(match b.kind {
        Kind::Normal => r.fz_eq_n,
        Kind::Shear => r.fx_eq_n.abs(),
        Kind::Rotation => r.tz_eq_nmm.abs(),
    })
}

fn sim_onset(data: &RunData, b: &Block) -> Option<u32> {
    let sim = data.sim.as_ref()?;
    let at = |step: u32| sim.iter().find(|r| r.step == step);
    let first = at(b.steps.first()?.step)?;
    let base = (first.shear_slips, first.twist_slips);
    b.steps.iter().filter(|s| !s.unloading).find_map(|s| {
        let r = at(s.step)?;
        let stick = if b.kind == Kind::Shear {
            r.shear_stick_fraction
        } else {
            r.twist_stick_fraction
        };
        (r.shear_slips > base.0 || r.twist_slips > base.1 || stick.is_some_and(|f| f < 0.1))
            .then_some(s.step)
    })
}

/// The relaxation of each held step of block `b`.
fn relaxation_of(data: &RunData, b: &Block) -> Vec<StepRelax> {
    let mut relaxation = Vec::new();
    for s in &b.steps {
        let (t, f, start_s) = step_record(data, b, s);
        if t.is_empty() {
            continue;
        }
        let window = data.steps[s.row].force_window_s.max(1.0);
        relaxation.push(StepRelax {
            step: s.step,
            kind: b.kind,
            fit: analyse_step(&t, &f, window, 3),
            truth: sim_truth(data, b, s.step),
            t_s: t,
            f,
            start_s,
        });
    }
    relaxation
}

/// Linearity of the loading steps, hysteresis against the unloading ones, and the slip cues
/// of the force record.
fn force_curves(data: &RunData, b: &mut Block, curved: bool) {
    let loading: Vec<&BlockStep> = b.steps.iter().filter(|s| !s.unloading).collect();
    let x: Vec<f64> = loading.iter().map(|s| s.load).collect();
    let y: Vec<f64> = loading.iter().map(|s| s.force).collect();
    if loading.len() >= 3 {
        // The stiffness is the slope over the linear range (thesis Fig. 4-10: the line
        // through the first points); the fits over every loading step are kept too.
        let range = linear_range(&x, &y, 0.05, 0.02);
        let k = range.as_ref().map_or(x.len(), |r| r.points.max(2));
        if let (Some(with_intercept), Some(through_origin), Some(all)) = (
            fit_line(&x[..k], &y[..k], true),
            fit_line(&x[..k], &y[..k], false),
            fit_line(&x, &y, true),
        ) {
            b.linearity = Some(Linearity {
                with_intercept,
                through_origin,
                all,
                range,
                power_law: (curved && b.kind == Kind::Normal)
                    .then(|| fit_power_law(&x, &y))
                    .flatten(),
                displacement_vs_force: None,
            });
        }
    }
    let unloading: Vec<(f64, f64)> = b
        .steps
        .iter()
        .filter(|s| s.unloading)
        .map(|s| (s.load, s.force))
        .collect();
    if unloading.len() >= 2 {
        let load: Vec<(f64, f64)> = x.iter().copied().zip(y.iter().copied()).collect();
        b.hysteresis = hysteresis(&load, &unloading);
    }
    if b.kind != Kind::Normal
        && let Some(report) = slip::classify(&slip_block(&b.steps), slip_thresholds(b.kind))
    {
        b.slip = Some(Slip {
            report,
            mu: None,
            mu_note: None,
            sim_onset_step: sim_onset(data, b),
        });
    }
}

/// The markers' mean displacement against force: its line and its hysteresis.
fn displacement_curves(b: &mut Block) {
    if b.displacement_px.is_empty() {
        return;
    }
    if let Some(lin) = b.linearity.as_mut() {
        let (f, d): (Vec<f64>, Vec<f64>) = b
            .steps
            .iter()
            .zip(&b.displacement_px)
            .filter(|(s, d)| !s.unloading && d.is_some())
            .map(|(s, d)| (s.force, d.map_or(f64::NAN, |d| d.0)))
            .unzip();
        lin.displacement_vs_force = fit_line(&f, &d, true);
    }
    let pts = |unloading: bool| -> Vec<(f64, f64)> {
        b.steps
            .iter()
            .zip(&b.displacement_px)
            .filter(|(s, _)| s.unloading == unloading)
            .filter_map(|(s, d)| d.map(|d| (s.force, d.0)))
            .collect()
    };
    let (up, down) = (pts(false), pts(true));
    if down.len() >= 2 {
        b.displacement_hysteresis = hysteresis(&up, &down);
    }
}

/// μ from the slip onset: the force ratio of a shear, or of a flat circular punch's twist.
fn friction_from_slip(b: &mut Block, model: Option<&RefModel>) {
    let Some(slip) = b.slip.as_mut() else { return };
    match (b.kind, slip.report.ratio_at_slip) {
        (_, None) => slip.mu_note = Some("no slip within the block".into()),
        (Kind::Shear, Some(r)) => slip.mu = Some(r),
        (Kind::Rotation, Some(r)) => {
            // Full torsional slip of a flat circular punch (pressure ∝ 1/√(a²−r²)):
            // T = μ·P·a·π/4 (integrate μ p r over the contact).
            match model.and_then(|m| indenter_radius_mm(&m.spec.contact.indenter)) {
                Some(a) => slip.mu = Some(r / (a * std::f64::consts::FRAC_PI_4)),
                None => slip.mu_note = Some("torsional μ needs a flat circular punch".into()),
            }
        }
        (Kind::Normal, _) => {}
    }
}

/// The slope of the simulated bench's true force against load over the linear range of the
/// longest block.
fn sim_slope(data: &RunData, blocks: &[Block]) -> Option<f64> {
    let b = blocks.iter().max_by_key(|b| b.steps.len())?;
    let (x, y): (Vec<f64>, Vec<f64>) = b
        .steps
        .iter()
        .filter(|s| !s.unloading)
        .filter_map(|s| sim_truth(data, b, s.step).map(|t| (s.load, t)))
        .unzip();
    let n = x.len();
    let k = linear_range(&x, &y, 0.05, 0.02).map_or(n, |r| r.points);
    fit_line(&x[..k.min(n)], &y[..k.min(n)], true).map(|l| l.slope)
}

/// Runs every analysis that applies.
pub(crate) fn analyse(data: &RunData, model: Result<RefModel, String>) -> Report {
    let mut blocks = blocks(data);
    let model_note = model.as_ref().err().cloned();
    let model = model.ok();
    let curved = model
        .as_ref()
        .is_some_and(|m| matches!(m.spec.contact.indenter, Indenter::Sphere { .. }));
    let mut relaxation = Vec::new();
    for b in &mut blocks {
        relaxation.extend(relaxation_of(data, b));
        force_curves(data, b, curved);
    }
    // Field analyses need the depth of the preload for shear/torsion blocks.
    for b in &mut blocks {
        let depth = b
            .before
            .and_then(|r| data.steps.get(r))
            .filter(|r| r.axis == "normal")
            .and_then(|r| r.position)
            .unwrap_or(0.1);
        let note = analyse_fields(data, model.as_ref(), b, depth);
        displacement_curves(b);
        friction_from_slip(b, model.as_ref());
        if let Some(n) = note
            && let Some(slip) = b.slip.as_mut()
        {
            slip.mu_note.get_or_insert(n);
        }
    }
    // Time constants shared by the steps whose relaxation stands above the noise.
    // Steps under 5 % of the run's largest force are left out of the pooled fit: a
    // contact that is barely there may be partial, and its relaxation not the material's.
    let largest = relaxation
        .iter()
        .map(|r| r.fit.f_inf.abs())
        .fold(0.0, f64::max);
    let relaxing: Vec<&StepRelax> = relaxation
        .iter()
        .filter(|r| r.fit.terms >= 1 && r.fit.f_inf.abs() >= 0.05 * largest)
        .collect();
    let shared = shared_fit(&relaxing);
    let views: Vec<super::settle_study::StepRelax<'_>> = relaxation
        .iter()
        .map(|r| super::settle_study::StepRelax {
            t_s: &r.t_s,
            f: &r.f,
            f_inf: r.fit.f_inf,
            terms: r.fit.terms,
            amplitude: r.fit.amplitudes.iter().sum(),
            truth: r.truth,
            start_s: r.start_s,
        })
        .collect();
    let settle = super::settle_study::settle_curve(&views);
    let sim_slope = sim_slope(data, &blocks);
    Report {
        blocks,
        relaxation,
        shared,
        settle,
        model_note,
        sim_slope,
    }
}

fn shared_fit(relaxing: &[&StepRelax]) -> Option<SharedFit> {
    if relaxing.len() < 2 {
        return None;
    }
    let recs: Vec<(&[f64], &[f64])> = relaxing.iter().map(|r| (&r.t_s[..], &r.f[..])).collect();
    let n: usize = recs.iter().map(|r| r.0.len()).sum();
    let mut best: Option<(f64, SharedFit)> = None;
    for terms in 1..=3usize {
        // Start from the median per-step time constants of steps fitted with this many
        // terms, or a log-spread default.
        let mut start = vec![Vec::new(); terms];
        for r in relaxing.iter().filter(|r| r.fit.terms == terms) {
            for (k, t) in r.fit.taus_s.iter().enumerate() {
                start[k].push(*t);
            }
        }
        let start: Vec<f64> = start
            .into_iter()
            .enumerate()
            .map(|(k, mut v)| {
                v.sort_by(f64::total_cmp);
                v.get(v.len() / 2)
                    .copied()
                    .unwrap_or(10f64.powi(k as i32) * 1.5)
            })
            .collect();
        let Some(fit) = fit_shared(&recs, &start) else {
            continue;
        };
        let p = terms + recs.len() * (terms + 1);
        let bic = n as f64 * (fit.rss.max(1e-300) / n as f64).ln() + p as f64 * (n as f64).ln();
        if best.as_ref().is_none_or(|(b, _)| bic < *b - 2.0) {
            best = Some((bic, fit));
        }
    }
    best.map(|b| b.1)
}
