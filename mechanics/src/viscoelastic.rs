//! Prony series (generalised Maxwell model) with the exact exponential update.
//!
//! The elastomer relaxes for minutes after each step (thesis Fig. 3-4, 4-5a), with time
//! constants that span milliseconds to hours. An explicit integrator diverges once the time
//! step exceeds twice the shortest τ (amplification |1 − Δt/τ|, spec §3), and a dry run steps
//! in whatever intervals the protocol's sample rates give. So every internal variable is
//! advanced by its exact solution over the step (Taylor, Pister & Goudreau 1970; Simo &
//! Hughes 1998 §10.3), which is unconditionally stable for any τ and Δt: the decay factor
//! e^{−x} and the ramp factor (1 − e^{−x})/x both lie in (0, 1].
//!
//! The model is written for a *driving elastic quantity* f_e(t) — a force computed with the
//! long-term modulus — rather than for stress and strain, so it also gives the hereditary
//! (Lee–Radok) form for contacts whose force is nonlinear in depth (spec §3, "Contact
//! correspondence"): F(t) = f_e(t) + Σ hᵢ(t), with ḣᵢ = −hᵢ/τᵢ + wᵢ ḟ_e.

use crate::{MechanicsError, check_range};

/// One Maxwell arm: extra modulus `weight · E∞` that relaxes with time constant `tau_s`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PronyTerm {
    /// Modulus of this arm relative to the long-term modulus (Gᵢ/G∞), ≥ 0.
    pub weight: f64,
    /// Relaxation time in seconds, > 0.
    pub tau_s: f64,
}

impl PronyTerm {
    /// Validates the term.
    pub fn check(&self) -> Result<(), MechanicsError> {
        check_range("prony.weight", self.weight, self.weight >= 0.0, ">= 0")?;
        check_range("prony.tau_s", self.tau_s, self.tau_s > 0.0, "> 0")
    }
}

/// Normalised relaxation function g(t) = G(t)/G∞ = 1 + Σ wᵢ e^{−t/τᵢ}.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Prony {
    terms: Vec<PronyTerm>,
}

impl Prony {
    /// Builds a series after checking every term.
    pub fn new(terms: Vec<PronyTerm>) -> Result<Self, MechanicsError> {
        for t in &terms {
            t.check()?;
        }
        Ok(Self { terms })
    }

    /// The terms, in the order given.
    pub fn terms(&self) -> &[PronyTerm] {
        &self.terms
    }

    /// g(t) for t ≥ 0: the response to a unit step of the driving quantity at t = 0.
    pub fn relaxation(&self, t_s: f64) -> f64 {
        1.0 + self
            .terms
            .iter()
            .map(|p| p.weight * (-t_s / p.tau_s).exp())
            .sum::<f64>()
    }

    /// g(0⁺) = 1 + Σ wᵢ: the ratio of instantaneous to relaxed stiffness.
    pub fn instantaneous(&self) -> f64 {
        1.0 + self.terms.iter().map(|p| p.weight).sum::<f64>()
    }

    /// The longest relaxation time, or 0 for a purely elastic material.
    pub fn slowest_tau_s(&self) -> f64 {
        self.terms.iter().map(|p| p.tau_s).fold(0.0, f64::max)
    }

    /// A fresh hereditary state at rest (no load history).
    pub fn state(&self) -> PronyState {
        PronyState {
            h: vec![0.0; self.terms.len()],
            driving: 0.0,
        }
    }
}

/// (1 − e^{−x})/x: what a Prony term keeps of a change applied as a ramp over x = Δt/τ
/// (rather than a jump at its start; spec §3, "strain linear over the step"). `-expm1(-x)/x`
/// keeps full precision as x → 0 (the jump's 1) and tends to 0 as x → ∞.
pub fn ramp_factor(x: f64) -> f64 {
    if x < 1e-300 { 1.0 } else { -(-x).exp_m1() / x }
}

/// Hereditary state of one loaded quantity: the driving elastic value and one internal
/// variable per Prony term.
#[derive(Debug, Clone, PartialEq)]
pub struct PronyState {
    h: Vec<f64>,
    driving: f64,
}

impl PronyState {
    /// Current total response f_e + Σ hᵢ.
    pub fn value(&self) -> f64 {
        self.driving + self.h.iter().sum::<f64>()
    }

    /// Current driving (long-term elastic) value f_e.
    pub fn driving(&self) -> f64 {
        self.driving
    }

    /// Advances by `dt_s` with the driving quantity moving *linearly* from its current
    /// value to `new_driving`. Exact for piecewise-linear histories; `dt_s = 0` is a jump.
    ///
    /// hᵢ ← e^{−x}hᵢ + wᵢ·(1 − e^{−x})/x·Δf, x = Δt/τᵢ (spec §3, "strain linear over the
    /// step"). `-expm1(-x)/x` keeps full precision for x → 0 and tends to 0 for x → ∞.
    pub fn advance_linear(&mut self, prony: &Prony, dt_s: f64, new_driving: f64) {
        let delta = new_driving - self.driving;
        for (h, term) in self.h.iter_mut().zip(prony.terms()) {
            let x = dt_s.max(0.0) / term.tau_s;
            let ramp = ramp_factor(x);
            *h = (-x).exp() * *h + term.weight * ramp * delta;
        }
        self.driving = new_driving;
    }

    /// The response after [`Self::advance_linear`] by `dt_s` to a new driving value f is
    /// affine in f: returns `(gain, offset)` with value = gain·f + offset, without moving
    /// the state. Where the driving value is not prescribed but set by a balance (the gel
    /// in series with a sponge in a grasp, whose force must equal the gel's viscoelastic
    /// one), the balance can then be solved for f in one pass: gain = 1 + Σ wᵢ·rampᵢ ≥ 1
    /// keeps it monotone.
    pub fn step_affine(&self, prony: &Prony, dt_s: f64) -> (f64, f64) {
        let (mut gain, mut offset) = (1.0, 0.0);
        for (h, term) in self.h.iter().zip(prony.terms()) {
            let x = dt_s.max(0.0) / term.tau_s;
            let ramp = ramp_factor(x);
            gain += term.weight * ramp;
            offset += (-x).exp() * h - term.weight * ramp * self.driving;
        }
        (gain, offset)
    }

    /// Scales the whole state (driving value and internal variables) by `factor`.
    ///
    /// Used where a contact constraint clips the response (Coulomb slip): the slipped part
    /// of the load history is forgotten proportionally rather than left to relax back.
    pub fn scale(&mut self, factor: f64) {
        self.driving *= factor;
        for h in &mut self.h {
            *h *= factor;
        }
    }

    /// Caps |value| at `limit` by trimming only the hereditary part, leaving the driving
    /// value as it is: a friction limit cuts the viscoelastic overshoot, and the memory of
    /// what drives the channel must stay right for the next update.
    pub fn cap_hereditary(&mut self, limit: f64) {
        let v = self.value();
        if v.abs() <= limit {
            return;
        }
        let hsum: f64 = self.h.iter().sum();
        let target = v.signum() * limit - self.driving;
        if hsum == 0.0 || target * hsum <= 0.0 {
            for h in &mut self.h {
                *h = 0.0;
            }
        } else {
            let k = target / hsum;
            for h in &mut self.h {
                *h *= k;
            }
        }
    }

    /// Shifts the driving value by `delta` without any hereditary response (a slip that
    /// moves the elastic anchor, not a new load).
    pub fn shift_driving(&mut self, delta: f64) {
        self.driving += delta;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Spec §3 test set: G∞ = 1, Gᵢ = (0.3, 0.2, 0.1), τ = (1e−3, 1, 1e3) s.
    fn spec_series() -> Prony {
        Prony::new(vec![
            PronyTerm {
                weight: 0.3,
                tau_s: 1e-3,
            },
            PronyTerm {
                weight: 0.2,
                tau_s: 1.0,
            },
            PronyTerm {
                weight: 0.1,
                tau_s: 1e3,
            },
        ])
        .expect("valid series")
    }

    #[test]
    fn unit_step_follows_relaxation_function_o19() {
        let p = spec_series();
        let mut s = p.state();
        s.advance_linear(&p, 0.0, 1.0);
        let dt = 0.05;
        let mut t = 0.0;
        for _ in 0..4000 {
            s.advance_linear(&p, dt, 1.0);
            t += dt;
            assert!((s.value() - p.relaxation(t)).abs() < 1e-12, "t = {t}");
        }
        let mut s = p.state();
        s.advance_linear(&p, 0.0, 1.0);
        s.advance_linear(&p, 0.05, 1.0);
        assert!((s.value() - 1.290241).abs() < 1e-6);
        let mut s2 = p.state();
        s2.advance_linear(&p, 0.0, 1.0);
        s2.advance_linear(&p, 200.0, 1.0);
        assert!((s2.value() - 1.081873).abs() < 1e-6);
    }

    #[test]
    fn ramp_and_hold_is_independent_of_step_size() {
        // Spec §3: rate 0.01 to t₁ = 10 s then hold: σ(10) = 0.111953, σ(100) = 0.109094.
        let p = spec_series();
        for dt in [0.1, 0.5, 1.0] {
            let mut s = p.state();
            let mut t: f64 = 0.0;
            while t < 100.0 - 1e-9 {
                let t_next = t + dt;
                let target = 0.01 * t_next.min(10.0);
                s.advance_linear(&p, dt, target);
                t = t_next;
                if (t - 10.0).abs() < 1e-9 {
                    assert!((s.value() - 0.111953).abs() < 1e-6, "dt {dt}");
                }
            }
            assert!((s.value() - 0.109094).abs() < 1e-6, "dt {dt}");
        }
    }

    #[test]
    fn stays_bounded_where_explicit_euler_diverges_o20() {
        // τ = 1 ms with Δt = 50 ms: explicit Euler amplifies by 49 per step.
        let p = Prony::new(vec![PronyTerm {
            weight: 1.0,
            tau_s: 1e-3,
        }])
        .expect("valid");
        let mut s = p.state();
        s.advance_linear(&p, 0.0, 1.0);
        for _ in 0..1000 {
            s.advance_linear(&p, 0.05, 1.0);
            assert!(s.value().is_finite() && s.value() <= 2.0 && s.value() >= 1.0);
        }
        assert!((s.value() - 1.0).abs() < 1e-15);
    }

    #[test]
    fn extreme_time_constants_and_steps_stay_finite() {
        for tau in [1e-3, 1.0, 1e4] {
            for dt in [1e-4, 1e-2, 1.0, 100.0] {
                let p = Prony::new(vec![PronyTerm {
                    weight: 2.0,
                    tau_s: tau,
                }])
                .expect("valid");
                let mut s = p.state();
                for k in 0..200 {
                    s.advance_linear(&p, dt, (k as f64 * 0.1).sin());
                    assert!(s.value().is_finite());
                }
            }
        }
    }

    #[test]
    fn ramp_and_hold_is_exact_for_stiff_and_slow_terms() {
        // F(t) = ∫ g(t−s) ḟ(s) ds for f ramping at rate 1 to t₁ then held:
        // t ≤ t₁: t + Σ wτ(1 − e^{−t/τ}); t > t₁: t₁ + Σ wτ(e^{−(t−t₁)/τ} − e^{−t/τ}).
        for tau in [1e-3, 1e-1, 10.0, 1e4] {
            for dt in [1e-4, 1e-2, 1.0, 100.0] {
                let w = 0.7;
                let p = Prony::new(vec![PronyTerm {
                    weight: w,
                    tau_s: tau,
                }])
                .expect("valid");
                let mut s = p.state();
                let t1 = 10.0 * dt;
                let mut t: f64 = 0.0;
                for k in 1..=30 {
                    let t_next = k as f64 * dt;
                    s.advance_linear(&p, dt, t_next.min(t1));
                    t = t_next;
                    let exact = if t <= t1 + 1e-15 {
                        t + w * tau * -(-t / tau).exp_m1()
                    } else {
                        t1 + w * tau * (-(t - t1) / tau).exp() * -(-t1 / tau).exp_m1()
                    };
                    assert!(
                        (s.value() - exact).abs() <= 1e-12 * exact.abs().max(1e-300) + 1e-300,
                        "τ {tau} Δt {dt} t {t}: {} vs {exact}",
                        s.value()
                    );
                }
                assert!(t > t1);
            }
        }
    }

    #[test]
    fn capping_trims_memory_not_the_driving_value() {
        let p = spec_series();
        let mut s = p.state();
        s.advance_linear(&p, 0.0, 1.0);
        assert!(s.value() > 1.5);
        s.cap_hereditary(1.2);
        assert!((s.value() - 1.2).abs() < 1e-12 && s.driving() == 1.0);
        // A later drop of the driving value is a real drop.
        s.advance_linear(&p, 1e3, 0.8);
        assert!(s.value() < 1.0);
    }

    /// The affine step predicts what advancing does, for any history and any new value;
    /// and a creep under a constant total (the balance it exists for) solved with it keeps
    /// the total and drives the elastic part up to it, as g(t) dictates.
    #[test]
    fn the_affine_step_predicts_the_advance_and_solves_a_creep() {
        let p = spec_series();
        let mut s = p.state();
        for (k, (dt, f)) in [
            (0.0, 1.0),
            (0.01, 1.3),
            (2.0, 0.7),
            (500.0, -0.2),
            (1e-4, 2.0),
        ]
        .into_iter()
        .enumerate()
        {
            let (gain, offset) = s.step_affine(&p, dt);
            s.advance_linear(&p, dt, f);
            let want = s.value();
            assert!((gain * f + offset - want).abs() < 1e-12, "step {k}");
        }
        // Creep: hold the total at 1 (a force held): f = (1 − offset)/gain each step.
        let mut s = p.state();
        let mut drive = Vec::new();
        for _ in 0..100_000 {
            let (gain, offset) = s.step_affine(&p, 0.1);
            let f = (1.0 - offset) / gain;
            s.advance_linear(&p, 0.1, f);
            assert!((s.value() - 1.0).abs() < 1e-9);
            drive.push(f);
        }
        // The elastic part starts near 1/g (the 1 ms term has relaxed within the first
        // 0.1 s ramp, so 1/(1 + 0.2 + 0.1) rather than 1/g(0) = 1/1.6) and creeps
        // monotonically towards 1.
        assert!(
            drive[0] > 1.0 / p.instantaneous() && drive[0] < 0.78,
            "{}",
            drive[0]
        );
        assert!(drive.windows(2).all(|w| w[1] >= w[0] - 1e-12));
        assert!(drive[drive.len() - 1] > 0.99 && drive[drive.len() - 1] <= 1.0 + 1e-9);
    }

    #[test]
    fn rejects_nonpositive_tau() {
        assert!(
            Prony::new(vec![PronyTerm {
                weight: 0.1,
                tau_s: 0.0
            }])
            .is_err()
        );
        assert!(
            Prony::new(vec![PronyTerm {
                weight: f64::NAN,
                tau_s: 1.0
            }])
            .is_err()
        );
    }
}
