//! The plant's side of a grasp (thesis §6.3): the gel's friction backbones at the grip's
//! depth, stepping the grasped can ([`super::super::grasp`]) with the plant's squeeze, lift
//! and disturbance, and the grasp's loads and ground truth.

use std::f64::consts::PI;

use mechanics::friction::{Backbone, FrictionElement};

use super::Plant;
use crate::grasp::{GelCurves, Grasp, GraspLoads, GraspParams};
use rig::config::AxisRole;
use rig::device::GraspTruth;

/// The gel side's friction backbones at one quantised depth of the grasp.
#[derive(Debug)]
pub(super) struct GraspCurves {
    key: i64,
    elastic_n: f64,
    shear: Option<Backbone>,
    stick: Vec<f64>,
    twist: Option<Backbone>,
    twist_stick: Vec<f64>,
}

/// Depth steps the grasp's backbones are scaled to: 1/200 of the thickness (10 µm on the
/// portable pad), as the field tables are.
const GRASP_DEPTH_STEPS: f64 = 200.0;

/// Depth, as a fraction of the thickness, at which the grasp's backbones are solved once.
const GRASP_REFERENCE_DEPTH: f64 = 0.2;

/// The gel's shear and twist backbones solved once, at the start of a grasping run, at
/// [`GRASP_REFERENCE_DEPTH`], with the normal force and contact half-width there.
///
/// A solve costs tens of milliseconds to a tenth of a second; doing one at every new depth of
/// a loosening grip, under the plant's lock, would stall the force sensor for as long (on a
/// real-time clock the watchdog would call it a dead sensor). Instead the reference curves
/// are scaled: forces (and torques: a strip's moment arm is its fixed length) with the
/// normal force P, displacements (and twist angles) with P/a — Cattaneo–Mindlin's
/// δ* = 3μP(2−ν)/(16Ga) (Johnson §7.2), whose force ratio against δ/δ* and stick fraction
/// against Q/μP do not depend on the depth. On the bonded layer the similarity is
/// approximate (the layer changes κ with a/h).
#[derive(Debug, Clone)]
pub(super) struct GraspReference {
    p_n: f64,
    a_mm: f64,
    shear: Option<(Backbone, Vec<f64>)>,
    twist: Option<(Backbone, Vec<f64>)>,
}

impl GraspReference {
    /// Solves the reference curves on `plant`'s model.
    pub(super) fn solve(plant: &mut Plant) -> Self {
        let h = plant.spec.contact.layer.thickness_mm;
        let d = GRASP_REFERENCE_DEPTH * h;
        Self {
            p_n: plant.elastic_normal_n(d),
            a_mm: plant.model.contact_radius_mm(d),
            shear: plant.model.shear_curve(d),
            twist: plant.model.twist_curve(d),
        }
    }
}

fn scaled(b: &Backbone, sx: f64, sf: f64) -> Backbone {
    Backbone {
        x: b.x.iter().map(|v| v * sx).collect(),
        f: b.f.iter().map(|v| v * sf).collect(),
    }
}

impl Plant {
    pub(super) fn grasp_params(&self) -> Option<GraspParams> {
        self.spec.object_mass_g.map(GraspParams::can)
    }

    /// Moves the grasped can over the interval (thesis §6.3): the gel's backbones at the
    /// present depth, the squeeze, the lift, and any disturbance on the can.
    pub(super) fn grasp_step(&mut self, t0_ns: u64, t1_ns: u64, d: f64, p: f64, kinetic: f64) {
        let (Some(params), Some(lift)) =
            (self.grasp_params(), self.position(AxisRole::Lift, t1_ns))
        else {
            return;
        };
        let h = self.spec.contact.layer.thickness_mm;
        let key = (d / h * GRASP_DEPTH_STEPS).round() as i64;
        if key <= 0 {
            return;
        }
        if self.grasp_curves.as_ref().is_none_or(|c| c.key != key) {
            let dk = key as f64 * h / GRASP_DEPTH_STEPS;
            let elastic_n = self.elastic_normal_n(dk);
            let a = self.model.contact_radius_mm(dk);
            let Some(r) = self.grasp_reference.as_ref() else {
                return;
            };
            let sf = if r.p_n > 0.0 { elastic_n / r.p_n } else { 0.0 };
            let sx = if a > 0.0 && r.p_n > 0.0 {
                (elastic_n / a) / (r.p_n / r.a_mm)
            } else {
                0.0
            };
            self.grasp_curves = Some(GraspCurves {
                key,
                elastic_n,
                stick: r.shear.as_ref().map(|(_, s)| s.clone()).unwrap_or_default(),
                shear: r.shear.as_ref().map(|(b, _)| scaled(b, sx, sf)),
                twist: r.twist.as_ref().map(|(b, _)| scaled(b, sx, sf)),
                twist_stick: r.twist.as_ref().map(|(_, s)| s.clone()).unwrap_or_default(),
            });
        }
        let Some(c) = self.grasp_curves.as_ref() else {
            return;
        };
        let grasp = self.grasp.get_or_insert_with(|| Grasp::new(params, lift));
        let disturbance = self.disturbance;
        let curves = GelCurves {
            shear: c.shear.as_ref(),
            twist: c.twist.as_ref(),
            // The backbones are solved at the quantised depth's elastic force; the present
            // (relaxed, exact-depth) squeeze scales their friction limits.
            scale: if c.elastic_n > 0.0 {
                p / c.elastic_n
            } else {
                0.0
            },
            kinetic,
        };
        let dt_s = (t1_ns - t0_ns) as f64 * 1e-9;
        grasp.advance(dt_s, lift, p, &curves, |into_s| {
            let t = t0_ns + (into_s * 1e9) as u64;
            match disturbance {
                Some(d) if t >= d.t0_ns && t < d.t1_ns => {
                    let phase = 2.0 * PI * d.frequency_hz * (t - d.t0_ns) as f64 * 1e-9;
                    (d.force_y_n * phase.sin(), d.torque_z_nmm * phase.sin())
                }
                _ => (0.0, 0.0),
            }
        });
    }

    /// The grasp's loads while the pads hold the can.
    pub(super) fn grasp_loads(&self) -> Option<GraspLoads> {
        self.grasp
            .as_ref()
            .filter(|_| self.in_contact)
            .map(Grasp::loads)
    }

    /// Ground truth of the grasp: the can's motion, and the gel's stick fractions and friction
    /// margins along the lift and about its normal.
    pub(super) fn grasp_truth(&self) -> Option<GraspTruth> {
        let g = self.grasp.as_ref()?;
        let s = g.state();
        let l = g.loads();
        let c = self.grasp_curves.as_ref();
        // Stick fraction of one of the gel's friction elements: the backbone is solved at the
        // depth's elastic force; the element's force is at the present (relaxed) squeeze, so
        // it is brought back by the capacity ratio before reading the backbone (stick fraction
        // against Q/μP does not depend on the squeeze: Cattaneo–Mindlin similarity).
        let stick = |b: Option<&Backbone>, fr: &[f64], e: &FrictionElement, cap: f64| {
            let Some(b) = b else { return 1.0 };
            if e.sliding() {
                return 0.0;
            }
            if cap <= 0.0 || e.force() == 0.0 {
                return 1.0;
            }
            let scale = cap / b.limit();
            stick_at(b, fr, b.displacement_at(e.force() / scale))
        };
        let margin = |load: f64, cap: f64| {
            if cap > 0.0 {
                1.0 - load.abs() / cap
            } else {
                1.0
            }
        };
        Some(GraspTruth {
            height_mm: s.height_mm,
            slip_mm_s: s.slip_mm_s,
            slid_mm: s.slid_mm,
            angle_deg: s.angle_rad.to_degrees(),
            gel_stick_fraction: stick(
                c.and_then(|c| c.shear.as_ref()),
                c.map_or(&[][..], |c| &c.stick),
                g.gel_element(),
                l.gel_capacity_n,
            ),
            gel_twist_stick_fraction: stick(
                c.and_then(|c| c.twist.as_ref()),
                c.map_or(&[][..], |c| &c.twist_stick),
                g.gel_twist_element(),
                l.gel_capacity_nmm,
            ),
            gel_margin: margin(l.gel_n, l.gel_capacity_n),
            gel_twist_margin: margin(l.gel_nmm, l.gel_capacity_nmm),
            sliding: s.gel_sliding,
            rotating: s.twist_sliding,
            on_table: s.on_table,
            slips: s.slips,
            drops: s.drops,
        })
    }
}

/// Stick fraction at displacement `x` of a backbone whose points have stick fractions `s`.
fn stick_at(b: &Backbone, s: &[f64], x: f64) -> f64 {
    let n = b.x.len().min(s.len());
    if n == 0 {
        return 1.0;
    }
    let xa = x.abs();
    if xa >= b.x[n - 1] {
        return 0.0;
    }
    let i = b.x[..n].partition_point(|v| *v <= xa).clamp(1, n - 1);
    let t = (xa - b.x[i - 1]) / (b.x[i] - b.x[i - 1]);
    s[i - 1] * (1.0 - t) + s[i] * t
}
