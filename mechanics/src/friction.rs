//! Frictional contact in closed form, and a hysteretic friction element for the plant.
//!
//! - Cattaneo–Mindlin partial slip of a Hertzian contact (Mindlin 1949; Johnson §7.2):
//!   stick radius, tangential force against displacement.
//! - Masing's rule for unloading and reloading (Mindlin & Deresiewicz 1953): a branch that
//!   starts at a reversal (δ*, Q*) is the virgin curve scaled by two,
//!   Q(δ) = Q* − 2F((δ* − δ)/2). This hysteresis is frictional, not viscoelastic.
//! - [`FrictionElement`]: a one-dimensional hysteretic element built on any monotone
//!   backbone (from the grid solver), with Masing branches, full slip at the static limit
//!   and sliding at the kinetic limit, and re-sticking when the motion stops — the stick-slip
//!   steps of thesis Fig. 4-16.

/// Stick-zone radius ratio c/a of Cattaneo–Mindlin at tangential displacement ratio δ/δ*.
pub fn cm_stick_ratio(delta_over_star: f64) -> f64 {
    (1.0 - delta_over_star.clamp(0.0, 1.0)).sqrt()
}

/// Q/(μP) of Cattaneo–Mindlin at δ/δ* (spec §1.5): 1 − (1 − δ/δ*)^{3/2}.
pub fn cm_force_ratio(delta_over_star: f64) -> f64 {
    1.0 - (1.0 - delta_over_star.clamp(0.0, 1.0)).powf(1.5)
}

/// δ* = 3μP(2−ν)/(16Ga): the displacement at full slip of a Hertzian contact.
pub fn cm_full_slip_displacement(mu: f64, p_n: f64, nu: f64, g_mpa: f64, a_mm: f64) -> f64 {
    3.0 * mu * p_n * (2.0 - nu) / (16.0 * g_mpa * a_mm)
}

/// Displacement on the virgin loading curve of Cattaneo–Mindlin at force ratio Q/(μP):
/// δ = δ*[1 − (1 − Q/μP)^{2/3}].
pub fn cm_displacement(q_over_mup: f64, delta_star: f64) -> f64 {
    let r = q_over_mup.clamp(-1.0, 1.0);
    r.signum() * delta_star * (1.0 - (1.0 - r.abs()).powf(2.0 / 3.0))
}

/// Masing unloading from (δ_L(Q*), Q*) to force Q: δ_U(Q) = δ_L(Q*) − 2δ_L((Q* − Q)/2),
/// for any odd virgin curve `virgin` mapping force to displacement.
pub fn masing_unloading(virgin: impl Fn(f64) -> f64, q_star: f64, q: f64) -> f64 {
    virgin(q_star) - 2.0 * virgin((q_star - q) / 2.0)
}

/// Twisting moment at which a flat circular punch starts to slip at its edge under
/// Sneddon pressure: (2/3)μPa (spec §1.6).
pub fn torsion_slip_onset_nmm(mu: f64, p_n: f64, a_mm: f64) -> f64 {
    2.0 / 3.0 * mu * p_n * a_mm
}

/// Twisting moment of a flat circular punch in full slip: (π/4)μPa (spec §1.6).
pub fn torsion_full_slip_nmm(mu: f64, p_n: f64, a_mm: f64) -> f64 {
    std::f64::consts::PI / 4.0 * mu * p_n * a_mm
}

/// Surface displacement u_x inside a circular contact of radius a under the Hertz-shaped
/// traction q = q₀√(1−r²/a²) (Johnson §7.1; spec O11):
/// u_x = (πq₀/(32Ga))[4(2−ν)a² − (4−3ν)x² − (4−ν)y²].
pub fn hertz_tangential_ux(q0: f64, g_mpa: f64, nu: f64, a_mm: f64, x: f64, y: f64) -> f64 {
    std::f64::consts::PI * q0 / (32.0 * g_mpa * a_mm)
        * (4.0 * (2.0 - nu) * a_mm * a_mm - (4.0 - 3.0 * nu) * x * x - (4.0 - nu) * y * y)
}

/// A monotone backbone: force (or torque) against displacement (or angle) on virgin
/// loading, tabulated, odd, saturating at its last value.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Backbone {
    /// Displacements, increasing from 0.
    pub x: Vec<f64>,
    /// Forces at `x`, increasing from 0 to the full-slip value.
    pub f: Vec<f64>,
}

impl Backbone {
    /// Force at displacement `x` (odd, linear interpolation, constant beyond the table).
    pub fn force(&self, x: f64) -> f64 {
        let s = x.signum();
        let x = x.abs();
        let n = self.x.len();
        if n == 0 {
            return 0.0;
        }
        if x >= self.x[n - 1] {
            return s * self.f[n - 1];
        }
        let i = self.x.partition_point(|v| *v <= x).clamp(1, n - 1);
        let t = (x - self.x[i - 1]) / (self.x[i] - self.x[i - 1]);
        s * (self.f[i - 1] + t * (self.f[i] - self.f[i - 1]))
    }

    /// The full-slip force.
    pub fn limit(&self) -> f64 {
        self.f.last().copied().unwrap_or(0.0)
    }

    /// Displacement on the virgin curve where the force is `f` (inverse of
    /// [`Backbone::force`]; the start of full slip at or beyond the limit).
    pub fn displacement_at(&self, f: f64) -> f64 {
        let s = f.signum();
        let f = f.abs();
        let n = self.f.len();
        if n == 0 {
            return 0.0;
        }
        if f >= self.limit() {
            return s * self.slip_start();
        }
        let i = self.f.partition_point(|v| *v <= f).clamp(1, n - 1);
        let span = self.f[i] - self.f[i - 1];
        let t = if span > 0.0 {
            (f - self.f[i - 1]) / span
        } else {
            0.0
        };
        s * (self.x[i - 1] + t * (self.x[i] - self.x[i - 1]))
    }

    /// Displacement at which the backbone reaches its limit (start of full slip).
    pub fn slip_start(&self) -> f64 {
        let lim = self.limit();
        let i = self
            .f
            .iter()
            .position(|v| *v >= lim * (1.0 - 1e-9))
            .unwrap_or(0);
        self.x.get(i).copied().unwrap_or(0.0)
    }
}

/// State of a hysteretic friction element.
#[derive(Debug, Clone, PartialEq)]
pub struct FrictionElement {
    /// Displacement where the current branch started.
    anchor: f64,
    /// Force where the current branch started.
    q0: f64,
    /// +1 or −1: the direction of the current branch.
    dir: f64,
    /// True on the virgin branch (no factor two).
    virgin: bool,
    /// Last displacement seen.
    last_x: f64,
    /// Sliding at the kinetic limit.
    sliding: bool,
    /// Force now.
    force: f64,
    /// How many times the element has entered full slip.
    slips: u32,
}

impl Default for FrictionElement {
    fn default() -> Self {
        Self {
            anchor: 0.0,
            q0: 0.0,
            dir: 1.0,
            virgin: true,
            last_x: 0.0,
            sliding: false,
            force: 0.0,
            slips: 0,
        }
    }
}

impl FrictionElement {
    /// A fresh element at rest at displacement `x`.
    pub fn at(x: f64) -> Self {
        Self {
            anchor: x,
            last_x: x,
            ..Self::default()
        }
    }

    /// Force now.
    pub fn force(&self) -> f64 {
        self.force
    }

    /// True while sliding in full slip.
    pub fn sliding(&self) -> bool {
        self.sliding
    }

    /// How many times the element has gone into full slip.
    pub fn slips(&self) -> u32 {
        self.slips
    }

    /// Moves to displacement `x` on `backbone` (scaled by `scale`, e.g. the current μP over
    /// the backbone's reference), with static limit `backbone.limit()·scale` and kinetic
    /// limit `kinetic` times that. Returns the force.
    pub fn update(&mut self, x: f64, backbone: &Backbone, scale: f64, kinetic: f64) -> f64 {
        let dx = x - self.last_x;
        let static_limit = backbone.limit() * scale;
        if dx == 0.0 {
            return self.force;
        }
        let moving_dir = dx.signum();
        if moving_dir != self.dir {
            // Reversal: a Masing branch from here.
            self.anchor = self.last_x;
            self.q0 = self.force;
            self.dir = moving_dir;
            self.virgin = false;
            self.sliding = false;
        } else if self.sliding {
            // Still sliding the same way: the force stays at the kinetic limit.
            self.last_x = x;
            self.force = self.dir * kinetic * static_limit;
            self.anchor = x;
            self.q0 = self.force;
            return self.force;
        }
        let travel = (x - self.anchor) * self.dir;
        let f = if self.virgin {
            backbone.force(self.dir * travel) * scale
        } else {
            self.q0 + self.dir * 2.0 * backbone.force(travel / 2.0) * scale
        };
        self.last_x = x;
        if f.abs() >= static_limit && f * self.dir > 0.0 {
            self.slips += 1;
            self.sliding = true;
            self.force = self.dir * kinetic * static_limit;
            self.anchor = x;
            self.q0 = self.force;
            self.virgin = false;
        } else {
            self.force = f;
        }
        self.force
    }

    /// Holds the force within a static limit that has just fallen (a squeeze that relaxes
    /// or opens without the contact moving): beyond it the contact goes into full slip at the
    /// kinetic limit, as [`Self::update`] would on the next move. Returns the force.
    pub fn cap(&mut self, static_limit: f64, kinetic: f64) -> f64 {
        if self.force.abs() > static_limit && !self.sliding {
            self.slips += 1;
            self.sliding = true;
            self.dir = self.force.signum();
            self.force = self.dir * kinetic * static_limit;
            self.anchor = self.last_x;
            self.q0 = self.force;
            self.virgin = false;
        } else if self.sliding && self.force.abs() > kinetic * static_limit {
            self.force = self.force.signum() * kinetic * static_limit;
            self.q0 = self.force;
        }
        self.force
    }

    /// Marks the contact as at rest: the next move in the same direction re-sticks and
    /// loads a fresh branch from the current force (stick-slip).
    pub fn rest(&mut self) {
        if self.sliding {
            self.sliding = false;
            self.anchor = self.last_x;
            self.q0 = self.force;
            self.virgin = false;
        }
    }

    /// Scales the stored force (when the normal load, hence the limits, relaxes).
    pub fn scale_force(&mut self, k: f64) {
        self.force *= k;
        self.q0 *= k;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cattaneo_mindlin_o12_closed_form() {
        for (r, c, q) in [
            (0.25, 0.866, 0.3505),
            (0.5, 0.707, 0.6464),
            (0.75, 0.500, 0.875),
        ] {
            assert!((cm_stick_ratio(r) - c).abs() < 1e-3);
            assert!((cm_force_ratio(r) - q).abs() < 1e-3);
            assert!((cm_displacement(cm_force_ratio(r), 1.0) - r).abs() < 1e-12);
        }
    }

    #[test]
    fn masing_o13() {
        let virgin = |q: f64| cm_displacement(q, 1.0);
        for q_star in [0.2, 0.5, 0.9] {
            assert!((masing_unloading(virgin, q_star, q_star) - virgin(q_star)).abs() < 1e-12);
            assert!((masing_unloading(virgin, q_star, -q_star) + virgin(q_star)).abs() < 1e-12);
        }
    }

    #[test]
    fn hertz_tangential_field_o11() {
        assert!((hertz_tangential_ux(1.0, 1.0, 0.3, 1.0, 0.0, 0.0) - 0.667588).abs() < 1e-6);
        assert!((hertz_tangential_ux(1.0, 1.0, 0.3, 1.0, 0.5, 0.0) - 0.591503).abs() < 1e-6);
        assert!((hertz_tangential_ux(1.0, 1.0, 0.3, 1.0, 0.0, 0.5) - 0.576777).abs() < 1e-6);
    }

    fn cm_backbone() -> Backbone {
        let x: Vec<f64> = (0..=100).map(|i| i as f64 / 100.0).collect();
        let f = x.iter().map(|v| cm_force_ratio(*v)).collect();
        Backbone { x, f }
    }

    #[test]
    fn element_follows_masing_and_closes_the_loop() {
        let b = cm_backbone();
        let mut e = FrictionElement::at(0.0);
        let mut x = 0.0;
        while x < 0.6 {
            x += 0.01;
            e.update(x, &b, 1.0, 1.0);
        }
        let q_star = e.force();
        assert!((q_star - cm_force_ratio(0.6)).abs() < 1e-3);
        // Unload to −0.6: the force reaches −Q* (Masing), and reloading returns to Q*.
        while x > -0.6 {
            x -= 0.01;
            e.update(x, &b, 1.0, 1.0);
        }
        assert!(
            (e.force() + q_star).abs() < 2e-3,
            "{} vs {}",
            e.force(),
            -q_star
        );
        while x < 0.6 {
            x += 0.01;
            e.update(x, &b, 1.0, 1.0);
        }
        assert!((e.force() - q_star).abs() < 2e-3);
    }

    #[test]
    fn element_slips_at_the_limit_and_sticks_again() {
        let b = cm_backbone();
        let mut e = FrictionElement::at(0.0);
        let mut peaks = Vec::new();
        let mut x = 0.0;
        for _ in 0..3 {
            let mut peak: f64 = 0.0;
            for _ in 0..150 {
                x += 0.01;
                peak = peak.max(e.update(x, &b, 1.0, 0.8));
            }
            peaks.push((peak, e.force()));
            e.rest();
        }
        for (peak, after) in peaks {
            assert!((peak - 1.0).abs() < 1e-2, "static limit {peak}");
            assert!((after - 0.8).abs() < 1e-12, "kinetic {after}");
        }
    }
}
