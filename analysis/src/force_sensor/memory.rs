//! The gel's memory of how it was pressed: why a field read on its own misses a relaxing
//! force, and how the force is recovered from the field's history.
//!
//! A gel pressed to a depth and held keeps its surface displacement while the force on it
//! relaxes: for a viscoelastic layer whose Poisson's ratio does not change with time, the
//! correspondence principle gives the displacement field of the elastic solution at that
//! depth, and only the stresses carry the relaxation function (Lee & Radok 1960; the thesis
//! measures the force relaxing at a held depth, Fig. 4-5a). So the pressing field reads the
//! *elastic* force f_e — the one the long-term modulus would give — and the force is the
//! hereditary integral F(t) = ∫ g(t − s) df_e(s), g(t) = 1 + Σ wᵢ e^{−t/τᵢ}, advanced exactly
//! frame by frame with [`mechanics::PronyState`].
//!
//! g is fitted from the force sensor's record of the calibration runs' held pressing steps:
//! time constants shared by all steps (variable projection, [`crate::relaxation::fit_shared`],
//! 1–3 terms by BIC), then each term's weight from how much each step's amplitude exceeds
//! what the earlier steps still relax by (least squares over the steps).

use mechanics::{Prony, PronyState, PronyTerm};

use crate::relaxation::fit_shared;

/// Frames further apart than this are not a continuous recording: the field is taken to
/// have changed at the start of the gap (a stepped run captures a frame at each step's end,
/// and the next step moves at once), not linearly across it.
pub const GAP_S: f64 = 0.5;

/// One held step of the pressing axis: when its move happened and the force while it held.
#[derive(Debug, Clone, PartialEq)]
pub struct HeldStep {
    /// Middle of the step's move, s on the run's clock (a ramp of duration T relaxes its
    /// terms by about what a jump at its middle does, e^{−T/2τ} ≈ (τ/T)(1 − e^{−T/τ})).
    pub change_s: f64,
    /// Sample times from the end of the move, s on the run's clock, increasing.
    pub t_s: Vec<f64>,
    /// The pressing force at those times.
    pub f: Vec<f64>,
}

/// Shortest held record, s, that enters the fit: shorter holds do not show a relaxation.
const MIN_HOLD_S: f64 = 10.0;

/// Fits the normalised relaxation function g from `steps` (in time order, one run's; give
/// each run separately and the results are pooled by [`fit_relaxation_runs`]).
///
/// Returns `None` when fewer than two steps hold long enough, the fit fails, or no term
/// carries weight (an elastic gel).
pub fn fit_relaxation_runs(runs: &[Vec<HeldStep>]) -> Option<Prony> {
    let held: Vec<(usize, &HeldStep)> = runs
        .iter()
        .enumerate()
        .flat_map(|(r, s)| s.iter().map(move |s| (r, s)))
        .filter(|(_, s)| {
            s.t_s.len() >= 12
                && s.t_s.len() == s.f.len()
                && s.t_s
                    .last()
                    .zip(s.t_s.first())
                    .is_some_and(|(b, a)| b - a >= MIN_HOLD_S)
        })
        .collect();
    if held.len() < 2 {
        return None;
    }
    let rel: Vec<(Vec<f64>, &[f64])> = held
        .iter()
        .map(|(_, s)| (s.t_s.iter().map(|t| t - s.t_s[0]).collect(), &s.f[..]))
        .collect();
    let recs: Vec<(&[f64], &[f64])> = rel.iter().map(|(t, f)| (&t[..], *f)).collect();
    let n: usize = recs.iter().map(|r| r.0.len()).sum();
    let mut best: Option<(f64, crate::relaxation::SharedFit)> = None;
    for start in [&[3.0][..], &[1.0, 20.0], &[1.0, 10.0, 60.0]] {
        let Some(fit) = fit_shared(&recs, start) else {
            continue;
        };
        let terms = start.len();
        let p = terms + recs.len() * (terms + 1);
        let bic = n as f64 * (fit.rss.max(1e-300) / n as f64).ln() + p as f64 * (n as f64).ln();
        if best.as_ref().is_none_or(|(b, _)| bic < *b - 2.0) {
            best = Some((bic, fit));
        }
    }
    let (_, fit) = best?;
    // Weights: step k's amplitude of term i is wᵢ Σ_{j≤k} Δf_e,j e^{−(t_k − t_j)/τᵢ}, the
    // steps of its run up to it, each the change of the equilibrium force F∞.
    let terms: Vec<PronyTerm> = fit
        .taus_s
        .iter()
        .enumerate()
        .map(|(i, &tau_s)| {
            let (mut num, mut den) = (0.0, 0.0);
            for (k, (run_k, step_k)) in held.iter().enumerate() {
                let t_k = step_k.t_s[0];
                let mut s = 0.0;
                let mut previous = 0.0;
                for (j, (run_j, step_j)) in held.iter().enumerate().take(k + 1) {
                    if run_j != run_k {
                        continue;
                    }
                    let f_inf = fit.linear[j][0];
                    s += (f_inf - previous) * (-(t_k - step_j.change_s).max(0.0) / tau_s).exp();
                    previous = f_inf;
                }
                let c = fit.linear[k][1 + i];
                num += c * s;
                den += s * s;
            }
            PronyTerm {
                weight: if den > 0.0 { (num / den).max(0.0) } else { 0.0 },
                tau_s,
            }
        })
        .filter(|t| t.weight > 1e-4 && t.tau_s.is_finite() && t.tau_s > 0.0)
        .collect();
    if terms.is_empty() {
        return None;
    }
    Prony::new(terms).ok()
}

/// The hereditary state of a reading: turns each frame's elastic force into the force.
#[derive(Debug, Clone)]
pub struct Memory {
    prony: Prony,
    state: PronyState,
    last_ns: Option<u64>,
    /// Whether the contact has pushed since the gel was last free (or since the start).
    pushing: bool,
}

impl Memory {
    /// A gel with no load history.
    pub fn new(prony: Prony) -> Self {
        let state = prony.state();
        Self {
            prony,
            state,
            last_ns: None,
            pushing: false,
        }
    }

    /// The force at `t_ns` whose field reads the elastic force `f_e`: the change since the
    /// last frame is a ramp across the interval, or a jump at its start after a gap longer
    /// than [`GAP_S`]. A frame earlier than the last (or the first) starts from `f_e` at rest.
    ///
    /// A pressed gel only pushes. Where, in a contact that has pushed, the hereditary force
    /// would pull, the indenter is leaving faster than the gel recovers, and the force lies
    /// between the hereditary integral's and the elastic force (Ting 1966: the contact
    /// shrinks, the gel let go of stays behind): the frame reads `f_e`, at least zero. Where
    /// a new contact meets a gel still recovering from the last (free since), it has not
    /// yet pushed: the frame reads zero until the integral turns positive, as the simulated
    /// bench's grasp does (its Fz is this integral, clamped at zero).
    ///
    /// Either way the history is kept: the gel let go of is still recovering, and the next
    /// grip meets its sunken surface. Restarting from rest there forgot every grip before,
    /// and `lifting-can`'s ten trials (seed 3) read their holds 7 % high in the first and
    /// 19–27 % in the later ones (7 % and 10–14 % with the history kept). Where the image
    /// shows the gel free, see [`Self::free`].
    pub fn apply(&mut self, t_ns: u64, f_e: f64) -> f64 {
        self.advance(t_ns, f_e);
        let value = self.state.value();
        if value >= 0.0 {
            self.pushing = true;
            value
        } else if self.pushing {
            f_e.max(0.0)
        } else {
            0.0
        }
    }

    /// Moves the state to `t_ns` with the elastic force reaching `f_e`.
    fn advance(&mut self, t_ns: u64, f_e: f64) {
        match self.last_ns.filter(|&l| t_ns >= l) {
            None => {
                self.state = self.prony.state();
                self.state.shift_driving(f_e);
            }
            Some(last) => {
                let dt_s = (t_ns - last) as f64 * 1e-9;
                if dt_s > GAP_S {
                    self.state.advance_linear(&self.prony, 0.0, f_e);
                    self.state.advance_linear(&self.prony, dt_s, f_e);
                } else {
                    self.state.advance_linear(&self.prony, dt_s, f_e);
                }
            }
        }
        self.last_ns = Some(t_ns);
    }

    /// The gel is free at `t_ns` (the image shows no contact): it carries no force, and its
    /// elastic force has gone to zero — applied like any other change, its hereditary part
    /// left to recover (a free surface's recovery pushes on nothing). So the next contact's
    /// force is applied from zero (its first reading carries its share of the overshoot) and
    /// a gel gripped again before it has recovered pushes back less, as the simulated
    /// bench's gel does (its Fz is the same hereditary integral, clamped at zero). Starting
    /// the next contact "at rest" instead dropped Σ wᵢ times the force at which the contact
    /// was first seen (the can's faint strip is first found near a quarter of the squeeze:
    /// the jig sensor read the lift and hold 0.3–0.4 N low) and forgot the last grip (read a
    /// grip 0.8 s after the last 0.2–0.3 N high).
    pub fn free(&mut self, t_ns: u64) -> f64 {
        self.advance(t_ns, 0.0);
        self.pushing = false;
        0.0
    }

    /// Reads `f_e` as a gel with no history (a recording where contact was not looked for:
    /// nothing tells when the gel was free).
    pub fn release(&mut self, t_ns: u64, f_e: f64) -> f64 {
        self.last_ns = None;
        self.apply(t_ns, f_e)
    }
}

/// The elastic force f_e behind a force record `f` at times `t_ns` (increasing): the inverse
/// of [`Memory::apply`] with a ramp between samples, solved sample by sample (g(0) ≥ 1, so the
/// inverse is stable and does not amplify noise).
pub fn elastic_of(prony: &Prony, t_ns: &[u64], f: &[f64]) -> Vec<f64> {
    let terms = prony.terms();
    let mut h = vec![0.0; terms.len()];
    let mut out = Vec::with_capacity(f.len());
    let mut prev_fe = 0.0;
    let mut prev_t: Option<u64> = None;
    for (&t, &fk) in t_ns.iter().zip(f) {
        let Some(pt) = prev_t.filter(|&p| t >= p) else {
            h.iter_mut().for_each(|v| *v = 0.0);
            prev_fe = fk;
            prev_t = Some(t);
            out.push(fk);
            continue;
        };
        let dt_s = (t - pt) as f64 * 1e-9;
        let (mut decayed, mut ramp_w) = (0.0, 0.0);
        let factors: Vec<(f64, f64)> = terms
            .iter()
            .map(|term| {
                let x = dt_s / term.tau_s;
                let ramp = mechanics::ramp_factor(x);
                ((-x).exp(), term.weight * ramp)
            })
            .collect();
        for (hv, (e, rw)) in h.iter().zip(&factors) {
            decayed += e * hv;
            ramp_w += rw;
        }
        // f = f_e + Σ (e hᵢ + rwᵢ (f_e − f_e,prev))
        let fe = (fk - decayed + ramp_w * prev_fe) / (1.0 + ramp_w);
        for (hv, (e, rw)) in h.iter_mut().zip(&factors) {
            *hv = e * *hv + rw * (fe - prev_fe);
        }
        prev_fe = fe;
        prev_t = Some(t);
        out.push(fe);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gel() -> Prony {
        Prony::new(vec![
            PronyTerm {
                weight: 0.3,
                tau_s: 1.0,
            },
            PronyTerm {
                weight: 0.2,
                tau_s: 10.0,
            },
            PronyTerm {
                weight: 0.1,
                tau_s: 40.0,
            },
        ])
        .expect("valid")
    }

    /// A stepped run: depth steps every `hold_s`, elastic force 1 N per step up then down to 1 N,
    /// the force sampled at 20 Hz through the hereditary integral.
    fn stepped(prony: &Prony, hold_s: f64, noise: f64) -> (Vec<u64>, Vec<f64>, Vec<HeldStep>) {
        let levels = [1.0, 2.0, 3.0, 4.0, 5.0, 4.0, 3.0, 2.0, 1.0];
        let dt = 0.05;
        let ramp_s = 0.5;
        let mut state = prony.state();
        // At rest at t = 0.
        let (mut t_ns, mut f, mut steps) = (vec![0u64], vec![0.0], Vec::new());
        let mut t = 0.0;
        let mut fe = 0.0;
        let mut k = 0u64;
        for &level in &levels {
            // the move: a ramp over ramp_s
            let n_ramp = (ramp_s / dt) as usize;
            let start = fe;
            for i in 1..=n_ramp {
                fe = start + (level - start) * i as f64 / n_ramp as f64;
                state.advance_linear(prony, dt, fe);
                t += dt;
                t_ns.push((t * 1e9).round() as u64);
                f.push(state.value());
            }
            let mut step = HeldStep {
                change_s: t - ramp_s / 2.0,
                t_s: Vec::new(),
                f: Vec::new(),
            };
            for _ in 0..(hold_s / dt) as usize {
                state.advance_linear(prony, dt, fe);
                t += dt;
                k += 1;
                // deterministic "noise": a fixed pseudo-random sequence
                let e = noise * (((k * 7919) % 1000) as f64 / 500.0 - 1.0);
                t_ns.push((t * 1e9).round() as u64);
                f.push(state.value() + e);
                step.t_s.push(t);
                step.f.push(state.value() + e);
            }
            steps.push(step);
        }
        (t_ns, f, steps)
    }

    #[test]
    fn the_relaxation_of_a_stepped_run_is_recovered_from_its_force_record() {
        let g = gel();
        let (_, _, steps) = stepped(&g, 120.0, 0.005);
        let fitted = fit_relaxation_runs(&[steps]).expect("fits");
        // The fitted g must match the true one over the times a grasp lives in.
        for t in [0.2, 0.5, 1.0, 2.0, 5.0, 10.0, 30.0, 60.0] {
            let (a, b) = (fitted.relaxation(t), g.relaxation(t));
            assert!((a - b).abs() < 0.02 * b, "g({t}) = {a}, true {b}");
        }
    }

    #[test]
    fn the_elastic_force_behind_a_record_is_what_the_memory_turns_back_into_it() {
        let g = gel();
        let (t_ns, f, _) = stepped(&g, 30.0, 0.0);
        let fe = elastic_of(&g, &t_ns, &f);
        // The elastic force is the staircase: at each step's end it equals the level.
        let i = t_ns
            .iter()
            .position(|&t| t >= 30_500_000_000)
            .expect("in range");
        assert!((fe[i - 1] - 1.0).abs() < 1e-9, "{}", fe[i - 1]);
        let mut m = Memory::new(g);
        for ((&t, &e), &want) in t_ns.iter().zip(&fe).zip(&f) {
            let got = m.apply(t, e);
            assert!((got - want).abs() < 1e-9, "{got} vs {want}");
        }
    }

    /// The bench's gel: the same hereditary integral of the elastic force, its output
    /// clamped at zero (rig's plant, `integrate`), the state kept through a free gel.
    fn bench(g: &Prony, drive: &[(u64, f64)]) -> Vec<f64> {
        let mut s = g.state();
        let mut last = 0u64;
        drive
            .iter()
            .map(|&(t, fe)| {
                s.advance_linear(g, (t - last) as f64 * 1e-9, fe);
                last = t;
                s.value().max(0.0)
            })
            .collect()
    }

    #[test]
    fn a_gel_let_go_faster_than_it_recovers_pushes_nothing_and_pressed_again_pushes_back_less() {
        let g = gel();
        let frame = 40_000_000u64;
        // Pressed to 4 N for 4 s, let go within a frame, free for 1 s, pressed to 1 N.
        let mut drive: Vec<(u64, f64)> = (1..=100).map(|k| (k * frame, 4.0)).collect();
        drive.extend((101..=125).map(|k| (k * frame, 0.0)));
        drive.push((126 * frame, 1.0));
        let want = bench(&g, &drive);
        let mut m = Memory::new(g.clone());
        m.apply(0, 0.0);
        let got: Vec<f64> = drive
            .iter()
            .map(
                |&(t, fe)| {
                    if fe == 0.0 { m.free(t) } else { m.apply(t, fe) }
                },
            )
            .collect();
        for (k, (a, b)) in got.iter().zip(&want).enumerate() {
            assert!((a - b).abs() < 1e-9, "frame {k}: {a} vs the bench's {b}");
        }
        // Let go: the hereditary integral would pull; the gel pushes nothing.
        assert_eq!(got[100], 0.0);
        // Pressed again before it has recovered: less than a fresh gel pushes back.
        let fresh = bench(&g, &[(frame, 1.0)])[0];
        assert!(got[125] < fresh - 0.05, "{} vs fresh {fresh}", got[125]);
    }

    #[test]
    fn in_contact_a_reading_that_would_pull_reads_the_elastic_force_and_keeps_the_history() {
        let g = gel();
        let mut m = Memory::new(g.clone());
        // The same history without the clamp: a bare hereditary state.
        let mut bare = g.state();
        m.apply(0, 0.0);
        for k in 1..=100u64 {
            m.apply(k * 40_000_000, 4.0);
            bare.advance_linear(&g, 0.04, 4.0);
        }
        // Still in contact, the field reads 0.2 N a frame later: 0.2 + Σhᵢ would pull. The
        // contact has pushed, so the frame reads its elastic force.
        bare.advance_linear(&g, 0.04, 0.2);
        assert!(bare.value() < 0.0, "{}", bare.value());
        let f = m.apply(101 * 40_000_000, 0.2);
        assert!((f - 0.2).abs() < 1e-12, "{f}");
        // The gel is let go of for a few frames, then gripped again: the new contact reads
        // zero while the kept history still pulls, then the bare integral — less than a gel
        // at rest would push back.
        for k in 102..=104u64 {
            assert_eq!(m.free(k * 40_000_000), 0.0);
            bare.advance_linear(&g, 0.04, 0.0);
        }
        let mut fresh = g.state();
        let (mut zero, mut pushed) = (0, 0);
        for k in 105..=160u64 {
            let fe = 0.1 * (k - 104) as f64;
            let f = m.apply(k * 40_000_000, fe);
            bare.advance_linear(&g, 0.04, fe);
            fresh.advance_linear(&g, 0.04, fe);
            if bare.value() < 0.0 && pushed == 0 {
                assert_eq!(f, 0.0, "frame {k}: not pushing yet");
                zero += 1;
            } else {
                assert!(
                    (f - bare.value()).abs() < 1e-12,
                    "frame {k}: {f} vs {}",
                    bare.value()
                );
                assert!(
                    f < fresh.value(),
                    "frame {k}: {f} vs fresh {}",
                    fresh.value()
                );
                pushed += 1;
            }
        }
        assert!(
            zero >= 1 && pushed >= 10,
            "{zero} frames at zero, {pushed} pushing"
        );
    }

    #[test]
    fn a_contact_first_seen_loaded_after_a_free_gel_carries_its_overshoot() {
        let g = gel();
        let mut m = Memory::new(g.clone());
        for k in 0..10u64 {
            assert_eq!(m.free(k * 40_000_000), 0.0);
        }
        // The image finds the contact only once it carries 1.25 N (elastic).
        let f = m.apply(10 * 40_000_000, 1.25);
        let want = bench(&g, &[(40_000_000, 1.25)])[0];
        assert!((f - want).abs() < 1e-12, "{f} vs {want}");
        assert!(f > 1.25 * 1.5, "the overshoot is read: {f}");
    }

    #[test]
    fn after_a_gap_the_change_is_a_jump_at_its_start() {
        let g = gel();
        let mut m = Memory::new(g.clone());
        m.apply(0, 0.0);
        // 100 s later at 1 N elastic: a jump 100 s ago has relaxed to g(100).
        let f = m.apply(100_000_000_000, 1.0);
        assert!((f - g.relaxation(100.0)).abs() < 1e-12, "{f}");
        // Frames 40 ms apart: a ramp, and at once the instantaneous response.
        let mut m = Memory::new(g.clone());
        m.apply(0, 0.0);
        let f = m.apply(40_000_000, 1.0);
        assert!(f > 1.5 && f < g.instantaneous(), "{f}");
    }
}
