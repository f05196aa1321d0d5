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

/// Solves the small normal equations by SVD with a relative cut-off, refusing non-finite
/// input and bounding the iterations: nalgebra's plain `svd` never returns on a matrix
/// with NaN (an optimiser step to an overflowing τ produces one).
fn bounded_svd_solve(ata: DMatrix<f64>, aty: &DVector<f64>) -> Option<DVector<f64>> {
    if !ata.iter().chain(aty.iter()).all(|v| v.is_finite()) {
        return None;
    }
    ata.try_svd(true, true, f64::EPSILON, 500)?
        .solve(aty, 1e-15)
        .ok()
}

/// Least-squares linear parameters [F∞, A…] and the residual for time constants `taus`.
///
/// Forms the (at most 4×4) normal equations in one pass and solves them by SVD with a
/// relative cut-off, so nearly equal τ give a minimum-norm answer instead of a blow-up.
fn linear_part(t: &[f64], y: &[f64], taus: &[f64]) -> Option<(DVector<f64>, DVector<f64>)> {
    let columns: Vec<Vec<f64>> = taus.iter().map(|tau| decay(t, *tau)).collect();
    let refs: Vec<&[f64]> = columns.iter().map(Vec::as_slice).collect();
    linear_part_of(y, &refs)
}

/// The column e^{−t/τ} over the record.
fn decay(t: &[f64], tau: f64) -> Vec<f64> {
    t.iter().map(|ti| (-ti / tau).exp()).collect()
}

/// [`linear_part`] from the columns e^{−t/τₖ}, computed once by the caller: the exponentials
/// were most of a fit's cost (docs/benchmarks/reports.md, "The relaxation fits, cheaper").
fn linear_part_of(y: &[f64], columns: &[&[f64]]) -> Option<(DVector<f64>, DVector<f64>)> {
    let m = columns.len() + 1;
    let mut ata = DMatrix::<f64>::zeros(m, m);
    let mut aty = DVector::<f64>::zeros(m);
    let mut row = vec![0.0; m];
    for (i, yi) in y.iter().enumerate() {
        row[0] = 1.0;
        for (k, col) in columns.iter().enumerate() {
            row[k + 1] = col[i];
        }
        for a in 0..m {
            aty[a] += row[a] * yi;
            for b in 0..m {
                ata[(a, b)] += row[a] * row[b];
            }
        }
    }
    let c = bounded_svd_solve(ata, &aty)?;
    let r = DVector::from_iterator(
        y.len(),
        y.iter().enumerate().map(|(i, yi)| {
            yi - c[0]
                - columns
                    .iter()
                    .enumerate()
                    .map(|(k, col)| c[k + 1] * col[i])
                    .sum::<f64>()
        }),
    );
    Some((c, r))
}

/// The columns e^{−t/τ} of the last few time constants asked for. Levenberg–Marquardt's
/// finite-difference Jacobian moves one time constant at a time, so each of its evaluations
/// needs one new column, not one per term.
struct Decays<'a> {
    t: &'a [f64],
    kept: std::cell::RefCell<Vec<(u64, std::rc::Rc<Vec<f64>>)>>,
    capacity: usize,
}

impl<'a> Decays<'a> {
    fn new(t: &'a [f64], terms: usize) -> Self {
        Self {
            t,
            kept: std::cell::RefCell::new(Vec::new()),
            capacity: 2 * terms + 2,
        }
    }

    /// The column of `tau`: kept, or computed and kept in place of the oldest.
    fn of(&self, tau: f64) -> std::rc::Rc<Vec<f64>> {
        let mut kept = self.kept.borrow_mut();
        if let Some((_, col)) = kept.iter().find(|(bits, _)| *bits == tau.to_bits()) {
            return std::rc::Rc::clone(col);
        }
        let col = std::rc::Rc::new(decay(self.t, tau));
        if kept.len() == self.capacity {
            kept.remove(0);
        }
        kept.push((tau.to_bits(), std::rc::Rc::clone(&col)));
        col
    }

    /// [`linear_part`] for `taus`, from kept columns where it can.
    fn linear_part(&self, y: &[f64], taus: &[f64]) -> Option<(DVector<f64>, DVector<f64>)> {
        let columns: Vec<std::rc::Rc<Vec<f64>>> = taus.iter().map(|tau| self.of(*tau)).collect();
        let refs: Vec<&[f64]> = columns.iter().map(|c| c.as_slice()).collect();
        linear_part_of(y, &refs)
    }
}

/// Levenberg–Marquardt over `theta` (finite-difference Jacobian) for a residual that may
/// refuse a point (`None`). Returns the last accepted point and whether it converged
/// (no further decrease possible, or a relative decrease under 1e-14).
pub(crate) fn levenberg_marquardt(
    mut theta: Vec<f64>,
    max_iter: usize,
    residual: impl Fn(&[f64]) -> Option<DVector<f64>>,
) -> Option<(Vec<f64>, bool)> {
    let m = theta.len();
    let mut r = residual(&theta)?;
    let mut lambda = 1e-3;
    for _ in 0..max_iter {
        let h = 1e-6;
        let mut jac = DMatrix::zeros(r.len(), m);
        for k in 0..m {
            let mut th = theta.clone();
            th[k] += h;
            let rp = residual(&th)?;
            jac.set_column(k, &((rp - &r) / h));
        }
        let jtj = jac.transpose() * &jac;
        let jtr = jac.transpose() * &r;
        let rss = r.norm_squared();
        let mut improved = false;
        let mut converged = false;
        for _ in 0..30 {
            let mut a = jtj.clone();
            for k in 0..m {
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
                converged = rel < 1e-14 || delta.norm() < 1e-12;
                theta = cand;
                r = rc;
                lambda = (lambda / 3.0).max(1e-12);
                improved = true;
                break;
            }
            lambda *= 10.0;
        }
        if !improved || converged {
            return Some((theta, true));
        }
    }
    Some((theta, false))
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
    if span <= 0.0 || !y.iter().all(|v| v.is_finite()) {
        return None;
    }
    let start = grid_start(t, y, terms)?;
    // Levenberg–Marquardt on θ over the projected residual.
    let decays = Decays::new(t, terms);
    let residual = |theta: &[f64]| -> Option<DVector<f64>> {
        let taus: Vec<f64> = theta.iter().map(|v| v.exp()).collect();
        decays.linear_part(y, &taus).map(|(_, r)| r)
    };
    let (mut theta, converged) = levenberg_marquardt(start, 200, residual)?;
    // Order by τ, then a Gauss–Newton polish over all parameters with the exact Jacobian.
    theta.sort_by(|a, b| a.total_cmp(b));
    let taus: Vec<f64> = theta.iter().map(|v| v.exp()).collect();
    let (c, _) = linear_part(t, y, &taus)?;
    let start: Vec<f64> = c.iter().copied().chain(theta.iter().copied()).collect();
    let params = polish(t, y, terms, start);
    Some(summarise(t, y, terms, params, converged))
}

/// The starting log-time-constants of the variable projection: the best combination of
/// `terms` values on a logarithmic grid from a couple of samples to ten record lengths
/// (coarsened for more terms), each scored by the residual of its linear least squares.
/// Variable projection from a poor start finds a poor local minimum; the grid is cheap,
/// since the columns e^{−t/τ} are computed once.
fn grid_start(t: &[f64], y: &[f64], terms: usize) -> Option<Vec<f64>> {
    let (grid, columns) = start_grid(t);
    // The normal equations of every combination are entries of one Gram matrix over the
    // constant and the grid's columns, summed once in the order each combination summed
    // them (the same products in the same order: the same bits).
    // Only the pairs some combination uses: the constant with each column, each column
    // with itself, and (for two terms or more) the columns on the coarsened grid together.
    let step = match terms {
        1 => 1,
        2 => 2,
        _ => 4,
    };
    let cols = grid.len() + 1;
    let col = |k: usize, i: usize| if k == 0 { 1.0 } else { columns[k - 1][i] };
    let used = |k: usize| k == 0 || (k - 1).is_multiple_of(step);
    let pairs: Vec<(usize, usize)> = (0..cols)
        .filter(|a| used(*a))
        .flat_map(|a| (a..cols).map(move |b| (a, b)))
        .filter(|&(a, b)| used(b) && (a == 0 || a == b || terms >= 2))
        .collect();
    let mut gram = vec![0.0; cols * cols];
    let mut gty = vec![0.0; cols];
    for (i, yi) in y.iter().enumerate() {
        for a in (0..cols).filter(|a| used(*a)) {
            gty[a] += col(a, i) * yi;
        }
        for &(a, b) in &pairs {
            gram[a * cols + b] += col(a, i) * col(b, i);
        }
    }
    // A combination's residual only grows as samples are added: once it reaches the best so
    // far it cannot be chosen (the choice is strictly better), and the rest is not summed.
    let rss_of_grid = |idx: &[usize], best: f64| -> f64 {
        let m = idx.len() + 1;
        // Column k of the combination is Gram column `at(k)`: the constant, then the grid's.
        let at = |k: usize| if k == 0 { 0 } else { idx[k - 1] + 1 };
        let mut ata = DMatrix::<f64>::zeros(m, m);
        let mut aty = DVector::<f64>::zeros(m);
        for a in 0..m {
            aty[a] = gty[at(a)];
            for b in a..m {
                ata[(a, b)] = gram[at(a) * cols + at(b)];
                ata[(b, a)] = ata[(a, b)];
            }
        }
        let Some(c) = bounded_svd_solve(ata, &aty) else {
            return f64::INFINITY;
        };
        let mut rss = 0.0;
        for (i, yi) in y.iter().enumerate() {
            let f: f64 = (0..m).map(|k| c[k] * col(at(k), i)).sum();
            rss += (yi - f).powi(2);
            if i % 32 == 31 && rss >= best {
                return f64::INFINITY;
            }
        }
        rss
    };
    let mut best = (f64::INFINITY, vec![0.0; terms]);
    for_each_combination(terms, step, grid.len(), |idx| {
        let rss = rss_of_grid(idx, best.0);
        if rss < best.0 {
            best = (rss, idx.iter().map(|i| grid[*i]).collect());
        }
    });
    best.0.is_finite().then_some(best.1)
}

/// Calls `f` with every increasing choice of `terms` indices below `len` on a grid coarsened
/// to every `step`-th point, the first index varying fastest.
fn for_each_combination(terms: usize, step: usize, len: usize, mut f: impl FnMut(&[usize])) {
    let mut idx = vec![0usize; terms];
    loop {
        if idx.windows(2).all(|w| w[0] < w[1]) {
            f(&idx);
        }
        let mut k = 0;
        while k < terms {
            idx[k] += step;
            if idx[k] < len {
                break;
            }
            idx[k] = 0;
            k += 1;
        }
        if k == terms {
            break;
        }
    }
}

/// The 48 log-time-constants of the starting grid, from two sample intervals to ten record
/// lengths, and their columns e^{−t/τ}.
fn start_grid(t: &[f64]) -> (Vec<f64>, Vec<Vec<f64>>) {
    let n = t.len();
    let span = t[n - 1] - t[0];
    let dt = span / (n - 1) as f64;
    let grid: Vec<f64> = (0..48)
        .map(|i| (2.0 * dt).ln() + i as f64 / 47.0 * ((10.0 * span).ln() - (2.0 * dt).ln()))
        .collect();
    let columns = grid
        .iter()
        .map(|th| t.iter().map(|ti| (-ti / th.exp()).exp()).collect())
        .collect();
    (grid, columns)
}

/// The model f(t) = F∞ + Σ Aₖ e^{−t/τₖ} with `params` = [F∞, A…, log τ…]: its residual
/// y − f and its exact Jacobian (∂/∂log τ of A e^{−t/τ} = A e^{−t/τ} · t/τ).
fn model_and_jacobian(
    t: &[f64],
    y: &[f64],
    terms: usize,
    params: &[f64],
) -> (DVector<f64>, DMatrix<f64>) {
    let (n, p) = (t.len(), params.len());
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
            jac[(i, 1 + terms + k)] = a * e * t[i] / tau;
        }
        res[i] = y[i] - f;
    }
    (res, jac)
}

/// A few Gauss–Newton steps over all parameters with the exact Jacobian, each taken only
/// if it lowers the residual and leaves a finite Jacobian (a step that drives a time
/// constant to 0 or ∞ is refused).
fn polish(t: &[f64], y: &[f64], terms: usize, mut params: Vec<f64>) -> Vec<f64> {
    for _ in 0..5 {
        let (res, jac) = model_and_jacobian(t, y, terms, &params);
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
        let (cand_res, cand_jac) = model_and_jacobian(t, y, terms, &cand);
        if cand_jac.iter().all(|v| v.is_finite()) && cand_res.norm_squared() <= res.norm_squared() {
            params = cand;
        } else {
            break;
        }
    }
    params
}

/// The fit at `params`: F∞, amplitudes, time constants, the residual, F∞'s standard error
/// from (JᵀJ)⁻¹ and the Jacobian's condition number.
fn summarise(t: &[f64], y: &[f64], terms: usize, params: Vec<f64>, converged: bool) -> ExpFit {
    let (n, p) = (t.len(), params.len());
    let (res, jac) = model_and_jacobian(t, y, terms, &params);
    let rss = res.norm_squared();
    let dof = (n - p).max(1) as f64;
    let jtj = jac.transpose() * &jac;
    // Bounded, and never on a non-finite matrix: nalgebra's plain `svd` does not return on
    // one (a run's report once hung here).
    let condition = jac
        .iter()
        .all(|v| v.is_finite())
        .then(|| jac.clone().try_svd(false, false, f64::EPSILON, 500))
        .flatten()
        .map_or(f64::INFINITY, |svd| {
            let sv = svd.singular_values;
            sv.max() / sv.min().max(1e-300)
        });
    let sigma = jtj
        .try_inverse()
        .map(|inv| (rss / dof * inv[(0, 0)].max(0.0)).sqrt())
        .unwrap_or(f64::INFINITY);
    ExpFit {
        f_inf: params[0],
        amplitudes: params[1..=terms].to_vec(),
        taus_s: params[1 + terms..].iter().map(|v| v.exp()).collect(),
        rss,
        n,
        sigma_f_inf: sigma,
        condition,
        converged,
    }
}

/// Refits the time constants `start_taus_s` with one more, `held_tau_s`, held fixed (variable
/// projection over the free ones, started where they are): the profile of a model with a
/// relaxation slower than the record shows, at that time constant. Returns the free time
/// constants found, increasing, and the residual sum of squares. Holding the extra term
/// while the others move is what lets a slower term and a faster one share the record's
/// slow decay between them (a 60 s and a 600 s term over 300 s look like one of ~120 s).
pub fn refit_with_held(
    t: &[f64],
    y: &[f64],
    start_taus_s: &[f64],
    held_tau_s: f64,
) -> Option<(Vec<f64>, f64)> {
    if start_taus_s.is_empty() || t.len() < 2 * start_taus_s.len() + 5 {
        return None;
    }
    let residual = |theta: &[f64]| -> Option<DVector<f64>> {
        let mut taus: Vec<f64> = theta.iter().map(|v| v.exp()).collect();
        taus.push(held_tau_s);
        linear_part(t, y, &taus).map(|(_, r)| r)
    };
    let theta0: Vec<f64> = start_taus_s.iter().map(|v| v.ln()).collect();
    let (theta, _) = levenberg_marquardt(theta0, 100, residual)?;
    let rss = residual(&theta)?.norm_squared();
    let mut taus: Vec<f64> = theta.iter().map(|v| v.exp()).collect();
    taus.sort_by(|a, b| a.total_cmp(b));
    (rss.is_finite() && taus.iter().all(|v| v.is_finite() && *v > 0.0)).then_some((taus, rss))
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

/// One step's relaxation: the model chosen by the data, F∞ with its uncertainty, and
/// every reason not to trust it.
#[derive(Debug, Clone, PartialEq)]
pub struct StepRelaxation {
    /// Exponential terms the Bayesian information criterion chose (0: no relaxation above
    /// the noise, F∞ is the mean).
    pub terms: usize,
    /// Equilibrium value.
    pub f_inf: f64,
    /// Standard error of `f_inf` (Jacobian; see `issues` for when it understates).
    pub sigma_f_inf: f64,
    /// Time constants, s, increasing.
    pub taus_s: Vec<f64>,
    /// Amplitudes, in the order of `taus_s`.
    pub amplitudes: Vec<f64>,
    /// The thesis's quasistatic value: the mean of the last `window_s` of the record.
    pub window_mean: f64,
    /// Rms residual of the chosen model.
    pub rms: f64,
    /// Why the numbers are not confident (empty: confident).
    pub issues: Vec<String>,
    /// The chosen fit, for plotting (`None` when `terms` is 0).
    pub fit: Option<ExpFit>,
}

impl StepRelaxation {
    /// Whether F∞ and τ can be quoted as measured.
    pub fn confident(&self) -> bool {
        self.issues.is_empty()
    }
}

/// BIC = n ln(RSS/n) + p ln n (Schwarz 1978), p = 2·terms + 1.
fn bic(rss: f64, n: usize, terms: usize) -> f64 {
    let n_f = n as f64;
    n_f * (rss.max(1e-300) / n_f).ln() + (2 * terms + 1) as f64 * n_f.ln()
}

/// Analyses one step's force record `f` at times `t_s` (t = 0 at the end of the move,
/// increasing): fits 0–`max_terms` exponentials, keeps the one the BIC prefers, and flags
/// ill-conditioned cases — a record shorter than 2τ_slow (F∞ extrapolated; spec §4),
/// time constants closer than 2× (not separable), τ below two samples, an unconverged or
/// ill-conditioned fit, too few samples — instead of returning them as confident numbers.
pub fn analyse_step(t_s: &[f64], f: &[f64], window_s: f64, max_terms: usize) -> StepRelaxation {
    let n = t_s.len().min(f.len());
    let (t_s, f) = (&t_s[..n], &f[..n]);
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
    let t_end = t_s.last().copied().unwrap_or(0.0);
    let window: Vec<f64> = t_s
        .iter()
        .zip(f)
        .filter(|(t, _)| **t >= t_end - window_s)
        .map(|(_, v)| *v)
        .collect();
    let window_mean = if window.is_empty() {
        f64::NAN
    } else {
        mean(&window)
    };
    let m = mean(f);
    let rss0: f64 = f.iter().map(|v| (v - m).powi(2)).sum();
    let mut best = StepRelaxation {
        terms: 0,
        f_inf: m,
        sigma_f_inf: (rss0 / (n.max(2) - 1) as f64 / n.max(1) as f64).sqrt(),
        taus_s: Vec::new(),
        amplitudes: Vec::new(),
        window_mean,
        rms: (rss0 / n.max(1) as f64).sqrt(),
        issues: Vec::new(),
        fit: None,
    };
    if n < 10 {
        best.issues
            .push(format!("only {n} samples: too short a record to fit"));
        return best;
    }
    let mut best_bic = bic(rss0, n, 0);
    for terms in 1..=max_terms {
        let Some(fit) = fit_exponentials(t_s, f, terms) else {
            continue;
        };
        // A term with a non-positive time constant or a vanishing amplitude adds nothing.
        if fit.taus_s.iter().any(|t| !(t.is_finite() && *t > 0.0)) {
            continue;
        }
        let b = bic(fit.rss, n, terms);
        if b < best_bic - 2.0 {
            best_bic = b;
            best = StepRelaxation {
                terms,
                f_inf: fit.f_inf,
                sigma_f_inf: fit.sigma_f_inf,
                taus_s: fit.taus_s.clone(),
                amplitudes: fit.amplitudes.clone(),
                window_mean,
                rms: (fit.rss / n as f64).sqrt(),
                issues: Vec::new(),
                fit: Some(fit),
            };
        }
    }
    let dt = t_end / (n - 1) as f64;
    if let Some(fit) = &best.fit {
        let slow = fit.taus_s.last().copied().unwrap_or(0.0);
        if t_end < 2.0 * slow {
            best.issues.push(format!(
                "record {t_end:.0} s is shorter than 2τ_slow = {:.0} s: F∞ is extrapolated and \
                 its σ understated; settle longer",
                2.0 * slow
            ));
        }
        for w in fit.taus_s.windows(2) {
            if w[1] < 2.0 * w[0] {
                best.issues.push(format!(
                    "time constants {:.3} s and {:.3} s are closer than 2×: not separable",
                    w[0], w[1]
                ));
            }
        }
        if fit.taus_s[0] < 2.0 * dt {
            best.issues.push(format!(
                "τ {:.3} s is below two sample intervals ({:.3} s)",
                fit.taus_s[0],
                2.0 * dt
            ));
        }
        if !fit.converged {
            best.issues.push("the fit did not converge".into());
        }
        if fit.condition > 1e10 || !fit.sigma_f_inf.is_finite() {
            best.issues.push(format!(
                "ill-conditioned fit (condition {:.1e}): parameters not identifiable",
                fit.condition
            ));
        }
    }
    best
}

/// Time constants shared by several steps of one run (the material's), with each step's
/// own F∞ and amplitudes: variable projection over the stacked records.
#[derive(Debug, Clone, PartialEq)]
pub struct SharedFit {
    /// Time constants, s, increasing.
    pub taus_s: Vec<f64>,
    /// Per record: F∞ then the amplitudes.
    pub linear: Vec<Vec<f64>>,
    /// Total residual sum of squares.
    pub rss: f64,
    /// Total samples.
    pub n: usize,
}

/// Fits `terms` time constants shared by all `records` (each (t, y) with t = 0 at the end
/// of its move), starting from `start_taus_s`. Pooling steps is what makes three
/// time constants identifiable from 3-minute records: each step alone sees the slowest
/// one for barely 3τ. Returns `None` for degenerate input.
pub fn fit_shared(records: &[(&[f64], &[f64])], start_taus_s: &[f64]) -> Option<SharedFit> {
    let terms = start_taus_s.len();
    if terms == 0 || records.is_empty() {
        return None;
    }
    let residual = |theta: &[f64]| -> Option<(DVector<f64>, Vec<Vec<f64>>)> {
        let taus: Vec<f64> = theta.iter().map(|v| v.exp()).collect();
        let mut all = Vec::new();
        let mut lin = Vec::new();
        for (t, y) in records {
            let (c, r) = linear_part(t, y, &taus)?;
            all.extend(r.iter().copied());
            lin.push(c.iter().copied().collect());
        }
        Some((DVector::from_vec(all), lin))
    };
    let theta0: Vec<f64> = start_taus_s.iter().map(|t| t.max(1e-6).ln()).collect();
    let (theta, _) = levenberg_marquardt(theta0, 100, |th| residual(th).map(|(r, _)| r))?;
    let (r, lin) = residual(&theta)?;
    let mut order: Vec<usize> = (0..terms).collect();
    order.sort_by(|&a, &b| theta[a].total_cmp(&theta[b]));
    Some(SharedFit {
        taus_s: order.iter().map(|&k| theta[k].exp()).collect(),
        linear: lin
            .into_iter()
            .map(|c| {
                std::iter::once(c[0])
                    .chain(order.iter().map(|&k| c[k + 1]))
                    .collect()
            })
            .collect(),
        rss: r.norm_squared(),
        n: r.len(),
    })
}

/// The quasistatic estimate's error against how long the step had waited: for each wait
/// `w` in `waits_s`, the mean of the `window_s` before `w` minus `reference` (F∞ of the
/// step's fit, or the simulator's true equilibrium). A wait up to 1 % past the record's
/// end (the move took that long) counts as the end; later waits give NaN.
pub fn settle_error(
    t_s: &[f64],
    f: &[f64],
    window_s: f64,
    waits_s: &[f64],
    reference: f64,
) -> Vec<f64> {
    let t_end = t_s.last().copied().unwrap_or(0.0);
    waits_s
        .iter()
        .map(|&w| {
            if w > 1.01 * t_end + 1e-9 || w < window_s {
                return f64::NAN;
            }
            let w = w.min(t_end);
            let (sum, k) = t_s
                .iter()
                .zip(f)
                .filter(|(t, _)| **t > w - window_s && **t <= w + 1e-9)
                .fold((0.0, 0usize), |(s, k), (_, v)| (s + v, k + 1));
            if k == 0 {
                f64::NAN
            } else {
                sum / k as f64 - reference
            }
        })
        .collect()
}

#[cfg(test)]
mod tests;
