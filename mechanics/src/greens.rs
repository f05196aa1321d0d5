//! Green's functions of the elastomer surface: what a point force does to it.
//!
//! - Point loads on a half-space (Boussinesq, Cerruti; Johnson §3.2–3.3), the closed-form
//!   oracles every numerical kernel is checked against.
//! - The Fourier tensors Ĝ(k) relating surface traction to surface displacement, û = Ĝ t̂,
//!   for the half-space and for a layer of thickness h bonded to a rigid base (spec §1.8).
//!   The bonded layer is the physics of GelSight: its normal–tangential coupling Ĉ stays
//!   positive at ν = ½, which pushes the surface *outward* under a normal load (thesis
//!   Fig. 4-2) where a half-space would move inward or not at all.
//!
//! Conventions (spec): z points into the gel, p > 0 is compressive; f(x) = ∫ f̂ e^{ik·x}
//! d²k/(2π)²; moduli in MPa, lengths in mm, forces in N.

use std::f64::consts::PI;

/// Surface displacement of a half-space under a normal point force `p_n` at distance
/// `r_mm` (Boussinesq, Johnson §3.2): returns (u_z, u_r), u_r < 0 meaning inward.
pub fn boussinesq(p_n: f64, e_mpa: f64, nu: f64, r_mm: f64) -> (f64, f64) {
    let uz = (1.0 - nu * nu) * p_n / (PI * e_mpa * r_mm);
    let ur = -(1.0 - 2.0 * nu) * (1.0 + nu) * p_n / (2.0 * PI * e_mpa * r_mm);
    (uz, ur)
}

/// Surface displacement of a half-space at (x, y) under a tangential point force `q_n`
/// along +x at the origin (Cerruti, Johnson §3.3): returns (u_x, u_y, u_z). Ahead of the
/// force the surface moves *into* the solid (u_z > 0), as Betti reciprocity with the
/// inward Boussinesq u_r requires (spec §1.1, sign warning).
pub fn cerruti(q_n: f64, e_mpa: f64, nu: f64, x: f64, y: f64) -> (f64, f64, f64) {
    let rho2 = x * x + y * y;
    let rho = rho2.sqrt();
    let c = (1.0 + nu) * q_n / (PI * e_mpa);
    let ux = c * ((1.0 - nu) / rho + nu * x * x / (rho2 * rho));
    let uy = c * nu * x * y / (rho2 * rho);
    let uz = (1.0 + nu) * (1.0 - 2.0 * nu) * q_n * x / (2.0 * PI * e_mpa * rho2);
    (ux, uy, uz)
}

/// The four scalar functions of an isotropic surface compliance tensor at one |k|: in the
/// frame of k (L along k, T across it, z normal), û_L = g_ll t̂_L + … Units mm³/N.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Scalars {
    /// Ĝ_LL: in-plane response along k.
    pub ll: f64,
    /// Ĝ_TT: in-plane response across k.
    pub tt: f64,
    /// Ĝ_zz: normal response.
    pub zz: f64,
    /// Ĉ: normal–tangential coupling; Ĝ_Lz = −iĈ, Ĝ_zL = +iĈ.
    pub c: f64,
}

impl Scalars {
    /// The Cartesian tensor at (kx, ky): returns [[Gxx, Gxy], [Gxy, Gyy]], Gzz, and the
    /// imaginary parts (cx, cy) with Ĝ_xz = −i·cx, Ĝ_zx = +i·cx, Ĝ_yz = −i·cy, Ĝ_zy = +i·cy.
    pub fn cartesian(&self, kx: f64, ky: f64) -> ([[f64; 2]; 2], f64, (f64, f64)) {
        let k2 = kx * kx + ky * ky;
        if k2 == 0.0 {
            return ([[self.ll, 0.0], [0.0, self.ll]], self.zz, (0.0, 0.0));
        }
        let k = k2.sqrt();
        let gxx = (kx * kx * self.ll + ky * ky * self.tt) / k2;
        let gyy = (ky * ky * self.ll + kx * kx * self.tt) / k2;
        let gxy = kx * ky * (self.ll - self.tt) / k2;
        (
            [[gxx, gxy], [gxy, gyy]],
            self.zz,
            (kx / k * self.c, ky / k * self.c),
        )
    }
}

/// Half-space surface compliance at |k| > 0 (spec §1.1; ContactMechanics `Isotropic.py`).
pub fn half_space(k: f64, mu_mpa: f64, nu: f64) -> Scalars {
    let mk = mu_mpa * k;
    Scalars {
        ll: (1.0 - nu) / mk,
        tt: 1.0 / mk,
        zz: (1.0 - nu) / mk,
        c: -(1.0 - 2.0 * nu) / (2.0 * mk),
    }
}

/// sinh(x) − x without cancellation for small x.
fn sinh_minus_x(x: f64) -> f64 {
    if x.abs() < 0.5 {
        let x2 = x * x;
        // x³/6 + x⁵/120 + x⁷/5040 + x⁹/362880 + x¹¹/39916800: < 1e-17 relative at x = 0.5.
        x * x2
            * (1.0 / 6.0
                + x2 * (1.0 / 120.0
                    + x2 * (1.0 / 5040.0 + x2 * (1.0 / 362_880.0 + x2 / 39_916_800.0))))
    } else {
        x.sinh() - x
    }
}

/// Surface compliance of a layer of thickness `h_mm` bonded to a rigid base, free on top,
/// at wavenumber `k` ≥ 0 (spec §1.8, derived; checked there against ContactMechanics'
/// `FFTElasticHalfSpace` thickness branch and Trepat et al. 2009).
///
/// With K = kh, κ = 3−4ν, c₀ = 5−12ν+8ν², Δ = κ cosh 2K + 2K² + c₀:
/// μkĜ_zz = (1−ν)(κ sinh 2K − 2K)/Δ, μkĜ_LL = (1−ν)(κ sinh 2K + 2K)/Δ, μkĜ_TT = tanh K,
/// μkĈ = [2K² − (1−2ν)κ(cosh 2K − 1)]/(2Δ). For K > 20 the half-space values are used
/// (relative difference < 1e-14); for small K, κ sinh 2K − 2K is formed as
/// (κ−1) sinh 2K + (sinh 2K − 2K) with a series for the latter, and cosh 2K − 1 as
/// 2 sinh² K, so ν = ½ and k → 0 lose no digits; k = 0 takes the exact limits.
pub fn layer(k: f64, h_mm: f64, mu_mpa: f64, nu: f64) -> Scalars {
    let kk = k * h_mm;
    if kk > 20.0 {
        return half_space(k, mu_mpa, nu);
    }
    if k == 0.0 {
        return Scalars {
            ll: h_mm / mu_mpa,
            tt: h_mm / mu_mpa,
            zz: h_mm * (1.0 - 2.0 * nu) / (2.0 * mu_mpa * (1.0 - nu)),
            c: 0.0,
        };
    }
    let kap = 3.0 - 4.0 * nu;
    let c0 = 5.0 - 12.0 * nu + 8.0 * nu * nu;
    let x = 2.0 * kk;
    let sinh2 = x.sinh();
    let cosh2m1 = 2.0 * kk.sinh().powi(2);
    let delta = kap * (cosh2m1 + 1.0) + 2.0 * kk * kk + c0;
    let mk = mu_mpa * k;
    let zz_num = (kap - 1.0) * sinh2 + sinh_minus_x(x);
    let ll_num = kap * sinh2 + x;
    Scalars {
        ll: (1.0 - nu) * ll_num / delta / mk,
        tt: kk.tanh() / mk,
        zz: (1.0 - nu) * zz_num / delta / mk,
        c: (2.0 * kk * kk - (1.0 - 2.0 * nu) * kap * cosh2m1) / (2.0 * delta) / mk,
    }
}

/// Δ(iy) = κ cos 2y − 2y² + c₀: the layer's denominator on the imaginary K axis. Its first
/// root sets the decay length of the layer kernel in real space, e^{−y r/h} (spec §1.8).
pub fn layer_denominator_imag(y: f64, nu: f64) -> f64 {
    let kap = 3.0 - 4.0 * nu;
    let c0 = 5.0 - 12.0 * nu + 8.0 * nu * nu;
    kap * (2.0 * y).cos() - 2.0 * y * y + c0
}

/// First root y of Δ(iy) = 0 (0.739085 at ν = ½, where it is cos y = y; 0.912785 at 0.3).
pub fn layer_pole(nu: f64) -> f64 {
    let (mut lo, mut hi) = (0.0, 1.5);
    // Δ(0) = κ + c₀ > 0 and Δ(i·1.5) < 0 for 0 ≤ ν ≤ ½.
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if layer_denominator_imag(mid, nu) > 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn boussinesq_o1() {
        let (uz, ur) = boussinesq(1.0, 1.0, 0.3, 1.0);
        assert!((uz - 0.91 / PI).abs() < 1e-12);
        assert!((uz - 0.289662).abs() < 1e-6);
        assert!((ur + 0.082761).abs() < 1e-6);
        assert!((ur + 0.4 * 1.3 / (2.0 * PI)).abs() < 1e-12);
    }

    #[test]
    fn cerruti_o2() {
        // G = 1 → E = 2(1+ν) = 2.6.
        let (ux, uy, uz) = cerruti(1.0, 2.6, 0.3, 1.0, 0.0);
        assert!((ux - 1.0 / (2.0 * PI)).abs() < 1e-12);
        assert!(uy.abs() < 1e-15);
        assert!((uz - 0.4 / (4.0 * PI)).abs() < 1e-12);
        assert!(
            uz > 0.0,
            "ahead of the force the surface moves into the solid"
        );
    }

    #[test]
    fn reciprocity_o3() {
        // u_x(A) due to P at B equals u_z(B) due to Q_x at A (Betti).
        let (e, nu) = (1.7, 0.27);
        let (a, b): ((f64, f64), (f64, f64)) = ((0.3, -1.1), (2.2, 0.4));
        let (dx, dy) = (a.0 - b.0, a.1 - b.1);
        let r = dx.hypot(dy);
        let (_, ur) = boussinesq(1.0, e, nu, r);
        let ux_a = ur * dx / r;
        let (_, _, uz_b) = cerruti(1.0, e, nu, b.0 - a.0, b.1 - a.1);
        assert!((ux_a - uz_b).abs() < 1e-12, "{ux_a} vs {uz_b}");
        // In Fourier space: Ĝ_xz = −Ĝ_zx by construction of `cartesian`.
        let s = layer(0.7, 2.0, 0.3, 0.45);
        let (_, _, (cx, _)) = s.cartesian(0.5, 0.49);
        assert!(cx != 0.0);
    }

    #[test]
    fn half_space_tensor_matches_isotropic_py_o4() {
        let (mu, nu) = (0.37, 0.31);
        for (kx, ky) in [(0.3, 0.4), (-2.0, 0.1), (0.0, 5.0), (1e-3, -7.0)] {
            let k = f64::hypot(kx, ky);
            let ([[gxx, gxy], [_, gyy]], gzz, (cx, cy)) = half_space(k, mu, nu).cartesian(kx, ky);
            let rel = |a: f64, b: f64| (a - b).abs() / b.abs().max(1e-300);
            assert!(rel(gxx, (1.0 - nu * kx * kx / (k * k)) / (mu * k)) < 1e-14);
            assert!(rel(gyy, (1.0 - nu * ky * ky / (k * k)) / (mu * k)) < 1e-14);
            assert!((gxy + nu * kx * ky / (mu * k.powi(3))).abs() < 1e-14 * gxx.abs());
            assert!(rel(gzz, (1.0 - nu) / (mu * k)) < 1e-14);
            // Ĝ_xz = i(1−2ν)k_x/(2μk²) = −i·cx.
            assert!((-cx - (1.0 - 2.0 * nu) * kx / (2.0 * mu * k * k)).abs() < 1e-14 * gzz);
            assert!((-cy - (1.0 - 2.0 * nu) * ky / (2.0 * mu * k * k)).abs() < 1e-14 * gzz);
        }
    }

    #[test]
    fn layer_limits_o5() {
        let (mu, nu, h) = (0.8, 0.5, 2.0);
        // K = 30: the half-space.
        let k = 30.0 / h;
        let (l, hs) = (layer(k, h, mu, nu), half_space(k, mu, nu));
        for (a, b) in [(l.ll, hs.ll), (l.tt, hs.tt), (l.zz, hs.zz)] {
            assert!((a - b).abs() < 1e-10 * b.abs());
        }
        assert!(l.c.abs() < 1e-10 / (mu * k));
        // Just below the switch (K = 19.9) the exact formulas already agree to 1e-10.
        let k = 19.9 / h;
        let (l, hs) = (layer(k, h, mu, 0.3), half_space(k, mu, 0.3));
        assert!((l.zz - hs.zz).abs() < 1e-10 * hs.zz && (l.c - hs.c).abs() < 1e-10 * hs.c.abs());
        // K = 1e-3 at ν = ½: thin incompressible layer (lubrication, spec §1.7).
        let k = 1e-3 / h;
        let l = layer(k, h, mu, 0.5);
        let zz_thin = k * k * h.powi(3) / (3.0 * mu);
        let c_thin = k * h * h / (2.0 * mu);
        assert!((l.zz / zz_thin - 1.0).abs() < 1e-5, "{}", l.zz / zz_thin);
        assert!((l.c / c_thin - 1.0).abs() < 1e-5, "{}", l.c / c_thin);
        // k = 0: exact limits.
        let z = layer(0.0, h, mu, 0.3);
        let near = layer(1e-9, h, mu, 0.3);
        assert!((z.zz - near.zz).abs() < 1e-8 * z.zz && (z.ll - near.ll).abs() < 1e-8 * z.ll);
        assert!(layer(0.0, h, mu, 0.5).zz == 0.0);
        // ν = 0.49999 stays finite and close to ν = ½.
        let a = layer(0.5, h, mu, 0.49999);
        let b = layer(0.5, h, mu, 0.5);
        assert!(a.zz.is_finite() && (a.zz - b.zz).abs() < 1e-4 * b.zz);
    }

    #[test]
    fn coupling_pushes_outward_on_the_incompressible_layer() {
        // Ĉ > 0 at ν = ½ for all K (outward), and −(1−2ν)/(2μk) < 0 on the half-space.
        for kk in [0.01, 0.3, 1.0, 3.0, 10.0] {
            assert!(layer(kk, 1.0, 1.0, 0.5).c > 0.0, "K = {kk}");
        }
        assert!(half_space(1.0, 1.0, 0.3).c < 0.0);
    }

    #[test]
    fn layer_pole_o6() {
        assert!((layer_pole(0.5) - 0.739085).abs() < 1e-6);
        assert!((layer_pole(0.3) - 0.912785).abs() < 1e-6);
        assert!(layer_denominator_imag(layer_pole(0.5), 0.5).abs() < 1e-12);
    }
}
