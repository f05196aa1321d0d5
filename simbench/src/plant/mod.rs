//! The simulated elastomer and everything that loads it.
//!
//! Stage positions go in; a Nano17 reading, ground truth and the surface field come out.
//! The elastic response is a [`ContactModel`] precomputed by the layer solvers of
//! `mechanics` for exactly what the run needs (shear tables only if the shear stage is
//! opened, fields only if the camera is). On top of it:
//! - **viscoelasticity**: every channel's elastic (long-term) force drives a Prony
//!   hereditary state with the exact exponential update, so a step relaxes and loading
//!   sits above unloading (Lee–Radok form, spec §3); a sphere's normal force follows
//!   Ting's treatment instead, its contact shrinking on unloading ([`normal`]; the truth's
//!   contact radius and the tangential channels still follow the depth);
//! - **friction**: shear and twist go through Masing friction elements on the solver's
//!   partial-slip backbones, saturate at the static limit μP, slide at the kinetic limit and
//!   stick again when the stage stops (the stick-slip steps of thesis Fig. 4-16);
//! - **sensor**: a per-seed offset, Gaussian noise at the Nano17's resolution, quantisation
//!   and clipping with a status flag beyond its range;
//! - **grasping**: a can held between the gel and a sponge-backed Nano17, lifted off its
//!   table, disturbed and let slip (thesis §6.3; [`super::grasp`]).

use std::collections::BTreeMap;

use mechanics::contact::Contact;
use mechanics::friction::{Backbone, FrictionElement};
use mechanics::response::{ContactModel, ModelSpec, Quality, SlipTilt, State};
use mechanics::unloading::TingContact;
use mechanics::{Indenter, Prony, PronyState, PronyTerm};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use std::sync::Arc;

use super::grasp::Grasp;
use grasping::{GraspCurves, GraspReference};
use rig::RigError;
use rig::config::AxisRole;
use rig::device::Wrench;

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
    /// Indenters pressed with friction (the default; `pressing_friction: false` under `sim:`
    /// or `contact:` turns it off).
    pub pressing_friction: bool,
    /// Flat punches pressed at finite strain (`finite_strain: true` under `sim:` or `contact:`).
    pub finite_strain: bool,
}

impl BenchGeometry {
    /// The rig file's `sim:` section, which a simulated `what` cannot do without.
    pub(crate) fn of(config: &rig::config::RigConfig, what: &str) -> Result<Self, RigError> {
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
            pressing_friction: config.presses_with_friction(),
            finite_strain: config.finite_strain(),
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
    curve: Option<Curve>,
    /// The contact's full-stick tilting-moment arms (mm) and the depth they were found at
    /// (shear channel only).
    tilt: Option<Tilt>,
}

/// A tangential channel's backbone, solved at the depth it was asked for.
#[derive(Debug)]
struct Curve {
    depth_mm: f64,
    backbone: Backbone,
    /// Stick fraction at each backbone point.
    stick: Vec<f64>,
    /// A shear's full-stick tilting arm along x at this depth, mm, and how it moves toward
    /// full slip along this backbone (`ContactModel::shear_slip_tilt`); none for twist or
    /// in a grasp.
    slip_tilt: Option<(f64, Arc<SlipTilt>)>,
}

/// A shear channel's tilting arms at the depth they were solved for.
#[derive(Debug)]
struct Tilt {
    depth_mm: f64,
    /// Full-stick arms along x and y, mm.
    arms_mm: (f64, f64),
}

/// Largest integration step while anything moves, so depth-nonlinear laws stay accurate.
const MAX_MOVING_STEP_NS: u64 = 5_000_000;
/// Fraction of the thickness beyond which the indenter is treated as hitting the base.
const BASE_CONTACT_FRACTION: f64 = 0.95;
/// Stiffness of the acrylic base once reached, N/mm: far beyond any sensor range.
const BASE_STIFFNESS_N_PER_MM: f64 = 1e4;

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
    /// The gel's normal force's hereditary state (Lee–Radok on the elastic force); with a
    /// curved indenter, only the rigid base's part ([`normal`]).
    normal: PronyState,
    /// A curved indenter's contact, whose area shrinks on unloading (Ting's treatment).
    ting: Option<TingContact>,
    /// The normal force after the last step, N.
    normal_n: f64,
    shear: Option<Channel>,
    twist: Option<Channel>,
    needs: PlantNeeds,
    in_contact: bool,
    /// The gel's depth in a grasp, solved each step ([`Self::grasp_depth_step`]).
    grasp_depth_mm: f64,
    grasp: Option<Grasp>,
    /// The gel's backbones in the grasp, at a quantised depth (key, shear, twist, stick
    /// fractions along the shear backbone).
    grasp_curves: Option<GraspCurves>,
    /// The gel's backbones solved once for the grasp, scaled to each depth.
    grasp_reference: Option<GraspReference>,
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
        // A grasp loads the gel along the lift and about its normal whatever stages exist.
        let grasping = spec.object_mass_g.is_some();
        let needs = PlantNeeds {
            shear: needs.shear || grasping,
            twist: needs.twist || grasping,
            ..needs
        };
        let prony = Prony::new(terms).map_err(|e| RigError::Plant(e.to_string()))?;
        // Tables kept by an earlier run of the same contact are read, not solved again
        // (`tablecache`; the same model bit for bit).
        let model = ContactModel::build_stored(
            ModelSpec {
                contact: spec.contact.clone(),
                max_depth_mm: spec.max_depth_mm,
                shear: needs.shear,
                twist: needs.twist,
                field_view_mm: needs
                    .fields
                    .then_some((spec.view_width_mm, spec.view_height_mm)),
                pressing_friction: geometry.pressing_friction,
                quality: spec.quality,
            },
            tablecache::store(),
        )
        .map_err(|e| RigError::Plant(e.to_string()))?;
        // A sphere pressed by a stage: its contact shrinks when the stage backs off. (The
        // treatment is for axisymmetric contacts: a cylinder's line contact, and a grasp's
        // gel balancing the sponge through Lee–Radok's affine step, stay Lee–Radok.) Built
        // to where the base is reached, so no depth the stage can press lies beyond it.
        let sphere = matches!(spec.contact.indenter, Indenter::Sphere { .. });
        let ting = (sphere && !grasping)
            .then(|| {
                let cap = BASE_CONTACT_FRACTION * spec.contact.layer.thickness_mm;
                TingContact::new(|d| model.normal_force_n(d), cap, &prony)
            })
            .flatten();
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
        let mut plant = Self {
            normal: prony.state(),
            ting,
            normal_n: 0.0,
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
            grasp_depth_mm: 0.0,
            grasp: None,
            grasp_curves: None,
            grasp_reference: None,
            disturbance: None,
            bias,
            rng: StdRng::seed_from_u64(seed.wrapping_add(0x9E37_79B9_7F4A_7C15)),
        };
        if grasping {
            plant.grasp_reference = Some(GraspReference::solve(&mut plant));
        }
        Ok(plant)
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
            if self.grasp.as_ref().is_some_and(Grasp::active) {
                moving = true;
            }
            if moving {
                next = next.min(self.t_ns + MAX_MOVING_STEP_NS);
            }
            self.integrate(next);
        }
    }

    /// The backbone of a tangential channel at depth `d`, recomputed only when the depth
    /// changed, and for a shear whose tilt is read (`tilted`) how its arm moves along it
    /// (solved with it, from the same table, so the two always match).
    fn curve(
        model: &mut ContactModel,
        shear: bool,
        tilted: bool,
        d: f64,
        cached: &mut Option<Curve>,
    ) {
        let stale = cached
            .as_ref()
            .is_none_or(|c| (c.depth_mm - d).abs() > 1e-9);
        if stale {
            let c = if shear {
                model.shear_curve(d)
            } else {
                model.twist_curve(d)
            };
            let slip_tilt = if shear && tilted {
                model
                    .shear_slip_tilt(d)
                    .map(|s| (model.tilt_arms_mm(d).0, s))
            } else {
                None
            };
            *cached = c.map(|(backbone, stick)| Curve {
                depth_mm: d,
                backbone,
                stick,
                slip_tilt,
            });
        }
    }

    fn integrate(&mut self, t1_ns: u64) {
        let t0_ns = self.t_ns;
        let dt_s = (t1_ns - self.t_ns) as f64 * 1e-9;
        self.t_ns = t1_ns;
        let d = match self.grasp_closure(t1_ns) {
            Some((closure_mm, k)) => self.grasp_depth_step(closure_mm, k, dt_s),
            None => self.depth_at(t1_ns),
        };
        let shear_pos = self.position(AxisRole::Shear, t1_ns).unwrap_or(0.0);
        let twist_pos = self
            .position(AxisRole::Rotation, t1_ns)
            .unwrap_or(0.0)
            .to_radians();
        if d <= 0.0 {
            // Out of contact: the elastomer recovers; tangential loads vanish with contact.
            self.advance_normal(d, dt_s);
            self.shear = None;
            self.twist = None;
            self.in_contact = false;
            let lift = self.position(AxisRole::Lift, t1_ns).unwrap_or(0.0);
            if let Some(g) = self.grasp.as_mut() {
                g.release(lift);
            }
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
                tilt: None,
            };
            self.shear = self.needs.shear.then(|| fresh(shear_pos, &self.prony));
            self.twist = self.needs.twist.then(|| fresh(twist_pos, &self.prony));
        }
        let f_e = self.elastic_normal_n(d);
        let p = self.advance_normal(d, dt_s);
        let mu = self.spec.contact.material.friction;
        let kinetic = if mu > 0.0 {
            (self.spec.kinetic_friction / mu).clamp(0.0, 1.0)
        } else {
            1.0
        };
        let d_el = d.min(BASE_CONTACT_FRACTION * self.spec.contact.layer.thickness_mm);
        let disturbed = self
            .disturbance
            .is_some_and(|dist| dist.t0_ns < t1_ns && dist.t1_ns > t0_ns);
        // A grasp trial's, from its spec: its grasp state starts only at first contact.
        let grasping = self.spec.object_mass_g.is_some();
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
            // The tilting arms with it, or when a disturbance pushes sideways: only then can
            // a tangential force act on them (a curved contact's are solved per depth
            // bucket, 0.1–3 s each; a depth ramp under a sheared contact does not re-solve
            // them, as it does not re-solve the backbone). A grasp's Nano17 sits behind the
            // sponge and reads no tilt: none are solved there.
            let arms_wanted = is_shear && !grasping && (pos != ch.last_pos || disturbed);
            if pos != ch.last_pos {
                Self::curve(&mut self.model, is_shear, !grasping, d_el, &mut ch.curve);
                ch.last_pos = pos;
            }
            if arms_wanted
                && ch
                    .tilt
                    .as_ref()
                    .is_none_or(|t| (t.depth_mm - d_el).abs() > 1e-9)
            {
                ch.tilt = Some(Tilt {
                    depth_mm: d_el,
                    arms_mm: self.model.tilt_arms_mm(d_el),
                });
            }
            let Some(Curve { backbone, .. }) = ch.curve.as_ref() else {
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
        self.grasp_step(t0_ns, t1_ns, d_el, p, kinetic);
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
            && let Some(Curve { backbone: b, .. }) = &c.curve
        {
            shear_n = c.element.force();
            slip_x = (shear_pos - c.origin) - b.displacement_at(shear_n);
        }
        let (mut slip_theta, mut torque) = (0.0, 0.0);
        if let Some(c) = &self.twist
            && let Some(Curve { backbone: b, .. }) = &c.curve
        {
            torque = c.element.force();
            slip_theta = (twist_pos - c.origin) - b.displacement_at(torque);
        }
        if let Some(g) = self.grasp.as_ref().filter(|_| self.in_contact) {
            // The can drags the gel's surface down (−x in the view: the lift axis is +x) and
            // turns it with the torque the gel carries.
            let l = g.loads();
            let st = g.state();
            return SurfacePose {
                state: State {
                    depth_mm: d.min(0.95 * h),
                    shear_n: -l.gel_n,
                    torque_nmm: l.gel_nmm,
                },
                centre_mm: (-st.slid_mm, 0.0),
                rotation_rad: 0.0,
            };
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
        self.grasp.as_ref().map(|g| g.state().slips).unwrap_or(0)
    }
}

mod depth;
mod grasping;
mod normal;
#[cfg(test)]
mod stability_tests;
#[cfg(test)]
mod tests;
mod wrench;
