//! From run tables to results: which analyses apply, and their numbers.

use analysis::field::{MarkerField, decompose};
use analysis::field_force::{self, Component};
use analysis::hysteresis::{Hysteresis, hysteresis};
use analysis::linearity::{LineFit, LinearRange, PowerLaw, fit_line, fit_power_law, linear_range};
use analysis::relaxation::{SharedFit, StepRelaxation, analyse_step, fit_shared};
use analysis::slip::{self, SlipReport};
use mechanics::Indenter;
use mechanics::response::{ContactModel, ModelSpec, State};
use rig::sim::PlantSpec;

use super::RunData;

/// Minimum settle for a step to count as quasistatic, s.
const QUASISTATIC_S: f64 = 5.0;

/// What the axis of a block loads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// Normal indentation: fz against depth.
    Normal,
    /// Shear: tangential force against shear offset.
    Shear,
    /// Torsion: torque against angle.
    Rotation,
}

impl Kind {
    pub(crate) fn name(self) -> &'static str {
        match self {
            Self::Normal => "normal",
            Self::Shear => "shear",
            Self::Rotation => "rotation",
        }
    }

    pub(crate) fn force_label(self) -> &'static str {
        match self {
            Self::Normal => "normal force Fz (N)",
            Self::Shear => "shear force (N)",
            Self::Rotation => "torque Tz (N·mm)",
        }
    }

    /// What the block's axis sets, in the lab's words: depth, shear offset, angle.
    pub(crate) fn load_name(self) -> &'static str {
        match self {
            Self::Normal => "depth",
            Self::Shear => "shear offset",
            Self::Rotation => "angle",
        }
    }

    pub(crate) fn force_unit(self) -> &'static str {
        if self == Self::Rotation { "N·mm" } else { "N" }
    }
}

/// One step of a block.
#[derive(Debug, Clone)]
pub struct BlockStep {
    /// Index into the run's steps.
    pub row: usize,
    /// Step number.
    pub step: u32,
    /// Load (depth, offset or angle) in the axis unit.
    pub load: f64,
    /// Quasistatic force (the thesis's last-window mean) along the block's channel.
    pub force: f64,
    /// Normal force, N.
    pub normal_n: f64,
    /// Whether this step unloads.
    pub unloading: bool,
}

/// Consecutive quasistatic steps of one axis.
#[derive(Debug, Clone)]
pub struct Block {
    /// What it loads.
    pub kind: Kind,
    /// Axis unit.
    pub unit: String,
    /// Steps in order.
    pub steps: Vec<BlockStep>,
    /// Shear direction of the measured force, rad (shear blocks).
    pub force_direction_rad: f64,
    /// Sign applied to the channel so loading is positive.
    pub sign: f64,
    /// The step before the block (the preload of a shear or torsion block), row index.
    pub before: Option<usize>,
    /// Linearity of the loading steps.
    pub linearity: Option<Linearity>,
    /// Loading against unloading.
    pub hysteresis: Option<Hysteresis>,
    /// Marker displacement against force, loading against unloading.
    pub displacement_hysteresis: Option<Hysteresis>,
    /// Slip (shear and rotation).
    pub slip: Option<Slip>,
    /// Force from the field.
    pub field_force: Option<FieldForce>,
    /// Marker displacement per step (mean, max) in px, when frames exist.
    pub displacement_px: Vec<Option<(f64, f64)>>,
    /// Profiles per step (radial or central line), px.
    pub profiles: Vec<(u32, Vec<(f64, f64)>)>,
}

/// Linearity results of a block.
#[derive(Debug, Clone)]
pub struct Linearity {
    /// Fit with intercept, over the linear range.
    pub with_intercept: LineFit,
    /// Fit through the origin, over the linear range.
    pub through_origin: LineFit,
    /// Fit with intercept over every loading step.
    pub all: LineFit,
    /// Linear range (5 % tolerance).
    pub range: Option<LinearRange>,
    /// Power law (curved indenters, normal load).
    pub power_law: Option<PowerLaw>,
    /// Mean marker displacement against force: slope px per force unit, R².
    pub displacement_vs_force: Option<LineFit>,
}

/// Slip results of a block.
#[derive(Debug, Clone)]
pub struct Slip {
    /// The classification.
    pub report: SlipReport,
    /// Friction coefficient estimate.
    pub mu: Option<f64>,
    /// Why μ is absent.
    pub mu_note: Option<String>,
    /// The simulator's onset (first full slip, or under 10 % of the contact still
    /// sticking), step number.
    pub sim_onset_step: Option<u32>,
}

/// Force-from-field results of a block.
#[derive(Debug, Clone)]
pub struct FieldForce {
    /// Fitted scale per step (NaN where no fit).
    pub scales: Vec<f64>,
    /// Calibration and prediction.
    pub prediction: field_force::Prediction,
}

/// Relaxation of one step.
#[derive(Debug, Clone)]
pub struct StepRelax {
    /// Step number.
    pub step: u32,
    /// Its block's kind.
    pub kind: Kind,
    /// Analysis.
    pub fit: StepRelaxation,
    /// Samples (t from the end of the move, s; force).
    pub t_s: Vec<f64>,
    /// Force samples.
    pub f: Vec<f64>,
    /// The simulator's equilibrium value, if known.
    pub truth: Option<f64>,
    /// The move's end, s on the run's clock.
    pub start_s: f64,
}

/// Everything the report shows.
#[derive(Debug, Clone)]
pub struct Report {
    /// Blocks in run order.
    pub blocks: Vec<Block>,
    /// Per relaxing step.
    pub relaxation: Vec<StepRelax>,
    /// Time constants shared by the run's steps.
    pub shared: Option<SharedFit>,
    /// Settle error curve.
    pub settle: Option<super::settle_study::SettleCurve>,
    /// Whether a reference contact model was available for field fits.
    pub model_note: Option<String>,
    /// The simulator's equilibrium stiffness of the main block, force per unit.
    pub sim_slope: Option<f64>,
}

/// The reference contact model of the run's own protocol (its sensor, material and
/// indenter), for force from field; `Err` says why there is none.
pub(crate) struct RefModel {
    pub spec: PlantSpec,
}

pub(crate) fn reference_model(data: &RunData) -> Result<RefModel, String> {
    let protocol = data.dir.join("protocol.yaml");
    let rig = data.dir.join("rig.yaml");
    let loaded = crate::protocol::load(&protocol, Some(&rig)).map_err(|d| {
        format!(
            "the run's protocol does not load ({})",
            d.first().map(|d| d.to_string()).unwrap_or_default()
        )
    })?;
    let spec = crate::protocol::plant_spec(&loaded.protocol, &loaded.compiled)?;
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

/// The field at the end of step `step` (its last frame).
fn step_field(data: &RunData, step: u32) -> Option<MarkerField> {
    crate::run_data::frame_field(data, data.last_frame_of(step)?)
}

pub(super) fn spacing_px(f: &MarkerField) -> f64 {
    let mut d: Vec<f64> = f
        .reference_px
        .iter()
        .enumerate()
        .map(|(i, p)| {
            f.reference_px
                .iter()
                .enumerate()
                .filter(|(j, _)| *j != i)
                .map(|(_, q)| (p[0] - q[0]).hypot(p[1] - q[1]))
                .fold(f64::INFINITY, f64::min)
        })
        .filter(|v| v.is_finite())
        .collect();
    d.sort_by(f64::total_cmp);
    d.get(d.len() / 2).copied().unwrap_or(30.0)
}

/// The field's geometry on the image.
struct Geometry {
    mm_per_px: f64,
    centre_px: [f64; 2],
    spacing_px: f64,
}

fn geometry(
    data: &RunData,
    model: &RefModel,
    b: &Block,
    fields: &[Option<MarkerField>],
) -> Option<Geometry> {
    let (w, h) = data.frame_size?;
    let mm_per_px = (model.spec.view_width_mm / w as f64).max(model.spec.view_height_mm / h as f64);
    // The contact centre: where the pressing field radiates from — the preload step of a
    // shear or torsion block, the deepest step of a normal block.
    let press = match b.kind {
        Kind::Normal => {
            let k = (0..b.steps.len())
                .max_by(|&i, &j| b.steps[i].force.total_cmp(&b.steps[j].force))?;
            fields.get(k)?.clone()
        }
        _ => b.before.and_then(|r| step_field(data, data.steps[r].step)),
    }?;
    let centre_px = decompose::radiating_centre(&press)?;
    Some(Geometry {
        mm_per_px,
        centre_px,
        spacing_px: spacing_px(&press),
    })
}

fn indenter_radius_mm(ind: &Indenter) -> Option<f64> {
    match ind {
        Indenter::FlatCircle { diameter_mm } => Some(0.5 * diameter_mm),
        _ => None,
    }
}

fn analyse_fields(
    data: &RunData,
    model: Option<&RefModel>,
    b: &mut Block,
    relax_depth: f64,
) -> Option<String> {
    if data.markers.is_empty() {
        return None;
    }
    let fields: Vec<Option<MarkerField>> =
        b.steps.iter().map(|s| step_field(data, s.step)).collect();
    b.displacement_px = fields
        .iter()
        .map(|f| {
            let f = f.as_ref()?;
            let m: Vec<f64> = f
                .measured_ids()
                .map(|i| f.displacement_px[i][0].hypot(f.displacement_px[i][1]))
                .collect();
            (!m.is_empty()).then(|| {
                (
                    m.iter().sum::<f64>() / m.len() as f64,
                    m.iter().fold(0.0, |a: f64, v| a.max(*v)),
                )
            })
        })
        .collect();
    let model = match model {
        Some(m) => m,
        None => {
            return Some("no reference model: force from field and field slip cues skipped".into());
        }
    };
    let g = geometry(data, model, b, &fields)?;
    // One reference field per block, as the thesis (§4.3): the field of a fixed load is
    // scaled to every step, and the scale measures the load. Normal blocks use the median
    // depth of the block; shear and torsion blocks the preload depth.
    let max_depth = b
        .steps
        .iter()
        .map(|s| s.load)
        .fold(relax_depth, f64::max)
        .max(1e-3);
    let ref_depth = match b.kind {
        Kind::Normal => {
            let mut d: Vec<f64> = b
                .steps
                .iter()
                .map(|s| s.load)
                .filter(|d| *d > 0.0)
                .collect();
            d.sort_by(f64::total_cmp);
            d.get(d.len() / 2).copied().unwrap_or(max_depth)
        }
        _ => relax_depth,
    };
    let depth_of = |s: &BlockStep| match b.kind {
        Kind::Normal => s.load.max(1e-3),
        _ => relax_depth,
    };
    let needs_shear = b.kind == Kind::Shear;
    let mut cm = match ContactModel::build(ModelSpec {
        contact: model.spec.contact.clone(),
        max_depth_mm: max_depth * 1.05,
        shear: needs_shear,
        twist: false,
        field_view_mm: Some((model.spec.view_width_mm, model.spec.view_height_mm)),
        pressing_friction: false,
        quality: model.spec.quality,
    }) {
        Ok(m) => m,
        Err(e) => return Some(format!("reference model failed: {e}")),
    };
    let a_px = |depth: f64, cm: &ContactModel| cm.contact_radius_mm(depth) / g.mm_per_px;
    let mut scales = vec![f64::NAN; b.steps.len()];
    let mut centre_over_edge = vec![f64::NAN; b.steps.len()];
    let mut contact_motion = vec![f64::NAN; b.steps.len()];
    let preload = b.before.and_then(|r| step_field(data, data.steps[r].step));
    for (k, s) in b.steps.iter().enumerate() {
        let Some(f) = fields[k].as_ref() else {
            continue;
        };
        let depth = depth_of(s);
        let a = a_px(depth, &cm);
        match b.kind {
            Kind::Normal => {
                let Some(rf) = cm.field(State {
                    depth_mm: ref_depth,
                    shear_n: 0.0,
                    torque_nmm: 0.0,
                }) else {
                    continue;
                };
                let a = a_px(ref_depth, &cm);
                let reference = field_force::reference_at_markers(
                    &rf,
                    &f.reference_px,
                    g.centre_px,
                    g.mm_per_px,
                    0.0,
                );
                if let Some(fit) =
                    field_force::fit_scale(f, &reference, g.centre_px, a, Component::Radial)
                {
                    scales[k] = fit.scale;
                }
                let prof = decompose::radial_profile(f, g.centre_px, 0.5 * g.spacing_px);
                b.profiles.push((
                    s.step,
                    prof.iter()
                        .map(|p| (p.at_px * g.mm_per_px, p.mean_px * g.mm_per_px))
                        .collect(),
                ));
            }
            Kind::Shear => {
                let Some(pre) = preload.as_ref() else {
                    continue;
                };
                let pure = decompose::subtract(f, pre);
                // Image direction of the shear from the pure field itself.
                let Some(sh) = decompose::shear(
                    &pure,
                    Some(g.centre_px),
                    0.5 * g.spacing_px,
                    0.5 * g.spacing_px,
                ) else {
                    continue;
                };
                let dir = [sh.direction_rad.cos(), sh.direction_rad.sin()];
                let (Some(f1), Some(f0)) = (
                    cm.field(State {
                        depth_mm: depth,
                        shear_n: 1.0,
                        torque_nmm: 0.0,
                    }),
                    cm.field(State {
                        depth_mm: depth,
                        shear_n: 0.0,
                        torque_nmm: 0.0,
                    }),
                ) else {
                    continue;
                };
                let unit = mechanics::response::Field {
                    grid: f1.grid,
                    ux: f1.ux.iter().zip(&f0.ux).map(|(a, b)| a - b).collect(),
                    uy: f1.uy.iter().zip(&f0.uy).map(|(a, b)| a - b).collect(),
                    uz: f1.uz.iter().zip(&f0.uz).map(|(a, b)| a - b).collect(),
                };
                let reference = field_force::reference_at_markers(
                    &unit,
                    &pure.reference_px,
                    g.centre_px,
                    g.mm_per_px,
                    sh.direction_rad,
                );
                if let Some(fit) =
                    field_force::fit_scale(&pure, &reference, g.centre_px, a, Component::Along(dir))
                {
                    scales[k] = fit.scale;
                }
                centre_over_edge[k] =
                    decompose::centre_over_edge(&pure, g.centre_px, dir, a, 0.6 * g.spacing_px)
                        .unwrap_or(f64::NAN);
                contact_motion[k] = decompose::mean_along_within(&pure, g.centre_px, dir, 0.5 * a)
                    .map_or(f64::NAN, |u| u * g.mm_per_px);
                b.profiles.push((
                    s.step,
                    sh.central_line
                        .iter()
                        .map(|p| (p.at_px * g.mm_per_px, p.mean_px * g.mm_per_px))
                        .collect(),
                ));
            }
            Kind::Rotation => {
                let Some(pre) = preload.as_ref() else {
                    continue;
                };
                let pure = decompose::subtract(f, pre);
                let inner = decompose::rotation(&pure, Some(g.centre_px), 0.5 * a);
                let whole = decompose::rotation(&pure, Some(g.centre_px), a);
                let outer = whole.as_ref().and(inner.as_ref()).and_then(|_| {
                    // The annulus 0.5a–a: markers outside 0.5a only.
                    let mut ring = pure.clone();
                    for (i, m) in ring.measured.iter_mut().enumerate() {
                        let p = pure.reference_px[i];
                        if (p[0] - g.centre_px[0]).hypot(p[1] - g.centre_px[1]) < 0.5 * a {
                            *m = false;
                        }
                    }
                    decompose::rotation(&ring, Some(g.centre_px), a)
                });
                if let (Some(i), Some(o)) = (&inner, &outer)
                    && o.angle_rad.abs() > 1e-6
                {
                    centre_over_edge[k] = i.angle_rad / o.angle_rad;
                }
                if let Some(w) = whole {
                    contact_motion[k] = b.sign * w.angle_rad.to_degrees();
                }
            }
        }
    }
    if b.kind != Kind::Rotation {
        let forces: Vec<f64> = b.steps.iter().map(|s| s.force).collect();
        let calibrate: Vec<bool> = (0..b.steps.len()).map(|i| i % 2 == 0).collect();
        let curved = !matches!(
            model.spec.contact.indenter,
            Indenter::FlatCircle { .. }
                | Indenter::FlatEllipse { .. }
                | Indenter::FlatRectangle { .. }
        );
        if let Some(prediction) = field_force::calibrate_and_predict(
            &scales,
            &forces,
            &calibrate,
            if curved && b.kind == Kind::Normal {
                field_force::Map::Piecewise
            } else {
                field_force::Map::Linear
            },
        ) {
            b.field_force = Some(FieldForce { scales, prediction });
        }
    }
    if b.kind != Kind::Normal
        && let Some(slip) = b.slip.as_mut()
    {
        let mut block = slip_block(&b.steps);
        block.centre_over_edge = Some(centre_over_edge);
        block.contact_motion = Some(contact_motion);
        if let Some(r) = slip::classify(&block, slip::Thresholds::default()) {
            slip.report = r;
        }
    }
    None
}

fn slip_block(steps: &[BlockStep]) -> slip::Block {
    let load: Vec<&BlockStep> = steps.iter().filter(|s| !s.unloading).collect();
    slip::Block {
        load: load.iter().map(|s| s.load).collect(),
        tangential: load.iter().map(|s| s.force).collect(),
        normal_n: load.iter().map(|s| s.normal_n).collect(),
        centre_over_edge: None,
        contact_motion: None,
    }
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
        // Relaxation per step.
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
            && let Some(report) = slip::classify(&slip_block(&b.steps), slip::Thresholds::default())
        {
            b.slip = Some(Slip {
                report,
                mu: None,
                mu_note: None,
                sim_onset_step: sim_onset(data, b),
            });
        }
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
        if let (Some(lin), false) = (b.linearity.as_mut(), b.displacement_px.is_empty()) {
            let (f, d): (Vec<f64>, Vec<f64>) = b
                .steps
                .iter()
                .zip(&b.displacement_px)
                .filter(|(s, d)| !s.unloading && d.is_some())
                .map(|(s, d)| (s.force, d.map_or(f64::NAN, |d| d.0)))
                .unzip();
            lin.displacement_vs_force = fit_line(&f, &d, true);
        }
        if !b.displacement_px.is_empty() {
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
        // μ from the slip onset.
        if let Some(slip) = b.slip.as_mut() {
            let ratio = slip.report.ratio_at_slip;
            match (b.kind, ratio) {
                (_, None) => slip.mu_note = Some("no slip within the block".into()),
                (Kind::Shear, Some(r)) => slip.mu = Some(r),
                (Kind::Rotation, Some(r)) => {
                    // Full torsional slip of a flat circular punch (pressure ∝ 1/√(a²−r²)):
                    // T = μ·P·a·π/4 (integrate μ p r over the contact).
                    match model
                        .as_ref()
                        .and_then(|m| indenter_radius_mm(&m.spec.contact.indenter))
                    {
                        Some(a) => slip.mu = Some(r / (a * std::f64::consts::FRAC_PI_4)),
                        None => {
                            slip.mu_note = Some("torsional μ needs a flat circular punch".into())
                        }
                    }
                }
                (Kind::Normal, _) => {}
            }
        }
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
    let sim_slope = blocks.iter().max_by_key(|b| b.steps.len()).and_then(|b| {
        let (x, y): (Vec<f64>, Vec<f64>) = b
            .steps
            .iter()
            .filter(|s| !s.unloading)
            .filter_map(|s| sim_truth(data, b, s.step).map(|t| (s.load, t)))
            .unzip();
        let n = x.len();
        let k = linear_range(&x, &y, 0.05, 0.02).map_or(n, |r| r.points);
        fit_line(&x[..k.min(n)], &y[..k.min(n)], true).map(|l| l.slope)
    });
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
