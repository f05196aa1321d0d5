//! A grasped object between the GelSight and a sponge-backed force sensor (thesis §6.3.1,
//! Fig. 6-18, 6-19): the can of the lifting trials, its table, and its slipping.
//!
//! The jig holds two pads on one crossbeam: the portable GelSight on one side, the Nano17
//! behind a sponge on the other. Only they touch the can in the air, so:
//! - **squeeze**: the grip's closure is shared in series by the gel's indentation and the
//!   sponge's compression; both carry the same normal force N ([`series_depth_mm`]);
//! - **tangential load**: both pads move with the lift axis; the can's displacement relative
//!   to them loads the two sides in parallel, each through its own stiffness and friction
//!   limit. The gel side follows the partial-slip backbone of the layer friction solver for a
//!   cylinder lying along the load (slip spreading from the strip's edges inward), the sponge
//!   side is a linear spring with Coulomb friction (elastic–perfectly plastic);
//! - **the can's own motion**: m·z̈ = F_gel + F_sponge + F_disturbance − m·g + R_table with a
//!   unilateral table (R ≥ 0 only at z = 0) and the sponge's damping on the relative velocity;
//!   integrated semi-implicitly in 0.25 ms substeps, well inside the stability limit of the
//!   stiffest side (ω·dt ≈ 0.1). When the sides' limits cannot hold the can it slides at
//!   the kinetic limit, decelerates, re-sticks, or falls to the table. So lift-off shows as a
//!   spike in Fy (the can's inertia as the stage starts, Fig. 6-20(b)) and set-down as a dip;
//! - **rotation about the pad normal** (a torque disturbance, Fig. 6-24): the same scheme for
//!   the can's angle, with the gel's twist backbone against the sponge's torsional spring.
//!
//! What it leaves out (docs/explanation/grasp.md): the can's tipping and its liquid; the
//! sponge's own viscoelasticity beyond a linear damper; the load's coupling into the gel's
//! normal force; the cylinder is rigid and the pads stay parallel.

use mechanics::friction::{Backbone, FrictionElement};

/// The grasp's fixed properties.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct GraspParams {
    pub mass_kg: f64,
    /// Sponge compressive stiffness, N/mm (a 20 × 20 × 5 mm foam of ~40 kPa: EA/t ≈ 3 N/mm).
    pub sponge_normal_n_per_mm: f64,
    /// Sponge tangential stiffness per newton of squeeze, N/mm/N (a compressed foam
    /// stiffens): 7.5 N/mm at 5 N, so the two sides carry comparable shares of the load, as
    /// the thesis's reading of its jig assumes (§6.3.1: "the shear forces are equal").
    pub sponge_shear_per_n: f64,
    /// Friction coefficient of the sponge on the can.
    pub sponge_friction: f64,
    /// Sponge torsional stiffness per newton of squeeze, N·mm/rad/N.
    pub sponge_twist_per_n: f64,
    /// Damping of the sponge on the relative velocity, N per mm/s.
    pub sponge_damping_n_s_per_mm: f64,
    /// The can's moment of inertia about the pad normal through the contact, kg·mm².
    pub inertia_kg_mm2: f64,
}

impl GraspParams {
    /// The thesis's half-full 222 mL can (57.2 mm across, ~100 mm tall) of `mass_g`.
    pub(crate) fn can(mass_g: f64) -> Self {
        let m = mass_g * 1e-3;
        let (r, h) = (28.6, 100.0);
        Self {
            mass_kg: m,
            sponge_normal_n_per_mm: 3.0,
            sponge_shear_per_n: 1.5,
            sponge_friction: 0.8,
            sponge_twist_per_n: 12.0,
            sponge_damping_n_s_per_mm: 0.004,
            inertia_kg_mm2: m * (3.0 * r * r + h * h) / 12.0,
        }
    }

    /// The sponge's tangential backbone per newton of squeeze: linear to its Coulomb limit.
    fn sponge_shear_backbone(&self) -> Backbone {
        Backbone {
            x: vec![0.0, self.sponge_friction / self.sponge_shear_per_n],
            f: vec![0.0, self.sponge_friction],
        }
    }

    /// The sponge's torsional backbone per newton of squeeze.
    fn sponge_twist_backbone(&self) -> Backbone {
        // Coulomb torque of the sponge: μN times an effective radius of a third of its side.
        Backbone {
            x: vec![
                0.0,
                self.sponge_friction * SPONGE_TWIST_RADIUS_MM / self.sponge_twist_per_n,
            ],
            f: vec![0.0, self.sponge_friction * SPONGE_TWIST_RADIUS_MM],
        }
    }
}

pub(crate) const GRAVITY_MM_S2: f64 = 9810.0;
const SUBSTEP_S: f64 = 0.25e-3;
/// A can that comes back to the table from higher than this while sliding was dropped, mm.
const DROP_MM: f64 = 0.5;
/// Coulomb radius of the sponge's torque: a third of its 20 mm side, mm.
const SPONGE_TWIST_RADIUS_MM: f64 = 6.7;
/// Relative speed below which the can counts as held, mm/s.
const HELD_SPEED_MM_S: f64 = 0.05;

/// Gel depth under closure `closure_mm` (grip travel past first touch) when the gel's force
/// law `gel_force_n` and the sponge's linear spring share it in series: solves
/// F_gel(d) = k_sponge·(closure − d) by bisection (both sides monotone).
pub(crate) fn series_depth_mm(
    closure_mm: f64,
    k_sponge_n_per_mm: f64,
    gel_force_n: impl Fn(f64) -> f64,
) -> f64 {
    if closure_mm <= 0.0 {
        return closure_mm;
    }
    let (mut lo, mut hi) = (0.0, closure_mm);
    for _ in 0..48 {
        let mid = 0.5 * (lo + hi);
        if gel_force_n(mid) > k_sponge_n_per_mm * (closure_mm - mid) {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    0.5 * (lo + hi)
}

/// What the grasp feeds back to the bench each instant.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(crate) struct GraspLoads {
    /// Tangential force on the gel along the lift axis, N (positive: the gel holds the can up).
    pub gel_n: f64,
    /// The sponge side's share, N: what the Nano17 behind it reads as Fy.
    pub sponge_n: f64,
    /// Torque the gel carries about its normal, N·mm.
    pub gel_nmm: f64,
    /// Torque the sponge carries, N·mm (the Nano17's Tz).
    pub sponge_nmm: f64,
    /// The gel's friction capacity along the lift at the present squeeze (its backbone's
    /// full-slip force), N; 0 when the gel does not touch.
    pub gel_capacity_n: f64,
    /// The gel's torsional capacity about its normal at the present squeeze, N·mm.
    pub gel_capacity_nmm: f64,
}

/// Ground truth of the grasp at one instant.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(crate) struct GraspState {
    /// Can height above where it stood on the table, mm.
    pub height_mm: f64,
    /// Can velocity relative to the pads, mm/s (negative: sliding down through the grasp).
    pub slip_mm_s: f64,
    /// How far the can has slid through the grasp since it was taken, mm.
    pub slid_mm: f64,
    /// The can's rotation in the grasp, rad.
    pub angle_rad: f64,
    /// Gross slip on the gel side.
    pub gel_sliding: bool,
    /// The can turns in the grasp: the gel's twist in full slip.
    pub twist_sliding: bool,
    /// The can stands on the table.
    pub on_table: bool,
    /// Times the can started a gross slip through the grasp.
    pub slips: u32,
    /// Times it fell back onto the table from the air.
    pub drops: u32,
}

/// The can, its table and the two pads' tangential contacts.
#[derive(Debug, Clone)]
pub(crate) struct Grasp {
    params: GraspParams,
    /// Lift position when the pads first held the can (the origin of relative motion).
    lift_origin_mm: f64,
    z_mm: f64,
    v_mm_s: f64,
    theta_rad: f64,
    omega_rad_s: f64,
    gel: FrictionElement,
    sponge: FrictionElement,
    gel_twist: FrictionElement,
    sponge_twist: FrictionElement,
    last_lift_mm: f64,
    loads: GraspLoads,
    state: GraspState,
    /// The highest the can got since it last stood on the table.
    peak_mm: f64,
}

/// Backbones of the gel side at the present squeeze: shear (N against mm) and twist
/// (N·mm against rad), and the factor from their elastic μP to the present (relaxed) one.
pub(crate) struct GelCurves<'a> {
    pub shear: Option<&'a Backbone>,
    pub twist: Option<&'a Backbone>,
    pub scale: f64,
    pub kinetic: f64,
}

impl Grasp {
    /// A can standing on the table, the pads at `lift_mm`.
    pub(crate) fn new(params: GraspParams, lift_mm: f64) -> Self {
        Self {
            params,
            lift_origin_mm: lift_mm,
            z_mm: 0.0,
            v_mm_s: 0.0,
            theta_rad: 0.0,
            omega_rad_s: 0.0,
            gel: FrictionElement::at(0.0),
            sponge: FrictionElement::at(0.0),
            gel_twist: FrictionElement::at(0.0),
            sponge_twist: FrictionElement::at(0.0),
            last_lift_mm: lift_mm,
            loads: GraspLoads::default(),
            state: GraspState {
                on_table: true,
                ..GraspState::default()
            },
            peak_mm: 0.0,
        }
    }

    /// The pads let go: the can stands where it is (on the table, or falls to it).
    pub(crate) fn release(&mut self, lift_mm: f64) {
        let (slips, drops) = (self.state.slips, self.state.drops);
        let dropped = !self.state.on_table && self.z_mm > DROP_MM;
        *self = Self::new(self.params, lift_mm);
        self.state.slips = slips;
        self.state.drops = drops + u32::from(dropped);
    }

    /// Whether the can needs integrating in short steps: carried, moving or off the table.
    pub(crate) fn active(&self) -> bool {
        !self.state.on_table || self.v_mm_s != 0.0 || self.loads.gel_n != 0.0
    }

    pub(crate) fn loads(&self) -> GraspLoads {
        self.loads
    }

    pub(crate) fn state(&self) -> GraspState {
        self.state
    }

    /// The gel's tangential element (for its stick fraction).
    pub(crate) fn gel_element(&self) -> &FrictionElement {
        &self.gel
    }

    /// The gel's torsional element (for its stick fraction under a twist).
    pub(crate) fn gel_twist_element(&self) -> &FrictionElement {
        &self.gel_twist
    }

    /// Integrates `dt_s` with the pads moving linearly from the last lift position to
    /// `lift_mm`, squeeze `squeeze_n`, a disturbance force (N, along the lift axis) and
    /// torque (N·mm) given as functions of the time into the interval.
    pub(crate) fn advance(
        &mut self,
        dt_s: f64,
        lift_mm: f64,
        squeeze_n: f64,
        gel: &GelCurves<'_>,
        disturbance: impl Fn(f64) -> (f64, f64),
    ) {
        if dt_s <= 0.0 {
            return;
        }
        let p = self.params;
        let n = squeeze_n.max(0.0);
        let sponge_shear = p.sponge_shear_backbone();
        let sponge_twist = p.sponge_twist_backbone();
        let steps = (dt_s / SUBSTEP_S).ceil().max(1.0) as usize;
        let h = dt_s / steps as f64;
        let lift0 = self.last_lift_mm;
        let m = p.mass_kg;
        let weight_n = m * GRAVITY_MM_S2 * 1e-3;
        for k in 0..steps {
            let f = (k + 1) as f64 / steps as f64;
            let lift = lift0 + (lift_mm - lift0) * f;
            let pad_v = (lift_mm - lift0) / dt_s;
            let s = (lift - self.lift_origin_mm) - self.z_mm;
            let (f_gel, f_sponge, damping) = self.shear_forces(s, pad_v, n, gel, &sponge_shear);
            let (dist_n, dist_nmm) = disturbance(f * dt_s);
            let net_n = f_gel + f_sponge + damping + dist_n - weight_n;
            self.lift_can(net_n / m * 1e3, h);
            let (t_gel, t_sponge, t_damp) = self.turn_can(dist_nmm, n, h, gel, &sponge_twist);
            self.note_slip(n, pad_v);
            let on = n > 0.0;
            self.loads = GraspLoads {
                gel_n: f_gel,
                sponge_n: f_sponge + damping,
                gel_nmm: t_gel,
                sponge_nmm: t_sponge + t_damp,
                gel_capacity_n: gel
                    .shear
                    .filter(|_| on)
                    .map_or(0.0, |b| b.limit() * gel.scale),
                gel_capacity_nmm: gel
                    .twist
                    .filter(|_| on)
                    .map_or(0.0, |b| b.limit() * gel.scale),
            };
        }
        let s = (lift_mm - self.lift_origin_mm) - self.z_mm;
        self.state.slid_mm = s - self.gel_backbone_x(gel);
        self.state.height_mm = self.z_mm;
        self.state.angle_rad = self.theta_rad;
        if self.state.on_table && self.v_mm_s == 0.0 && self.state.slip_mm_s.abs() < HELD_SPEED_MM_S
        {
            self.state.slip_mm_s = 0.0;
        }
        self.last_lift_mm = lift_mm;
    }

    /// The tangential forces on the can in one substep, N: the gel's and the sponge's
    /// friction elements at relative displacement `s_mm` (reset when the squeeze `n` is
    /// gone), and the sponge's damping of the relative speed (`pad_v`, mm/s, the pads').
    fn shear_forces(
        &mut self,
        s_mm: f64,
        pad_v: f64,
        n: f64,
        gel: &GelCurves<'_>,
        sponge_shear: &Backbone,
    ) -> (f64, f64, f64) {
        let kin = gel.kinetic;
        let f_gel = match (gel.shear, n > 0.0) {
            (Some(b), true) => {
                self.gel.update(s_mm, b, gel.scale, kin);
                self.gel.cap(b.limit() * gel.scale, kin)
            }
            _ => {
                self.gel = FrictionElement::at(s_mm);
                0.0
            }
        };
        let f_sponge = if n > 0.0 {
            self.sponge.update(s_mm, sponge_shear, n, kin);
            self.sponge.cap(sponge_shear.limit() * n, kin)
        } else {
            self.sponge = FrictionElement::at(s_mm);
            0.0
        };
        let rel_v = pad_v - self.v_mm_s;
        let damping = if n > 0.0 {
            self.params.sponge_damping_n_s_per_mm * rel_v
        } else {
            0.0
        };
        (f_gel, f_sponge, damping)
    }

    /// One semi-implicit Euler substep `h_s` of the can's height under acceleration
    /// `a_mm_s2`, with the table below it (a fall onto it from the air while sliding
    /// through the grasp is counted as a drop).
    fn lift_can(&mut self, a_mm_s2: f64, h_s: f64) {
        // Semi-implicit Euler: velocity first, then position with the new velocity.
        let mut v = self.v_mm_s + a_mm_s2 * h_s;
        let mut z = self.z_mm + v * h_s;
        if z <= 0.0 {
            // Back on the table: a fall if it came down sliding through the grasp.
            if !self.state.on_table && self.peak_mm > DROP_MM && self.gel.sliding() {
                self.state.drops += 1;
            }
            z = 0.0;
            v = 0.0;
            self.state.on_table = true;
            self.peak_mm = 0.0;
        } else {
            self.state.on_table = false;
            self.peak_mm = self.peak_mm.max(z);
        }
        self.v_mm_s = v;
        self.z_mm = z;
    }

    /// One substep `h_s` of the can's rotation about the pad normal under the disturbance
    /// torque `dist_nmm`: the same balance for its angle. Returns the torques of the gel,
    /// the sponge and the damping, N·mm.
    fn turn_can(
        &mut self,
        dist_nmm: f64,
        n: f64,
        h_s: f64,
        gel: &GelCurves<'_>,
        sponge_twist: &Backbone,
    ) -> (f64, f64, f64) {
        let p = self.params;
        let kin = gel.kinetic;
        let t_gel = match (gel.twist, n > 0.0) {
            (Some(b), true) => {
                self.gel_twist.update(self.theta_rad, b, gel.scale, kin);
                self.gel_twist.cap(b.limit() * gel.scale, kin)
            }
            _ => 0.0,
        };
        let t_sponge = if n > 0.0 {
            self.sponge_twist
                .update(self.theta_rad, sponge_twist, n, kin);
            self.sponge_twist.cap(sponge_twist.limit() * n, kin)
        } else {
            0.0
        };
        let t_damp = p.sponge_damping_n_s_per_mm * 100.0 * self.omega_rad_s;
        let alpha = (dist_nmm - t_gel - t_sponge - t_damp) / p.inertia_kg_mm2 * 1e3;
        if n > 0.0 {
            self.omega_rad_s += alpha * h_s;
            self.theta_rad += self.omega_rad_s * h_s;
        } else {
            self.omega_rad_s = 0.0;
        }
        (t_gel, t_sponge, t_damp)
    }

    /// The slip state after a substep: twisting and gross slip on the gel side (a new slip
    /// counted), and the can's speed relative to the pads moving at `pad_v`, mm/s.
    fn note_slip(&mut self, n: f64, pad_v: f64) {
        self.state.twist_sliding = n > 0.0 && self.gel_twist.sliding();
        let was_sliding = self.state.gel_sliding;
        self.state.gel_sliding = self.gel.sliding() && !self.state.on_table;
        if self.state.gel_sliding && !was_sliding {
            self.state.slips += 1;
        }
        self.state.slip_mm_s = self.v_mm_s - pad_v;
    }

    /// Elastic part of the gel's tangential displacement (the rest of the relative motion
    /// is slip of the can through the grasp).
    fn gel_backbone_x(&self, gel: &GelCurves<'_>) -> f64 {
        match gel.shear {
            Some(b) if gel.scale > 0.0 => b.displacement_at(self.gel.force() / gel.scale),
            _ => 0.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gel_backbone() -> Backbone {
        // A partial-slip curve: stiffness 8 N/mm, full slip at 3 N (μN of 5 N at μ = 0.6).
        let x: Vec<f64> = (0..=20).map(|i| i as f64 * 0.75 / 20.0).collect();
        let f = x
            .iter()
            .map(|v| 3.0 * mechanics::friction::cm_force_ratio(v / 0.75))
            .collect();
        Backbone { x, f }
    }

    /// Runs `t_s` in 5 ms steps; the gel's limit follows the squeeze (backbone at 5 N).
    fn run(grasp: &mut Grasp, t_s: f64, lift: impl Fn(f64) -> f64, squeeze: impl Fn(f64) -> f64) {
        let b = gel_backbone();
        let dt = 5e-3;
        let steps = (t_s / dt) as usize;
        for i in 0..steps {
            let t = (i + 1) as f64 * dt;
            let curves = GelCurves {
                shear: Some(&b),
                twist: None,
                scale: squeeze(t) / 5.0,
                kinetic: 0.9,
            };
            grasp.advance(dt, lift(t), squeeze(t), &curves, |_| (0.0, 0.0));
        }
    }

    #[test]
    fn series_depth_shares_the_closure() {
        let d = series_depth_mm(2.0, 3.0, |d| 10.0 * d);
        // 10 d = 3 (2 − d) → d = 6/13.
        assert!((d - 6.0 / 13.0).abs() < 1e-9, "{d}");
        assert_eq!(series_depth_mm(-1.0, 3.0, |d| d), -1.0);
    }

    #[test]
    fn lifted_can_is_carried_with_a_spike_at_lift_off() {
        let mut g = Grasp::new(GraspParams::can(100.0), 0.0);
        let mut peak: f64 = 0.0;
        let b = gel_backbone();
        let curves = GelCurves {
            shear: Some(&b),
            twist: None,
            scale: 1.0,
            kinetic: 0.9,
        };
        for i in 0..600 {
            let t = (i + 1) as f64 * 5e-3;
            let lift = (10.0 * (t - 0.5)).clamp(0.0, 20.0);
            g.advance(5e-3, lift, 5.0, &curves, |_| (0.0, 0.0));
            let l = g.loads();
            peak = peak.max(l.gel_n + l.sponge_n);
        }
        let l = g.loads();
        let s = g.state();
        assert!(!s.on_table && s.height_mm > 15.0, "{s:?}");
        // Held: the two sides carry the weight between them.
        assert!((l.gel_n + l.sponge_n - 0.981).abs() < 0.01, "{l:?}");
        assert!(l.gel_n > 0.2 && l.sponge_n > 0.2, "{l:?}");
        // Lift-off accelerates the can: the carried force overshoots its weight.
        assert!(peak > 1.0, "peak {peak}");
        assert_eq!(s.slips, 0);
    }

    #[test]
    fn a_loosening_grip_lets_the_can_slide_and_drop() {
        let mut g = Grasp::new(GraspParams::can(100.0), 0.0);
        run(&mut g, 3.0, |t| (10.0 * t).min(20.0), |_| 5.0);
        assert!(!g.state().on_table);
        // Open until μ_total·N < m·g: 0.981 / (0.6 + 0.8) ≈ 0.7 N.
        run(&mut g, 3.0, |_| 20.0, |t| (5.0 - 2.0 * t).max(0.3));
        let s = g.state();
        assert!(s.slips >= 1, "{s:?}");
        assert!(s.on_table, "{s:?}");
    }
}
