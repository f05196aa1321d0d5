//! The user's own gel from recorded pressing runs: its long-term modulus, its relaxation
//! (Prony terms) and where contact really began, fitted to the whole force record.
//!
//! A linear viscoelastic gel pressed along a depth history d(t) carries
//! F(t) = s·[φ(d(t) − d₀) + Σ wᵢ ∫ e^{−(t−u)/τᵢ} dφ(d(u) − d₀)] (Lee & Radok 1960: the
//! hereditary integral of the elastic force), with φ the elastic force of the layer and
//! indenter at the modulus the protocol assumed (the mechanics model; a flat punch's is linear
//! in depth, a sphere's is not), s the ratio of the gel's relaxed modulus E∞ to that one, wᵢ
//! and τᵢ its Prony terms, and d₀ the contact's true start from the recorded origin (the
//! approach stops at a force threshold, so the origin is a little past the surface). The
//! force sensor is taken as tared before contact: a constant offset would be the same
//! parameter as d₀ for a flat punch (F = s·k·(d − d₀) + c). For given τ and d₀ the force is
//! linear in s and s·wᵢ; the fit is a
//! variable projection (Golub & Pereyra 1973) of those out, with Levenberg–Marquardt over
//! ln τᵢ and d₀ (one per run), 1–3 terms chosen by BIC. Fitting the whole record — the
//! ramps, the holds, the unloading — rather than each held step's decay separately is what
//! recovers the weights: a step's decay alone cannot tell a term's weight from the part of
//! earlier steps still relaxing.
//!
//! Uncertainties are the Gauss–Newton standard errors of all parameters at the optimum
//! (white force noise assumed; the Nano17 also quantises, so they are a lower bound).

use nalgebra::{DMatrix, DVector};

use crate::relaxation::levenberg_marquardt;

/// One run's pressing record.
#[derive(Debug, Clone, PartialEq)]
pub struct PressRecord {
    /// Force sample times, s, increasing.
    pub t_s: Vec<f64>,
    /// The pressing force at those times, N.
    pub f_n: Vec<f64>,
    /// The commanded depth from the recorded contact origin, mm, as knots (t_s, depth_mm)
    /// of a piecewise-linear history (a stage moving at constant speed); before the first
    /// knot the depth is the first knot's.
    pub depth_knots: Vec<(f64, f64)>,
}

/// A value and its standard uncertainty.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Estimate {
    /// The value.
    pub value: f64,
    /// Its standard uncertainty (Gauss–Newton).
    pub sd: f64,
}

/// One fitted Prony term.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FittedTerm {
    /// Weight relative to the relaxed modulus.
    pub weight: Estimate,
    /// Time constant, s.
    pub tau_s: Estimate,
}

/// The fit.
#[derive(Debug, Clone, PartialEq)]
pub struct MaterialFit {
    /// E∞ over the modulus φ was computed with.
    pub modulus_ratio: Estimate,
    /// Prony terms, by increasing τ.
    pub terms: Vec<FittedTerm>,
    /// Per record: the contact's true start from the recorded origin, mm (positive: the
    /// surface lies deeper than the origin).
    pub offsets_mm: Vec<Estimate>,
    /// The force record's lag behind the step log's times, s (a latency common to all
    /// records: the fast terms are sensitive to where each move sits against the force
    /// samples — 50 ms off moves a 2 s term's weight by 10–20 %).
    pub lag_s: Estimate,
    /// Per record: the residual's rms, N.
    pub residual_rms_n: Vec<f64>,
    /// Samples fitted.
    pub samples: usize,
}

/// Longest time step of the hereditary integral while the depth moves, s: φ of a curved
/// indenter is not linear in depth, so a ramp is cut into pieces short enough for the
/// linear-ramp update to be exact to well under the force noise.
const MOVING_STEP_S: f64 = 0.01;

/// Shortest time constant fitted, s: a force record at 20 Hz cannot show a faster one.
const MIN_TAU_S: f64 = 0.1;

/// Largest Prony weight taken as a gel's (an instantaneous modulus 20× the relaxed one);
/// beyond it a term is the fit trading a fast τ against its weight.
const MAX_WEIGHT: f64 = 20.0;

/// Starting time constants for one, two and three terms, s.
const STARTS: [&[f64]; 3] = [&[3.0], &[1.0, 20.0], &[1.0, 10.0, 60.0]];

/// Fits the gel to `records` with `phi(k, d)`, record k's elastic force (N) at depth d (mm)
/// for a unit modulus ratio (each record may have its own indenter). `None` when nothing
/// can be fitted (a record too short, or every fit fails).
pub fn fit_material(
    records: &[PressRecord],
    phi: &dyn Fn(usize, f64) -> f64,
) -> Option<MaterialFit> {
    if records.is_empty()
        || records
            .iter()
            .any(|r| r.t_s.len() != r.f_n.len() || r.t_s.len() < 20 || r.depth_knots.is_empty())
    {
        return None;
    }
    let records: Vec<(usize, &PressRecord)> = records.iter().enumerate().collect();
    let n: usize = records.iter().map(|(_, r)| r.t_s.len()).sum();
    let mut best: Option<(f64, MaterialFit)> = None;
    for start in STARTS {
        let Some(fit) = fit_terms(&records, phi, start) else {
            continue;
        };
        let rss: f64 = fit
            .residual_rms_n
            .iter()
            .zip(&records)
            .map(|(rms, (_, r))| rms * rms * r.t_s.len() as f64)
            .sum();
        let p = 2 + 2 * start.len() + records.len();
        let bic = n as f64 * (rss.max(1e-300) / n as f64).ln() + p as f64 * (n as f64).ln();
        if best.as_ref().is_none_or(|(b, _)| bic < *b - 2.0) {
            best = Some((bic, fit));
        }
    }
    best.map(|(_, f)| f)
}

/// The piecewise-linear depth of `knots` at `t`: the first knot's before it, the last's
/// after.
fn depth_at(knots: &[(f64, f64)], t: f64) -> f64 {
    let i = knots.partition_point(|(tk, _)| *tk <= t);
    match (i, knots.get(i)) {
        (0, _) => knots.first().map_or(0.0, |k| k.1),
        (_, None) => knots[i - 1].1,
        (_, Some(&(t1, d1))) => {
            let (t0, d0) = knots[i - 1];
            if t1 > t0 {
                d0 + (d1 - d0) * (t - t0) / (t1 - t0)
            } else {
                d1
            }
        }
    }
}

/// The bases of one record at its sample times for time constants `taus` and offset `d0`:
/// the elastic force and one hereditary variable per term.
fn bases(
    (k, r): (usize, &PressRecord),
    phi: &dyn Fn(usize, f64) -> f64,
    taus: &[f64],
    d0: f64,
    lag_s: f64,
) -> Vec<Vec<f64>> {
    let knots: Vec<(f64, f64)> = r.depth_knots.iter().map(|(t, d)| (t + lag_s, *d)).collect();
    let depth = |t: f64| depth_at(&knots, t);
    let elastic = |t: f64| phi(k, depth(t) - d0);
    let m = taus.len();
    let mut out = vec![Vec::with_capacity(r.t_s.len()); m + 1];
    let mut h = vec![0.0; m];
    let mut t_prev = r.t_s[0];
    let mut e_prev = elastic(t_prev);
    // Knot times inside (t_prev, t]: the depth's kinks, where the ramp must be cut.
    let mut knot = knots.partition_point(|(tk, _)| *tk <= t_prev);
    for &t in &r.t_s {
        let mut cuts: Vec<f64> = Vec::new();
        while knot < knots.len() && knots[knot].0 < t {
            cuts.push(knots[knot].0);
            knot += 1;
        }
        cuts.push(t);
        for &tc in &cuts {
            if tc <= t_prev {
                continue;
            }
            let moving = (depth(tc) - depth(t_prev)).abs() > 0.0;
            let pieces = if moving {
                ((tc - t_prev) / MOVING_STEP_S).ceil().max(1.0) as usize
            } else {
                1
            };
            for p in 1..=pieces {
                let tp = t_prev + (tc - t_prev) * p as f64 / pieces as f64;
                let dt = tp - (t_prev + (tc - t_prev) * (p - 1) as f64 / pieces as f64);
                let e = elastic(tp);
                for (hv, &tau) in h.iter_mut().zip(taus) {
                    let x = dt / tau;
                    let ramp = mechanics::ramp_factor(x);
                    *hv = (-x).exp() * *hv + ramp * (e - e_prev);
                }
                e_prev = e;
            }
            t_prev = tc;
        }
        out[0].push(e_prev);
        for (k, hv) in h.iter().enumerate() {
            out[k + 1].push(*hv);
        }
    }
    out
}

/// The linear part for `theta` = (ln τ₁…ₘ, d₀ per record): coefficients (s, s·w₁…ₘ) and the
/// residuals, record after record.
fn project(
    records: &[(usize, &PressRecord)],
    phi: &dyn Fn(usize, f64) -> f64,
    m: usize,
    theta: &[f64],
) -> Option<(DVector<f64>, DVector<f64>)> {
    let taus: Vec<f64> = theta[..m].iter().map(|v| v.exp()).collect();
    // A term faster than the samples or slower than the records is not in the data.
    let span = records
        .iter()
        .map(|(_, r)| r.t_s.last().unwrap_or(&0.0) - r.t_s[0])
        .fold(0.0, f64::max);
    if taus
        .iter()
        .any(|t| !t.is_finite() || *t < MIN_TAU_S || *t > 10.0 * span)
    {
        return None;
    }
    let lag_s = theta[m + records.len()];
    let cols = m + 1;
    let n: usize = records.iter().map(|(_, r)| r.t_s.len()).sum();
    let mut a = DMatrix::<f64>::zeros(n, cols);
    let mut y = DVector::<f64>::zeros(n);
    let mut row = 0;
    for (k, &(i_rec, r)) in records.iter().enumerate() {
        let b = bases((i_rec, r), phi, &taus, theta[m + k], lag_s);
        for i in 0..r.t_s.len() {
            for (j, bj) in b.iter().enumerate() {
                a[(row, j)] = bj[i];
            }
            y[row] = r.f_n[i];
            row += 1;
        }
    }
    let svd = a.clone().try_svd(true, true, f64::EPSILON, 1000)?;
    let c = svd.solve(&y, 1e-12).ok()?;
    let resid = &a * &c - &y;
    Some((c, resid))
}

fn fit_terms(
    records: &[(usize, &PressRecord)],
    phi: &dyn Fn(usize, f64) -> f64,
    start: &[f64],
) -> Option<MaterialFit> {
    let m = start.len();
    let theta0: Vec<f64> = start
        .iter()
        .map(|t| t.ln())
        .chain(records.iter().map(|_| 0.0))
        .chain(std::iter::once(0.0))
        .collect();
    let (theta, _) =
        levenberg_marquardt(theta0, 200, |th| project(records, phi, m, th).map(|p| p.1))?;
    let (c, resid) = project(records, phi, m, &theta)?;
    let s = c[0];
    if !(s.is_finite() && s > 0.0) {
        return None;
    }
    // Standard errors: the full model's Jacobian in (ln τ, d₀, then the linear coefficients)
    // at the optimum; the linear columns are minus the bases.
    let n = resid.len();
    let p_nl = theta.len();
    let p = p_nl + c.len();
    let full = |th: &[f64], lin: &DVector<f64>| -> Option<DVector<f64>> {
        let taus: Vec<f64> = th[..m].iter().map(|v| v.exp()).collect();
        let mut out = DVector::zeros(n);
        let mut row = 0;
        for (k, &(i_rec, r)) in records.iter().enumerate() {
            let b = bases((i_rec, r), phi, &taus, th[m + k], th[m + records.len()]);
            for i in 0..r.t_s.len() {
                let mut v = -r.f_n[i];
                for (j, bj) in b.iter().enumerate() {
                    v += lin[j] * bj[i];
                }
                out[row] = v;
                row += 1;
            }
        }
        Some(out)
    };
    let mut jac = DMatrix::<f64>::zeros(n, p);
    let h = 1e-6;
    let r0 = full(&theta, &c)?;
    for k in 0..p_nl {
        let mut th = theta.clone();
        th[k] += h;
        jac.set_column(k, &((full(&th, &c)? - &r0) / h));
    }
    for k in 0..c.len() {
        let mut lin = c.clone();
        lin[k] += 1.0;
        jac.set_column(p_nl + k, &(full(&theta, &lin)? - &r0));
    }
    let dof = n.saturating_sub(p).max(1) as f64;
    let sigma2 = resid.norm_squared() / dof;
    let cov = (jac.transpose() * &jac).try_inverse()? * sigma2;
    let sd = |k: usize| cov[(k, k)].max(0.0).sqrt();
    // Weights wᵢ = (s·wᵢ)/s, by the delta method.
    let mut terms: Vec<FittedTerm> = (0..m)
        .map(|i| {
            let (a, ia) = (c[1 + i], p_nl + 1 + i);
            let w = a / s;
            let (ds, da) = (-a / (s * s), 1.0 / s);
            let var = ds * ds * cov[(p_nl, p_nl)]
                + da * da * cov[(ia, ia)]
                + 2.0 * ds * da * cov[(p_nl, ia)];
            let tau = theta[i].exp();
            FittedTerm {
                weight: Estimate {
                    value: w,
                    sd: var.max(0.0).sqrt(),
                },
                tau_s: Estimate {
                    value: tau,
                    sd: tau * sd(i),
                },
            }
        })
        .collect();
    if terms
        .iter()
        .any(|t| !(t.weight.value > 0.0 && t.weight.value < MAX_WEIGHT))
    {
        return None;
    }
    terms.sort_by(|a, b| a.tau_s.value.total_cmp(&b.tau_s.value));
    let mut residual_rms_n = Vec::new();
    let mut row = 0;
    for (_, r) in records {
        let k = r.t_s.len();
        let ss: f64 = resid.rows(row, k).norm_squared();
        residual_rms_n.push((ss / k as f64).sqrt());
        row += k;
    }
    Some(MaterialFit {
        modulus_ratio: Estimate {
            value: s,
            sd: sd(p_nl),
        },
        terms,
        offsets_mm: (0..records.len())
            .map(|k| Estimate {
                value: theta[m + k],
                sd: sd(m + k),
            })
            .collect(),
        lag_s: Estimate {
            value: theta[m + records.len()],
            sd: sd(m + records.len()),
        },
        residual_rms_n,
        samples: n,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use mechanics::{Prony, PronyTerm};

    /// A stepped load/unload record of a gel with `prony` and modulus ratio `s`, a punch
    /// of stiffness `k` N/mm whose surface lies `d0` past the origin, sampled at 20 Hz.
    fn record(prony: &Prony, s: f64, k: f64, d0: f64, noise: f64) -> PressRecord {
        let levels = [0.1, 0.2, 0.3, 0.4, 0.5, 0.4, 0.3, 0.2, 0.1];
        let (hold_s, move_s, dt) = (60.0, 0.5, 0.005);
        let mut knots = vec![(0.0, 0.0)];
        let mut t = 0.0;
        let mut last = 0.0;
        for &l in &levels {
            t += 1.0;
            knots.push((t, last));
            t += move_s;
            knots.push((t, l));
            t += hold_s;
            last = l;
        }
        let t_end = t;
        let depth = |t: f64| depth_at(&knots, t);
        let mut state = prony.state();
        let mut fe_prev = s * k * (depth(0.0) - d0).max(0.0);
        state.shift_driving(fe_prev);
        let (mut ts, mut fs) = (Vec::new(), Vec::new());
        let steps = (t_end / dt).round() as usize;
        for i in 1..=steps {
            let tt = i as f64 * dt;
            let fe = s * k * (depth(tt) - d0).max(0.0);
            state.advance_linear(prony, dt, fe);
            fe_prev = fe;
            if i % 10 == 0 {
                let e = noise * (((i * 7919) % 1000) as f64 / 500.0 - 1.0);
                ts.push(tt);
                fs.push(state.value() + e);
            }
        }
        let _ = fe_prev;
        PressRecord {
            t_s: ts,
            f_n: fs,
            depth_knots: knots,
        }
    }

    #[test]
    fn a_gels_modulus_relaxation_and_contact_offset_are_recovered_from_its_record() {
        let prony = Prony::new(vec![
            PronyTerm {
                weight: 0.25,
                tau_s: 2.0,
            },
            PronyTerm {
                weight: 0.15,
                tau_s: 15.0,
            },
        ])
        .expect("valid");
        let k = 40.0;
        let rec = record(&prony, 1.2, k, 0.004, 0.005);
        let fit =
            fit_material(std::slice::from_ref(&rec), &|_, d: f64| k * d.max(0.0)).expect("fits");
        assert!((fit.modulus_ratio.value - 1.2).abs() < 0.002, "{fit:?}");
        assert_eq!(fit.terms.len(), 2, "{fit:?}");
        for (got, want) in fit.terms.iter().zip(prony.terms()) {
            assert!(
                (got.weight.value / want.weight - 1.0).abs() < 0.01,
                "{got:?} vs {want:?}"
            );
            assert!(
                (got.tau_s.value / want.tau_s - 1.0).abs() < 0.02,
                "{got:?} vs {want:?}"
            );
            assert!(got.weight.sd > 0.0 && got.tau_s.sd > 0.0);
        }
        assert!((fit.offsets_mm[0].value - 0.004).abs() < 2e-4, "{fit:?}");
        assert!(fit.residual_rms_n[0] < 0.01, "{fit:?}");
    }

    #[test]
    fn nothing_to_fit_is_refused() {
        assert!(fit_material(&[], &|_, d: f64| d).is_none());
        let short = PressRecord {
            t_s: vec![0.0, 1.0],
            f_n: vec![0.0, 1.0],
            depth_knots: vec![(0.0, 0.0)],
        };
        assert!(fit_material(&[short], &|_, d: f64| d).is_none());
    }
}
