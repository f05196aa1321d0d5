//! Where the elastomer is pressed to: the pressing stage's travel past first touch, or, in
//! a grasp, the grip's closure shared with the sponge behind the Nano17.
//!
//! In a grasp the gel and the sponge are in series and carry one force. The gel is
//! viscoelastic, so that force is its hereditary one, not its relaxed law: right after the
//! grip the stiffer gel takes less of the closure, and as it relaxes the sponge pushes it
//! deeper — under a held grip the squeeze relaxes less than at a held depth, and the gel's
//! field creeps (the correspondence principle's other half: a held load lets the
//! displacement follow the creep function, thesis §4.2's relaxation seen from the force
//! side). Each step solves the balance k·(closure − d) = gain·F∞(d) + offset, where the
//! gel's force after the step is affine in its elastic force
//! ([`mechanics::PronyState::step_affine`]).

use super::{BASE_CONTACT_FRACTION, BASE_STIFFNESS_N_PER_MM, Plant};
use crate::grasp::series_depth_mm;
use rig::config::AxisRole;

impl Plant {
    /// Which axis presses the indenter (or the grasped object) into the elastomer.
    pub(super) fn pressing_axis(&self) -> Option<(AxisRole, f64)> {
        if self.axes.contains_key(&AxisRole::Normal) {
            Some((AxisRole::Normal, self.geometry.normal_contact_mm))
        } else if self.axes.contains_key(&AxisRole::Grip) {
            Some((AxisRole::Grip, self.geometry.grip_contact_mm))
        } else {
            None
        }
    }

    /// In a grasp, the grip's closure past first touch at `t_ns` and the sponge's normal
    /// stiffness (N/mm); `None` when nothing is grasped.
    pub(super) fn grasp_closure(&self, t_ns: u64) -> Option<(f64, f64)> {
        match self.pressing_axis() {
            Some((AxisRole::Grip, contact)) if self.spec.object_mass_g.is_some() => {
                let closure = self
                    .position(AxisRole::Grip, t_ns)
                    .map(|p| p - contact)
                    .unwrap_or(0.0);
                let k = self
                    .grasp_params()
                    .map_or(f64::INFINITY, |g| g.sponge_normal_n_per_mm);
                Some((closure, k))
            }
            _ => None,
        }
    }

    /// The gel's depth at `t_ns` (the plant advanced to it): the pressing stage's travel
    /// past first touch, or in a grasp the depth solved at the last step.
    pub(super) fn depth_at(&self, t_ns: u64) -> f64 {
        if self.grasp_closure(t_ns).is_some() {
            return self.grasp_depth_mm;
        }
        match self.pressing_axis() {
            Some((role, contact)) => self
                .position(role, t_ns)
                .map(|p| p - contact)
                .unwrap_or(0.0),
            None => 0.0,
        }
    }

    /// One step of a grasp of closure `closure_mm` with a sponge of `k` N/mm: the depth at
    /// which the gel's viscoelastic force after `dt_s` equals the sponge's (the normal
    /// state is advanced by the caller with this depth's elastic force).
    pub(super) fn grasp_depth_step(&mut self, closure_mm: f64, k: f64, dt_s: f64) -> f64 {
        let (gain, offset) = self.normal.step_affine(&self.prony, dt_s);
        let d = series_depth_mm(closure_mm, k, |d| gain * self.elastic_normal_n(d) + offset);
        self.grasp_depth_mm = d;
        d
    }

    /// The normal force the present state settles to if nothing moves: the elastic force
    /// at the depth, or in a grasp where the relaxed gel balances the sponge.
    pub(super) fn equilibrium_normal_n(&self, t_ns: u64) -> f64 {
        let d = match self.grasp_closure(t_ns) {
            Some((closure, k)) => series_depth_mm(closure, k, |d| self.elastic_normal_n(d)),
            None => self.depth_at(t_ns),
        };
        if d > 0.0 {
            self.elastic_normal_n(d)
        } else {
            0.0
        }
    }

    /// Long-term elastic normal force at depth `d`, saturating on the rigid base; a flat
    /// punch at finite strain where the rig asks for it ([`mechanics::finite_strain`]).
    pub(super) fn elastic_normal_n(&self, d: f64) -> f64 {
        let h = self.spec.contact.layer.thickness_mm;
        let d_max = BASE_CONTACT_FRACTION * h;
        let d_el = d.min(d_max);
        let stiffening = if self.geometry.finite_strain && self.model.is_flat() {
            let a = self.model.contact_radius_mm(d_el);
            mechanics::finite_strain::flat_punch_stiffening(d_el / h, a / h)
        } else {
            1.0
        };
        self.model.normal_force_n(d_el) * stiffening
            + BASE_STIFFNESS_N_PER_MM * (d - d_max).max(0.0)
    }
}
