//! The simulated elastomer and everything that loads it.

use std::collections::BTreeMap;
use std::f64::consts::PI;

use mechanics::contact::Contact;
use mechanics::{Prony, PronyState, PronyTerm};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rand_distr::StandardNormal;

use crate::RigError;
use crate::config::AxisRole;
use crate::device::{ForceRange, STATUS_SATURATED, Wrench};

/// How markers are laid out on the elastomer (thesis §3.3 and §6.2).
#[derive(Debug, Clone, PartialEq)]
pub enum MarkerLayout {
    /// Regular grid of round dots (box sensor: 18 × 16 dots of 1.4 mm at 2.52 mm).
    Grid {
        /// Markers per row.
        columns: u32,
        /// Rows.
        rows: u32,
        /// Centre-to-centre spacing.
        spacing_mm: f64,
        /// Dot diameter.
        diameter_mm: f64,
    },
    /// Random triangles (portable sensor: 0.7 mm, about 2 mm apart).
    Random {
        /// Mean nearest-neighbour spacing.
        spacing_mm: f64,
        /// Triangle side.
        size_mm: f64,
    },
}

/// Everything the simulated bench needs to know about the sensor and what touches it.
#[derive(Debug, Clone, PartialEq)]
pub struct PlantSpec {
    /// Layer, material and indenter.
    pub contact: Contact,
    /// Marker layout on the elastomer.
    pub markers: MarkerLayout,
    /// Width of the camera's view on the elastomer.
    pub view_width_mm: f64,
    /// Height of the camera's view on the elastomer.
    pub view_height_mm: f64,
    /// Mass of a grasped object (lifting trials), if any.
    pub object_mass_g: Option<f64>,
}

/// Bench geometry from the rig file's `sim:` section.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct BenchGeometry {
    pub normal_contact_mm: f64,
    pub grip_contact_mm: f64,
    pub force_bias_n: f64,
    pub noise: bool,
}

/// A constant-speed move from `from` at `t0_ns` to `to` at `t1_ns`.
#[derive(Debug, Clone, Copy)]
struct Motion {
    from: f64,
    to: f64,
    t0_ns: u64,
    t1_ns: u64,
}

impl Motion {
    fn at_rest(p: f64) -> Self {
        Self {
            from: p,
            to: p,
            t0_ns: 0,
            t1_ns: 0,
        }
    }

    fn position(&self, t_ns: u64) -> f64 {
        if t_ns >= self.t1_ns || self.t1_ns == self.t0_ns {
            self.to
        } else if t_ns <= self.t0_ns {
            self.from
        } else {
            let f = (t_ns - self.t0_ns) as f64 / (self.t1_ns - self.t0_ns) as f64;
            self.from + (self.to - self.from) * f
        }
    }
}

#[derive(Debug, Clone, Copy)]
pub(crate) struct AxisState {
    motion: Motion,
    pub referenced: bool,
    homing: bool,
}

#[derive(Debug, Clone, Copy)]
struct Disturbance {
    t0_ns: u64,
    t1_ns: u64,
    force_y_n: f64,
    torque_z_nmm: f64,
    frequency_hz: f64,
}

/// Snapshot of the surface state the camera renders.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct SurfaceState {
    /// Indentation depth, mm (≤ 0: no contact).
    pub depth_mm: f64,
    /// Effective contact radius, mm.
    pub radius_mm: f64,
    /// Indenter centre relative to the view centre, mm.
    pub centre_x_mm: f64,
    /// Stuck tangential displacement of the contact along x, mm.
    pub stick_x_mm: f64,
    /// Stuck twist of the contact, rad.
    pub stick_twist_rad: f64,
}

/// Largest integration step while anything moves, so depth-nonlinear laws stay accurate.
const MAX_MOVING_STEP_NS: u64 = 5_000_000;
/// Fraction of the thickness beyond which the indenter is treated as hitting the base.
const BASE_CONTACT_FRACTION: f64 = 0.98;
/// Stiffness of the acrylic base once reached, N/mm: far beyond any sensor range.
const BASE_STIFFNESS_N_PER_MM: f64 = 1e4;
/// Lift over which the table's support of a grasped object hands over to the grasp, mm.
const TABLE_HANDOVER_MM: f64 = 0.5;
const GRAVITY_M_S2: f64 = 9.81;

/// The simulated elastomer, its indenter, and the stage positions that load it.
#[derive(Debug)]
pub(crate) struct Plant {
    spec: PlantSpec,
    geometry: BenchGeometry,
    prony: Prony,
    axes: BTreeMap<AxisRole, AxisState>,
    t_ns: u64,
    normal: PronyState,
    shear: PronyState,
    twist: PronyState,
    shear_anchor_mm: f64,
    twist_anchor_rad: f64,
    shear_at_contact_mm: f64,
    in_contact: bool,
    object_rest_lift_mm: Option<f64>,
    object_slips: u32,
    disturbance: Option<Disturbance>,
    bias: Wrench,
    rng: StdRng,
}

impl Plant {
    pub(crate) fn new(
        spec: PlantSpec,
        geometry: BenchGeometry,
        seed: u64,
    ) -> Result<Self, RigError> {
        let terms: Vec<PronyTerm> = spec.contact.material.prony.clone();
        let prony = Prony::new(terms).map_err(|e| RigError::Plant(e.to_string()))?;
        let mut rng = StdRng::seed_from_u64(seed);
        let b = geometry.force_bias_n;
        let mut draw = |scale: f64| (rng.random::<f64>() * 2.0 - 1.0) * b * scale;
        let bias = Wrench {
            fx_n: draw(1.0),
            fy_n: draw(1.0),
            fz_n: draw(1.0),
            tx_nmm: draw(5.0),
            ty_nmm: draw(5.0),
            tz_nmm: draw(5.0),
        };
        Ok(Self {
            normal: prony.state(),
            shear: prony.state(),
            twist: prony.state(),
            prony,
            spec,
            geometry,
            axes: BTreeMap::new(),
            t_ns: 0,
            shear_anchor_mm: 0.0,
            twist_anchor_rad: 0.0,
            shear_at_contact_mm: 0.0,
            in_contact: false,
            object_rest_lift_mm: None,
            object_slips: 0,
            disturbance: None,
            bias,
            rng: StdRng::seed_from_u64(seed.wrapping_add(0x9E37_79B9_7F4A_7C15)),
        })
    }

    pub(crate) fn spec(&self) -> &PlantSpec {
        &self.spec
    }

    pub(crate) fn add_axis(&mut self, role: AxisRole, start: f64) {
        self.axes.insert(
            role,
            AxisState {
                motion: Motion::at_rest(start),
                referenced: false,
                homing: false,
            },
        );
    }

    pub(crate) fn axis(&self, role: AxisRole) -> Option<AxisState> {
        self.axes.get(&role).copied()
    }

    fn position(&self, role: AxisRole, t_ns: u64) -> Option<f64> {
        self.axes.get(&role).map(|a| a.motion.position(t_ns))
    }

    /// Position and motion state of an axis at `t_ns` (advancing the plant first).
    pub(crate) fn axis_status(&mut self, role: AxisRole, t_ns: u64) -> Option<(f64, bool, bool)> {
        self.advance_to(t_ns);
        let a = self.axes.get_mut(&role)?;
        let moving = t_ns < a.motion.t1_ns;
        if !moving && a.homing {
            a.homing = false;
            a.referenced = true;
        }
        Some((a.motion.position(t_ns), moving, a.referenced))
    }

    /// Starts a constant-speed move of `role` to `target` at `speed` (units/s) at `t_ns`.
    pub(crate) fn start_move(
        &mut self,
        role: AxisRole,
        target: f64,
        speed: f64,
        t_ns: u64,
        homing: bool,
    ) {
        self.advance_to(t_ns);
        if let Some(a) = self.axes.get_mut(&role) {
            let from = a.motion.position(t_ns);
            let dur_ns = ((target - from).abs() / speed * 1e9).round() as u64;
            a.motion = Motion {
                from,
                to: target,
                t0_ns: t_ns,
                t1_ns: t_ns + dur_ns,
            };
            a.homing = homing;
            if homing {
                a.referenced = false;
            }
        }
    }

    /// Stops `role` where it is at `t_ns`, on the nearest step of its `resolution`.
    pub(crate) fn stop(&mut self, role: AxisRole, t_ns: u64, resolution: f64) {
        self.advance_to(t_ns);
        if let Some(a) = self.axes.get_mut(&role) {
            let p = a.motion.position(t_ns);
            let p = if resolution > 0.0 {
                (p / resolution).round() * resolution
            } else {
                p
            };
            a.motion = Motion::at_rest(p);
            a.motion.t0_ns = t_ns;
            a.motion.t1_ns = t_ns;
            a.homing = false;
        }
    }

    pub(crate) fn disturb(
        &mut self,
        t_ns: u64,
        force_y_n: f64,
        torque_z_nmm: f64,
        frequency_hz: f64,
        duration_s: f64,
    ) {
        self.advance_to(t_ns);
        self.disturbance = Some(Disturbance {
            t0_ns: t_ns,
            t1_ns: t_ns + (duration_s.max(0.0) * 1e9) as u64,
            force_y_n,
            torque_z_nmm,
            frequency_hz,
        });
    }

    /// Which axis presses the indenter (or the grasped object) into the elastomer.
    fn pressing_axis(&self) -> Option<(AxisRole, f64)> {
        if self.axes.contains_key(&AxisRole::Normal) {
            Some((AxisRole::Normal, self.geometry.normal_contact_mm))
        } else if self.axes.contains_key(&AxisRole::Grip) {
            Some((AxisRole::Grip, self.geometry.grip_contact_mm))
        } else {
            None
        }
    }

    fn depth_at(&self, t_ns: u64) -> f64 {
        match self.pressing_axis() {
            Some((role, contact)) => self
                .position(role, t_ns)
                .map(|p| p - contact)
                .unwrap_or(0.0),
            None => 0.0,
        }
    }

    /// Long-term elastic normal force at depth `d`, saturating on the rigid base.
    fn elastic_normal_n(&self, d: f64) -> f64 {
        let h = self.spec.contact.layer.thickness_mm;
        let d_max = BASE_CONTACT_FRACTION * h;
        let d_el = d.min(d_max);
        let f = self.spec.contact.normal_force_n(d_el).unwrap_or(0.0);
        f + BASE_STIFFNESS_N_PER_MM * (d - d_max).max(0.0)
    }

    /// Integrates the plant's hereditary state up to `t_ns`, splitting at the end of every
    /// move (positions are piecewise linear, so each piece is exact for the flat punch) and
    /// into steps of at most 5 ms while anything moves.
    pub(crate) fn advance_to(&mut self, t_ns: u64) {
        while self.t_ns < t_ns {
            let mut next = t_ns;
            let mut moving = false;
            for a in self.axes.values() {
                if a.motion.t1_ns > self.t_ns {
                    moving = true;
                    next = next.min(a.motion.t1_ns);
                }
            }
            if let Some(d) = self.disturbance
                && d.t1_ns > self.t_ns
            {
                moving = true;
                next = next.min(d.t1_ns);
            }
            if moving {
                next = next.min(self.t_ns + MAX_MOVING_STEP_NS);
            }
            self.integrate(next);
        }
    }

    fn integrate(&mut self, t1_ns: u64) {
        let dt_s = (t1_ns - self.t_ns) as f64 * 1e-9;
        self.t_ns = t1_ns;
        let d = self.depth_at(t1_ns);
        let shear_pos = self.position(AxisRole::Shear, t1_ns).unwrap_or(0.0);
        let twist_pos = self
            .position(AxisRole::Rotation, t1_ns)
            .unwrap_or(0.0)
            .to_radians();
        if d <= 0.0 {
            // Out of contact: the elastomer recovers; tangential loads vanish with contact.
            self.normal.advance_linear(&self.prony, dt_s, 0.0);
            self.shear = self.prony.state();
            self.twist = self.prony.state();
            self.shear_anchor_mm = shear_pos;
            self.twist_anchor_rad = twist_pos;
            self.in_contact = false;
            self.object_rest_lift_mm = None;
            return;
        }
        if !self.in_contact {
            self.in_contact = true;
            self.shear_at_contact_mm = shear_pos;
            self.shear_anchor_mm = shear_pos;
            self.twist_anchor_rad = twist_pos;
        }
        let f_e = self.elastic_normal_n(d);
        self.normal.advance_linear(&self.prony, dt_s, f_e);
        let p = self.normal.value().max(0.0);
        let contact = &self.spec.contact;
        // Coulomb spring-slider on each tangential channel: stick until the limit, then
        // slip with the anchor following (the partial-slip model is the physics issue's).
        let k_t = contact.tangential_stiffness_n_per_mm(d.min(0.98 * contact.layer.thickness_mm));
        let drive = k_t * (shear_pos - self.shear_anchor_mm);
        self.shear.advance_linear(&self.prony, dt_s, drive);
        let limit = contact.slip_force_n(p);
        let q = self.shear.value();
        if q.abs() > limit && k_t > 0.0 {
            self.shear
                .scale(if q == 0.0 { 0.0 } else { limit / q.abs() });
            self.shear_anchor_mm = shear_pos - self.shear.driving() / k_t;
        }
        let k_r = contact.torsional_stiffness_nmm_per_rad(d.min(0.98 * contact.layer.thickness_mm));
        let drive = k_r * (twist_pos - self.twist_anchor_rad);
        self.twist.advance_linear(&self.prony, dt_s, drive);
        let limit = contact.slip_torque_nmm(p, d);
        let t = self.twist.value();
        if t.abs() > limit && k_r > 0.0 {
            self.twist
                .scale(if t == 0.0 { 0.0 } else { limit / t.abs() });
            self.twist_anchor_rad = twist_pos - self.twist.driving() / k_r;
        }
        // A grasped object rests on the table until lifted; then each of the two fingers
        // carries half its weight, up to the friction limit (thesis §6.3.1).
        if let (Some(mass_g), Some(lift)) = (
            self.spec.object_mass_g,
            self.position(AxisRole::Lift, t1_ns),
        ) {
            let rest = *self.object_rest_lift_mm.get_or_insert(lift);
            let share = ((lift - rest) / TABLE_HANDOVER_MM).clamp(0.0, 1.0);
            let weight_n = mass_g * 1e-3 * GRAVITY_M_S2 / 2.0 * share;
            if weight_n > contact.slip_force_n(p) {
                // The object slides out of the grasp and falls back onto the table.
                self.object_rest_lift_mm = Some(lift);
                self.object_slips += 1;
            }
        }
    }

    /// Weight share carried by the grasp at the current time, N (0 without an object).
    fn object_load_n(&self) -> f64 {
        match (
            self.spec.object_mass_g,
            self.position(AxisRole::Lift, self.t_ns),
            self.object_rest_lift_mm,
        ) {
            (Some(m), Some(lift), Some(rest)) if self.in_contact => {
                m * 1e-3 * GRAVITY_M_S2 / 2.0 * ((lift - rest) / TABLE_HANDOVER_MM).clamp(0.0, 1.0)
            }
            _ => 0.0,
        }
    }

    /// The true wrench at the plant's current time, before sensor effects.
    pub(crate) fn true_wrench(&self) -> Wrench {
        let mut fy = self.object_load_n();
        let mut tz = self.twist.value();
        if let Some(d) = self.disturbance
            && self.t_ns >= d.t0_ns
            && self.t_ns < d.t1_ns
            && self.in_contact
        {
            let phase = 2.0 * PI * d.frequency_hz * (self.t_ns - d.t0_ns) as f64 * 1e-9;
            fy += d.force_y_n * phase.sin();
            tz += d.torque_z_nmm * phase.sin();
        }
        Wrench {
            fx_n: self.shear.value(),
            fy_n: fy,
            fz_n: self.normal.value().max(0.0),
            tx_nmm: 0.0,
            ty_nmm: 0.0,
            tz_nmm: tz,
        }
    }

    /// Reads the simulated sensor at `t_ns`: true wrench plus bias, noise at the sensor's
    /// resolution, quantisation to it, and clipping with the saturation flag.
    pub(crate) fn sense(&mut self, t_ns: u64, range: &ForceRange) -> (Wrench, u32) {
        self.advance_to(t_ns);
        let truth = self.true_wrench();
        let mut status = 0;
        let noise = self.geometry.noise;
        let mut channel = |v: f64, bias: f64, res: f64, lim: f64, rng: &mut StdRng| -> f64 {
            let z: f64 = if noise {
                rng.sample(StandardNormal)
            } else {
                0.0
            };
            let raw = ((v + bias + z * res) / res).round() * res;
            if raw.abs() > lim {
                status |= STATUS_SATURATED;
                raw.signum() * lim
            } else {
                raw
            }
        };
        let (fr, tr) = (range.force_resolution_n, range.torque_resolution_nmm);
        let b = self.bias;
        let rng = &mut self.rng;
        let w = Wrench {
            fx_n: channel(truth.fx_n, b.fx_n, fr, range.fxy_n, rng),
            fy_n: channel(truth.fy_n, b.fy_n, fr, range.fxy_n, rng),
            fz_n: channel(truth.fz_n, b.fz_n, fr, range.fz_n, rng),
            tx_nmm: channel(truth.tx_nmm, b.tx_nmm, tr, range.torque_nmm, rng),
            ty_nmm: channel(truth.ty_nmm, b.ty_nmm, tr, range.torque_nmm, rng),
            tz_nmm: channel(truth.tz_nmm, b.tz_nmm, tr, range.torque_nmm, rng),
        };
        (w, status)
    }

    /// The surface state at `t_ns`, for the camera.
    pub(crate) fn surface(&mut self, t_ns: u64) -> SurfaceState {
        self.advance_to(t_ns);
        let d = self.depth_at(t_ns);
        let shear_pos = self.position(AxisRole::Shear, t_ns).unwrap_or(0.0);
        let twist_pos = self
            .position(AxisRole::Rotation, t_ns)
            .unwrap_or(0.0)
            .to_radians();
        if d <= 0.0 {
            return SurfaceState {
                depth_mm: d,
                radius_mm: 0.0,
                centre_x_mm: 0.0,
                stick_x_mm: 0.0,
                stick_twist_rad: 0.0,
            };
        }
        SurfaceState {
            depth_mm: d,
            radius_mm: self.spec.contact.contact_radius_mm(d),
            centre_x_mm: shear_pos - self.shear_at_contact_mm,
            stick_x_mm: shear_pos - self.shear_anchor_mm,
            stick_twist_rad: -(twist_pos - self.twist_anchor_rad),
        }
    }

    /// How many times a grasped object slipped out of the grasp (ground truth for tests).
    #[cfg(test)]
    pub(crate) fn object_slips(&self) -> u32 {
        self.object_slips
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mechanics::{Indenter, Layer, Material};

    fn plant(indenter: Indenter, prony: Vec<PronyTerm>, mass: Option<f64>) -> Plant {
        let contact = Contact::new(
            Layer {
                width_mm: 125.0,
                length_mm: 70.0,
                thickness_mm: 4.2,
            },
            Material {
                youngs_modulus_mpa: 0.25,
                poisson_ratio: 0.5,
                prony,
                friction: 1.0,
            },
            indenter,
        )
        .expect("valid");
        let spec = PlantSpec {
            contact,
            markers: MarkerLayout::Grid {
                columns: 18,
                rows: 16,
                spacing_mm: 2.52,
                diameter_mm: 1.4,
            },
            view_width_mm: 45.4,
            view_height_mm: 40.3,
            object_mass_g: mass,
        };
        let geometry = BenchGeometry {
            normal_contact_mm: 10.0,
            grip_contact_mm: 10.0,
            force_bias_n: 0.0,
            noise: false,
        };
        Plant::new(spec, geometry, 1).expect("plant")
    }

    const S: u64 = 1_000_000_000;

    #[test]
    fn step_relaxes_to_the_elastic_force() {
        let prony = vec![PronyTerm {
            weight: 0.5,
            tau_s: 10.0,
        }];
        let mut p = plant(Indenter::FlatCircle { diameter_mm: 9.5 }, prony, None);
        p.add_axis(AxisRole::Normal, 10.0);
        p.start_move(AxisRole::Normal, 10.084, 1.0, 0, false);
        p.advance_to(S / 10);
        let peak = p.true_wrench().fz_n;
        p.advance_to(600 * S);
        let relaxed = p.true_wrench().fz_n;
        let elastic = p.spec.contact.normal_force_n(0.084).expect("ok");
        assert!(
            (relaxed - elastic).abs() < 1e-9 * elastic,
            "{relaxed} vs {elastic}"
        );
        assert!(peak > 1.4 * elastic && peak < 1.5 * elastic, "peak {peak}");
    }

    #[test]
    fn shear_saturates_at_the_coulomb_limit() {
        let mut p = plant(Indenter::FlatCircle { diameter_mm: 12.68 }, vec![], None);
        p.add_axis(AxisRole::Normal, 10.0);
        p.add_axis(AxisRole::Shear, 0.0);
        p.start_move(AxisRole::Normal, 10.42, 1.0, 0, false);
        p.advance_to(S);
        let fz = p.true_wrench().fz_n;
        p.start_move(AxisRole::Shear, 0.01, 1.0, S, false);
        p.advance_to(2 * S);
        let small = p.true_wrench().fx_n;
        assert!(small > 0.0 && small < fz);
        p.start_move(AxisRole::Shear, 20.0, 5.0, 2 * S, false);
        p.advance_to(10 * S);
        assert!((p.true_wrench().fx_n - fz).abs() < 1e-9, "slip force = μP");
    }

    #[test]
    fn lifted_object_hangs_until_the_grip_is_too_light() {
        let mut p = plant(
            Indenter::Cylinder {
                diameter_mm: 57.2,
                length_mm: 100.0,
            },
            vec![],
            Some(100.0),
        );
        p.add_axis(AxisRole::Grip, 0.0);
        p.add_axis(AxisRole::Lift, 0.0);
        p.start_move(AxisRole::Grip, 10.2, 1.0, 0, false);
        p.advance_to(20 * S);
        p.start_move(AxisRole::Lift, 20.0, 10.0, 20 * S, false);
        p.advance_to(30 * S);
        let w = p.true_wrench();
        assert!((w.fy_n - 0.1 * 9.81 / 2.0).abs() < 1e-9, "{w:?}");
        assert_eq!(p.object_slips(), 0);
        // Open the grip until friction cannot hold the can.
        p.start_move(AxisRole::Grip, 10.0001, 1.0, 30 * S, false);
        p.advance_to(40 * S);
        assert!(p.object_slips() > 0);
        assert!(p.true_wrench().fy_n < 0.1 * 9.81 / 2.0);
    }

    #[test]
    fn pressing_on_the_base_saturates_the_sensor_instead_of_nan() {
        let mut p = plant(Indenter::FlatCircle { diameter_mm: 9.5 }, vec![], None);
        p.add_axis(AxisRole::Normal, 10.0);
        p.start_move(AxisRole::Normal, 15.0, 1.0, 0, false);
        let (w, status) = p.sense(10 * S, &ForceRange::NANO17);
        assert!(w.fz_n.is_finite());
        assert_eq!(w.fz_n, 70.0);
        assert_ne!(status & STATUS_SATURATED, 0);
    }
}
