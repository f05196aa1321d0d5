//! Relaxation fits: the equilibrium force F∞ of a step from a partial relaxation record.
//!
//! Model F(t) = F∞ + Σᵢ Aᵢ e^{−t/τᵢ} with one to three terms (spec §4). Fitting exponentials
//! is a classic ill-posed problem (Lanczos 1956; Istratov & Vyvenko 1999): over a record
//! shorter than about 2τ_slow only F∞ + A and A/τ are identifiable, and Jacobian error bars
//! then understate the true error by orders of magnitude. So the fit reports its
//! uncertainty *and* how far to trust it.
//!
//! Method: variable projection (Golub & Pereyra 1973; O'Leary & Rust 2013). For fixed
//! θ = log τ the linear parameters (F∞, Aᵢ) solve a least-squares problem; the projected
//! residual is minimised over θ by Levenberg–Marquardt, started from the best point of a
//! log-spaced grid. A final Gauss–Newton pass over all parameters gives the Jacobian and
//! σ(F∞) = s·√[(JᵀJ)⁻¹]₀₀, s² = RSS/(n − p).

use nalgebra::{DMatrix, DVector};

/// A fitted sum of exponentials.
#[derive(Debug, Clone, PartialEq)]
pub struct ExpFit {
    /// Equilibrium value F∞.
    pub f_inf: f64,
    /// Amplitudes Aᵢ, in the order of `taus_s`.
    pub amplitudes: Vec<f64>,
    /// Time constants τᵢ in seconds, increasing.
    pub taus_s: Vec<f64>,
    /// Residual sum of squares.
    pub rss: f64,
    /// Number of samples.
    pub n: usize,
    /// Jacobian standard error of F∞ (trust only when the record is ≥ 2τ_slow long).
    pub sigma_f_inf: f64,
    /// Condition number of the Jacobian (large: parameters not identifiable).
    pub condition: f64,
    /// Whether the optimiser converged.
    pub converged: bool,
}

impl ExpFit {
    /// The model at time `t_s`.
    pub fn eval(&self, t_s: f64) -> f64 {
        self.f_inf
            + self
                .amplitudes
                .iter()
                .zip(&self.taus_s)
                .map(|(a, tau)| a * (-t_s / tau).exp())
                .sum::<f64>()
    }
}

/// Least-squares linear parameters [F∞, A…] and the residual for time constants `taus`.
///
/// Forms the (at most 4×4) normal equations in one pass and solves them by SVD with a
/// relative cut-off, so nearly equal τ give a minimum-norm answer instead of a blow-up.
fn linear_part(t: &[f64], y: &[f64], taus: &[f64]) -> Option<(DVector<f64>, DVector<f64>)> {
    let m = taus.len() + 1;
    let mut ata = DMatrix::<f64>::zeros(m, m);
    let mut aty = DVector::<f64>::zeros(m);
    let mut row = vec![0.0; m];
    for (ti, yi) in t.iter().zip(y) {
        row[0] = 1.0;
        for (k, tau) in taus.iter().enumerate() {
            row[k + 1] = (-ti / tau).exp();
        }
        for a in 0..m {
            aty[a] += row[a] * yi;
            for b in 0..m {
                ata[(a, b)] += row[a] * row[b];
            }
        }
    }
    let c = ata.svd(true, true).solve(&aty, 1e-15).ok()?;
    let r = DVector::from_iterator(
        t.len(),
        t.iter().zip(y).map(|(ti, yi)| {
            yi - c[0]
                - taus
                    .iter()
                    .enumerate()
                    .map(|(k, tau)| c[k + 1] * (-ti / tau).exp())
                    .sum::<f64>()
        }),
    );
    Some((c, r))
}

/// Fits `terms` exponentials to (t, y) by variable projection. `t` must start at the step
/// (t = 0 at the move) and be increasing. Returns `None` when the data cannot support the
/// model (fewer than 2·terms + 3 samples, or a degenerate record).
pub fn fit_exponentials(t: &[f64], y: &[f64], terms: usize) -> Option<ExpFit> {
    let n = t.len();
    if terms == 0 || n != y.len() || n < 2 * terms + 3 {
        return None;
    }
    let span = t[n - 1] - t[0];
    let dt = span / (n - 1) as f64;
    if span <= 0.0 || !y.iter().all(|v| v.is_finite()) {
        return None;
    }
    // Grid of candidate τ from a couple of samples to ten record lengths.
    let grid: Vec<f64> = (0..48)
        .map(|i| (2.0 * dt).ln() + i as f64 / 47.0 * ((10.0 * span).ln() - (2.0 * dt).ln()))
        .collect();
    // Columns e^{−t/τ} of every grid τ, computed once; each candidate combination then
    // only assembles its small normal equations from them.
    let columns: Vec<Vec<f64>> = grid
        .iter()
        .map(|th| t.iter().map(|ti| (-ti / th.exp()).exp()).collect())
        .collect();
    let rss_of_grid = |idx: &[usize]| -> f64 {
        let m = idx.len() + 1;
        let col = |k: usize, i: usize| if k == 0 { 1.0 } else { columns[idx[k - 1]][i] };
        let mut ata = DMatrix::<f64>::zeros(m, m);
        let mut aty = DVector::<f64>::zeros(m);
        for (i, yi) in y.iter().enumerate() {
            for a in 0..m {
                let ca = col(a, i);
                aty[a] += ca * yi;
                for b in a..m {
                    ata[(a, b)] += ca * col(b, i);
                }
            }
        }
        for a in 0..m {
            for b in 0..a {
                ata[(a, b)] = ata[(b, a)];
            }
        }
        let Ok(c) = ata.svd(true, true).solve(&aty, 1e-15) else {
            return f64::INFINITY;
        };
        (0..n)
            .map(|i| {
                let f: f64 = (0..m).map(|k| c[k] * col(k, i)).sum();
                (y[i] - f).powi(2)
            })
            .sum()
    };
    let mut best = (f64::INFINITY, vec![0.0; terms]);
    let mut idx = vec![0usize; terms];
    let step = match terms {
        1 => 1,
        2 => 2,
        _ => 4,
    };
    loop {
        if idx.windows(2).all(|w| w[0] < w[1]) {
            let rss = rss_of_grid(&idx);
            if rss < best.0 {
                best = (rss, idx.iter().map(|i| grid[*i]).collect());
            }
        }
        // Next combination on the (coarsened) grid.
        let mut k = 0;
        loop {
            if k == terms {
                break;
            }
            idx[k] += step;
            if idx[k] < grid.len() {
                break;
            }
            idx[k] = 0;
            k += 1;
        }
        if k == terms {
            break;
        }
    }
    if !best.0.is_finite() {
        return None;
    }
    // Levenberg–Marquardt on θ over the projected residual (finite-difference Jacobian).
    let mut theta = best.1;
    let mut lambda = 1e-3;
    let mut converged = false;
    let residual = |theta: &[f64]| -> Option<DVector<f64>> {
        let taus: Vec<f64> = theta.iter().map(|v| v.exp()).collect();
        linear_part(t, y, &taus).map(|(_, r)| r)
    };
    let mut r = residual(&theta)?;
    for _ in 0..200 {
        let h = 1e-6;
        let mut jac = DMatrix::zeros(n, terms);
        for k in 0..terms {
            let mut th = theta.clone();
            th[k] += h;
            let rp = residual(&th)?;
            jac.set_column(k, &((rp - &r) / h));
        }
        let jtj = jac.transpose() * &jac;
        let jtr = jac.transpose() * &r;
        let rss = r.norm_squared();
        let mut improved = false;
        for _ in 0..30 {
            let mut a = jtj.clone();
            for k in 0..terms {
                a[(k, k)] += lambda * jtj[(k, k)].max(1e-300);
            }
            let Some(delta) = a.lu().solve(&(-&jtr)) else {
                lambda *= 10.0;
                continue;
            };
            let cand: Vec<f64> = theta.iter().zip(delta.iter()).map(|(a, d)| a + d).collect();
            if let Some(rc) = residual(&cand)
                && rc.norm_squared() <= rss
            {
                let rel = (rss - rc.norm_squared()) / rss.max(1e-300);
                theta = cand;
                r = rc;
                lambda = (lambda / 3.0).max(1e-12);
                improved = true;
                if rel < 1e-14 || delta.norm() < 1e-12 {
                    converged = true;
                }
                break;
            }
            lambda *= 10.0;
        }
        if !improved || converged {
            converged = converged || !improved;
            break;
        }
    }
    // Order by τ, then a Gauss–Newton polish over all parameters with the exact Jacobian.
    theta.sort_by(|a, b| a.total_cmp(b));
    let taus: Vec<f64> = theta.iter().map(|v| v.exp()).collect();
    let (c, _) = linear_part(t, y, &taus)?;
    let mut params: Vec<f64> = c.iter().copied().chain(theta.iter().copied()).collect();
    let p = params.len();
    let model_jac = |params: &[f64]| -> (DVector<f64>, DMatrix<f64>) {
        let mut res = DVector::zeros(n);
        let mut jac = DMatrix::zeros(n, p);
        for i in 0..n {
            let mut f = params[0];
            jac[(i, 0)] = 1.0;
            for k in 0..terms {
                let (a, tau) = (params[1 + k], params[1 + terms + k].exp());
                let e = (-t[i] / tau).exp();
                f += a * e;
                jac[(i, 1 + k)] = e;
                // ∂/∂log τ of A e^{−t/τ} = A e^{−t/τ} · t/τ.
                jac[(i, 1 + terms + k)] = a * e * t[i] / tau;
            }
            res[i] = y[i] - f;
        }
        (res, jac)
    };
    for _ in 0..5 {
        let (res, jac) = model_jac(&params);
        let Some(delta) = (jac.transpose() * &jac)
            .lu()
            .solve(&(jac.transpose() * &res))
        else {
            break;
        };
        let cand: Vec<f64> = params
            .iter()
            .zip(delta.iter())
            .map(|(a, d)| a + d)
            .collect();
        if model_jac(&cand).0.norm_squared() <= res.norm_squared() {
            params = cand;
        } else {
            break;
        }
    }
    let (res, jac) = model_jac(&params);
    let rss = res.norm_squared();
    let dof = (n - p).max(1) as f64;
    let jtj = jac.transpose() * &jac;
    let sv = jac.clone().svd(false, false).singular_values;
    let condition = sv.max() / sv.min().max(1e-300);
    let sigma = jtj
        .try_inverse()
        .map(|inv| (rss / dof * inv[(0, 0)].max(0.0)).sqrt())
        .unwrap_or(f64::INFINITY);
    Some(ExpFit {
        f_inf: params[0],
        amplitudes: params[1..=terms].to_vec(),
        taus_s: params[1 + terms..].iter().map(|v| v.exp()).collect(),
        rss,
        n,
        sigma_f_inf: sigma,
        condition,
        converged,
    })
}

/// Aitken's Δ² extrapolation of a single exponential from three equally spaced samples:
/// F∞ = (F₁F₃ − F₂²)/(F₁ + F₃ − 2F₂). Exact for one exponential; `None` when the
/// denominator vanishes (no curvature: no relaxation, or noise only).
pub fn aitken(f1: f64, f2: f64, f3: f64) -> Option<f64> {
    let den = f1 + f3 - 2.0 * f2;
    if den.abs() <= 1e-12 * (f1.abs() + f2.abs() + f3.abs()).max(1e-300) {
        return None;
    }
    Some((f1 * f3 - f2 * f2) / den)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand::rngs::StdRng;
    use rand_distr::{Distribution, Normal};

    fn record(t_end: f64, hz: f64, noise: f64, rng: Option<&mut StdRng>) -> (Vec<f64>, Vec<f64>) {
        let n = (t_end * hz).round() as usize + 1;
        let t: Vec<f64> = (0..n).map(|i| i as f64 / hz).collect();
        let mut y: Vec<f64> = t
            .iter()
            .map(|t| 1.0 + 0.2 * (-t / 3.0).exp() + 0.15 * (-t / 40.0).exp())
            .collect();
        if let Some(rng) = rng {
            let d = Normal::new(0.0, noise).expect("σ > 0");
            for v in &mut y {
                *v += d.sample(rng);
            }
        }
        (t, y)
    }

    #[test]
    fn noise_free_two_exponentials_o21() {
        let (t, y) = record(300.0, 10.0, 0.0, None);
        let fit = fit_exponentials(&t, &y, 2).expect("fits");
        assert!((fit.f_inf - 1.0).abs() < 1e-9, "{}", fit.f_inf);
        assert!(
            (fit.taus_s[0] - 3.0).abs() < 1e-9 && (fit.taus_s[1] - 40.0).abs() < 1e-9,
            "{:?}",
            fit.taus_s
        );
        assert!((fit.amplitudes[0] - 0.2).abs() < 1e-9 && (fit.amplitudes[1] - 0.15).abs() < 1e-9);
    }

    #[test]
    fn aitken_o22() {
        let f = |t: f64| 1.0 + 0.3 * (-t / 7.0).exp();
        let est = aitken(f(5.0), f(9.0), f(13.0)).expect("curvature");
        assert!((est - 1.0).abs() < 1e-12, "{est}");
        assert!(aitken(2.0, 2.0, 2.0).is_none());
    }

    #[test]
    fn settle_calibration_monte_carlo_o23() {
        // Spec §4: noise 1e-3, 10 Hz, 200 runs. At T = 2τ_slow and 4τ_slow the median
        // Jacobian σ̂ is ≈ 3.8e-4 and 7.2e-5, and the actual RMSE is within 1.3× of it.
        for (t_end, sigma_expect) in [(80.0, 3.8e-4), (160.0, 7.2e-5)] {
            let mut rng = StdRng::seed_from_u64(23);
            let mut errs = Vec::new();
            let mut sigmas = Vec::new();
            for _ in 0..200 {
                let (t, y) = record(t_end, 10.0, 1e-3, Some(&mut rng));
                let fit = fit_exponentials(&t, &y, 2).expect("fits");
                errs.push(fit.f_inf - 1.0);
                sigmas.push(fit.sigma_f_inf);
            }
            sigmas.sort_by(|a, b| a.total_cmp(b));
            let median = sigmas[100];
            let rmse = (errs.iter().map(|e| e * e).sum::<f64>() / errs.len() as f64).sqrt();
            assert!(
                (median / sigma_expect - 1.0).abs() < 0.25,
                "T {t_end}: median σ̂ {median:.2e}"
            );
            assert!(
                rmse / median < 1.3 && median / rmse < 1.3,
                "T {t_end}: RMSE {rmse:.2e} vs σ̂ {median:.2e}"
            );
        }
    }
}
