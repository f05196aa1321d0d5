//! A block's marker fields: where the contact is on the image, the thesis's force from the
//! field (the reference model's field scaled to each step), and the field's slip cues
//! (centre over edge, the contact's motion).

use analysis::field_force::{self, Component};
use analysis::slip;
use mechanics::Indenter;
use mechanics::response::{ContactModel, ModelSpec, State};
use tracking::field::{MarkerField, decompose};

use super::RunData;
use super::results::{Block, BlockStep, FieldForce, Kind, RefModel};

/// The field at the end of step `step` (its last frame).
fn step_field(data: &RunData, step: u32) -> Option<MarkerField> {
    sensing::run_data::frame_field(data, data.last_frame_of(step)?)
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

pub(super) fn indenter_radius_mm(ind: &Indenter) -> Option<f64> {
    match ind {
        Indenter::FlatCircle { diameter_mm } => Some(0.5 * diameter_mm),
        _ => None,
    }
}

/// The mean and largest marker displacement of each step's field, px.
fn displacement_px(fields: &[Option<MarkerField>]) -> Vec<Option<(f64, f64)>> {
    fields
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
        .collect()
}

/// The deepest depth of the block and the depth of its one reference field: as the thesis
/// (§4.3), the field of a fixed load is scaled to every step, and the scale measures the
/// load. Normal blocks use the median depth of the block; shear and torsion blocks the
/// preload depth.
fn reference_depths(b: &Block, relax_depth: f64) -> (f64, f64) {
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
    (max_depth, ref_depth)
}

/// What one step's field says: the scale of the reference field, the slip cues, and the
/// profile drawn in the report.
struct StepCues {
    scale: f64,
    centre_over_edge: f64,
    contact_motion: f64,
    profile: Option<Vec<(f64, f64)>>,
}

impl Default for StepCues {
    fn default() -> Self {
        Self {
            scale: f64::NAN,
            centre_over_edge: f64::NAN,
            contact_motion: f64::NAN,
            profile: None,
        }
    }
}

fn at_rest(depth_mm: f64, shear_n: f64) -> State {
    State {
        depth_mm,
        shear_n,
        torque_nmm: 0.0,
    }
}

/// A normal step: the reference field at `ref_depth` scaled to the radial field.
fn normal_step(cm: &mut ContactModel, g: &Geometry, f: &MarkerField, ref_depth: f64) -> StepCues {
    let mut cues = StepCues::default();
    let Some(rf) = cm.field(at_rest(ref_depth, 0.0)) else {
        return cues;
    };
    let a = cm.contact_radius_mm(ref_depth) / g.mm_per_px;
    let reference =
        field_force::reference_at_markers(&rf, &f.reference_px, g.centre_px, g.mm_per_px, 0.0);
    if let Some(fit) = field_force::fit_scale(f, &reference, g.centre_px, a, Component::Radial) {
        cues.scale = fit.scale;
    }
    let prof = decompose::radial_profile(f, g.centre_px, 0.5 * g.spacing_px);
    let mm = |p: &decompose::ProfileBin| (p.at_px * g.mm_per_px, p.mean_px * g.mm_per_px);
    cues.profile = Some(prof.iter().map(mm).collect());
    cues
}

/// A shear step: the field less the preload's, scaled to the model's field of a unit shear;
/// the centre-over-edge ratio and the contact's motion along the shear.
fn shear_step(
    cm: &mut ContactModel,
    g: &Geometry,
    f: &MarkerField,
    pre: &MarkerField,
    depth: f64,
) -> StepCues {
    let mut cues = StepCues::default();
    let a = cm.contact_radius_mm(depth) / g.mm_per_px;
    let pure = decompose::subtract(f, pre);
    // Image direction of the shear from the pure field itself.
    let half = 0.5 * g.spacing_px;
    let Some(sh) = decompose::shear(&pure, Some(g.centre_px), half, half) else {
        return cues;
    };
    let dir = [sh.direction_rad.cos(), sh.direction_rad.sin()];
    let (Some(f1), Some(f0)) = (cm.field(at_rest(depth, 1.0)), cm.field(at_rest(depth, 0.0)))
    else {
        return cues;
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
    let along = Component::Along(dir);
    if let Some(fit) = field_force::fit_scale(&pure, &reference, g.centre_px, a, along) {
        cues.scale = fit.scale;
    }
    cues.centre_over_edge =
        decompose::centre_over_edge(&pure, g.centre_px, dir, a, 0.6 * g.spacing_px)
            .unwrap_or(f64::NAN);
    cues.contact_motion = decompose::mean_along_within(&pure, g.centre_px, dir, 0.5 * a)
        .map_or(f64::NAN, |u| u * g.mm_per_px);
    let mm = |p: &decompose::ProfileBin| (p.at_px * g.mm_per_px, p.mean_px * g.mm_per_px);
    cues.profile = Some(sh.central_line.iter().map(mm).collect());
    cues
}

/// A twist: the rotation inside 0.5a over that of the annulus 0.5a–a, and the whole
/// contact's rotation (degrees, in the block's sense).
fn rotation_step(g: &Geometry, f: &MarkerField, pre: &MarkerField, a: f64, sign: f64) -> StepCues {
    let mut cues = StepCues::default();
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
        cues.centre_over_edge = i.angle_rad / o.angle_rad;
    }
    if let Some(w) = whole {
        cues.contact_motion = sign * w.angle_rad.to_degrees();
    }
    cues
}

/// Force from field: the scales calibrated on every other step and predicted on the rest.
fn field_force(model: &RefModel, b: &mut Block, scales: Vec<f64>) {
    if b.kind == Kind::Rotation {
        return;
    }
    let forces: Vec<f64> = b.steps.iter().map(|s| s.force).collect();
    let calibrate: Vec<bool> = (0..b.steps.len()).map(|i| i % 2 == 0).collect();
    let curved = !matches!(
        model.spec.contact.indenter,
        Indenter::FlatCircle { .. } | Indenter::FlatEllipse { .. } | Indenter::FlatRectangle { .. }
    );
    let map = if curved && b.kind == Kind::Normal {
        field_force::Map::Piecewise
    } else {
        field_force::Map::Linear
    };
    if let Some(prediction) = field_force::calibrate_and_predict(&scales, &forces, &calibrate, map)
    {
        b.field_force = Some(FieldForce { scales, prediction });
    }
}

pub(super) fn analyse_fields(
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
    b.displacement_px = displacement_px(&fields);
    let Some(model) = model else {
        return Some("no reference model: force from field and field slip cues skipped".into());
    };
    let g = geometry(data, model, b, &fields)?;
    let (max_depth, ref_depth) = reference_depths(b, relax_depth);
    let mut cm = match ContactModel::build(ModelSpec {
        contact: model.spec.contact.clone(),
        max_depth_mm: max_depth * 1.05,
        shear: b.kind == Kind::Shear,
        twist: false,
        field_view_mm: Some((model.spec.view_width_mm, model.spec.view_height_mm)),
        pressing_friction: false,
        quality: model.spec.quality,
    }) {
        Ok(m) => m,
        Err(e) => return Some(format!("reference model failed: {e}")),
    };
    let n = b.steps.len();
    let (mut scales, mut centre_over_edge, mut contact_motion) =
        (vec![f64::NAN; n], vec![f64::NAN; n], vec![f64::NAN; n]);
    let preload = b.before.and_then(|r| step_field(data, data.steps[r].step));
    for (k, s) in b.steps.iter().enumerate() {
        let Some(f) = fields[k].as_ref() else {
            continue;
        };
        let depth = match b.kind {
            Kind::Normal => s.load.max(1e-3),
            _ => relax_depth,
        };
        let cues = match (b.kind, preload.as_ref()) {
            (Kind::Normal, _) => normal_step(&mut cm, &g, f, ref_depth),
            (Kind::Shear, Some(pre)) => shear_step(&mut cm, &g, f, pre, depth),
            (Kind::Rotation, Some(pre)) => {
                let a = cm.contact_radius_mm(depth) / g.mm_per_px;
                rotation_step(&g, f, pre, a, b.sign)
            }
            (_, None) => continue,
        };
        scales[k] = cues.scale;
        centre_over_edge[k] = cues.centre_over_edge;
        contact_motion[k] = cues.contact_motion;
        if let Some(profile) = cues.profile {
            b.profiles.push((s.step, profile));
        }
    }
    field_force(model, b, scales);
    if b.kind != Kind::Normal
        && let Some(slip) = b.slip.as_mut()
    {
        let mut block = slip_block(&b.steps);
        block.centre_over_edge = Some(centre_over_edge);
        block.contact_motion = Some(contact_motion);
        if let Some(r) = slip::classify(&block, slip_thresholds(b.kind)) {
            slip.report = r;
        }
    }
    None
}

/// The slip cues' thresholds for a block of `kind` (a twist's force cue is the shear's
/// cubed: [`slip::Thresholds::for_torsion`]).
pub(super) fn slip_thresholds(kind: Kind) -> slip::Thresholds {
    match kind {
        Kind::Rotation => slip::Thresholds::default().for_torsion(),
        _ => slip::Thresholds::default(),
    }
}

pub(super) fn slip_block(steps: &[BlockStep]) -> slip::Block {
    let load: Vec<&BlockStep> = steps.iter().filter(|s| !s.unloading).collect();
    slip::Block {
        load: load.iter().map(|s| s.load).collect(),
        tangential: load.iter().map(|s| s.force).collect(),
        normal_n: load.iter().map(|s| s.normal_n).collect(),
        centre_over_edge: None,
        contact_motion: None,
    }
}
