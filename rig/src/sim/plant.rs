//! The simulated elastomer and everything that loads it.
//!
//! Stage positions go in; a Nano17 reading, ground truth and the surface field come out.
//! The elastic response is a [`ContactModel`] precomputed by the layer solvers of
//! `mechanics` for exactly what the run needs (shear tables only if the shear stage is
//! opened, fields only if the camera is). On top of it:
//! - **viscoelasticity**: every channel's elastic (long-term) force drives a Prony
//!   hereditary state with the exact exponential update, so a step relaxes and loading
//!   sits above unloading (Lee–Radok form, spec §3);
//! - **friction**: shear and twist go through Masing friction elements on the solver's
//!   partial-slip backbones, saturate at the static limit μP, slide at the kinetic limit and
//!   stick again when the stage stops (the stick-slip steps of thesis Fig. 4-16);
//! - **sensor**: a per-seed offset, Gaussian noise at the Nano17's resolution, quantisation
//!   and clipping with a status flag beyond its range;
//! - **grasping**: a lifted object's weight passes to the grasp and slips out when μP
//!   cannot hold it (thesis §6.3).

use std::collections::BTreeMap;
use std::f64::consts::PI;

use mechanics::contact::Contact;
use mechanics::friction::{Backbone, FrictionElement};
use mechanics::response::{ContactModel, ModelSpec, Quality, State};
use mechanics::{Prony, PronyState, PronyTerm};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rand_distr::StandardNormal;

use crate::RigError;
use crate::config::AxisRole;
use crate::device::{ForceRange, STATUS_SATURATED, SimTruth, Wrench};

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
    /// Deepest indentation the run can reach, mm (the contact tables stop there).
    pub max_depth_mm: f64,
    /// Sliding (kinetic) friction coefficient, at most the static one.
    pub kinetic_friction: f64,
    /// Resolution of the contact model.
    pub quality: Quality,
}

/// Bench geometry from the rig file's `sim:` section.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct BenchGeometry {
    pub normal_contact_mm: f64,
    pub grip_contact_mm: f64,
    pub force_bias_n: f64,
    pub noise: bool,
}

impl BenchGeometry {
    /// The rig file's `sim:` section, which a simulated `what` cannot do without.
    pub(crate) fn of(config: &crate::config::RigConfig, what: &str) -> Result<Self, RigError> {
        let sim = config.sim.as_ref().ok_or_else(|| RigError::Unsupported {
            device: what.to_string(),
            detail: format!(
                "rig `{}` has simulated devices but no `sim:` section",
                config.name
            ),
        })?;
        Ok(Self {
            normal_contact_mm: sim.normal_contact.mm(),
            grip_contact_mm: sim
                .grip_contact
                .map(|l| l.mm())
                .unwrap_or(sim.normal_contact.mm()),
            force_bias_n: sim.force_bias.map(|f| f.n()).unwrap_or(0.0),
            noise: sim.noise.unwrap_or(true),
        })
    }
}

/// What the opened devices need from the plant.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub(crate) struct PlantNeeds {
    pub shear: bool,
    pub twist: bool,
    pub fields: bool,
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
    fn at_rest(p: f64, t_ns: u64) -> Self {
        Self {
            from: p,
            to: p,
            t0_ns: t_ns,
            t1_ns: t_ns,
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
    /// Driven from outside ([`Plant::follow`]) and moved during the last interval: the
    /// stage is still travelling at the interval's end, so friction must not re-stick.
    followed_moving: bool,
}

#[derive(Debug, Clone, Copy)]
struct Disturbance {
    t0_ns: u64,
    t1_ns: u64,
    force_y_n: f64,
    torque_z_nmm: f64,
    frequency_hz: f64,
}

/// One tangential channel: its friction element, its hereditary state, its backbone.
#[derive(Debug)]
struct Channel {
    element: FrictionElement,
    state: PronyState,
    origin: f64,
    last_pos: f64,
    curve: Option<(f64, Backbone, Vec<f64>)>,
}

/// Largest integration step while anything moves, so depth-nonlinear laws stay accurate.
const MAX_MOVING_STEP_NS: u64 = 5_000_000;
/// Fraction of the thickness beyond which the indenter is treated as hitting the base.
const BASE_CONTACT_FRACTION: f64 = 0.95;
/// Stiffness of the acrylic base once reached, N/mm: far beyond any sensor range.
const BASE_STIFFNESS_N_PER_MM: f64 = 1e4;
/// Lift over which the table's support of a grasped object hands over to the grasp, mm.
const TABLE_HANDOVER_MM: f64 = 0.5;
const GRAVITY_M_S2: f64 = 9.81;

/// The contact's state and its placement in the camera view at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct SurfacePose {
    /// Depth and the elastic tangential loads the field is computed for.
    pub(crate) state: State,
    /// Where the contact centre has slipped to, mm.
    pub(crate) centre_mm: (f64, f64),
    /// How far the contact has turned by slipping, rad.
    pub(crate) rotation_rad: f64,
}

/// The simulated elastomer, its indenter, and the stage positions that load it.
#[derive(Debug)]
pub(crate) struct Plant {
    spec: PlantSpec,
    geometry: BenchGeometry,
    prony: Prony,
    model: ContactModel,
    axes: BTreeMap<AxisRole, AxisState>,
    t_ns: u64,
    normal: PronyState,
    shear: Option<Channel>,
    twist: Option<Channel>,
    needs: PlantNeeds,
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
        needs: PlantNeeds,
        seed: u64,
    ) -> Result<Self, RigError> {
        let terms: Vec<PronyTerm> = spec.contact.material.prony.clone();
        let prony = Prony::new(terms).map_err(|e| RigError::Plant(e.to_string()))?;
        let model = ContactModel::build(ModelSpec {
            contact: spec.contact.clone(),
            max_depth_mm: spec.max_depth_mm,
            shear: needs.shear,
            twist: needs.twist,
            field_view_mm: needs
                .fields
                .then_some((spec.view_width_mm, spec.view_height_mm)),
            quality: spec.quality,
        })
        .map_err(|e| RigError::Plant(e.to_string()))?;
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
            prony,
            model,
            spec,
            geometry,
            needs,
            axes: BTreeMap::new(),
            t_ns: 0,
            shear: None,
            twist: None,
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
                motion: Motion::at_rest(start, self.t_ns),
                referenced: false,
                homing: false,
                followed_moving: false,
            },
        );
    }

    pub(crate) fn axis(&self, role: AxisRole) -> Option<AxisState> {
        self.axes.get(&role).copied()
    }

    fn position(&self, role: AxisRole, t_ns: u64) -> Option<f64> {
        self.axes.get(&role).map(|a| a.motion.position(t_ns))
    }

    fn moving(&self, role: AxisRole, t_ns: u64) -> bool {
        self.axes
            .get(&role)
            .is_some_and(|a| t_ns < a.motion.t1_ns || a.followed_moving)
    }

    /// Moves the stages to where something outside says they are at `t_ns` (the wire
    /// twins of `gelrig sim serve`), linearly from where they were at the plant's last
    /// time, and integrates up to `t_ns`. An axis seen for the first time starts there.
    /// `stopped`: the reporter knows the stages have come to rest there (a driver's
    /// status), so friction re-sticks now rather than at the next report; without it a
    /// stage counts as moving until a report finds it where the last one did.
    pub(crate) fn follow(&mut self, positions: &[(AxisRole, f64)], t_ns: u64, stopped: bool) {
        let t0 = self.t_ns;
        let t1 = t_ns.max(t0);
        for &(role, p) in positions {
            let a = self.axes.entry(role).or_insert(AxisState {
                motion: Motion::at_rest(p, t0),
                referenced: true,
                homing: false,
                followed_moving: false,
            });
            let from = a.motion.position(t0);
            // A stage at rest is integrated in one exact step, a moving one in short ones.
            a.followed_moving = from != p;
            a.motion = if a.followed_moving {
                Motion {
                    from,
                    to: p,
                    t0_ns: t0,
                    t1_ns: t1,
                }
            } else {
                Motion::at_rest(p, t0)
            };
        }
        self.advance_to(t1);
        if stopped {
            for &(role, p) in positions {
                if let Some(a) = self.axes.get_mut(&role) {
                    a.followed_moving = false;
                    a.motion = Motion::at_rest(p, t1);
                }
            }
        }
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
            a.motion = Motion::at_rest(p, t_ns);
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
        self.model.normal_force_n(d.min(d_max)) + BASE_STIFFNESS_N_PER_MM * (d - d_max).max(0.0)
    }

    /// Integrates the plant's hereditary state up to `t_ns`, splitting at the end of every
    /// move and into steps of at most 5 ms while anything moves.
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

    /// The backbone of a tangential channel at depth `d`, recomputed only when the depth
    /// changed.
    fn curve(
        model: &mut ContactModel,
        shear: bool,
        d: f64,
        cached: &mut Option<(f64, Backbone, Vec<f64>)>,
    ) {
        let stale = cached
            .as_ref()
            .is_none_or(|(cd, _, _)| (cd - d).abs() > 1e-9);
        if stale {
            let c = if shear {
                model.shear_curve(d)
            } else {
                model.twist_curve(d)
            };
            *cached = c.map(|(b, s)| (d, b, s));
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
            self.shear = None;
            self.twist = None;
            self.in_contact = false;
            self.object_rest_lift_mm = None;
            return;
        }
        if !self.in_contact {
            self.in_contact = true;
            let fresh = |x: f64, prony: &Prony| Channel {
                element: FrictionElement::at(x),
                state: prony.state(),
                origin: x,
                last_pos: x,
                curve: None,
            };
            self.shear = self.needs.shear.then(|| fresh(shear_pos, &self.prony));
            self.twist = self.needs.twist.then(|| fresh(twist_pos, &self.prony));
        }
        let f_e = self.elastic_normal_n(d);
        self.normal.advance_linear(&self.prony, dt_s, f_e);
        let p = self.normal.value().max(0.0);
        let mu = self.spec.contact.material.friction;
        let kinetic = if mu > 0.0 {
            (self.spec.kinetic_friction / mu).clamp(0.0, 1.0)
        } else {
            1.0
        };
        let d_el = d.min(BASE_CONTACT_FRACTION * self.spec.contact.layer.thickness_mm);
        let shear_moving = self.moving(AxisRole::Shear, t1_ns);
        let twist_moving = self.moving(AxisRole::Rotation, t1_ns);
        for (channel, pos, moving, is_shear) in [
            (&mut self.shear, shear_pos, shear_moving, true),
            (&mut self.twist, twist_pos, twist_moving, false),
        ] {
            let Some(ch) = channel.as_mut() else {
                continue;
            };
            // The backbone is only needed when the tangential stage moves; it is refreshed
            // then if the depth changed (solving it costs milliseconds to a second).
            if pos != ch.last_pos {
                Self::curve(&mut self.model, is_shear, d_el, &mut ch.curve);
                ch.last_pos = pos;
            }
            let Some((_, backbone, _)) = ch.curve.as_ref() else {
                ch.state.advance_linear(&self.prony, dt_s, 0.0);
                continue;
            };
            let q_e = ch.element.update(pos, backbone, 1.0, kinetic);
            if !moving {
                ch.element.rest();
            }
            ch.state.advance_linear(&self.prony, dt_s, q_e);
            // The viscoelastic overshoot may not exceed the (viscoelastic) friction limit.
            let limit = if f_e > 0.0 {
                backbone.limit() * p / f_e
            } else {
                0.0
            };
            ch.state.cap_hereditary(limit);
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
            if weight_n > mu * p {
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
        let mut tz = self.twist.as_ref().map(|c| c.state.value()).unwrap_or(0.0);
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
            fx_n: self.shear.as_ref().map(|c| c.state.value()).unwrap_or(0.0),
            fy_n: fy,
            fz_n: self.normal.value().max(0.0),
            tx_nmm: 0.0,
            ty_nmm: 0.0,
            tz_nmm: tz,
        }
    }

    /// Ground truth at `t_ns`: depth, the wrench without sensor effects, the long-term
    /// (equilibrium) wrench of the present state, and the contact's slip state.
    pub(crate) fn truth(&mut self, t_ns: u64) -> SimTruth {
        self.advance_to(t_ns);
        let d = self.depth_at(t_ns);
        let stick = |c: &Option<Channel>| -> Option<f64> {
            let c = c.as_ref()?;
            let (_, b, s) = c.curve.as_ref()?;
            let x = b.displacement_at(c.element.force());
            let n = b.x.len();
            if n == 0 {
                return None;
            }
            let xa = x.abs();
            if xa >= b.x[n - 1] || c.element.sliding() {
                return Some(0.0);
            }
            let i = b.x.partition_point(|v| *v <= xa).clamp(1, n - 1);
            let t = (xa - b.x[i - 1]) / (b.x[i] - b.x[i - 1]);
            Some(s[i - 1] * (1.0 - t) + s[i] * t)
        };
        let h = self.spec.contact.layer.thickness_mm;
        SimTruth {
            depth_mm: d,
            wrench: self.true_wrench(),
            equilibrium: Wrench {
                fx_n: self
                    .shear
                    .as_ref()
                    .map(|c| c.element.force())
                    .unwrap_or(0.0),
                fy_n: self.object_load_n(),
                fz_n: if d > 0.0 {
                    self.elastic_normal_n(d)
                } else {
                    0.0
                },
                tx_nmm: 0.0,
                ty_nmm: 0.0,
                tz_nmm: self
                    .twist
                    .as_ref()
                    .map(|c| c.element.force())
                    .unwrap_or(0.0),
            },
            contact_radius_mm: if d > 0.0 {
                self.model.contact_radius_mm(d.min(0.95 * h))
            } else {
                0.0
            },
            shear_stick_fraction: stick(&self.shear),
            twist_stick_fraction: stick(&self.twist),
            shear_sliding: self.shear.as_ref().is_some_and(|c| c.element.sliding()),
            twist_sliding: self.twist.as_ref().is_some_and(|c| c.element.sliding()),
            shear_slips: self.shear.as_ref().map(|c| c.element.slips()).unwrap_or(0),
            twist_slips: self.twist.as_ref().map(|c| c.element.slips()).unwrap_or(0),
            object_slips: self.object_slips,
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

    /// A copy of the contact model, for a camera to compute surface fields from without
    /// holding the plant (a field can take most of a second to compute the first time,
    /// and the force sensor must not wait for it, as it would not on a real bench).
    pub(crate) fn field_model(&self) -> ContactModel {
        self.model.clone()
    }

    /// The contact state at `t_ns` and where it sits in the camera view: what a field is
    /// computed from.
    pub(crate) fn surface_pose(&mut self, t_ns: u64) -> SurfacePose {
        self.advance_to(t_ns);
        let d = self.depth_at(t_ns);
        let h = self.spec.contact.layer.thickness_mm;
        let shear_pos = self.position(AxisRole::Shear, t_ns).unwrap_or(0.0);
        let twist_pos = self
            .position(AxisRole::Rotation, t_ns)
            .unwrap_or(0.0)
            .to_radians();
        let (mut slip_x, mut shear_n) = (0.0, 0.0);
        if let Some(c) = &self.shear
            && let Some((_, b, _)) = &c.curve
        {
            shear_n = c.element.force();
            slip_x = (shear_pos - c.origin) - b.displacement_at(shear_n);
        }
        let (mut slip_theta, mut torque) = (0.0, 0.0);
        if let Some(c) = &self.twist
            && let Some((_, b, _)) = &c.curve
        {
            torque = c.element.force();
            slip_theta = (twist_pos - c.origin) - b.displacement_at(torque);
        }
        // The sensor turns under a fixed indenter: relative to the gel the indenter turns
        // the other way, so the field's twist (and its slipped rotation) change sign.
        SurfacePose {
            state: State {
                depth_mm: d.min(0.95 * h),
                shear_n,
                torque_nmm: -torque,
            },
            centre_mm: (slip_x, 0.0),
            rotation_rad: -slip_theta,
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
    use mechanics::{Indenter, Material};

    fn plant(
        indenter: Indenter,
        prony: Vec<PronyTerm>,
        mass: Option<f64>,
        needs: PlantNeeds,
    ) -> Plant {
        let contact = Contact::new(
            mechanics::geometry::presets::BOX_LAYER,
            Material {
                youngs_modulus_mpa: 0.25,
                poisson_ratio: 0.49,
                prony,
                friction: 0.6,
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
            max_depth_mm: 1.0,
            kinetic_friction: 0.5,
            quality: Quality::default(),
        };
        let geometry = BenchGeometry {
            normal_contact_mm: 10.0,
            grip_contact_mm: 10.0,
            force_bias_n: 0.0,
            noise: false,
        };
        Plant::new(spec, geometry, needs, 1).expect("plant")
    }

    const S: u64 = 1_000_000_000;

    /// A followed stage counts as moving until it is reported stopped, or found again
    /// where it was last reported.
    #[test]
    fn a_followed_stage_rests_when_reported_stopped() {
        let flat = Indenter::FlatCircle { diameter_mm: 9.5 };
        let n = AxisRole::Normal;
        for stopped in [false, true] {
            let mut p = plant(flat, vec![], None, PlantNeeds::default());
            p.follow(&[(n, 9.0)], 0, false);
            p.follow(&[(n, 10.2)], S, stopped);
            assert_eq!(p.moving(n, S), !stopped, "stopped: {stopped}");
            p.follow(&[(n, 10.2)], 2 * S, false);
            assert!(!p.moving(n, 2 * S));
        }
    }

    #[test]
    fn step_relaxes_to_the_elastic_force() {
        let prony = vec![PronyTerm {
            weight: 0.5,
            tau_s: 10.0,
        }];
        let mut p = plant(
            Indenter::FlatCircle { diameter_mm: 9.5 },
            prony,
            None,
            PlantNeeds::default(),
        );
        p.add_axis(AxisRole::Normal, 10.0);
        p.start_move(AxisRole::Normal, 10.084, 1.0, 0, false);
        p.advance_to(S / 10);
        let peak = p.true_wrench().fz_n;
        p.advance_to(600 * S);
        let relaxed = p.true_wrench().fz_n;
        let elastic = p.model.normal_force_n(0.084);
        assert!(
            (relaxed - elastic).abs() < 1e-9 * elastic,
            "{relaxed} vs {elastic}"
        );
        assert!(peak > 1.4 * elastic && peak < 1.5 * elastic, "peak {peak}");
    }

    #[test]
    fn shear_sticks_partially_slips_then_slides_with_a_drop() {
        let needs = PlantNeeds {
            shear: true,
            ..PlantNeeds::default()
        };
        let mut p = plant(
            Indenter::FlatCircle { diameter_mm: 12.68 },
            vec![],
            None,
            needs,
        );
        p.add_axis(AxisRole::Normal, 10.0);
        p.add_axis(AxisRole::Shear, 0.0);
        p.start_move(AxisRole::Normal, 10.21, 1.0, 0, false);
        p.advance_to(S);
        let fz = p.true_wrench().fz_n;
        let mut t = S;
        let mut stick = Vec::new();
        let mut slips = Vec::new();
        let mut fx = Vec::new();
        for k in 1..=24 {
            p.start_move(AxisRole::Shear, 0.05 * k as f64, 0.1, t, false);
            t += 2 * S;
            p.advance_to(t);
            fx.push(p.true_wrench().fx_n);
            let truth = p.truth(t);
            stick.push(truth.shear_stick_fraction.unwrap_or(-1.0));
            slips.push(truth.shear_slips);
        }
        // Linear at first, partial slip (0 < stick < 1) before full slip, then the static
        // limit μP is hit and the force drops to the kinetic limit.
        assert!((fx[1] / fx[0] - 2.0).abs() < 0.05, "{fx:?}");
        let first_slip = slips.iter().position(|n| *n > 0).expect("slips in the end");
        assert!(
            stick[..first_slip].iter().any(|s| *s > 0.05 && *s < 0.95),
            "incipient before full slip: {stick:?}"
        );
        assert!(first_slip > 5, "{slips:?}");
        let peak = fx.iter().cloned().fold(0.0, f64::max);
        assert!(
            peak <= 0.6 * fz * 1.03 && peak > 0.55 * fz,
            "peak {peak} vs μP {}",
            0.6 * fz
        );
        let last = *fx.last().unwrap_or(&0.0);
        assert!(last < 0.95 * peak, "drop after slip: {last} vs {peak}");
    }

    #[test]
    fn shear_far_beyond_the_slip_limit_slides_at_the_kinetic_force() {
        let needs = PlantNeeds {
            shear: true,
            ..PlantNeeds::default()
        };
        let mut p = plant(
            Indenter::FlatCircle { diameter_mm: 9.5 },
            vec![],
            None,
            needs,
        );
        p.add_axis(AxisRole::Normal, 10.0);
        p.add_axis(AxisRole::Shear, -12.0);
        p.start_move(AxisRole::Normal, 10.2, 1.0, 0, false);
        p.advance_to(S);
        let fz = p.true_wrench().fz_n;
        p.start_move(AxisRole::Shear, 12.0, 2.0, S, false);
        let mut t = S;
        while t < 12 * S {
            t += S / 10;
            let w = p.true_wrench();
            assert!(w.fx_n.is_finite() && w.fx_n <= 0.6 * fz * 1.02, "{w:?}");
            p.advance_to(t);
        }
        let fx = p.true_wrench().fx_n;
        // Kinetic/static = 0.5/0.6 in this plant.
        let kinetic = p
            .model
            .shear_curve(0.2)
            .map(|(b, _)| b.limit() * 0.5 / 0.6)
            .unwrap_or(0.0);
        assert!((fx - kinetic).abs() < 1e-6 * kinetic, "{fx} vs {kinetic}");
        assert!(p.truth(t).shear_slips >= 1);
    }

    #[test]
    fn a_thousand_load_unload_steps_return_to_where_they_started() {
        let prony = vec![
            PronyTerm {
                weight: 0.3,
                tau_s: 0.5,
            },
            PronyTerm {
                weight: 0.2,
                tau_s: 20.0,
            },
        ];
        let needs = PlantNeeds {
            shear: true,
            ..PlantNeeds::default()
        };
        let mut p = plant(
            Indenter::FlatCircle { diameter_mm: 9.5 },
            prony,
            None,
            needs,
        );
        p.add_axis(AxisRole::Normal, 10.0);
        p.add_axis(AxisRole::Shear, 0.0);
        p.start_move(AxisRole::Normal, 10.3, 1.0, 0, false);
        let mut t = S;
        p.advance_to(t);
        // 500 cycles of ±0.05 mm on the normal axis and ±0.1 mm of shear.
        let mut ends = Vec::new();
        for k in 0..1000 {
            let up = k % 2 == 0;
            p.start_move(
                AxisRole::Normal,
                if up { 10.35 } else { 10.3 },
                1.0,
                t,
                false,
            );
            p.start_move(AxisRole::Shear, if up { 0.1 } else { 0.0 }, 1.0, t, false);
            t += S;
            p.advance_to(t);
            if !up {
                ends.push(p.true_wrench());
            }
        }
        // Once the slowest relaxation (20 s, ten cycles) has settled, the loop repeats
        // itself: no drift in the normal force, and the Masing loop of the shear closes.
        let (a, b) = (ends[250], ends[ends.len() - 1]);
        assert!(
            (a.fz_n - b.fz_n).abs() < 1e-3 * a.fz_n.abs(),
            "{} vs {}",
            a.fz_n,
            b.fz_n
        );
        assert!(
            (a.fx_n - b.fx_n).abs() < 1e-3 * (a.fx_n.abs() + 0.01),
            "{} vs {}",
            a.fx_n,
            b.fx_n
        );
        // Resting long at the start position relaxes everything back to the elastic state.
        t += 3600 * S;
        p.advance_to(t);
        let elastic = p.model.normal_force_n(0.3);
        assert!((p.true_wrench().fz_n - elastic).abs() < 1e-6 * elastic);
        assert!(p.true_wrench().fx_n.is_finite());
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
            PlantNeeds::default(),
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
        let mut p = plant(
            Indenter::FlatCircle { diameter_mm: 9.5 },
            vec![],
            None,
            PlantNeeds::default(),
        );
        p.add_axis(AxisRole::Normal, 10.0);
        p.start_move(AxisRole::Normal, 15.0, 1.0, 0, false);
        let (w, status) = p.sense(10 * S, &ForceRange::NANO17);
        assert!(w.fz_n.is_finite());
        assert_eq!(w.fz_n, 70.0);
        assert_ne!(status & STATUS_SATURATED, 0);
    }
}
