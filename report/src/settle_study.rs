//! The settle study of a report: on the run's own relaxation records, the equilibrium error
//! each settle rule would have left against the settle time it would have taken — fixed
//! waits, the rate rule and the adaptive rule replayed step by step
//! ([`analysis::settle_rules`], the runner's own rules) — against each step's fitted F∞, and
//! the simulator's equilibrium when the run has it.

use analysis::relaxation::settle_error;
use analysis::settle_rules::{AdaptiveRule, GelMemory, RateRule, adaptive_stop, rate_stop};

/// A relaxing step, as the study reads it.
pub(super) struct StepRelax<'a> {
    /// Samples, t from the end of the move, s.
    pub t_s: &'a [f64],
    /// The channel.
    pub f: &'a [f64],
    /// F∞ of the step's whole record.
    pub f_inf: f64,
    /// Exponential terms of that fit.
    pub terms: usize,
    /// The relaxation's size: the fit's amplitudes summed.
    pub amplitude: f64,
    /// The simulator's equilibrium value, if known.
    pub truth: Option<f64>,
    /// The move's end, s on the run's clock (the adaptive rule carries the load history).
    pub start_s: f64,
}

/// Settle error against settle time, over the run's relaxing steps.
#[derive(Debug, Clone)]
pub struct SettleCurve {
    /// Waits, s.
    pub waits_s: Vec<f64>,
    /// Median |error| against each step's fitted F∞, force units.
    pub median_abs_vs_fit: Vec<f64>,
    /// Median |error| against the simulator's equilibrium.
    pub median_abs_vs_truth: Option<Vec<f64>>,
    /// Median |error| as % of the step's force change.
    pub median_pct_vs_fit: Vec<f64>,
    /// The rate and adaptive rules replayed on the same records.
    pub rules: Vec<RuleOutcome>,
}

/// A settle rule replayed on the run's records.
#[derive(Debug, Clone)]
pub struct RuleOutcome {
    /// The rule, as a protocol writes it.
    pub rule: String,
    /// Median settle time it would have taken, s.
    pub median_settle_s: f64,
    /// Median |error| of the value it would have recorded (the window mean at its stop; F∞
    /// for the adaptive rule), against the simulator's equilibrium when known, else F∞ of the
    /// step's whole record.
    pub median_abs_error: f64,
    /// Steps on which it settled before its max (the record's length).
    pub settled: usize,
    /// Steps replayed.
    pub steps: usize,
}

fn median(mut v: Vec<f64>) -> f64 {
    v.retain(|x| x.is_finite());
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

/// The rate rule (0.005 per s over 20 s, at least 20 s) and the adaptive rule (1 %, at
/// least 20 s), each stopped at the record's end at the latest, replayed step by step (the
/// adaptive rule learning from one step to the next as in a run).
fn replay(steps: &[&StepRelax<'_>], window: f64) -> Vec<RuleOutcome> {
    let reference = |r: &StepRelax<'_>| r.truth.unwrap_or(r.f_inf);
    let mean_before = |r: &StepRelax<'_>, at: f64| {
        let v: Vec<f64> = r
            .t_s
            .iter()
            .zip(r.f)
            .filter(|(t, _)| **t > at - window && **t <= at + 1e-9)
            .map(|(_, f)| *f)
            .collect();
        v.iter().sum::<f64>() / v.len().max(1) as f64
    };
    let (mut rate, mut adaptive) = (Vec::new(), Vec::new());
    let mut memory = GelMemory::default();
    for r in steps {
        let end = r.t_s.last().copied().unwrap_or(0.0);
        let rule = RateRule {
            below: 0.005,
            window_s: 20.0,
            min_s: 20.0f64.min(end),
            max_s: end,
        };
        let (at, ok) = rate_stop(r.t_s, r.f, &rule);
        rate.push((at, (mean_before(r, at) - reference(r)).abs(), ok));
        let rule = AdaptiveRule {
            tolerance: 0.01,
            min_s: 20.0f64.min(end),
            max_s: end,
            window_s: window,
        };
        if let Some((at, e, ok)) = adaptive_stop(Some(r.start_s), r.t_s, r.f, &rule, &mut memory) {
            adaptive.push((at, (e.f_inf - reference(r)).abs(), ok));
        }
    }
    let outcome = |rule: &str, v: &[(f64, f64, bool)]| RuleOutcome {
        rule: rule.into(),
        median_settle_s: median(v.iter().map(|x| x.0).collect()),
        median_abs_error: median(v.iter().map(|x| x.1).collect()),
        settled: v.iter().filter(|x| x.2).count(),
        steps: v.len(),
    };
    vec![
        outcome("rate: {below: 0.005/s, window: 20 s, min: 20 s}", &rate),
        outcome("adaptive: {tolerance: 1 %, min: 20 s}", &adaptive),
    ]
}

pub(super) fn settle_curve(relaxation: &[StepRelax<'_>]) -> Option<SettleCurve> {
    let fitted: Vec<&StepRelax<'_>> = relaxation.iter().filter(|r| r.terms >= 1).collect();
    let longest = fitted
        .iter()
        .filter_map(|r| r.t_s.last().copied())
        .fold(0.0, f64::max);
    if fitted.is_empty() || longest < 20.0 {
        return None;
    }
    let window = 10.0f64.min(longest / 4.0);
    let waits: Vec<f64> = [
        10.0, 15.0, 20.0, 30.0, 45.0, 60.0, 90.0, 120.0, 150.0, 180.0, 240.0, 300.0, 450.0, 600.0,
    ]
    .into_iter()
    .filter(|w| *w >= window && *w <= 1.01 * longest + 1e-9)
    .collect();
    let per_wait = |reference: &dyn Fn(&StepRelax<'_>) -> Option<f64>, pct: bool| -> Vec<f64> {
        let errs: Vec<Vec<f64>> = fitted
            .iter()
            .filter_map(|r| {
                let refv = reference(r)?;
                let e = settle_error(r.t_s, r.f, window, &waits, refv);
                let scale = if pct {
                    100.0 / r.amplitude.abs().max(1e-9)
                } else {
                    1.0
                };
                Some(e.into_iter().map(|v| v.abs() * scale).collect())
            })
            .collect();
        (0..waits.len())
            .map(|k| median(errs.iter().map(|e| e[k]).collect()))
            .collect()
    };
    let truth_known = fitted.iter().all(|r| r.truth.is_some());
    Some(SettleCurve {
        median_abs_vs_fit: per_wait(&|r| Some(r.f_inf), false),
        median_pct_vs_fit: per_wait(&|r| Some(r.f_inf), true),
        median_abs_vs_truth: truth_known.then(|| per_wait(&|r| r.truth, false)),
        rules: replay(&fitted, window),
        waits_s: waits,
    })
}
