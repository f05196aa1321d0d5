//! `gelrig fit-material`: the gel of a bench, fitted to its recorded runs.
//!
//! Pressing runs (stepped on the `normal` axis, with a force record) give E∞, the Prony
//! terms and each run's contact offset ([`analysis::material_fit`]); shear runs that reach
//! gross slip give the static friction coefficient (the largest tangential-to-normal ratio
//! up to the first slipping step, [`analysis::slip`]) and the sliding one (the mean ratio of
//! the steps after). Poisson's ratio: the force of one indenter depends on E and ν together
//! (through E* and the layer's κ(ν)), so one indenter's force record cannot tell them apart;
//! the marker field around a flat circular punch can, being set by the depth alone
//! ([`super::field_nu`]), and so can two flat punch sizes' forces, where their moduli agree
//! ([`super::poisson`]). With neither, ν is held at the protocols' value.

use std::path::{Path, PathBuf};

use analysis::material_fit::{MaterialFit, PressRecord, fit_material};
use mechanics::response::ModelSpec;
use rig::units::{Duration, Pressure};

use super::file::{FORMAT, FittedRun, MaterialFile, TermUncertainty, Uncertainty, VERSION};
use super::law::{ForceLaw, interp, law_scale};
use super::nu_choice::{chosen_nu, distinct_sizes, held_reason, nu_checks, nu_from_fields};
use super::run::{FittedNu, PRESSING_AXES, Run};
use crate::run_data::{RunData, StepRow, read_run_tables};
use experiments::protocol::schema::{MaterialSpec, PronySpec};

/// Why a material could not be fitted.
#[derive(Debug, thiserror::Error)]
#[error("{path}: {detail}; fix: {fix}")]
pub struct FitError {
    /// The run (or the first run) concerned.
    pub path: PathBuf,
    /// What went wrong.
    pub detail: String,
    /// What to do.
    pub fix: String,
}

fn unfit(path: &Path, detail: impl Into<String>, fix: impl Into<String>) -> FitError {
    FitError {
        path: path.to_path_buf(),
        detail: detail.into(),
        fix: fix.into(),
    }
}

/// Fits a material to `runs` (run directories made by `gelrig run`).
pub fn fit(runs: &[PathBuf]) -> Result<MaterialFile, FitError> {
    let Some(first) = runs.first() else {
        return Err(unfit(
            Path::new("."),
            "no run directories given",
            "name the runs: gelrig fit-material runs/A runs/B --out material.yaml",
        ));
    };
    let read = read_runs(runs)?;
    let (pressing, nu) = pressing_runs(&read, first)?;
    let records: Vec<PressRecord> = pressing.iter().map(|(_, p)| p.clone()).collect();
    let laws: Vec<&ForceLaw> = pressing.iter().map(|(k, _)| &read[*k].law).collect();
    let no_model = || unfit(first, "a run's indenter has no model", "report this");
    let tables_at = |nu: f64| -> Option<Vec<(Vec<f64>, Vec<f64>)>> {
        laws.iter().map(|l| l.table(nu)).collect()
    };
    let joint = |tables: &[(Vec<f64>, Vec<f64>)]| {
        fit_material(&records, &|k, d| interp(&tables[k], d)).ok_or_else(|| {
            unfit(
                first,
                "the pressing records cannot be fitted (too short, or no relaxation model fits)",
                "fit on runs whose steps hold at least 10 s with a force record throughout",
            )
        })
    };
    let tables0 = tables_at(nu).ok_or_else(no_model)?;
    // Flat circular punches of two sizes or more tell ν; one indenter's record cannot, and a
    // curved indenter's law changes its shape with ν while its contact offset trades with
    // the modulus (a 9.5 mm punch and a 12.68 mm sphere told 0.483 for a gel of 0.49 on dry
    // runs).
    let flat: Vec<(usize, f64)> = (0..pressing.len())
        .filter_map(|j| Some((j, laws[j].flat_circle_a_over_h()?)))
        .collect();
    let sizes = distinct_sizes(&flat);
    let poisson = (sizes >= 2).then(|| {
        let recs: Vec<PressRecord> = flat.iter().map(|&(j, _)| records[j].clone()).collect();
        let tabs: Vec<(Vec<f64>, Vec<f64>)> =
            flat.iter().map(|&(j, _)| tables0[j].clone()).collect();
        super::poisson::fit_poisson(&recs, &tabs, nu, sizes, &|k, nu| laws[flat[k].0].table(nu))
    });
    let fit0 = joint(&tables0);
    let offsets: Vec<f64> = (0..pressing.len())
        .map(|j| {
            fit0.as_ref()
                .ok()
                .and_then(|f| f.offsets_mm.get(j))
                .map_or(0.0, |o| o.value)
        })
        .collect();
    let (field, field_notes) = nu_from_fields(&read, &pressing, &flat, &laws, &offsets);
    let chosen = chosen_nu(&field, &poisson, &laws);
    let mut checks = nu_checks(&chosen, &field, &poisson, &field_notes);
    let mut refit_failed = None;
    let (fit, nu_fit) = match chosen {
        Some(c) => {
            // The whole record again at the fitted ν; should it not fit there, ν stays held.
            match tables_at(c.nu).map(|t| joint(&t)) {
                Some(Ok(fit)) => {
                    let per_nu = c
                        .per_nu
                        .unwrap_or_else(|| log_modulus_per_nu(&laws, &records, &fit, c.nu));
                    (fit, Some((c, per_nu)))
                }
                _ => {
                    refit_failed = Some(format!(
                        "ν {:.4} was told {}, but the whole record does not fit there",
                        c.nu, c.how
                    ));
                    checks.clear();
                    (fit0?, None)
                }
            }
        }
        None => (fit0?, None),
    };
    let friction = friction_of(&read);
    let held_why = held_reason(&read, &pressing, &field, &poisson, refit_failed);
    Ok(file(
        &read,
        &pressing,
        &fit,
        friction,
        Poisson {
            nu: nu_fit.as_ref().map_or(nu, |p| p.0.nu),
            assumed: nu,
            fitted: nu_fit,
            held_why,
            checks,
        },
    ))
}

/// Every run read, all of one sensor's gel.
fn read_runs(runs: &[PathBuf]) -> Result<Vec<Run>, FitError> {
    let mut read = Vec::new();
    for dir in runs {
        read.push(read_one(dir)?);
    }
    if let Some(r) = read.iter().find(|r| r.sensor != read[0].sensor) {
        return Err(unfit(
            &r.dir,
            format!(
                "a {} sensor's run, but {} is of a {} sensor: one gel per fit",
                r.sensor,
                read[0].dir.display(),
                read[0].sensor
            ),
            "fit each sensor's gel on its own runs",
        ));
    }
    Ok(read)
}

/// The runs that press the gel in held steps with a force record (by index into `read`,
/// with their record), and the ν their protocols all assume. A resumed run was unloaded,
/// re-homed and pressed again between its segments: its depth history is not the step
/// log's, and it does not count.
fn pressing_runs(read: &[Run], first: &Path) -> Result<(Vec<(usize, PressRecord)>, f64), FitError> {
    let pressing: Vec<(usize, PressRecord)> = read
        .iter()
        .enumerate()
        .filter(|(_, r)| r.data.manifest.resumed.is_empty())
        .filter_map(|(k, r)| Some((k, press_record(&r.data, &r.speeds, r.approach_speed)?)))
        .collect();
    if pressing.is_empty() {
        return Err(unfit(
            first,
            "none of the runs presses the gel in held steps with a force record (a resumed \
             run does not count: its depth history broke where it was resumed)",
            "fit on stepped `normal` runs recorded with `record: {force: 20 Hz}` (e.g. \
             protocols/portable-normal.yaml)",
        ));
    }
    let nu = read[pressing[0].0].assumed.poisson_ratio;
    if let Some(r) = read
        .iter()
        .find(|r| (r.assumed.poisson_ratio - nu).abs() > 1e-9)
    {
        return Err(unfit(
            &r.dir,
            format!(
                "its protocol assumes ν = {}, another run's {nu}: one gel has one ν",
                r.assumed.poisson_ratio
            ),
            "fit runs of one gel together",
        ));
    }
    Ok((pressing, nu))
}

/// Poisson's ratio: fitted (with d ln E∞/dν at it), or held at the protocols' value and
/// why.
struct Poisson {
    nu: f64,
    assumed: f64,
    fitted: Option<(FittedNu, f64)>,
    held_why: String,
    /// The other method's ν where both told it, or why the field did not.
    checks: Vec<String>,
}

/// d ln E∞/dν at `nu`: how far ν's uncertainty moves the modulus. E∞ scales as the inverse of
/// the force laws' scale with ν (the least-squares ratio of each law at ν ± h to its law at
/// ν over the depths its run reached), weighted by the runs' samples.
fn log_modulus_per_nu(
    laws: &[&ForceLaw],
    records: &[PressRecord],
    fit: &MaterialFit,
    nu: f64,
) -> f64 {
    let h = 1e-3_f64.min(0.5 * (0.4995 - nu)).max(1e-5);
    let (mut num, mut den) = (0.0, 0.0);
    for (k, (law, rec)) in laws.iter().zip(records).enumerate() {
        let d0 = fit.offsets_mm.get(k).map_or(0.0, |o| o.value);
        let deepest = rec.depth_knots.iter().map(|k| k.1).fold(0.0, f64::max) - d0;
        let (Some(t0), Some(tm), Some(tp)) = (law.table(nu), law.table(nu - h), law.table(nu + h))
        else {
            continue;
        };
        let (Some(sp), Some(sm)) = (law_scale(&t0, &tp, deepest), law_scale(&t0, &tm, deepest))
        else {
            continue;
        };
        let slope = -(sp.ln() - sm.ln()) / (2.0 * h);
        if slope.is_finite() {
            let w = rec.t_s.len() as f64;
            num += w * slope;
            den += w;
        }
    }
    if den > 0.0 { num / den } else { 0.0 }
}

fn read_one(dir: &Path) -> Result<Run, FitError> {
    let data = read_run_tables(dir).map_err(|e| {
        unfit(
            dir,
            format!("not a readable run ({e})"),
            "point fit-material at run directories made by `gelrig run`",
        )
    })?;
    let loaded = crate::run_data::run_protocol(dir).map_err(|e| {
        unfit(
            dir,
            e,
            "point fit-material at run directories made by `gelrig run`",
        )
    })?;
    let spec =
        experiments::protocol::plant_spec(&loaded.protocol, &loaded.compiled).map_err(|e| {
            unfit(
                dir,
                e,
                "point fit-material at runs of a simulated or real gel",
            )
        })?;
    let assumed = loaded
        .protocol
        .sensor
        .material
        .as_ref()
        .and_then(|m| m.values())
        .cloned()
        .ok_or_else(|| unfit(dir, "its protocol gives no material", "report this"))?;
    // The layer's force at 1 MPa: the contact model is linear in the modulus.
    let mut contact = spec.contact.clone();
    contact.material.youngs_modulus_mpa = 1.0;
    let law = ForceLaw {
        spec: ModelSpec {
            contact,
            max_depth_mm: spec.max_depth_mm,
            shear: false,
            twist: false,
            field_view_mm: None,
            pressing_friction: loaded.rig.presses_with_friction(),
            quality: spec.quality,
        },
        finite_strain: loaded.rig.finite_strain(),
    };
    let indenter = serde_json::to_string(&loaded.protocol.indenter).unwrap_or_default();
    let speeds = loaded
        .compiled
        .actions
        .iter()
        .filter_map(|a| match &a.kind {
            experiments::protocol::compile::ActionKind::Step(s) => Some((s.step, s.speed)),
            _ => None,
        })
        .collect();
    let approach_speed = loaded.compiled.actions.iter().find_map(|a| match &a.kind {
        experiments::protocol::compile::ActionKind::Approach(s)
            if PRESSING_AXES.contains(&s.axis.to_string().as_str()) =>
        {
            Some(s.speed)
        }
        _ => None,
    });
    let sensor = format!("{:?}", loaded.protocol.sensor.kind).to_lowercase();
    Ok(Run {
        dir: dir.to_path_buf(),
        data,
        assumed,
        sensor,
        speeds,
        approach_speed,
        law,
        indenter,
        view_mm: (spec.view_width_mm, spec.view_height_mm),
    })
}

/// How much of the approach before the first step the record keeps, s.
const APPROACH_S: f64 = 5.0;

/// The run's pressing record: its held steps on a pressing axis, the commanded depth as a
/// ramp from each step's start at the protocol's speed (the stage moves at constant speed;
/// the settle starts only when the runner has seen it stop, a poll later, so the settle's
/// start would stretch the ramp) and the force throughout; up to the first step back at (or
/// above) the contact origin, where a gel unloaded faster than it recovers leaves the
/// indenter (a clamp the linear model does not have).
///
/// The approach that found the contact ends where the first step starts, pressing the gel at
/// its creep speed until the force threshold: its last seconds are in the record too, so
/// the first step starts with the gel's fresh memory of that press (left out, the fitted
/// weights read 1–2 % high).
fn press_record(
    data: &RunData,
    speeds: &std::collections::BTreeMap<u32, f64>,
    approach_speed: Option<f64>,
) -> Option<PressRecord> {
    let steps: Vec<&StepRow> = data
        .steps
        .iter()
        .filter(|s| PRESSING_AXES.contains(&s.axis.as_str()) && s.position.is_some())
        .collect();
    let first = steps.first()?;
    let mut knots = Vec::new();
    let mut from_ns = first.t_start_ns;
    if let Some(v) = approach_speed.filter(|v| *v > 0.0) {
        let t0 = first.t_start_ns as f64 * 1e-9;
        knots.push((t0 - APPROACH_S, -v * APPROACH_S));
        from_ns = first.t_start_ns.saturating_sub((APPROACH_S * 1e9) as u64);
    }
    let mut last = 0.0;
    let mut end_ns = first.t_start_ns;
    for s in &steps {
        let pos = s.position?;
        if pos <= 0.0 {
            break;
        }
        let settle_start = s
            .settle_end_ns
            .checked_sub((s.settle_s * 1e9) as u64)?
            .max(s.t_start_ns);
        let t0 = s.t_start_ns as f64 * 1e-9;
        let t1 = match speeds.get(&s.step) {
            Some(&v) if v > 0.0 => (t0 + (pos - last).abs() / v).min(settle_start as f64 * 1e-9),
            _ => settle_start as f64 * 1e-9,
        };
        knots.push((t0, last));
        knots.push((t1, pos));
        last = pos;
        end_ns = s.settle_end_ns;
    }
    if knots.is_empty() {
        return None;
    }
    let (t_s, f_n): (Vec<f64>, Vec<f64>) = data
        .force
        .iter()
        .filter(|r| r.t_ns >= from_ns && r.t_ns <= end_ns)
        .map(|r| (r.t_ns as f64 * 1e-9, r.fz_n))
        .unzip();
    (t_s.len() >= 20).then_some(PressRecord {
        t_s,
        f_n,
        depth_knots: knots,
    })
}

/// Static and sliding friction from the runs' shear steps, with the static one's
/// uncertainty (half the ratio's rise over the step that found slip).
struct Friction {
    static_mu: f64,
    static_sd: f64,
    sliding_mu: Option<f64>,
    run: usize,
}

fn friction_of(runs: &[Run]) -> Option<Friction> {
    runs.iter().enumerate().find_map(|(k, r)| {
        let load: Vec<&StepRow> = r
            .data
            .steps
            .iter()
            .filter(|s| s.axis == "shear" && s.phase == "load" && s.position.is_some())
            .collect();
        let block = analysis::slip::Block {
            load: load.iter().filter_map(|s| s.position).collect(),
            tangential: load.iter().map(|s| s.fx_n.abs()).collect(),
            normal_n: load.iter().map(|s| s.fz_n).collect(),
            centre_over_edge: None,
            contact_motion: None,
        };
        let report = analysis::slip::classify(&block, analysis::slip::Thresholds::default())?;
        // Gross slip is where the force first drops (stick–slip), or else where the force cue
        // says it stopped rising. Pressed with friction (`sim: {pressing_friction: true}`) a
        // contact's edge already slides inward, so the force bends over gradually and keeps
        // climbing after the cue's plateau (a fourth of the first steps' slope) toward μ·Fz:
        // there the largest ratio before the drop, not before the plateau, brackets the
        // limit (a 0.35 gel read 0.334 at the plateau, 0.349 at the drop).
        let drop = (1..block.tangential.len()).find(|&i| {
            block.tangential[..i]
                .iter()
                .any(|&f| block.tangential[i] < f)
        });
        let onset = drop.or(report.onset)?;
        let ratio = |i: usize| block.tangential[i] / block.normal_n[i].max(1e-9);
        // The steps bracket the limit: it is above the last step that held, and below where
        // the next step would have reached had it held (its ratio plus the last increment).
        let held = (0..onset).max_by(|&a, &b| ratio(a).total_cmp(&ratio(b)))?;
        let rise = if held > 0 {
            (ratio(held) - ratio(held - 1)).max(0.0)
        } else {
            ratio(held)
        };
        // Sliding: where the force fell, the contact slid and came to rest at the sliding
        // level (a stick–slip run re-sticks and climbs on the next step, which says nothing
        // of it); without a fall, the steps after the onset.
        let slid: Vec<f64> = drop
            .map(|d| {
                (d..block.tangential.len())
                    .filter(|&i| block.tangential[i] < block.tangential[i - 1])
                    .map(ratio)
                    .collect()
            })
            .unwrap_or_default();
        let after: Vec<f64> = if slid.is_empty() {
            (onset + 1..block.load.len()).map(ratio).collect()
        } else {
            slid
        };
        Some(Friction {
            static_mu: ratio(held) + 0.5 * rise,
            static_sd: 0.5 * rise,
            sliding_mu: (!after.is_empty()).then(|| after.iter().sum::<f64>() / after.len() as f64),
            run: k,
        })
    })
}

fn file(
    runs: &[Run],
    pressing: &[(usize, PressRecord)],
    fit: &MaterialFit,
    friction: Option<Friction>,
    poisson: Poisson,
) -> MaterialFile {
    let nu = poisson.nu;
    let assumed = &runs[pressing[0].0].assumed;
    let (mu, mu_kinetic) = match &friction {
        Some(f) => (
            f.static_mu,
            Some(f.sliding_mu.unwrap_or(f.static_mu).min(f.static_mu)),
        ),
        None => (assumed.friction, assumed.kinetic_friction),
    };
    let material = MaterialSpec {
        youngs_modulus: Pressure::new(fit.modulus_ratio.value),
        poisson_ratio: nu,
        friction: mu,
        kinetic_friction: mu_kinetic,
        prony: fit
            .terms
            .iter()
            .map(|t| PronySpec {
                weight: t.weight.value,
                tau: Duration::new(t.tau_s.value),
            })
            .collect(),
    };
    let mut provenance = vec![
        format!(
            "youngs_modulus and prony: fitted to the whole force record of {} pressing run(s) \
             ({} samples; {} Prony term(s) by BIC; the force record's lag behind the step log \
             {:.4} ± {:.4} s)",
            pressing.len(),
            fit.samples,
            fit.terms.len(),
            fit.lag_s.value,
            fit.lag_s.sd
        ),
        match &poisson.fitted {
            Some((p, _)) => format!(
                "poisson_ratio: {:.4} ± {:.4}, {} (the protocols assumed {}; the whole record \
                 fitted again at the fitted ν)",
                p.nu, p.sd, p.how, poisson.assumed
            ),
            None => format!(
                "poisson_ratio: held at the protocols' {nu} ({})",
                poisson.held_why
            ),
        },
    ];
    provenance.extend(poisson.checks);
    provenance.push(match &friction {
        Some(f) => format!(
            "friction: bracketed by the shear steps of {} — above the last step that held, \
             below where the next would have reached (the middle, ± half the bracket); \
             kinetic_friction: the mean tangential-to-normal ratio of the steps whose force fell \
             as the contact slid (or, without a fall, of the steps after slip)",
            runs[f.run].data.protocol_name
        ),
        None => format!(
            "friction and kinetic_friction: held at the protocol's {} and {} (no run \
             reached gross slip)",
            assumed.friction,
            assumed
                .kinetic_friction
                .map_or_else(|| "its default".to_string(), |k| k.to_string())
        ),
    });
    let mut fitted_on: Vec<FittedRun> = runs
        .iter()
        .enumerate()
        .filter_map(|(k, r)| {
            let j = pressing.iter().position(|(i, _)| *i == k);
            let sliding = friction.as_ref().is_some_and(|f| f.run == k);
            (j.is_some() || sliding).then(|| FittedRun {
                run: r
                    .dir
                    .file_name()
                    .map(|n| n.to_string_lossy().into_owned())
                    .unwrap_or_default(),
                protocol: r.data.protocol_name.clone(),
                used_for: if j.is_some() { "pressing" } else { "sliding" }.into(),
                contact_offset_mm: j.map(|j| fit.offsets_mm[j].value),
                contact_offset_sd_mm: j.map(|j| fit.offsets_mm[j].sd),
                residual_rms_n: j.map(|j| fit.residual_rms_n[j]),
                samples: j.map(|j| pressing[j].1.t_s.len()),
            })
        })
        .collect();
    fitted_on.sort_by(|a, b| a.run.cmp(&b.run));
    MaterialFile {
        format: FORMAT.into(),
        // Version 1 where nothing of version 2 is in it, so older readers still take it.
        version: if poisson.fitted.is_some() { VERSION } else { 1 },
        created: jiff::Timestamp::now().to_string(),
        material,
        uncertainty: Uncertainty {
            // A fitted ν's uncertainty reaches E∞ through the force law's dependence on it.
            youngs_modulus_mpa: poisson.fitted.as_ref().map_or(
                fit.modulus_ratio.sd,
                |(p, per_nu)| {
                    fit.modulus_ratio
                        .sd
                        .hypot(fit.modulus_ratio.value * per_nu * p.sd)
                },
            ),
            prony: fit
                .terms
                .iter()
                .map(|t| TermUncertainty {
                    weight: t.weight.sd,
                    tau_s: t.tau_s.sd,
                })
                .collect(),
            friction: friction.as_ref().map(|f| f.static_sd),
            poisson_ratio: poisson.fitted.as_ref().map(|(p, _)| p.sd),
        },
        provenance,
        fitted_on,
    }
}
