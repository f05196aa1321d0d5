//! A later step's F∞ with the slowest relaxation carried from the steps before it.
//!
//! With the gel's time constants learned ([`crate::equilibrium::Learned`]), a later step is
//! F(t) = F∞ + Σ aᵢ e^{−t/τᵢ} with only F∞ and the amplitudes to fit — but over a record of
//! 20–30 s the slowest term (τ ≈ 60 s on the box gel) is nearly a straight line, and its
//! amplitude trades against F∞: that collinearity, not the noise, is what keeps such a step
//! waiting. The load history fixes the amplitude. For a linear viscoelastic gel each change
//! ΔF∞ⱼ of the equilibrium force at time tⱼ relaxes with the same normalised function
//! g(t) = 1 + Σ wᵢ e^{−t/τᵢ} (Boltzmann superposition; for a contact that grows or holds,
//! Lee & Radok 1960), so at the start t₀ of step k
//!
//!   a_slow = w_slow · (H + F∞ − F∞ₖ₋₁),  H = Σ_{j<k} ΔF∞ⱼ e^{−(t₀ − tⱼ)/τ_slow},
//!
//! with w_slow learned from the records that taught the time constants (each one's amplitude
//! over its own load change, pooled; [`crate::settle_rules::GelMemory`] learns it again
//! whenever the time constants move). The record then fits F∞ and the faster amplitudes
//! only:
//!
//!   F(t) − w (H − F∞ₖ₋₁) e^{−t/τ} = F∞ (1 + w e^{−t/τ}) + Σ_{fast} aᵢ e^{−t/τᵢ}.
//!
//! The uncertainty carries the fit's ±2σ, w moved by its ±2σ and each time constant by its
//! ±2σ, and σ is half the larger distance from F∞ to the ends, as in
//! [`crate::equilibrium`]. Where the history does not explain the record — a contact that
//! shrinks on unloading (Ting 1966), a punch lifting off, a load the memory did not see —
//! the tied fit's residual rises above the free one's by more than Δχ² =
//! [`crate::equilibrium::DRIFT_CHI2`], and the step keeps the free fit.

use nalgebra::{DMatrix, DVector};

use crate::equilibrium::{self, Equilibrium, Learned, MAX_POINTS};

/// The weight's smallest relative uncertainty: it is learned with time constants that are
/// themselves uncertain.
const WEIGHT_FLOOR: f64 = 0.05;

/// What the load history says of a later step's slowest relaxation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Carry {
    /// w_slow: the slowest term's amplitude per unit change of F∞.
    pub weight: f64,
    /// Its standard uncertainty.
    pub weight_sd: f64,
    /// H: the earlier changes of F∞, each decayed by the slowest term to this step's start.
    pub history: f64,
    /// F∞ of the step before (0 for the first).
    pub f_prev: f64,
}

/// The slowest term's weight learned from a record (t from its settle's start, the channel)
/// with the time constants `learned`, whose load changed by `load_change` (H + ΔF∞ of that
/// step): its amplitude over the change, and the standard uncertainty (the fit's, and 5 % of
/// the weight at least: the time constants are themselves uncertain).
pub fn slow_weight(
    t_s: &[f64],
    y: &[f64],
    learned: &Learned,
    load_change: f64,
) -> Option<(f64, f64)> {
    if load_change.abs() < 1e-9 {
        return None;
    }
    let (t, y) = equilibrium::binned(t_s, y, MAX_POINTS);
    let (x, se) = equilibrium::fit_with_errors(&t, &y, &learned.taus_s)?;
    let k = learned.taus_s.len();
    let w = x[k] / load_change;
    let sd = (se[k] / load_change.abs()).max(WEIGHT_FLOOR * w.abs());
    (w.is_finite() && sd.is_finite()).then_some((w, sd))
}

/// The tied fit for time constants `taus_s` and weight `w`: F∞, its standard error, the
/// residual sum.
fn tied(t: &[f64], y: &[f64], taus_s: &[f64], w: f64, carry: &Carry) -> Option<(f64, f64, f64)> {
    let s = taus_s.len().checked_sub(1)?;
    let tau = taus_s[s];
    let a = DMatrix::from_fn(t.len(), taus_s.len(), |i, j| {
        if j == 0 {
            1.0 + w * (-t[i] / tau).exp()
        } else {
            (-t[i] / taus_s[j - 1]).exp()
        }
    });
    let z = DVector::from_iterator(
        t.len(),
        t.iter()
            .zip(y)
            .map(|(ti, yi)| yi - w * (carry.history - carry.f_prev) * (-ti / tau).exp()),
    );
    let (x, se, rss) = equilibrium::lsq(&a, &z)?;
    Some((x[0], se[0], rss))
}

/// F∞ of a later step's record (t from its settle's start, the channel) with the slowest
/// amplitude tied to the load history; `free` is the step's estimate with the learned time
/// constants ([`equilibrium::estimate_with`]). `None` when the history does not explain the
/// record as well as the free amplitudes do (then the free estimate stands).
pub fn estimate_carried(
    t_s: &[f64],
    y: &[f64],
    learned: &Learned,
    carry: &Carry,
    free: &Equilibrium,
) -> Option<Equilibrium> {
    if !free.used_learned {
        return None;
    }
    let (t, y) = equilibrium::binned(t_s, y, MAX_POINTS);
    let n = t.len();
    let taus = &learned.taus_s;
    let (f_inf, se, rss) = tied(&t, &y, taus, carry.weight, carry)?;
    let (_, rss_free) = equilibrium::linear_fit(&t, &y, taus)?;
    let s2 = rss_free / n.saturating_sub(taus.len() + 1).max(1) as f64;
    if rss > rss_free + equilibrium::DRIFT_CHI2 * s2 {
        return None;
    }
    let mut lo = f_inf - 2.0 * se;
    let mut hi = f_inf + 2.0 * se;
    for sign in [-1.0, 1.0] {
        let w = carry.weight + sign * 2.0 * carry.weight_sd;
        if let Some((f, _, _)) = tied(&t, &y, taus, w, carry) {
            lo = lo.min(f);
            hi = hi.max(f);
        }
        for i in 0..taus.len() {
            let mut moved = taus.clone();
            moved[i] *= 1.0 + sign * 2.0 * learned.rel_sigma;
            if let Some((f, _, _)) = tied(&t, &y, &moved, carry.weight, carry) {
                lo = lo.min(f);
                hi = hi.max(f);
            }
        }
    }
    Some(Equilibrium {
        f_inf,
        sigma: 0.5 * (hi - f_inf).max(f_inf - lo),
        range: [lo, hi],
        noise_rms: (rss / n as f64).sqrt(),
        ..free.clone()
    })
}

/// A staircase of load changes `steps` (each at `start_s`, then held) on a gel
/// g = 1 + Σ wᵢ e^{−t/τᵢ}, sampled at 20 Hz from `from_s` for `len_s`, with a ±1 mN
/// ripple: t from `from_s`, the force.
#[cfg(test)]
pub(crate) fn staircase(
    steps: &[(f64, f64)],
    w: &[(f64, f64)],
    from_s: f64,
    len_s: f64,
) -> (Vec<f64>, Vec<f64>) {
    let t: Vec<f64> = (0..(len_s * 20.0) as usize)
        .map(|i| i as f64 / 20.0)
        .collect();
    let y = t
        .iter()
        .enumerate()
        .map(|(i, ti)| {
            let now = from_s + ti;
            let mut prev = 0.0;
            let mut f = 0.0;
            for (start, f_inf) in steps.iter().filter(|(s, _)| *s <= now) {
                let d = f_inf - prev;
                prev = *f_inf;
                f += d
                    * (1.0
                        + w.iter()
                            .map(|(wi, tau)| wi * (-(now - start) / tau).exp())
                            .sum::<f64>());
            }
            f + if i % 2 == 0 { 0.001 } else { -0.001 }
        })
        .collect();
    (t, y)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_load_history_pins_a_short_later_step_and_a_wrong_history_is_refused() {
        let gel = [(0.625, 1.5), (0.5, 15.0), (0.375, 60.0)];
        let learned = Learned {
            taus_s: vec![1.5, 15.0, 60.0],
            rel_sigma: 0.01,
            records: 1,
        };
        // Step 1 (to 1 N at 0 s), followed 300 s: it teaches the slow weight.
        let (t0, y0) = staircase(&[(0.0, 1.0)], &gel, 0.0, 300.0);
        let (w, sd) = slow_weight(&t0, &y0, &learned, 1.0).expect("weight");
        assert!((w - 0.375).abs() < 0.02 && sd < 0.05, "{w} ± {sd}");
        // Step 2 (to 2 N at 310 s), 20 s of record.
        let steps = [(0.0, 1.0), (310.0, 2.0)];
        let (t, y) = staircase(&steps, &gel, 310.0, 20.0);
        let free = equilibrium::estimate_with(&t, &y, 10.0, Some(&learned)).expect("fits");
        let carry = Carry {
            weight: w,
            weight_sd: sd,
            history: 1.0 * (-310.0f64 / 60.0).exp(),
            f_prev: 1.0,
        };
        let tied =
            estimate_carried(&t, &y, &learned, &carry, &free).expect("the history explains it");
        assert!((tied.f_inf - 2.0).abs() <= 2.0 * tied.sigma, "{tied:?}");
        assert!(
            tied.sigma < 0.5 * free.sigma,
            "tied {} vs free {}",
            tied.sigma,
            free.sigma
        );
        assert!(tied.known_within(0.01, 0.1), "{tied:?}");
        // A history that says the step came from 3 N, not 1 N: refused.
        let wrong = Carry {
            f_prev: 3.0,
            history: 3.0 * (-310.0f64 / 60.0).exp(),
            ..carry
        };
        assert!(estimate_carried(&t, &y, &learned, &wrong, &free).is_none());
    }
}
