#!/usr/bin/env python3
# Tested with: python 3.11.7, numpy==2.4.6, scipy==1.17.1 (one core; BLAS pinned to 1 thread)
"""Rigid sphere indenting / withdrawing from a linear viscoelastic half-space: a brute-force
time-stepping surface-traction contact solver, an oracle independent of gelrig's MDR code.

Problem
  A rigid sphere of radius R (parabolic profile f(r) = r^2/(2R)) is pushed into a linear
  viscoelastic half-space with constant Poisson ratio, frictionless, to a prescribed depth
  history delta(t), and withdrawn again.  The normalised relaxation function of the contact
  modulus is a Prony series G(t) = 1 + sum_i w_i exp(-t/tau_i), so E*(t) = E*_inf G(t).
  While the contact radius a(t) grows, Lee & Radok's F(t) = int_0^t G(t-s) dF_e(delta(s)),
  F_e = (4/3) E*_inf R^1/2 delta^3/2, is exact; while it shrinks it is not (Ting 1966).
  This script computes the true force F(t) and contact radius a(t) numerically for all
  phases, including separation, without MDR and without Ting's closed-form solution.
  Units: R = 1, E*_inf = 1, times in s.

Formulation
  * Surface discretised into N concentric rings of width dr = r_max/N, r_max = 1.5 a_max
    (a_max = sqrt(R delta_max)), uniform pressure p_j per ring; displacements collocated at
    ring centres r_i = (i+1/2) dr.  Elastic influence matrix K (unit contact modulus E*):
    the exact half-space displacement of a uniformly loaded disc of radius b (Johnson,
    Contact Mechanics, eqs. 3.33/3.35 (3.2)), with k = r/b resp. b/r and scipy's parameter
    m = k^2 convention (ellipk(m), ellipe(m)):
        r < b:  u = (4 p b / (pi E*)) E(m = r^2/b^2)
        r > b:  u = (4 p r / (pi E*)) [E(m) - (1 - m) K(m)],  m = b^2/r^2
    differenced between the ring's outer and inner radius (centres never hit an edge).
    Pressure acts only inside a_max < r_max, so there is no truncation error: the
    half-space is infinite, r_max only bounds where the gap is checked.
  * Viscoelasticity by the correspondence principle (constant nu):
        u(r,t) = int_0^t J(t-s) d/ds [K p(.,s)](r) ds,
    J the normalised creep function (J * dG = 1 in the Stieltjes sense).  For the Prony G,
    s G^(s) = 1 + sum w_i s/(s + 1/tau_i) =: H(s) and s J^(s) = 1/H(s), so
        J(t) = 1 - sum_k c_k exp(-mu_k t),  H(-mu_k) = 0,  c_k = 1/(mu_k H'(-mu_k)),
    with one retardation rate mu_k in each interval between consecutive 1/tau_i and below
    the smallest (found by bracketing root search).  Checked: J(0) = 1/G(0), J(inf) = 1, and
    the Stieltjes identity int_0^t G(t-s) dJ(s) = 1 on a grid (quadrature).
  * Time stepping with internal variables: w = K p is taken piecewise linear in t between
    steps, q_k(t) = int_0^t exp(-mu_k (t-s)) dw(s) is then updated exactly,
        q_k^n = E_k q_k^{n-1} + gamma_k (w^n - w^{n-1}),  E_k = exp(-mu_k dt),
        gamma_k = (1 - E_k)/(mu_k dt),
    and u^n = w^n - sum c_k q_k^n = alpha K p^n + h^n with alpha = 1 - sum c_k gamma_k and
    h^n = sum c_k (gamma_k w^{n-1} - E_k q_k^{n-1}) (the whole pressure history).
  * Each step solves the linear complementarity problem (LCP) with gap g = u - (delta - r^2/2R):
        p >= 0,  g = alpha K p + h - (delta - r^2/2R) >= 0,  p_i g_i = 0   (all rings)
    by a primal-dual active-set iteration warm-started from the previous step; no disc
    shape of the contact set is assumed (it is checked afterwards: always a disc).
    Force F = sum p_j pi (r_{j+1}^2 - r_j^2).  Contact radius a: the root of a straight-line
    fit of p^2 over the six outermost contact rings (p ~ sqrt(a - r) at a non-adhesive
    edge; fewer rings if fewer are loaded, the ring edge if < 3), clamped to within one
    ring of the discrete edge; a = 0 when no ring is loaded.

Checks (printed, and stored under "checks" in the JSON)
  1. Elastic Hertz (G = 1): F = (4/3) E* R^1/2 delta^3/2 and a = sqrt(R delta) at
     delta = 0.25, 0.5, 1 x delta_max; both errors must be < 0.5 %.
  2. Loading phase (delta monotone increasing, and the hold in case 2): solver force vs
     Lee-Radok F_LR(t) = int G(t-s) dF_e (adaptive quadrature, scipy.integrate.quad),
     max |F - F_LR| / F_LR over t > 0.1 t_load (and / F_peak over the whole phase) < 0.5 %.
     Also a(t) vs sqrt(R delta(t)).
  3. Convergence: the solver at two resolutions (N, dt) and (2N, dt/2); max |dF| / F_peak
     over the unloading phase (and over the whole history), and max |da| / a_max (largest
     just before separation, where a(t) ~ sqrt(t_sep - t) is steep in time).
  4. Consistency with Ting's theorem (not used by the solver): while a(t) decreases,
     F(t) = int_0^{t1} G(t-s) dF_e(delta(s)), t1 the loading time with a(t1) = a(t).  Here
     a(t) is the solver's own contact radius, so this tests the solver's force-radius
     relation in unloading, to within the a-estimate's accuracy (F ~ a^3).

Cases (delta_max = 0.01 R in both)
  case1_T{0.3,1,3}: G = 1 + 1.0 exp(-t/1); delta ramps 0 -> delta_max over T_load, then back
                    to 0 over T_load.
  case2:            G = 1 + 0.3 e^{-t/1} + 0.2 e^{-t/10} + 0.1 e^{-t/40}; up over 2 s, hold
                    5 s, down over 2 s, hold at delta = 0 for 5 s.

Run
  python3 tests/peers/viscoelastic_sphere_unloading.py            # ~35 s, writes the JSON
  python3 tests/peers/viscoelastic_sphere_unloading.py --quick    # < 20 s, coarser, no JSON
                                                                  # unless --out is given
  Options: --out PATH (default: viscoelastic_sphere_unloading.json next to this script).

Output JSON (see the report at the end of the run; all forces in units E*_inf R^2, radii R)
  {"meta": {...}, "checks": {"elastic_hertz": [...], "creep_functions": {...}},
   "cases": {name: {"G": {...}, "J": {...}, "schedule": [...], "t": [...], "delta": [...],
                    "F_ting": [...], "a": [...], "F_lee_radok": [...],
                    "a_lee_radok": [...], "F_ting_theorem_from_a": [...],
                    "lee_radok_negative_from": t or null, "separation_time": t or null,
                    "F_peak": x, "checks": {...}, "convergence": {...}}}}
  F_ting / a are the fine-resolution solver values on the output grid (~50 points).
"""
import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse
import json
import platform
import sys
import time

import numpy as np
import scipy
from scipy.integrate import quad
from scipy.optimize import brentq
from scipy.special import ellipe, ellipk

R = 1.0
DELTA_MAX = 0.01


# ----------------------------------------------------------------------------------------
# elastic influence matrix
def disc_displacement(r, b):
    """Surface normal displacement at radius r from unit pressure on a disc of radius b,
    half-space of unit contact modulus E* (Johnson 3.2).  scipy uses m = k^2."""
    r, b = np.broadcast_arrays(np.asarray(r, float), np.asarray(b, float))
    out = np.zeros(r.shape)
    ins = (r < b) & (b > 0)
    out[ins] = 4.0 * b[ins] / np.pi * ellipe((r[ins] / b[ins]) ** 2)
    o = (r > b) & (b > 0)
    m = (b[o] / r[o]) ** 2
    out[o] = 4.0 * r[o] / np.pi * (ellipe(m) - (1.0 - m) * ellipk(m))
    return out


def ring_mesh(N, rmax):
    e = np.linspace(0.0, rmax, N + 1)
    c = 0.5 * (e[1:] + e[:-1])
    D = disc_displacement(c[:, None], e[None, :])
    K = D[:, 1:] - D[:, :-1]
    area = np.pi * (e[1:] ** 2 - e[:-1] ** 2)
    return e, c, K, area


# ----------------------------------------------------------------------------------------
# LCP: p >= 0, g = M p + q >= 0, p.g = 0 ; primal-dual active set
def solve_lcp(M, q, active, tol):
    n = len(q)
    seen = set()
    for _ in range(200):
        p = np.zeros(n)
        idx = np.flatnonzero(active)
        if idx.size:
            p[idx] = np.linalg.solve(M[np.ix_(idx, idx)], -q[idx])
        g = M[:, idx] @ p[idx] + q
        new = (active & (p > 0.0)) | (~active & (g < -tol))
        if np.array_equal(new, active):
            return p, g, active
        key = new.tobytes()
        if key in seen:  # cycling guard: fall back to the (checked) disc search below
            break
        seen.add(key)
        active = new
    # fallback: contact set = first m rings, m from a scan
    best = None
    for m in range(n + 1):
        p = np.zeros(n)
        if m:
            p[:m] = np.linalg.solve(M[:m, :m], -q[:m])
        g = M[:, :m] @ p[:m] + q
        if (m == 0 or p[:m].min() >= 0) and g[m:].min(initial=0.0) >= -tol:
            best = (p, g, np.arange(n) < m)
            break
    if best is None:
        raise RuntimeError("LCP not solved")
    return best


def contact_radius(p, active, e, c):
    idx = np.flatnonzero(active)
    if idx.size == 0:
        return 0.0
    m = idx.max() + 1
    if m < 3:
        return e[m]
    j = np.arange(m - min(m, 6), m)
    slope, icpt = np.polyfit(c[j], p[j] ** 2, 1)
    a = -icpt / slope if slope < 0 else e[m]
    return float(np.clip(a, e[m - 1], e[min(m + 1, len(e) - 1)]))


# ----------------------------------------------------------------------------------------
# Prony relaxation -> creep function
class Prony:
    def __init__(self, w, tau):
        self.w = np.asarray(w, float)
        self.tau = np.asarray(tau, float)
        lam = 1.0 / self.tau
        H = lambda s: 1.0 + np.sum(self.w * s / (s + lam))
        dH = lambda s: np.sum(self.w * lam / (s + lam) ** 2)
        # roots of H(-mu) on (0, inf): one in (0, lam_min) and one between consecutive lams
        ls = np.sort(lam)
        brackets = [(0.0, ls[0])] + [(ls[i], ls[i + 1]) for i in range(len(ls) - 1)]
        mus = []
        for lo, hi in brackets:
            eps = 1e-14 * max(hi, 1.0)
            mus.append(brentq(lambda mu: H(-mu), lo + eps, hi - eps, xtol=1e-15, rtol=1e-15,
                              maxiter=500))
        self.mu = np.array(mus)
        self.c = np.array([1.0 / (mu * dH(-mu)) for mu in self.mu])

    def G(self, t):
        t = np.asarray(t, float)
        return 1.0 + np.sum(self.w * np.exp(-t[..., None] / self.tau), axis=-1)

    def J(self, t):
        t = np.asarray(t, float)
        return 1.0 - np.sum(self.c * np.exp(-self.mu * t[..., None]), axis=-1)

    def check(self):
        G0 = 1.0 + self.w.sum()
        J0 = float(self.J(0.0))
        # Stieltjes: int_0^t G(t-s) dJ(s) = G(t) J(0) + int_0^t G(t-s) J'(s) ds = 1
        resid = 0.0
        for t in np.linspace(0.1, 5 * self.tau.max(), 25):
            dJ = lambda s: np.sum(self.c * self.mu * np.exp(-self.mu * s))
            val = float(self.G(t)) * J0 + quad(lambda s: float(self.G(t - s)) * dJ(s), 0, t,
                                               limit=200, epsabs=1e-13, epsrel=1e-12)[0]
            resid = max(resid, abs(val - 1.0))
        return {"J0_times_G0_minus_1": J0 * G0 - 1.0,
                "J_inf_minus_1": float(self.J(1e6 * self.tau.max())) - 1.0,
                "max_abs_stieltjes_residual": resid}

    def as_dict(self):
        return {"w": self.w.tolist(), "tau": self.tau.tolist()}

    def J_dict(self):
        return {"form": "J(t) = 1 - sum_k c_k exp(-t/theta_k)", "c": self.c.tolist(),
                "theta": (1.0 / self.mu).tolist()}


# ----------------------------------------------------------------------------------------
# depth schedule: piecewise linear, list of (duration, delta_end, n_out_intervals, kind)
class Schedule:
    def __init__(self, segs):
        self.segs = segs
        self.t_knots = np.concatenate([[0.0], np.cumsum([s[0] for s in segs])])
        self.d_knots = np.concatenate([[0.0], [s[1] for s in segs]])

    def delta(self, t):
        return np.interp(t, self.t_knots, self.d_knots)

    def grids(self, steps_per_out):
        """solver time grid (uniform within a segment) and indices of output points"""
        ts, outs = [0.0], [0]
        for k, (dur, _, nout, _) in enumerate(self.segs):
            nst = nout * steps_per_out[k]
            t0 = self.t_knots[k]
            loc = t0 + dur * np.arange(1, nst + 1) / nst
            base = len(ts)
            ts.extend(loc.tolist())
            outs.extend([base + steps_per_out[k] * i - 1 for i in range(1, nout + 1)])
        return np.array(ts), np.array(outs)

    def phase_mask(self, t, kinds):
        m = np.zeros(len(t), bool)
        for k, s in enumerate(self.segs):
            if s[3] in kinds:
                m |= (t > self.t_knots[k] + 1e-12) & (t <= self.t_knots[k + 1] + 1e-12)
        return m


# ----------------------------------------------------------------------------------------
def simulate(G, sched, N, steps_per_out, rmax):
    e, c, K, area = ring_mesh(N, rmax)
    t, out_idx = sched.grids(steps_per_out)
    delta = sched.delta(t)
    nk = len(G.mu)
    q = np.zeros((nk, N))
    w_prev = np.zeros(N)
    active = np.zeros(N, bool)
    F = np.zeros(len(t))
    a = np.zeros(len(t))
    tol = 1e-12 * DELTA_MAX
    noncircular = 0
    for n in range(1, len(t)):
        dt = t[n] - t[n - 1]
        E = np.exp(-G.mu * dt)
        gam = -np.expm1(-G.mu * dt) / (G.mu * dt)
        alpha = 1.0 - np.sum(G.c * gam)
        h = np.sum(G.c[:, None] * (gam[:, None] * w_prev[None, :] - E[:, None] * q), axis=0)
        qvec = h - (delta[n] - c ** 2 / (2 * R))
        p, g, active = solve_lcp(alpha * K, qvec, active, tol)
        idx = np.flatnonzero(active)
        w = K[:, idx] @ p[idx]
        q = E[:, None] * q + gam[:, None] * (w - w_prev)[None, :]
        w_prev = w
        F[n] = area @ p
        a[n] = contact_radius(p, active, e, c)
        if idx.size and idx.size != idx.max() + 1:
            noncircular += 1
        if idx.size and (p.min() < -1e-12 * abs(p).max() or g.min() < -1e-9 * DELTA_MAX):
            raise RuntimeError("complementarity violated at step %d" % n)
    return {"t": t, "delta": delta, "F": F, "a": a, "out": out_idx,
            "noncircular_steps": noncircular}


def lee_radok(G, sched, t, upto=None):
    """F_LR(t) = int_0^min(t,upto) G(t-s) d/ds[(4/3) R^1/2 delta(s)^3/2] ds by quad."""
    out = np.zeros(len(t))
    kn = sched.t_knots
    for i, ti in enumerate(t):
        top = ti if upto is None else min(ti, upto[i])
        if top <= 0:
            continue
        tot = 0.0
        for k in range(len(kn) - 1):
            lo, hi = kn[k], min(kn[k + 1], top)
            if hi <= lo:
                break
            rate = (sched.d_knots[k + 1] - sched.d_knots[k]) / (kn[k + 1] - kn[k])
            if rate == 0.0:
                continue
            f = lambda s: float(G.G(ti - s)) * 2.0 * np.sqrt(R * max(sched.delta(s), 0.0)) * rate
            tot += quad(f, lo, hi, limit=200, epsabs=1e-15, epsrel=1e-11)[0]
        out[i] = tot
    return out


def ting_theorem_force(G, sched, t, a, load_end):
    """While a decreases: F = int_0^{t1} G(t-s) dF_e, a(t1) = a(t) on the loading ramp
    (there a = sqrt(R delta), so delta(t1) = a^2/R)."""
    d0, d1 = sched.d_knots[0], sched.d_knots[1]
    t_ramp = sched.t_knots[1]
    upto = np.full(len(t), np.nan)
    for i in range(len(t)):
        if t[i] > load_end + 1e-12:
            dd = a[i] ** 2 / R
            upto[i] = t_ramp * (dd - d0) / (d1 - d0)
    F = np.full(len(t), np.nan)
    sel = ~np.isnan(upto)
    F[sel] = lee_radok(G, sched, t[sel], upto[sel])
    return F


# ----------------------------------------------------------------------------------------
def elastic_hertz_check(N, rmax):
    e, c, K, area = ring_mesh(N, rmax)
    res = []
    active = np.zeros(N, bool)
    for frac in (0.25, 0.5, 1.0):
        d = frac * DELTA_MAX
        p, g, active = solve_lcp(K, -(d - c ** 2 / (2 * R)), active, 1e-12 * DELTA_MAX)
        F = area @ p
        a = contact_radius(p, active, e, c)
        res.append({"N": N, "delta": d, "F": F, "F_hertz": 4 / 3 * np.sqrt(R) * d ** 1.5,
                    "F_rel_err": F / (4 / 3 * np.sqrt(R) * d ** 1.5) - 1,
                    "a": a, "a_hertz": np.sqrt(R * d), "a_rel_err": a / np.sqrt(R * d) - 1})
    return res


def run_case(name, G, sched, N_lvls, spo_lvls, rmax, t_load_end):
    t0 = time.time()
    sims = [simulate(G, sched, N, spo, rmax) for N, spo in zip(N_lvls, spo_lvls)]
    fine = sims[-1]
    o = fine["out"]
    t_out = fine["t"][o]
    F_out, a_out = fine["F"][o], fine["a"][o]
    F_lr_out = lee_radok(G, sched, t_out)
    Fpk = fine["F"].max()
    kinds_load = ("up", "hold")
    # loading check on every solver step of the fine level
    tt = fine["t"]
    mload = sched.phase_mask(tt, kinds_load) & (tt <= t_load_end + 1e-12)
    F_lr_steps = lee_radok(G, sched, tt[mload])
    rel = (fine["F"][mload] - F_lr_steps)
    big = tt[mload] > 0.1 * sched.t_knots[1]
    a_lr = np.sqrt(R * sched.delta(tt[mload]))
    load_chk = {
        "n_steps": int(mload.sum()),
        "max_rel_err_vs_lee_radok_t_gt_0.1_tramp": float(np.max(np.abs(rel[big] / F_lr_steps[big]))),
        "max_abs_err_over_F_peak": float(np.max(np.abs(rel)) / Fpk),
        "max_abs_a_err_over_a_max": float(np.max(np.abs(fine["a"][mload] - a_lr)) / np.sqrt(R * DELTA_MAX)),
    }
    # convergence: coarse vs fine at the output points and at all coarse steps
    co = sims[0]
    tc = co["t"]
    Ff_on_c = np.interp(tc, fine["t"], fine["F"])
    af_on_c = np.interp(tc, fine["t"], fine["a"])
    munl = sched.phase_mask(tc, ("down", "zero")) 
    mdown = sched.phase_mask(tc, ("down",))
    pos = mdown & (Ff_on_c > 0.1 * Fpk)
    conv = {
        "levels": [{"N": N, "dt_per_segment": [s[0] / (s[2] * k) for s, k in zip(sched.segs, spo)]}
                   for N, spo in zip(N_lvls, spo_lvls)],
        "max_abs_dF_over_F_peak_unloading": float(np.max(np.abs(co["F"][munl] - Ff_on_c[munl])) / Fpk),
        "max_rel_dF_unloading_where_F_gt_0.1_F_peak": float(np.max(np.abs(co["F"][pos] / Ff_on_c[pos] - 1))),
        "max_abs_dF_over_F_peak_all": float(np.max(np.abs(co["F"] - Ff_on_c)) / Fpk),
        "max_abs_da_over_a_max_all": float(np.max(np.abs(co["a"] - af_on_c)) / np.sqrt(R * DELTA_MAX)),
        "note": "coarse level compared with the fine level (fine interpolated to the coarse "
                "time steps); unloading = delta decreasing phase plus any later hold at 0",
    }
    # Ting theorem consistency during unloading (solver a)
    F_tt = ting_theorem_force(G, sched, t_out, a_out, t_load_end)
    mt = (t_out > t_load_end + 1e-12) & (a_out > 0)
    ting_chk = {"max_abs_diff_over_F_peak": float(np.nanmax(np.abs(F_out[mt] - F_tt[mt])) / Fpk)
                if mt.any() else None}
    neg = np.flatnonzero(F_lr_out < 0)
    lr_neg_from = None
    if neg.size:
        # refine the first sign change of F_LR with a root search
        i = neg[0]
        f = lambda x: lee_radok(G, sched, np.array([x]))[0]
        lr_neg_from = float(brentq(f, t_out[i - 1], t_out[i], xtol=1e-10))
    sep_idx = np.flatnonzero((fine["t"] > t_load_end) & (fine["F"] == 0.0))
    # first fine step with no contact (the true separation lies within one step before it)
    sep = float(fine["t"][sep_idx[0]]) if sep_idx.size else None
    sep_dt = float(fine["t"][sep_idx[0]] - fine["t"][sep_idx[0] - 1]) if sep_idx.size else None
    out = {
        "G": G.as_dict(), "J": G.J_dict(),
        "schedule": [{"duration": s[0], "delta_end": s[1], "kind": s[3]} for s in sched.segs],
        "t": t_out.tolist(), "delta": fine["delta"][o].tolist(),
        "F_ting": F_out.tolist(), "a": a_out.tolist(),
        "F_lee_radok": F_lr_out.tolist(),
        "a_lee_radok": np.sqrt(R * sched.delta(t_out)).tolist(),
        "F_ting_theorem_from_a": [None if np.isnan(x) else float(x) for x in F_tt],
        "lee_radok_negative_from": lr_neg_from,
        "separation_time": sep, "separation_time_resolution": sep_dt,
        "F_peak": float(Fpk), "t_F_peak": float(fine["t"][np.argmax(fine["F"])]),
        "checks": {"loading_vs_lee_radok": load_chk, "ting_theorem_consistency": ting_chk,
                   "noncircular_contact_steps": fine["noncircular_steps"] + co["noncircular_steps"]},
        "convergence": conv,
        "runtime_s": time.time() - t0,
    }
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    here = os.path.dirname(os.path.abspath(__file__))
    out_path = args.out or (None if args.quick else
                            os.path.join(here, "viscoelastic_sphere_unloading.json"))
    T0 = time.time()
    amax = np.sqrt(R * DELTA_MAX)
    rmax = 1.5 * amax
    if args.quick:
        N_lvls, mult = (150, 300), (1, 2)
        base_c1, base_c2 = 6, (12, 6, 9, 4)
    else:
        N_lvls, mult = (400, 800), (1, 2)
        base_c1, base_c2 = 16, (32, 16, 24, 10)

    hertz = elastic_hertz_check(N_lvls[-1], rmax) + elastic_hertz_check(N_lvls[0], rmax)
    print("elastic Hertz check:")
    for h in hertz:
        print("  N=%4d delta=%.4f  F err %+.2e  a err %+.2e" % (h["N"], h["delta"], h["F_rel_err"], h["a_rel_err"]))

    G1 = Prony([1.0], [1.0])
    G2 = Prony([0.3, 0.2, 0.1], [1.0, 10.0, 40.0])
    creep = {"case1": G1.check(), "case2": G2.check()}
    print("creep functions:", json.dumps(creep))

    cases = {}
    for T in (0.3, 1.0, 3.0):
        sched = Schedule([(T, DELTA_MAX, 25, "up"), (T, 0.0, 25, "down")])
        name = "case1_T%g" % T
        cases[name] = run_case(name, G1, sched, N_lvls,
                               [(base_c1 * m, base_c1 * m) for m in mult], rmax, T)
        cases[name]["T_load"] = T
    sched2 = Schedule([(2.0, DELTA_MAX, 12, "up"), (5.0, DELTA_MAX, 10, "hold"),
                       (2.0, 0.0, 16, "down"), (5.0, 0.0, 10, "zero")])
    cases["case2"] = run_case("case2", G2, sched2, N_lvls,
                              [tuple(b * m for b in base_c2) for m in mult], rmax, 7.0)

    for name, cs in cases.items():
        ch, cv = cs["checks"], cs["convergence"]
        print("\n%s: F_peak %.5e at t=%.3f, separation t=%s, Lee-Radok < 0 from t=%s (%.1fs)" % (
            name, cs["F_peak"], cs["t_F_peak"], cs["separation_time"], cs["lee_radok_negative_from"],
            cs["runtime_s"]))
        print("  loading vs LR: max rel %.2e (t>0.1T), max abs/Fpk %.2e, a err/amax %.2e" % (
            ch["loading_vs_lee_radok"]["max_rel_err_vs_lee_radok_t_gt_0.1_tramp"],
            ch["loading_vs_lee_radok"]["max_abs_err_over_F_peak"],
            ch["loading_vs_lee_radok"]["max_abs_a_err_over_a_max"]))
        print("  convergence: unloading |dF|/Fpk %.2e, rel(F>0.1Fpk) %.2e, all %.2e, |da|/amax %.2e" % (
            cv["max_abs_dF_over_F_peak_unloading"], cv["max_rel_dF_unloading_where_F_gt_0.1_F_peak"],
            cv["max_abs_dF_over_F_peak_all"], cv["max_abs_da_over_a_max_all"]))
        print("  Ting-theorem consistency |F - F_thm(a)|/Fpk: %s; noncircular steps %d" % (
            ch["ting_theorem_consistency"]["max_abs_diff_over_F_peak"], ch["noncircular_contact_steps"]))
        print("  %8s %9s %11s %11s %9s" % ("t", "delta", "F", "F_LR", "a"))
        n = len(cs["t"])
        for i in sorted(set(np.linspace(0, n - 1, 13).round().astype(int))):
            print("  %8.3f %9.6f %11.4e %11.4e %9.5f" % (cs["t"][i], cs["delta"][i], cs["F_ting"][i],
                                                        cs["F_lee_radok"][i], cs["a"][i]))
    meta = {
        "description": "rigid sphere on linear viscoelastic half-space (constant nu), loading "
                       "and unloading; brute-force axisymmetric surface-traction solver "
                       "(rings + exact half-space kernel + creep-function hereditary integral "
                       "+ per-step LCP). Units R = 1, E*_inf = 1, s.",
        "R": R, "E_star_inf": 1.0, "delta_max": DELTA_MAX, "r_max": rmax,
        "resolutions_N": list(N_lvls), "quick": args.quick,
        "versions": {"python": platform.python_version(), "numpy": np.__version__,
                     "scipy": scipy.__version__},
        "runtime_s": time.time() - T0,
        "F_ting_is": "fine-level solver force at the output times",
    }
    result = {"meta": meta, "checks": {"elastic_hertz": hertz, "creep_functions": creep},
              "cases": cases}
    print("\ntotal runtime %.1f s" % (time.time() - T0))
    if out_path:
        with open(out_path, "w") as f:
            json.dump(result, f, indent=1)
        print("wrote", out_path)


if __name__ == "__main__":
    main()
