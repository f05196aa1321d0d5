//! Contact solvers on a grid (spec §2): conjugate gradients on the masked compliance.
//!
//! - [`normal_known_area`]: a flat punch — the contact is the punch face, displacement
//!   prescribed there; plain CG (the operator restricted to the face is SPD).
//! - [`normal_unknown_area`]: a curved indenter — Polonsky & Keer (1999, *Wear* 231:206)
//!   constrained CG with p ≥ 0 and gap ≥ 0, under prescribed depth.
//! - [`tangential`]: Coulomb friction with partial slip — an active-set loop (stick cells by
//!   CG on u_t = prescribed, cells with |q| > μp become slip with q = μp along the relative
//!   slip, slip cells whose slip would reverse return to stick), converging in a few outer
//!   loops. The prescribed field is any rigid motion of the indenter (shift and twist), and
//!   a known source (the displacement the normal pressure causes through the layer's
//!   normal–tangential coupling) can be added: the one-way Goodman approximation, in which
//!   friction does not feed back into the pressure.

use crate::operator::Compliance;

/// Iteration limits and tolerances.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tolerance {
    /// Relative residual (CG) or relative gap error (Polonsky–Keer).
    pub rel: f64,
    /// Iteration cap.
    pub max_iter: usize,
}

impl Default for Tolerance {
    fn default() -> Self {
        Self {
            rel: 1e-10,
            max_iter: 2000,
        }
    }
}

/// A normal contact solution.
#[derive(Debug, Clone, PartialEq)]
pub struct NormalSolution {
    /// Pressure, MPa, per cell.
    pub p: Vec<f64>,
    /// Total force, N.
    pub force_n: f64,
    /// Contact area, mm².
    pub area_mm2: f64,
    /// Iterations used.
    pub iterations: usize,
    /// Whether the tolerance was met.
    pub converged: bool,
}

fn dot_masked(a: &[f64], b: &[f64], mask: &[bool]) -> f64 {
    a.iter()
        .zip(b)
        .zip(mask)
        .filter(|(_, m)| **m)
        .map(|((x, y), _)| x * y)
        .sum()
}

/// CG for A x = b on the cells where `mask` is true, A = masked `apply`; entries of `x`
/// outside the mask stay as given and act as a fixed load.
pub(crate) fn cg(
    apply: &dyn Fn(&[f64], &mut [f64]),
    mask: &[bool],
    b: &[f64],
    x: &mut [f64],
    tol: Tolerance,
) -> (usize, bool) {
    let len = x.len();
    let mut ax = vec![0.0; len];
    apply(x, &mut ax);
    let mut r: Vec<f64> = (0..len)
        .map(|i| if mask[i] { b[i] - ax[i] } else { 0.0 })
        .collect();
    let bnorm = dot_masked(b, b, mask).sqrt().max(1e-300);
    let mut d = r.clone();
    let mut rr = dot_masked(&r, &r, mask);
    if rr.sqrt() <= tol.rel * bnorm {
        return (0, true);
    }
    let mut ad = vec![0.0; len];
    for it in 1..=tol.max_iter {
        apply(&d, &mut ad);
        let dad = dot_masked(&d, &ad, mask);
        if dad <= 0.0 {
            return (it, false);
        }
        let alpha = rr / dad;
        for i in 0..len {
            if mask[i] {
                x[i] += alpha * d[i];
                r[i] -= alpha * ad[i];
            }
        }
        let rr_new = dot_masked(&r, &r, mask);
        if rr_new.sqrt() <= tol.rel * bnorm {
            return (it, true);
        }
        let beta = rr_new / rr;
        rr = rr_new;
        for i in 0..len {
            d[i] = if mask[i] { r[i] + beta * d[i] } else { 0.0 };
        }
    }
    (tol.max_iter, false)
}

/// Pressure under a punch whose face (`mask`) is pushed to `uz_target` (mm, per cell).
pub fn normal_known_area(
    op: &dyn Compliance,
    mask: &[bool],
    uz_target: &[f64],
    tol: Tolerance,
) -> NormalSolution {
    let g = op.grid();
    let mut p = vec![0.0; g.len()];
    let apply = |x: &[f64], out: &mut [f64]| op.normal(x, out);
    let (iterations, converged) = cg(&apply, mask, uz_target, &mut p, tol);
    NormalSolution {
        force_n: p.iter().sum::<f64>() * g.area(),
        area_mm2: mask.iter().filter(|m| **m).count() as f64 * g.area(),
        p,
        iterations,
        converged,
    }
}

/// Frictionless contact of an indenter whose surface is `profile` (mm above its lowest
/// point, per cell) pressed `depth_mm` into the surface, contact area unknown
/// (Polonsky–Keer under prescribed displacement). `initial` warm-starts the pressure.
pub fn normal_unknown_area(
    op: &dyn Compliance,
    profile: &[f64],
    depth_mm: f64,
    initial: Option<&[f64]>,
    tol: Tolerance,
) -> NormalSolution {
    let grid = op.grid();
    let len = grid.len();
    let mut p: Vec<f64> = match initial {
        Some(p0) => p0.to_vec(),
        None => {
            // Start from the known-area solution on the geometric overlap.
            let mask: Vec<bool> = profile.iter().map(|h| *h < depth_mm).collect();
            let target: Vec<f64> = profile.iter().map(|h| (depth_mm - h).max(0.0)).collect();
            let mut s = normal_known_area(
                op,
                &mask,
                &target,
                Tolerance {
                    rel: 1e-3,
                    max_iter: 200,
                },
            );
            for v in s.p.iter_mut() {
                *v = v.max(0.0);
            }
            s.p
        }
    };
    let mut u = vec![0.0; len];
    let mut t = vec![0.0; len];
    let mut r = vec![0.0; len];
    let mut g_old = 1.0;
    let mut delta = 0.0;
    let scale = depth_mm.abs().max(1e-300);
    let mut converged = false;
    let mut iterations = 0;
    for it in 1..=tol.max_iter {
        iterations = it;
        op.normal(&p, &mut u);
        let gap: Vec<f64> = (0..len).map(|i| u[i] + profile[i] - depth_mm).collect();
        let s: Vec<bool> = p.iter().map(|v| *v > 0.0).collect();
        let g_norm = dot_masked(&gap, &gap, &s);
        for i in 0..len {
            t[i] = if s[i] {
                gap[i] + delta * (g_norm / g_old) * t[i]
            } else {
                0.0
            };
        }
        g_old = g_norm.max(1e-300);
        op.normal(&t, &mut r);
        let rt = dot_masked(&r, &t, &s);
        let tau = if rt > 0.0 {
            dot_masked(&gap, &t, &s) / rt
        } else {
            0.0
        };
        for i in 0..len {
            if s[i] {
                p[i] = (p[i] - tau * t[i]).max(0.0);
            }
        }
        let mut overlap = false;
        for i in 0..len {
            if !s[i] && gap[i] < 0.0 {
                overlap = true;
                p[i] -= tau * gap[i];
            }
        }
        delta = if overlap { 0.0 } else { 1.0 };
        let max_err = (0..len)
            .filter(|i| s[*i])
            .map(|i| gap[i].abs())
            .fold(0.0_f64, f64::max);
        let penetration = (0..len)
            .filter(|i| !s[*i])
            .map(|i| -gap[i])
            .fold(0.0_f64, f64::max);
        if !overlap && max_err < tol.rel * scale && penetration < tol.rel * scale {
            converged = true;
            break;
        }
    }
    let force = p.iter().sum::<f64>() * grid.area();
    let area = p.iter().filter(|v| **v > 0.0).count() as f64 * grid.area();
    NormalSolution {
        p,
        force_n: force,
        area_mm2: area,
        iterations,
        converged,
    }
}

/// A tangential (frictional) problem on a known normal pressure.
pub struct Tangential<'a> {
    /// The compliance.
    pub op: &'a dyn Compliance,
    /// Normal pressure, MPa (contact where > 0).
    pub p: &'a [f64],
    /// Coulomb coefficient.
    pub mu: f64,
    /// Prescribed tangential displacement of stuck points (x, y), mm: the indenter's rigid
    /// motion plus whatever the stuck points had before.
    pub target: (&'a [f64], &'a [f64]),
    /// Known tangential displacement from other loads (the coupling of the normal
    /// pressure), mm; added to what the tangential traction causes.
    pub source: Option<(&'a [f64], &'a [f64])>,
    /// Solve for q_x only, with q_y = 0 and the stick condition on u_x only (the classical
    /// Cattaneo–Mindlin assumption).
    pub x_only: bool,
    /// Warm start (q_x, q_y).
    pub initial: Option<(&'a [f64], &'a [f64])>,
    /// CG tolerance of the inner solves.
    pub tol: Tolerance,
}

/// A tangential solution.
#[derive(Debug, Clone, PartialEq)]
pub struct TangentialSolution {
    /// Traction along x, MPa.
    pub qx: Vec<f64>,
    /// Traction along y, MPa.
    pub qy: Vec<f64>,
    /// Cells in contact that stick.
    pub stick: Vec<bool>,
    /// Total force along x, N.
    pub fx_n: f64,
    /// Total force along y, N.
    pub fy_n: f64,
    /// Outer active-set loops used.
    pub outer: usize,
    /// Whether the active set settled.
    pub converged: bool,
}

impl TangentialSolution {
    /// Fraction of the contact area that sticks.
    pub fn stick_fraction(&self, p: &[f64]) -> f64 {
        let contact = p.iter().filter(|v| **v > 0.0).count();
        if contact == 0 {
            return 0.0;
        }
        self.stick.iter().filter(|s| **s).count() as f64 / contact as f64
    }

    /// Twisting moment about the origin, N·mm.
    pub fn torque_nmm(&self, grid: crate::operator::Grid) -> f64 {
        (0..grid.len())
            .map(|i| {
                let (x, y) = grid.xy(i);
                x * self.qy[i] - y * self.qx[i]
            })
            .sum::<f64>()
            * grid.area()
    }
}

/// Solves a frictional tangential problem with partial slip.
///
/// With the pressure fixed, friction is the convex problem: minimise
/// ½ qᵀGq − bᵀq subject to |q_i| ≤ μp_i per cell (b = prescribed minus source
/// displacement). Its optimality conditions are exactly stick (Gq = b where |q| < μp) and
/// slip (|q| = μp, traction along the relative slip). It is solved by spectral projected
/// gradient (Birgin, Martínez & Raydan 2000): Barzilai–Borwein steps, projection onto each
/// cell's friction disc, a nonmonotone line search (Grippo et al. 1986, memory 10) that makes
/// it converge from any start. Active-set and primal–dual variants were tried first and
/// chattered or stalled near full slip on the bonded layer.
pub fn tangential(prob: &Tangential<'_>) -> TangentialSolution {
    let grid = prob.op.grid();
    let len = grid.len();
    let contact: Vec<bool> = prob.p.iter().map(|v| *v > 0.0).collect();
    let limit: Vec<f64> = prob.p.iter().map(|v| prob.mu * v.max(0.0)).collect();
    let (tx, ty) = prob.target;
    let mut b = vec![0.0; 2 * len];
    for i in 0..len {
        let (sx, sy) = prob.source.map(|(a, c)| (a[i], c[i])).unwrap_or((0.0, 0.0));
        b[i] = tx[i] - sx;
        b[len + i] = if prob.x_only { 0.0 } else { ty[i] - sy };
    }
    let project = |q: &mut [f64]| {
        for i in 0..len {
            if !contact[i] {
                q[i] = 0.0;
                q[len + i] = 0.0;
                continue;
            }
            if prob.x_only {
                q[len + i] = 0.0;
            }
            let m = q[i].hypot(q[len + i]);
            if m > limit[i] {
                q[i] *= limit[i] / m;
                q[len + i] *= limit[i] / m;
            }
        }
    };
    let apply = |x: &[f64], out: &mut [f64]| {
        let (ox, oy) = out.split_at_mut(len);
        prob.op.tangential(&x[..len], &x[len..], ox, oy);
    };
    let mut q = vec![0.0; 2 * len];
    match prob.initial {
        Some((qx0, qy0)) => {
            q[..len].copy_from_slice(qx0);
            q[len..].copy_from_slice(qy0);
        }
        None => {
            // Full stick, then clipped: a good start below the slip limit.
            let mask: Vec<bool> = (0..2 * len)
                .map(|j| contact[j % len] && (j < len || !prob.x_only))
                .collect();
            cg(
                &apply,
                &mask,
                &b,
                &mut q,
                Tolerance {
                    rel: 1e-6,
                    max_iter: 500,
                },
            );
        }
    }
    project(&mut q);
    // Gradient r = Gq − b (= u − w: gel minus prescribed), objective f = ½qᵀ(r − b).
    let mut gq = vec![0.0; 2 * len];
    apply(&q, &mut gq);
    let grad = |gq: &[f64]| -> Vec<f64> { gq.iter().zip(&b).map(|(a, c)| a - c).collect() };
    let objective = |q: &[f64], r: &[f64]| -> f64 {
        0.5 * q
            .iter()
            .zip(r.iter().zip(&b))
            .map(|(x, (g, c))| x * (g - c))
            .sum::<f64>()
    };
    let mut r = grad(&gq);
    let mut f = objective(&q, &r);
    let diag = prob.op.tangential_diagonal().max(1e-300);
    let mut alpha = 1.0 / diag;
    let mut history = std::collections::VecDeque::from([f]);
    let w_scale = b.iter().fold(0.0_f64, |m, v| m.max(v.abs())).max(1e-300);
    let tol = prob.tol.rel.max(1e-12);
    let mut converged = false;
    let mut outer = 0;
    let mut trial = vec![0.0; 2 * len];
    let mut g_trial = vec![0.0; 2 * len];
    for it in 1..=prob.tol.max_iter {
        outer = it;
        // Projected-gradient stationarity, measured as a displacement (mm).
        trial
            .iter_mut()
            .zip(q.iter().zip(&r))
            .for_each(|(t, (x, g))| *t = x - g / diag);
        project(&mut trial);
        let pg = trial
            .iter()
            .zip(&q)
            .fold(0.0_f64, |m, (t, x)| m.max((t - x).abs()))
            * diag;
        if pg <= tol * w_scale {
            converged = true;
            break;
        }
        // Spectral step, projected; then a nonmonotone backtracking line search.
        trial
            .iter_mut()
            .zip(q.iter().zip(&r))
            .for_each(|(t, (x, g))| *t = x - alpha * g);
        project(&mut trial);
        let d: Vec<f64> = trial.iter().zip(&q).map(|(t, x)| t - x).collect();
        let gd: f64 = r.iter().zip(&d).map(|(g, x)| g * x).sum();
        let f_ref = history.iter().cloned().fold(f64::MIN, f64::max);
        let mut lambda = 1.0;
        loop {
            for j in 0..2 * len {
                trial[j] = q[j] + lambda * d[j];
            }
            apply(&trial, &mut g_trial);
            let r_trial = grad(&g_trial);
            let f_trial = objective(&trial, &r_trial);
            if f_trial <= f_ref + 1e-4 * lambda * gd || lambda < 1e-10 {
                let s: Vec<f64> = trial.iter().zip(&q).map(|(a, c)| a - c).collect();
                let y: Vec<f64> = r_trial.iter().zip(&r).map(|(a, c)| a - c).collect();
                let sy: f64 = s.iter().zip(&y).map(|(a, c)| a * c).sum();
                let ss: f64 = s.iter().map(|a| a * a).sum();
                alpha = if sy > 0.0 {
                    (ss / sy).clamp(1e-3 / diag, 1e6 / diag)
                } else {
                    1e3 / diag
                };
                q.copy_from_slice(&trial);
                r = r_trial;
                f = f_trial;
                break;
            }
            lambda *= 0.5;
        }
        history.push_back(f);
        if history.len() > 10 {
            history.pop_front();
        }
    }
    let stick: Vec<bool> = (0..len)
        .map(|i| contact[i] && q[i].hypot(q[len + i]) < limit[i] * (1.0 - 1e-6))
        .collect();
    if prob.x_only {
        for v in q[len..].iter_mut() {
            *v = 0.0;
        }
    }
    let a = grid.area();
    let (qx, qy) = (q[..len].to_vec(), q[len..].to_vec());
    TangentialSolution {
        fx_n: qx.iter().sum::<f64>() * a,
        fy_n: qy.iter().sum::<f64>() * a,
        qx,
        qy,
        stick: (0..len).map(|i| contact[i] && stick[i]).collect(),
        outer,
        converged,
    }
}
