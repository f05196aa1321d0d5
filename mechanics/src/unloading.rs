//! Viscoelastic contact of a curved indenter whose contact may shrink: Ting's treatment
//! (Ting 1966) by the method of dimensionality reduction (Popov, Heß & Willert 2018,
//! "MDR … handbook III: viscoelastic contacts"; Argatov & Popov 2016, ZAMM 96:956, the
//! rebound indentation problem).
//!
//! Lee & Radok's hereditary integral F(t) = ∫ G(t − τ) dF_e(δ(τ)) is exact only while the
//! contact grows. Unloading a sphere, the contact shrinks: the edge of the old contact lets
//! go of the indenter while the gel under it is still compressed by its history, and the
//! true force stays above Lee–Radok's (which dips below zero on a fast unload, the indenter
//! "pulling" a gel it no longer touches). Ting's solution follows the contact's shrinking
//! radius; the MDR reproduces it exactly for a half-space with a one-dimensional foundation of
//! independent viscoelastic elements of width Δx at x ≥ 0, each pressed by the indenter's
//! equivalent profile g(x) — an element touches while the indenter pushes it (its force is
//! compressive), lets go when its force would pull, and then creeps back at zero force until
//! the indenter reaches it again.
//!
//! On a bonded layer the elastic force F_e(δ) is not Hertz's; the foundation is built so that
//! it reproduces F_e exactly: with a unit modulus per length, dF/dδ = 2a(δ) for the
//! foundation's contact half-width a, so a(δ) = F_e′(δ)/2 and g is its inverse. Loading it
//! gives Lee–Radok on F_e to the element discretisation (each element's force is the
//! hereditary integral of its own indentation, which starts when δ reaches g); unloading, its
//! contact shrinks as the equivalent half-space's does. For the layer that is the treatment
//! of a half-space with the layer's force law — exact for the layer while the contact grows,
//! an approximation of the layer's own (unsolved here) viscoelastic unloading once it
//! shrinks.
//!
//! Each element is a generalised Maxwell body with the gel's normalised relaxation
//! G(t) = 1 + Σ wᵢ e^{−t/τᵢ}: force f = w + Σ wᵢ sᵢ (w its indentation, sᵢ the stretch of the
//! i-th Maxwell spring), advanced over a step with w linear in time, sᵢ ← e^{−x}sᵢ +
//! r(x)·Δw, x = Δt/τᵢ, r the ramp factor ([`crate::ramp_factor`]) — for a pressed element the
//! same exact update as [`crate::PronyState`]. A free element's indentation is not linear in
//! time (it creeps back exponentially), so a step is cut into pieces of at most a tenth of
//! the shortest τ, over which the linear update is accurate to well under 1 %.

use crate::viscoelastic::{Prony, ramp_factor};

/// The indenter on its equivalent foundation.
#[derive(Debug, Clone, PartialEq)]
pub struct TingContact {
    /// Equivalent profile at each element, mm (increasing).
    g: Vec<f64>,
    /// Each element's width times the foundation's two sides (unit modulus per width:
    /// forces in N when F_e is).
    width: f64,
    /// Each element's indentation, mm (positive into the gel).
    w: Vec<f64>,
    /// Each element's Maxwell stretches, mm, `terms` per element.
    s: Vec<f64>,
    /// Whether the indenter presses each element.
    touching: Vec<bool>,
    weights: Vec<f64>,
    taus_s: Vec<f64>,
    /// The depth at the end of the last step, mm.
    depth_mm: f64,
}

/// Elements of the foundation: the force's discretisation error is below 1e-4 of F_e.
pub const ELEMENTS: usize = 400;

impl TingContact {
    /// The foundation reproducing the elastic force law `elastic_n` (N at depth, mm;
    /// increasing, zero at zero) up to `max_depth_mm`, with the gel's relaxation `prony`.
    /// `None` when the law is not finite and increasing over that range.
    pub fn new(elastic_n: impl Fn(f64) -> f64, max_depth_mm: f64, prony: &Prony) -> Option<Self> {
        if !(max_depth_mm.is_finite() && max_depth_mm > 0.0) {
            return None;
        }
        // a(δ) = F_e′(δ)/2 on a fine depth grid (central differences; one-sided at the ends).
        let m = 4 * ELEMENTS;
        let step = max_depth_mm / m as f64;
        let depths: Vec<f64> = (0..=m).map(|j| j as f64 * step).collect();
        let forces: Vec<f64> = depths.iter().map(|&d| elastic_n(d)).collect();
        if !forces.iter().all(|f| f.is_finite()) {
            return None;
        }
        // Made non-decreasing: a law that is locally concave is read at its running maximum.
        let mut running = 0.0f64;
        let a: Vec<f64> = (0..=m)
            .map(|j| {
                let (lo, hi) = (j.saturating_sub(1), (j + 1).min(m));
                running = running.max(0.5 * (forces[hi] - forces[lo]) / (depths[hi] - depths[lo]));
                running
            })
            .collect();
        let a_max = a[m];
        if a_max.is_nan() || a_max <= 0.0 {
            return None;
        }
        // Elements uniform in x; g(x) is the depth at which a(δ) reaches x.
        let dx = a_max / ELEMENTS as f64;
        let g: Vec<f64> = (0..ELEMENTS)
            .map(|k| {
                let x = (k as f64 + 0.5) * dx;
                let j = a.partition_point(|v| *v < x).clamp(1, m);
                let (a0, a1) = (a[j - 1], a[j]);
                let t = if a1 > a0 {
                    ((x - a0) / (a1 - a0)).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                depths[j - 1] + t * (depths[j] - depths[j - 1])
            })
            .collect();
        // Scaled so the foundation's force at the deepest depth is F_e's there (the
        // midpoint rule's O(Δx²) error taken out where it is largest).
        let raw: f64 = g
            .iter()
            .map(|gk| 2.0 * dx * (max_depth_mm - gk).max(0.0))
            .sum();
        let scale = if raw > 0.0 { forces[m] / raw } else { 1.0 };
        let nt = prony.terms().len();
        Some(Self {
            width: 2.0 * dx * scale,
            g,
            w: vec![0.0; ELEMENTS],
            s: vec![0.0; ELEMENTS * nt],
            touching: vec![false; ELEMENTS],
            weights: prony.terms().iter().map(|t| t.weight).collect(),
            taus_s: prony.terms().iter().map(|t| t.tau_s).collect(),
            depth_mm: 0.0,
        })
    }

    /// Advances the state by `dt_s` to depth `depth_mm` (the depth moving linearly over the
    /// step); returns the force, N.
    pub fn step(&mut self, depth_mm: f64, dt_s: f64) -> f64 {
        let dt = if dt_s.is_finite() { dt_s.max(0.0) } else { 0.0 };
        let tau_min = self.taus_s.iter().copied().fold(f64::INFINITY, f64::min);
        let pieces = if tau_min.is_finite() && dt > 0.0 {
            (dt / (0.1 * tau_min)).ceil().clamp(1.0, 1e6) as usize
        } else {
            1
        };
        let d0 = self.depth_mm;
        let mut f = 0.0;
        for j in 1..=pieces {
            let d = d0 + (depth_mm - d0) * j as f64 / pieces as f64;
            f = self.piece(d, dt / pieces as f64);
        }
        self.depth_mm = depth_mm;
        f
    }

    /// One piece of [`Self::step`].
    fn piece(&mut self, depth_mm: f64, dt_s: f64) -> f64 {
        let nt = self.weights.len();
        let decay: Vec<(f64, f64)> = self
            .taus_s
            .iter()
            .map(|tau| {
                let x = dt_s.max(0.0) / tau;
                ((-x).exp(), ramp_factor(x))
            })
            .collect();
        let wr: f64 = self
            .weights
            .iter()
            .zip(&decay)
            .map(|(w, (_, r))| w * r)
            .sum();
        let mut total = 0.0;
        for k in 0..ELEMENTS {
            let w_c = depth_mm - self.g[k];
            let s = &mut self.s[k * nt..(k + 1) * nt];
            let w0 = self.w[k];
            if w0 == 0.0 && w_c < 0.0 && s.iter().all(|v| *v == 0.0) {
                continue; // never touched, at rest, out of reach
            }
            // Free at zero force: w₁(1 + Σwᵢrᵢ) = w₀Σwᵢrᵢ − Σwᵢeᵢsᵢ.
            let mut num = w0 * wr;
            for (i, si) in s.iter().enumerate() {
                num -= self.weights[i] * decay[i].0 * si;
            }
            let free_w = num / (1.0 + wr);
            // The indenter presses the element where it reaches at least as deep as the
            // element's free surface; otherwise the element creeps back at zero force.
            let touching = w_c >= free_w;
            let w1 = if touching { w_c } else { free_w };
            let mut f = w1;
            for (i, si) in s.iter_mut().enumerate() {
                *si = decay[i].0 * *si + decay[i].1 * (w1 - w0);
                f += self.weights[i] * *si;
            }
            self.w[k] = w1;
            self.touching[k] = touching;
            if touching {
                total += self.width * f.max(0.0);
            }
        }
        total
    }

    /// How many of the foundation's elements the indenter presses now: the equivalent
    /// contact's half-width in elements (it shrinks on unloading).
    pub fn touching_elements(&self) -> usize {
        self.touching.iter().filter(|t| **t).count()
    }
}

#[cfg(test)]
mod tests;
