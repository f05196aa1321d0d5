//! Flat circular punch on a bonded layer, semi-analytically (Hayes, Keer, Herrmann &
//! Mockros 1972, *J. Biomech.* 5:541; spec §1.9).
//!
//! The pressure is written through an Abel-type density f(t), which satisfies the Fredholm
//! equation of the second kind
//!
//!   f(t) − (1/π) ∫₀^a f(τ)[K̃(t−τ) + K̃(t+τ)] dτ = E*d/π,
//!   K̃(x) = ∫₀^∞ H(kh) cos(kx) dk,  H = 1 − μkĜ_zz/(1−ν),
//!
//! and the force is P = 2π∫₀^a f dt. f is smooth, so Nyström quadrature with Gauss–Legendre
//! nodes converges exponentially (7 digits with 32–128 nodes). H decays like K²e^{−2K}, so
//! K̃ is a smooth function of x on the scale h; it is tabulated once per solve on a uniform
//! grid (step h/64) by composite Gauss–Legendre in K over [0, 30] and interpolated by cubic
//! Hermite splines. With H = 0 (half-space) the solution is f = E*d/π and κ = 1 exactly.

use std::f64::consts::PI;

use nalgebra::{DMatrix, DVector};

use crate::greens;

/// Gauss–Legendre nodes and weights on [−1, 1] (Golub–Welsch would do; Newton on P_n is
/// simpler and accurate to machine precision for n ≤ 512).
pub fn gauss_legendre(n: usize) -> (Vec<f64>, Vec<f64>) {
    let mut x = vec![0.0; n];
    let mut w = vec![0.0; n];
    for i in 0..n.div_ceil(2) {
        let mut z = (PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
        let mut dp = 0.0;
        for _ in 0..100 {
            let (mut p0, mut p1) = (1.0, z);
            for k in 2..=n {
                let p2 = ((2 * k - 1) as f64 * z * p1 - (k - 1) as f64 * p0) / k as f64;
                p0 = p1;
                p1 = p2;
            }
            let pn = if n == 1 { z } else { p1 };
            let pnm1 = if n == 1 { 1.0 } else { p0 };
            dp = n as f64 * (z * pn - pnm1) / (z * z - 1.0);
            let dz = pn / dp;
            z -= dz;
            if dz.abs() < 1e-16 {
                break;
            }
        }
        x[i] = -z;
        x[n - 1 - i] = z;
        w[i] = 2.0 / ((1.0 - z * z) * dp * dp);
        w[n - 1 - i] = w[i];
    }
    (x, w)
}

/// H(K) = 1 − μkĜ_zz/(1−ν) of the bonded layer.
fn kernel_h(kk: f64, nu: f64) -> f64 {
    // μkĜ_zz depends on K and ν only: evaluate with h = μ = 1, k = K.
    1.0 - kk * greens::layer(kk, 1.0, 1.0, nu).zz / (1.0 - nu)
}

/// K̃ tabulated for x ∈ [0, x_max] (units of h), with cubic Hermite interpolation.
struct KernelTable {
    step: f64,
    values: Vec<f64>,
    slopes: Vec<f64>,
}

impl KernelTable {
    fn new(x_max: f64, nu: f64) -> Self {
        let step = 1.0 / 64.0;
        let m = (x_max / step).ceil() as usize + 2;
        // Composite Gauss–Legendre over K ∈ [0, 30]: panels of width 0.25, 8 nodes each,
        // enough for cos(Kx) with x up to several hundred h.
        let (gx, gw) = gauss_legendre(8);
        let panel = 0.25;
        let panels = (30.0 / panel) as usize;
        let mut nodes = Vec::with_capacity(panels * 8);
        for p in 0..panels {
            let a = p as f64 * panel;
            for (x, w) in gx.iter().zip(&gw) {
                let kk = a + (x + 1.0) * panel / 2.0;
                nodes.push((kk, w * panel / 2.0 * kernel_h(kk, nu)));
            }
        }
        let values: Vec<f64> = (0..m)
            .map(|i| {
                let x = i as f64 * step;
                nodes.iter().map(|(k, wh)| wh * (k * x).cos()).sum()
            })
            .collect();
        let slopes: Vec<f64> = (0..m)
            .map(|i| {
                let x = i as f64 * step;
                -nodes
                    .iter()
                    .map(|(k, wh)| wh * k * (k * x).sin())
                    .sum::<f64>()
            })
            .collect();
        Self {
            step,
            values,
            slopes,
        }
    }

    /// K̃(x) in units where h = 1 (even in x).
    fn at(&self, x: f64) -> f64 {
        let x = x.abs();
        let s = x / self.step;
        let i = (s.floor() as usize).min(self.values.len() - 2);
        let t = s - i as f64;
        let (y0, y1) = (self.values[i], self.values[i + 1]);
        let (m0, m1) = (self.slopes[i] * self.step, self.slopes[i + 1] * self.step);
        let (t2, t3) = (t * t, t * t * t);
        (2.0 * t3 - 3.0 * t2 + 1.0) * y0
            + (t3 - 2.0 * t2 + t) * m0
            + (-2.0 * t3 + 3.0 * t2) * y1
            + (t3 - t2) * m1
    }
}

/// Finite-thickness stiffening κ = P/(2E*ad) of a rigid flat circular punch of radius a on
/// a frictionless layer of thickness h bonded to a rigid base, by Nyström with `nodes`
/// Gauss–Legendre points.
pub fn layer_kappa(a_over_h: f64, nu: f64, nodes: usize) -> f64 {
    // Units: h = 1, a = a/h, E*d = π so the right-hand side is 1.
    let a = a_over_h;
    let table = KernelTable::new(2.0 * a + 1.0, nu);
    let (gx, gw) = gauss_legendre(nodes);
    let t: Vec<f64> = gx.iter().map(|x| (x + 1.0) * a / 2.0).collect();
    let w: Vec<f64> = gw.iter().map(|x| x * a / 2.0).collect();
    let n = nodes;
    let m = DMatrix::from_fn(n, n, |i, j| {
        let k = (table.at(t[i] - t[j]) + table.at(t[i] + t[j])) / PI;
        (if i == j { 1.0 } else { 0.0 }) - w[j] * k
    });
    let rhs = DVector::from_element(n, 1.0);
    let f = match m.lu().solve(&rhs) {
        Some(f) => f,
        None => return f64::NAN,
    };
    // P = 2π Σ w f with E*d = π; κ = P/(2E*ad) = Σ w f / a.
    f.iter().zip(&w).map(|(fi, wi)| fi * wi).sum::<f64>() / a
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gauss_legendre_integrates_polynomials() {
        let (x, w) = gauss_legendre(10);
        let integral: f64 = x.iter().zip(&w).map(|(x, w)| w * x.powi(18)).sum();
        assert!((integral - 2.0 / 19.0).abs() < 1e-14);
        assert!((w.iter().sum::<f64>() - 2.0).abs() < 1e-14);
    }

    #[test]
    fn kappa_semi_analytic_o15() {
        for (ah, nu, kappa) in [
            (0.2, 0.5, 1.2806),
            (1.131, 0.5, 4.1749),
            (1.51, 0.5, 6.0581),
            (0.2, 0.3, 1.2066),
            (1.0, 0.49, 3.4840),
            (2.0, 0.45, 6.4206),
        ] {
            let k = layer_kappa(ah, nu, 64);
            assert!(
                (k - kappa).abs() < 1e-4 * kappa.max(1.0) + 5e-5,
                "a/h {ah} ν {nu}: {k} vs {kappa}"
            );
        }
    }

    #[test]
    fn nystrom_converges_with_nodes() {
        let a = layer_kappa(1.131, 0.5, 32);
        let b = layer_kappa(1.131, 0.5, 128);
        assert!((a - b).abs() < 1e-6, "{a} vs {b}");
    }

    #[test]
    fn thin_layer_trend_o17() {
        // κ / κ_thin with κ_thin = 3π(a/h)³/64 (lubrication limit, spec §1.7): 2.72, 1.72,
        // 1.32 at a/h = 5, 10, 20, tending to 1.
        let ratio =
            |ah: f64, nodes: usize| layer_kappa(ah, 0.5, nodes) / (3.0 * PI * ah.powi(3) / 64.0);
        let r5 = ratio(5.0, 96);
        let r10 = ratio(10.0, 160);
        let r20 = ratio(20.0, 256);
        assert!((r5 - 2.72).abs() < 0.02, "{r5}");
        assert!((r10 - 1.72).abs() < 0.02, "{r10}");
        assert!((r20 - 1.32).abs() < 0.02, "{r20}");
        assert!(r5 > r10 && r10 > r20 && r20 > 1.0);
    }
}
