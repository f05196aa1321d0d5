//! The settle rules as pure functions of a relaxation record: what the runner judges live,
//! and what a report replays on a recorded run to compare rules (the equilibrium error
//! against settle time each would have given).
//!
//! - The **rate rule**: settled once the drift bound — the least-squares slope over the last
//!   `window_s` plus twice its standard error — is below `below` (and `min_s` has passed).
//! - The **adaptive rule** ([`crate::equilibrium`]): settled once F∞ is known within the
//!   tolerance; a fit every max(2 s, a tenth of the wait). [`GelMemory`] carries what a run
//!   learns of the gel's time constants from one step to the next, and the load history a
//!   later step's slowest relaxation is carried from ([`crate::carried_relaxation`]).

use std::collections::VecDeque;

use crate::carried_relaxation::{self, Carry};
use crate::equilibrium::{self, Equilibrium, Learned};

/// Upper bound of |slope| of `y` against `t` (per unit of t): the least-squares slope plus
/// twice its standard error; `None` for fewer than three points or no spread in `t`.
/// Judging the bound rather than the slope keeps noise from settling a step by chance: a
/// threshold below what the noise can resolve is never met.
pub fn drift_bound(t: &[f64], y: &[f64]) -> Option<f64> {
    let n = t.len().min(y.len());
    if n < 3 {
        return None;
    }
    let nf = n as f64;
    let mx = t[..n].iter().sum::<f64>() / nf;
    let my = y[..n].iter().sum::<f64>() / nf;
    let sxx: f64 = t[..n].iter().map(|v| (v - mx).powi(2)).sum();
    if sxx <= 0.0 {
        return None;
    }
    let slope = t[..n]
        .iter()
        .zip(&y[..n])
        .map(|(a, b)| (a - mx) * (b - my))
        .sum::<f64>()
        / sxx;
    let rss: f64 = t[..n]
        .iter()
        .zip(&y[..n])
        .map(|(a, b)| (b - my - slope * (a - mx)).powi(2))
        .sum();
    let se = (rss / (nf - 2.0) / sxx).sqrt();
    Some(slope.abs() + 2.0 * se)
}

/// The rate rule's parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RateRule {
    /// Threshold on the drift bound, per s.
    pub below: f64,
    /// Slope window, s.
    pub window_s: f64,
    /// Shortest settle, s.
    pub min_s: f64,
    /// Longest settle, s.
    pub max_s: f64,
}

/// When the rate rule would have ended the settle of record (`t_s` from its start): the
/// first sample time at which it holds, or the max (or the record's end, if shorter) with
/// `false`.
pub fn rate_stop(t_s: &[f64], y: &[f64], rule: &RateRule) -> (f64, bool) {
    let end = t_s.last().copied().unwrap_or(0.0).min(rule.max_s);
    let mut from = 0;
    for (i, &now) in t_s.iter().enumerate() {
        if now > end {
            break;
        }
        while t_s[from] < now - rule.window_s {
            from += 1;
        }
        if now >= rule.min_s
            && now >= rule.window_s
            && drift_bound(&t_s[from..=i], &y[from..=i]).is_some_and(|b| b < rule.below)
        {
            return (now, true);
        }
    }
    (end, false)
}

/// The adaptive rule's parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AdaptiveRule {
    /// Twice F∞'s uncertainty, as a fraction of |F∞|.
    pub tolerance: f64,
    /// Shortest settle, s.
    pub min_s: f64,
    /// Longest settle, s.
    pub max_s: f64,
    /// The quasistatic window, s (its mean is kept beside F∞).
    pub window_s: f64,
}

/// The next fit after one at `elapsed_s`: a tenth of the wait later, at least 2 s. Not
/// more often: every look is a chance to stop on a momentarily narrow band (optional
/// stopping) — fitting every max(1 s, a twentieth) shortened `box-normal-flat`'s mean settle
/// from 46.0 to 45.2 s and worsened its worst step from 1.38 % to 1.86 % (BENCHMARKS.md;
/// measured before the load history was carried).
pub fn next_check_s(elapsed_s: f64) -> f64 {
    elapsed_s + (elapsed_s / 10.0).max(2.0)
}

/// What a run has learned of the gel's relaxation, from step to step.
#[derive(Debug, Clone, Default)]
pub struct GelMemory {
    records: VecDeque<(Vec<f64>, Vec<f64>)>,
    /// Where each kept record's settle started on the run's clock, when known: what its
    /// load change (and so the slowest weight it teaches) is measured from.
    record_starts: VecDeque<Option<f64>>,
    learned: Option<Learned>,
    /// The largest |F∞| so far: near zero force a relative tolerance is measured against a
    /// tenth of it.
    peak: f64,
    /// The slowest relaxation any step's own record has shown, s: a time constant its fit
    /// found inside the record, or the record's length when a still slower term was under
    /// way (the drift test). A later step's own fit is trusted only over 2.5× it.
    slowest_seen_s: f64,
    /// Each settled step's start (s on the run's clock) and F∞, where the start is known:
    /// the load history a later step's slowest relaxation is carried from.
    steps: Vec<(f64, f64)>,
    /// The slowest learned term's weight per unit change of F∞, and its uncertainty.
    slow_weight: Option<(f64, f64)>,
    announced: bool,
}

/// Records kept for learning the gel's time constants (the newest).
const KEEP_RECORDS: usize = 4;

impl GelMemory {
    /// The time constants learned so far.
    pub fn learned(&self) -> Option<&Learned> {
        self.learned.as_ref()
    }

    /// The smallest denominator of the relative tolerance: a tenth of the largest |F∞| so far.
    pub fn floor(&self) -> f64 {
        0.1 * self.peak
    }

    /// F∞ of `record` (t from the settle's start, the channel) with what is learned; a
    /// step's own fit must span 2.5× the slowest relaxation the run has shown.
    pub fn estimate(&self, t_s: &[f64], y: &[f64], window_s: f64) -> Option<Equilibrium> {
        self.estimate_at(None, t_s, y, window_s)
    }

    /// As [`Self::estimate`], for a settle that started at `start_s` on the run's clock:
    /// with the time constants learned and the load history known, the slowest term's
    /// amplitude is carried from the steps before ([`crate::carried_relaxation`]) where
    /// that history explains the record.
    pub fn estimate_at(
        &self,
        start_s: Option<f64>,
        t_s: &[f64],
        y: &[f64],
        window_s: f64,
    ) -> Option<Equilibrium> {
        let mut e = equilibrium::estimate_with(t_s, y, window_s, self.learned.as_ref())?;
        e.needs_record_s = e
            .needs_record_s
            .max(equilibrium::SPAN_OVER_TAU * self.slowest_seen_s);
        if let (Some(start), Some(l), Some((weight, weight_sd))) =
            (start_s, self.learned.as_ref(), self.slow_weight)
        {
            let (history, f_prev) = self.history_at(start, l);
            let carry = Carry {
                weight,
                weight_sd,
                history,
                f_prev,
            };
            if let Some(c) = carried_relaxation::estimate_carried(t_s, y, l, &carry, &e) {
                return Some(c);
            }
        }
        Some(e)
    }

    /// H (the earlier changes of F∞ decayed by the slowest learned term to `start_s`) and
    /// the last F∞, from the steps whose start is known.
    fn history_at(&self, start_s: f64, learned: &Learned) -> (f64, f64) {
        let tau = learned.taus_s.last().copied().unwrap_or(f64::INFINITY);
        let mut prev = 0.0;
        let mut h = 0.0;
        for (t_j, f_j) in self.steps.iter().filter(|(t, _)| *t < start_s) {
            h += (f_j - prev) * (-(start_s - t_j) / tau).exp();
            prev = *f_j;
        }
        (h, prev)
    }

    /// As [`Self::settled`], for a settle that started at `start_s` on the run's clock: the
    /// step joins the load history, and whenever the time constants are (re)learned the
    /// slowest term's weight is learned again with them (see [`Self::learn_slow_weight`]).
    pub fn settled_at(
        &mut self,
        start_s: Option<f64>,
        e: &Equilibrium,
        record: (Vec<f64>, Vec<f64>),
    ) {
        let before = self.learned.clone();
        self.settle_record(start_s, e, record);
        if let Some(start) = start_s {
            self.steps.push((start, e.f_inf));
        }
        if self.learned != before {
            self.learn_slow_weight();
        }
    }

    /// The slowest term's weight per unit change of F∞, from every kept record that taught
    /// the time constants and whose start is known, with the time constants as now learned.
    /// A weight learned once, with the time constants of the first record alone, and kept
    /// when later records moved them (a sphere's faint first step taught 50 s for the
    /// 60 s term, and its weight with it) put every later step that carried it off by the
    /// same fraction (0.5–0.75 % on `box-normal-sphere`, seed 2) at a claimed ±0.25 %. The
    /// records' weights are pooled by their uncertainties; the spread is the larger of the
    /// pooled standard error and the records' scatter about it (a later step deviates as one
    /// record does, not as their mean).
    fn learn_slow_weight(&mut self) {
        let Some(l) = self.learned.clone() else {
            return;
        };
        let weights: Vec<(f64, f64)> = self
            .records
            .iter()
            .zip(&self.record_starts)
            .filter_map(|((t, y), start)| {
                let (h, f_prev) = self.history_at((*start)?, &l);
                let f_inf = self
                    .steps
                    .iter()
                    .find(|(s, _)| Some(*s) == *start)
                    .map(|(_, f)| *f)?;
                carried_relaxation::slow_weight(t, y, &l, h + f_inf - f_prev)
            })
            .collect();
        self.slow_weight = pool(&weights);
    }
    /// A settle ended with estimate `e` of `record`: its scale counts towards the run's
    /// force scale, and a record long enough against its own fit's slowest time constant
    /// (even one whose F∞ band stayed wider than the tolerance) teaches the gel's time
    /// constants, pooled with the newest few such records. A record that did not pin them
    /// teaches nothing: later steps would inherit its mistake with a confidence they
    /// cannot have.
    pub fn settled(&mut self, e: &Equilibrium, record: (Vec<f64>, Vec<f64>)) {
        self.settle_record(None, e, record);
    }

    /// [`Self::settled`], keeping where a teaching record started.
    fn settle_record(
        &mut self,
        start_s: Option<f64>,
        e: &Equilibrium,
        record: (Vec<f64>, Vec<f64>),
    ) {
        self.peak = self.peak.max(e.f_inf.abs());
        if !e.used_learned {
            let shown = e
                .taus_s
                .iter()
                .copied()
                .filter(|tau| *tau <= e.record_s)
                .fold(0.0, f64::max);
            let drift = if e.drifting { e.record_s } else { 0.0 };
            self.slowest_seen_s = self.slowest_seen_s.max(shown).max(drift);
        }
        if !e.pins_time_constants() {
            return;
        }
        if self.records.len() == KEEP_RECORDS {
            self.records.pop_front();
            self.record_starts.pop_front();
        }
        self.records.push_back(record);
        self.record_starts.push_back(start_s);
        let records: Vec<(Vec<f64>, Vec<f64>)> = self.records.iter().cloned().collect();
        if let Some(l) = equilibrium::learn(&records, &e.taus_s) {
            self.learned = Some(l);
        }
    }

    /// The time constants now learned, once, the first time there are some: what later
    /// steps assume (a gel relaxing slower than the slowest of them, over times no record so
    /// far could show, would make those steps' F∞ wrong).
    pub fn newly_learned(&mut self) -> Option<String> {
        if self.announced {
            return None;
        }
        let l = self.learned.as_ref()?;
        self.announced = true;
        Some(format!(
            "adaptive settling: later steps fit F∞ with the gel's time constants learned so far \
             ({} s, ±{:.0} %), the slowest term's amplitude carried from the load history where \
             it explains their record; they assume nothing relaxes slower than {:.0} s — a \
             slower relaxation needs a `max` of at least 2.5× it to be seen",
            l.taus_s
                .iter()
                .map(|t| format!("{t:.1}"))
                .collect::<Vec<_>>()
                .join(", "),
            200.0 * l.rel_sigma,
            l.taus_s.last().copied().unwrap_or(0.0)
        ))
    }
}

/// Weights `(w, sd)` pooled by inverse variance; the spread is the larger of the pooled
/// standard error and the weights' scatter about the pooled value. `None` for none.
fn pool(weights: &[(f64, f64)]) -> Option<(f64, f64)> {
    let inv: f64 = weights.iter().map(|(_, sd)| 1.0 / (sd * sd)).sum();
    if weights.is_empty() || !(inv.is_finite() && inv > 0.0) {
        return None;
    }
    let mean = weights.iter().map(|(w, sd)| w / (sd * sd)).sum::<f64>() / inv;
    let se = inv.sqrt().recip();
    let n = weights.len();
    let scatter = if n > 1 {
        (weights.iter().map(|(w, _)| (w - mean).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt()
    } else {
        0.0
    };
    Some((mean, se.max(scatter)))
}

/// When the adaptive rule would have ended the settle of `record` (`t_s` from its start),
/// fitting on the runner's schedule: the time, the estimate then, and whether it was known
/// (false: the max, or the record's end, came first). `memory` learns from it as a run
/// would; `start_s`, the settle's start on the run's clock, lets it carry the load history.
pub fn adaptive_stop(
    start_s: Option<f64>,
    t_s: &[f64],
    y: &[f64],
    rule: &AdaptiveRule,
    memory: &mut GelMemory,
) -> Option<(f64, Equilibrium, bool)> {
    let end = t_s.last().copied()?.min(rule.max_s);
    let mut at = rule.min_s.min(end);
    let mut last = None;
    loop {
        let k = t_s.partition_point(|t| *t <= at);
        if let Some(e) = memory.estimate_at(start_s, &t_s[..k], &y[..k], rule.window_s) {
            let known = e.known_within(rule.tolerance, memory.floor());
            if known || at >= end {
                memory.settled_at(start_s, &e, (t_s[..k].to_vec(), y[..k].to_vec()));
                return Some((at, e, known));
            }
            last = Some(e);
        }
        if at >= end {
            break;
        }
        at = next_check_s(at).min(end);
    }
    let e = last?;
    memory.settled_at(start_s, &e, (t_s.to_vec(), y.to_vec()));
    Some((end, e, false))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pooled_weights_take_the_scatter_between_records_when_it_exceeds_their_errors() {
        assert_eq!(super::pool(&[]), None);
        // Two records that agree: the pooled standard error, smaller than either's.
        let (w, sd) = super::pool(&[(0.15, 0.01), (0.15, 0.01)]).expect("pooled");
        assert!((w - 0.15).abs() < 1e-12 && (sd - 0.01 / 2f64.sqrt()).abs() < 1e-12);
        // A precise record and a loose one that disagree: the mean leans to the precise
        // one, and the spread is their scatter, not the tiny pooled error.
        let (w, sd) = super::pool(&[(0.17, 0.002), (0.12, 0.02)]).expect("pooled");
        assert!(w > 0.165 && w < 0.17, "{w}");
        assert!(sd > 0.02, "{sd}");
    }

    /// 20 Hz samples of 5 + Σ aᵢ e^{−t/τᵢ}, with a fixed ±1 mN ripple as noise.
    fn relaxing(t_end: f64, taus: &[f64], amps: &[f64]) -> (Vec<f64>, Vec<f64>) {
        let gel: Vec<(f64, f64)> = amps.iter().zip(taus).map(|(a, t)| (a / 5.0, *t)).collect();
        crate::carried_relaxation::staircase(&[(0.0, 5.0)], &gel, 0.0, t_end)
    }

    #[test]
    fn a_short_record_cannot_claim_once_the_run_has_shown_a_slower_relaxation() {
        // A 40 s record relaxing with 1.5 and 10 s terms only: alone, its own fit is
        // followed long enough (2.5 × 10 s) and F∞ is known.
        let (t, y) = relaxing(40.0, &[1.5, 10.0], &[0.5, 0.3]);
        let fresh = GelMemory::default();
        let alone = fresh.estimate(&t, &y, 10.0).expect("fits");
        assert!(alone.known_within(0.01, 0.1), "{alone:?}");
        // After a step whose record showed a 100 s relaxation that a 150 s record could not
        // pin, the same record is no longer long enough to trust its own time constants.
        let mut memory = GelMemory::default();
        let (ts, ys) = relaxing(150.0, &[1.5, 10.0, 100.0], &[0.5, 0.3, 0.4]);
        let slow = memory.estimate(&ts, &ys, 10.0).expect("fits");
        assert!(!slow.pins_time_constants(), "{slow:?}");
        memory.settled(&slow, (ts, ys));
        let after = memory.estimate(&t, &y, 10.0).expect("fits");
        assert!(after.needs_record_s >= 2.5 * 90.0, "{after:?}");
        assert!(!after.known_within(0.01, 0.1), "{after:?}");
    }

    #[test]
    fn the_drift_bound_of_a_line_is_its_slope_and_noise_raises_it() {
        let t: Vec<f64> = (0..100).map(|i| i as f64 * 0.1).collect();
        let y: Vec<f64> = t.iter().map(|v| 0.5 * v).collect();
        assert!((drift_bound(&t, &y).expect("bound") - 0.5).abs() < 1e-9);
        let noisy: Vec<f64> = y
            .iter()
            .enumerate()
            .map(|(i, v)| v + if i % 2 == 0 { 0.01 } else { -0.01 })
            .collect();
        assert!(drift_bound(&t, &noisy).expect("bound") > 0.5);
        assert!(drift_bound(&t[..2], &y[..2]).is_none());
    }

    #[test]
    fn the_rate_rule_stops_when_the_drift_falls_below_its_threshold() {
        // y = e^{−t/10}: slope e^{−t/10}/10 falls below 0.001 at t = 10 ln 100 ≈ 46 s (the
        // windowed slope lags a little).
        let t: Vec<f64> = (0..3000).map(|i| i as f64 * 0.05).collect();
        let y: Vec<f64> = t.iter().map(|v| (-v / 10.0).exp()).collect();
        let rule = RateRule {
            below: 0.001,
            window_s: 5.0,
            min_s: 10.0,
            max_s: 120.0,
        };
        let (stop, settled) = rate_stop(&t, &y, &rule);
        assert!(settled && (45.0..56.0).contains(&stop), "{stop}");
        let strict = RateRule {
            below: 1e-9,
            ..rule
        };
        assert_eq!(rate_stop(&t, &y, &strict), (120.0, false));
    }
}
