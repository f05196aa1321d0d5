//! The gel's normal force over time: the hereditary integral of its elastic force.
//!
//! A flat punch's contact keeps its area, so Lee & Radok's integral of the elastic force is
//! exact for it, loading or unloading (for a linear elastic law; at finite strain it is the
//! quasi-linear approximation). A sphere's contact shrinks when the stage backs off, where
//! that integral is not (it would have the indenter pull on a gel it no longer touches);
//! Ting's treatment is followed instead ([`mechanics::unloading`]), and only the rigid base's
//! part beyond 95 % of the thickness (a constant area) stays Lee–Radok. The truth's contact
//! radius and the tangential channels still follow the depth, not Ting's shrinking contact.

use super::{BASE_CONTACT_FRACTION, BASE_STIFFNESS_N_PER_MM, Plant};

impl Plant {
    /// Advances the normal force by `dt_s` to depth `d` (mm, ≤ 0 out of contact); returns
    /// the force, N (never pulling).
    pub(super) fn advance_normal(&mut self, d: f64, dt_s: f64) -> f64 {
        let f = match self.ting.as_mut() {
            Some(ting) => {
                let cap = BASE_CONTACT_FRACTION * self.spec.contact.layer.thickness_mm;
                let base = BASE_STIFFNESS_N_PER_MM * (d - cap).max(0.0);
                self.normal.advance_linear(&self.prony, dt_s, base);
                ting.step(d.min(cap), dt_s) + self.normal.value().max(0.0)
            }
            None => {
                let f_e = if d > 0.0 {
                    self.elastic_normal_n(d)
                } else {
                    0.0
                };
                self.normal.advance_linear(&self.prony, dt_s, f_e);
                self.normal.value().max(0.0)
            }
        };
        self.normal_n = f;
        f
    }
}
