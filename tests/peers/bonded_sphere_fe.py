#!/usr/bin/env python3
# Tested with: python 3.11.7, scikit-fem==12.0.2, numpy==2.4.6, scipy==1.17.1 (one core)
#   (python3 -m pip install --root-user-action=ignore scikit-fem==12.0.2)
"""Rigid sphere pressed into an elastic layer bonded to a rigid base, frictionless and
fully stuck (incremental loading): an axisymmetric finite-element oracle, independent of
gelrig's solver.

It shares no code or tables with the Rust side and does not import bonded_punch_fe.py (the
flat-punch oracle of the same layer); the FE formulation and mesh style are copied from it.

Problem
  Layer 0 <= z <= h (z points into the layer, z = 0 is the free surface), 0 <= r <= R_out,
  R_out = a_max + 15 h.  Linear isotropic elasticity, small strain, E = 1 (P scales with
  E; the ratio P_stuck / P_frictionless does not depend on it), Poisson ratio nu.
  A rigid sphere of radius R touches the surface at r = 0 and is pressed to depth delta,
  monotonically from first touch.  Profile f(r) = R - sqrt(R^2 - r^2) (the exact sphere,
  at the undeformed r; infinite for r >= R).  With --flat A the profile is a flat face of
  radius A (f = 0 for r <= A, infinite beyond).
  Boundary conditions:
    z = h (rigid base, bonded):  u_r = u_z = 0
    r = 0 (axis):                u_r = 0
    r = R_out (truncation):      u_r = 0 (as bonded_punch_fe.py, which shows the kernel's
                                 exp(-0.739 r/h) decay makes this immaterial)
    z = 0, node in contact:      u_z = delta - f(r) and
                                   frictionless: no tangential force (u_r free);
                                   stuck: u_r frozen at the value it had when the node
                                   was caught (see "catch"); a node that leaves contact
                                   has its u_r released;
    z = 0, not in contact:       traction free.
  Contact is enforced at the surface nodes of the P2 displacement (vertices and edge
  midpoints).  Path: delta_k = delta_max (k/K)^2, k = 1..K (even in sqrt(delta), so the
  contact radius advances roughly evenly), with the reported depths added to the path.
  At each increment a primal-dual active set, starting from the previous contact set: add
  the nodes the sphere penetrates (u_z < delta - f(r) - 1e-9 delta: the sphere's face, at
  depth delta - f(r), lies below the free surface point; with z into the layer this is
  u_z < delta - f, not >), drop the nodes whose normal reaction is tensile
  (< -1e-9 max reaction), solve again, until the set repeats.
  Catch (stuck):
    previous      (the definition used for the headline "ratio"): a newly caught node's
                  u_r is frozen at the previous increment's converged value.  The lag of
                  one increment makes the force first order in 1/K.  This scheme can
                  cycle: an edge node is penetrated when free, but pulls when caught with
                  the lagged u_r; the node is then kept in contact (per mesh/path the
                  number of cycles and the largest accepted tension, <= ~3 % of the
                  largest nodal reaction and shrinking with K, are in the JSON).
    interpolated  ("ratio_interp", a cross-check of the K -> inf limit): u_r linearly
                  interpolated between the previous increment and the current trial state
                  to where the node's gap closes.  Same limit; its K -> 2K change is
                  ~1e-5, and the "previous" values approach it as K grows.
  The frictionless solution does not depend on the path (the discrete problem, an LCP with
  SPD compliance, has one solution); it is computed on the K path.

Formulation
  Mixed Taylor-Hood u-p: continuous P2 displacement (u_r, u_z), continuous P1 pressure
  p = lambda div u (sigma = 2 mu eps + p I), free of volumetric locking as nu -> 1/2
  (nu = 0.5 exactly is allowed: the p-p block is then zero).  Axisymmetric weak form with
  dV ~ r dr dz (2 pi dropped and restored for the force):
      int [ 2 mu eps(u):eps(v) + p div v ] r dr dz = 0
      int [ div u q - p q / lambda ]      r dr dz = 0
  with the hoop strain u_r/r, div u = du_r/dr + u_r/r + du_z/dz (as bonded_punch_fe.py).
  Surface condensation: the non-fixed dofs are factorised once per mesh (SuperLU) and the
  surface compliance G (u_c = G f_c) is formed for the candidate surface dofs c (both
  components of every surface node with r <= r_f = 1.2 a_max; u_r at r = 0 is fixed).
  Every other surface dof is traction free.  A contact set D with prescribed u_D costs
  one dense solve: f_D = G_DD^{-1} u_D, u_c = G_cD f_D.  f_D are the consistent nodal
  reactions (force of the sphere on the layer, > 0 pushing into it) and
  P = 2 pi * (sum of the u_z reactions).  condensation_check: the reactions agree with a
  full sparse solve with the same Dirichlet set to ~1e-12.
  Surface field: at each reported depth the whole displacement is recovered with f_D as
  nodal loads (one back substitution with the kept factorisation; per level
  full_field_check: its candidate dofs vs G_cD f_D, ~1e-12) and its P2 trace on z = 0
  (quadratic on each surface edge) is evaluated at the requested r, also beyond r_f.

Mesh and refinement
  Base mesh of [0, R_out] x [0, h] graded toward the surface segment 0 <= r <= r_f:
  size s(d) = min(s0 + gamma d, h/4), d = distance to the segment, s0 = r_f/30 = a_max/25
  (uniform on the segment), gamma = 0.25.  Points on the offset curves of the segment (the
  line z = d over it and a quarter arc about (r_f, 0)), spaced s(d) along and between
  them, and on the boundary lines; Delaunay-triangulated (angles 21 - 121 deg).  Level L
  is the base mesh uniformly refined L times (nested): surface element size a_max/25,
  /50, /100, i.e. P2 contact nodes every a_max/200 at the finest level (481 candidate
  dofs, ~65k-92k unknowns).
  a_max: from a pre-pass on a coarse mesh (frictionless and stuck, K = 16, candidates out
  to ~1.5 sqrt(2 R delta_max)): the larger contact radius plus 1.5 coarse spacings.  Each
  level checks that its contact stays below 0.95 r_f.
  Richardson over levels as bonded_punch_fe.py (observed order if the last three levels
  are monotone with order in [0.5, 8], else nominal 2; the contact radius is quantised to
  the node spacing, so P wobbles by ~1e-4 relative and the order is mostly nominal);
  error_estimate = max(|f2 - f1|, |f_ext - f2|).  Stuck values are at 2K; their
  error_estimate_total adds |K -> 2K change| (about the 2K value's distance to the K -> inf
  limit when first order).

Outputs (JSON beside this script, bonded_sphere_fe.json, written by the default run)
  summary: per case and depth, extrapolated P_frictionless, P_stuck, ratio (= P_stuck /
  P_frictionless, "previous" catch), ratio_interp, with error estimates and K changes, and
  the finest level's contact radii a_frictionless, a_stuck (largest r of a contacting
  node, quantised to a_max/200), ur_over_delta {r_over_a, free, stuck_interp}.
  cases: everything per level.  validation: below.
  results[i]["surface"] (per case and depth): the surface displacement / delta, u_r > 0
  outward, u_z > 0 into the layer (= 1 - f/delta in contact, < 0 where the surface
  bulges), of the frictionless ("free") and stuck ("stuck": previous catch,
  "stuck_interp") solutions at r = r_over_a * a (0.5, 0.9 inside the contact; 1.25, 1.5,
  2, 3 outside), a = that solution's contact edge a_edge per level: where the separation
  s ~ (r - a)^1.5 vanishes, from a least-squares line through s^(2/3) at the four nodes
  beyond the last contacting node (a_edge_free, a_edge_stuck, a_edge_stuck_interp:
  richardson dicts).  Keys ur_free, ur_stuck, ur_stuck_interp, uz_free, uz_stuck,
  uz_stuck_interp, each {levels: [level][point], extrapolated, error_estimate, method}
  (lists over the points); method "richardson" as above, or "finest" where the last three
  levels are not monotone (the edge is still quantised): the finest level, error |f2 - f1|.
  Stuck also K_change (2K - K, finest level) and error_estimate_total.  at_mm: the same at
  fixed radii r_mm (--ur-at R1,R2,... in mm; default none).  Printed: u_r/delta table.
  Default run (K = 128/256, 3 levels), ratio +- error estimate (ratio_interp):
    box sphere R 6.34, h 4.2, nu 0.49: delta 0.5: 1.00360 +- 3e-5 (1.00357)
                                             1.0: 1.01646 +- 3e-4 (1.01634)
                                             2.0: 1.05240 +- 3e-4 (1.05209)
    thin       R 6.0,  h 2.0, nu 0.49: delta 0.075: 1.00106 +- 2e-5 (1.00105)
                                             0.3: 1.02850 +- 2e-4 (1.02834)
  u_r/delta at r/a = 1.25, 1.5, 2 (free; stuck_interp), errors <= 3e-4:
    box sphere delta 2.0: 0.2173 0.1977 0.1368; 0.1889 0.1829 0.1294 (a 4.362; 4.384)
    thin       delta 0.3: 0.1612 0.1560 0.1230; 0.1409 0.1451 0.1180 (a 1.718; 1.726)

Validation (default run; "validation" in the JSON)
  * hertz: frictionless, R = 6.34, nu = 0.3, delta = 0.1, h = 200, 400, 800 (a/h = 0.004
    ... 0.001).  Against Hertz, (4/3) E* sqrt(R) delta^1.5, E* = E/(1 - nu^2), and against
    the half-space solution for the exact spherical profile (Sneddon's integrals,
    sneddon_sphere; 1.6e-3 below Hertz here, the a^2/R^2 profile difference).  At h = 200
    P is 3.5e-3 above Sneddon (1.9e-3 above Hertz): the layer's finite thickness,
    ~0.88 a/h as for a flat punch.  Quadratic extrapolation in a/h -> 0: 1.4e-5 from
    Sneddon.
    Surface field (same runs, at r = 0.5 ... 3 a_sn in mm): outside the contact the
    half-space's u_r = -(1 - 2 nu)(1 + nu) P / (2 pi E r) is exact for any axisymmetric
    pressure of total P (Boussinesq's ring loads; Johnson eq. 3.41b, a^2/r with
    P = 2 pi p0 a^2 / 3; inward for nu < 1/2), here with P = P_sn.  At h = 200 |u_r| is
    3.4e-3 above it at r/a = 1.25 ... 3 (as P); a/h -> 0: 1.2e-5 (required at r/a = 1.5,
    2: 1e-2 at h = 200, 2e-4 extrapolated).  r/a = 0.5 (Hertz's pressure, -1.9e-3: not
    the exact sphere's) and u_z (Hertz's pressure, Johnson 3.42; <= 8e-5 outside) are
    reported for information.
  * incompressible: nu = 0.5, R = 6.34, h = 200, delta = 0.1.  On an incompressible
    half-space normal and tangential problems decouple, so P_stuck/P_frictionless -> 1
    (required |ratio - 1| < 5e-3 on the thick layer; found < 1e-5).
  * flat: flat face A = 4.75, h = 4.2, nu = 0.49.  The flat face loads proportionally (all
    nodes are caught at first touch with u_r = 0), so the incremental stuck solution is the
    bonded punch and the ratio must reproduce bonded_punch_fe.py's 1.08932 (required
    2e-3; found -3e-5; the mesh here is not graded to the punch edge, so the levels
    converge like h^1.3).
  Spence's (1975) no-slip half-space result is not checked (formula not pinned down); the
  stuck/frictionless ratio extrapolated to the nu = 0.3 half-space (1.0165 at fixed delta;
  interpolated catch 1.0163) is reported for information.

Runtime: default run ~100 s on one core (BLAS pinned to one thread), --quick ~11 s.

Usage
  python3 tests/peers/bonded_sphere_fe.py               (default: cases + validation,
                                                         writes bonded_sphere_fe.json)
  python3 tests/peers/bonded_sphere_fe.py --quick       (2 levels, K = 16, writes no file)
  python3 tests/peers/bonded_sphere_fe.py --R 6.34 --h 4.2 --nu 0.49 --depths 0.5,1,2
                                          [--levels 3] [--K 128] [--ur-at 5,8] [--out FILE]
  python3 tests/peers/bonded_sphere_fe.py --flat 4.75 --h 4.2 --nu 0.49
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # one core (set before numpy loads)
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse
import json
import math
import sys
import time

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

import skfem
from skfem import Basis, BilinearForm, ElementTriP1, ElementTriP2, ElementVector, MeshTri, asm
from skfem.helpers import ddot, sym_grad

R_OUT_FACTOR = 15.0
R_OVER_A = [0.5, 0.9, 1.25, 1.5, 2.0, 3.0]  # where the surface field is reported
MESH_DEFAULTS = dict(n_base=30, r_f_over_a=1.2, gamma=0.25, hmax_rel=0.25)
DEFAULT_CASES = [
    dict(name="box sphere", R=6.34, h=4.2, nu=0.49, depths=[0.5, 1.0, 2.0]),
    dict(name="thin", R=6.0, h=2.0, nu=0.49, depths=[0.075, 0.3]),
]


# ----------------------------------------------------------------------------- mesh
def surface_graded_mesh(r_f, n_f, h, r_out, gamma=0.25, hmax_rel=0.25):
    """Mesh of [0, r_out] x [0, h] graded toward the surface segment [0, r_f] x {0}.

    Size s(d) = min(s0 + gamma d, hmax_rel h), s0 = r_f / n_f, d = distance to the
    segment.  The segment gets n_f + 1 uniformly spaced points; then points on the offset
    curves {d = d_j} (line z = d_j for r <= r_f, quarter arc about (r_f, 0)),
    d_{j+1} = d_j + s(d_j), spaced s(d_j) along the curve and clipped half a spacing off
    the axis, base and outer side (the arc's end on z = 0 is kept: the surface points
    beyond r_f); points on the axis, base and outer side with density 1/s; Delaunay."""
    from scipy.spatial import Delaunay

    s0 = r_f / n_f
    hmax = hmax_rel * h

    def s_of(d):
        return np.minimum(s0 + gamma * np.asarray(d, dtype=float), hmax)

    def dist(r, z):
        return np.where(r <= r_f, z, np.hypot(r - r_f, z))

    pts = [np.column_stack([np.linspace(0.0, r_f, n_f + 1), np.zeros(n_f + 1)]),
           np.array([(r_out, 0.0), (0.0, h), (r_out, h)])]
    d_max = math.hypot(r_out - r_f, h)
    d = s0
    while d < d_max:
        s = float(s_of(d))
        m = 0.5 * s
        # the offset curve, from (0, d) along z = d to (r_f, d), then the arc to (r_f + d, 0)
        L_line, L_arc = r_f, 0.5 * math.pi * d
        n_samp = int(max(4000, 40 * (L_line + L_arc) / s))
        t = np.linspace(0.0, L_line + L_arc, n_samp + 1)
        on_line = t <= L_line
        th = 0.5 * math.pi - (t - L_line) / d
        x = np.where(on_line, t, r_f + d * np.cos(th))
        z = np.where(on_line, d, d * np.sin(th))
        x[-1], z[-1] = r_f + d, 0.0
        ok = (x >= m) & (x <= r_out - m) & (z <= h - m)
        sel = np.nonzero(ok)[0]
        if sel.size:
            brk = np.nonzero(np.diff(sel) > 1)[0]
            starts = np.concatenate([[sel[0]], sel[brk + 1]])
            ends = np.concatenate([sel[brk], [sel[-1]]])
            for i0, i1 in zip(starts, ends):
                arclen = t[i1] - t[i0]
                on_surface = i1 == n_samp
                if arclen < 0.3 * s and not on_surface:
                    continue
                n = max(1, int(math.ceil(arclen / s - 1e-9)))
                tq = np.linspace(t[i0], t[i1], n + 1)
                thq = 0.5 * math.pi - (tq - L_line) / d
                xq = np.where(tq <= L_line, tq, r_f + d * np.cos(thq))
                zq = np.where(tq <= L_line, d, d * np.sin(thq))
                if on_surface:
                    xq[-1], zq[-1] = r_f + d, 0.0
                pts.append(np.column_stack([xq, zq]))
        d += s

    def line(p0, p1):
        p0 = np.asarray(p0, dtype=float)
        p1 = np.asarray(p1, dtype=float)
        tt = np.linspace(0.0, 1.0, 40001)
        P = p0[:, None] + (p1 - p0)[:, None] * tt
        dens = 1.0 / s_of(dist(P[0], P[1]))
        ln = float(np.linalg.norm(p1 - p0))
        cum = np.concatenate([[0.0], np.cumsum(0.5 * (dens[1:] + dens[:-1]) * np.diff(tt) * ln)])
        n = max(1, int(math.ceil(cum[-1])))
        tq = np.interp(np.linspace(0.0, cum[-1], n + 1), cum, tt)[1:-1]
        pts.append(p0[None, :] + (p1 - p0)[None, :] * tq[:, None])

    line((0.0, 0.0), (0.0, h))
    line((0.0, h), (r_out, h))
    line((r_out, 0.0), (r_out, h))
    P = np.vstack(pts)
    P[:, 1] = np.where(np.abs(P[:, 1]) < 1e-14 * h, 0.0, P[:, 1])
    tri = Delaunay(P)
    if len(tri.coplanar):
        raise RuntimeError("mesh generation failed (points dropped by Delaunay)")
    T = tri.simplices.copy()
    dd = ((P[T[:, 1], 0] - P[T[:, 0], 0]) * (P[T[:, 2], 1] - P[T[:, 0], 1])
          - (P[T[:, 2], 0] - P[T[:, 0], 0]) * (P[T[:, 1], 1] - P[T[:, 0], 1]))
    T[dd < 0] = T[dd < 0][:, [0, 2, 1]]
    area = 0.5 * np.abs(dd).sum()
    if abs(area / (r_out * h) - 1.0) > 1e-9 or np.min(np.abs(dd)) <= 1e-14 * s0 * s0:
        raise RuntimeError("mesh generation failed (area %.12g vs %.12g)" % (area, r_out * h))
    return MeshTri(P.T.copy(), T.T.copy())


def mesh_quality(m):
    p, t = m.p, m.t
    P = [p[:, t[i]] for i in range(3)]
    angs = []
    for i in range(3):
        u = P[(i + 1) % 3] - P[i]
        v = P[(i + 2) % 3] - P[i]
        c = (u * v).sum(0) / np.linalg.norm(u, axis=0) / np.linalg.norm(v, axis=0)
        angs.append(np.degrees(np.arccos(np.clip(c, -1, 1))))
    angs = np.array(angs)
    return dict(n_triangles=int(t.shape[1]), min_angle_deg=float(angs.min()),
                max_angle_deg=float(angs.max()))


# ----------------------------------------------------------------------------- forms
def make_forms(mu, inv_lam):
    @BilinearForm
    def a_form(u, v, w):
        r = w.x[0]
        return 2.0 * mu * (ddot(sym_grad(u), sym_grad(v)) * r + u.value[0] * v.value[0] / r)

    @BilinearForm
    def b_form(u, q, w):  # rows: pressure test q, cols: displacement trial u
        r = w.x[0]
        divu = u.grad[0][0] + u.grad[1][1]
        return q.value * (divu * r + u.value[0])

    @BilinearForm
    def c_form(p, q, w):
        return p.value * q.value * w.x[0] * inv_lam

    return a_form, b_form, c_form


# ----------------------------------------------------------------------------- profiles
def sphere_profile(R):
    def f(r):
        r = np.asarray(r, dtype=float)
        out = np.full(r.shape, np.inf)
        m = r < R
        out[m] = R - np.sqrt(R * R - r[m] ** 2)
        return out
    return f


def flat_profile(A):
    def f(r):
        r = np.asarray(r, dtype=float)
        return np.where(r <= A * (1.0 + 1e-12), 0.0, np.inf)
    return f


# ----------------------------------------------------------------------------- solver
class Problem:
    """One mesh: assembled and condensed onto the candidate surface dofs once."""

    def __init__(self, mesh, h, nu, r_cand, E=1.0):
        self.mesh, self.h, self.nu, self.E = mesh, h, nu, E
        self.mu = E / (2.0 * (1.0 + nu))
        inv_lam = (1.0 + nu) * (1.0 - 2.0 * nu) / (E * nu)
        self.ub = Basis(mesh, ElementVector(ElementTriP2()), intorder=5)
        self.pb = self.ub.with_element(ElementTriP1())
        a_form, b_form, c_form = make_forms(self.mu, inv_lam)
        A = asm(a_form, self.ub)
        B = asm(b_form, self.ub, self.pb)
        C = asm(c_form, self.pb)
        self.K = sp.bmat([[A, B.T], [B, -C]], format="csr")
        self.N = self.K.shape[0]
        self.r_out = float(mesh.p[0].max())
        ub = self.ub
        rdofs = np.concatenate([ub.nodal_dofs[0], ub.facet_dofs[0]])
        zdofs = np.concatenate([ub.nodal_dofs[1], ub.facet_dofs[1]])
        tol = self.tol = 1e-9 * max(h, r_cand)
        xr, xz = ub.doflocs[:, rdofs], ub.doflocs[:, zdofs]
        fixed = np.concatenate([
            rdofs[np.abs(xr[1] - h) < tol], zdofs[np.abs(xz[1] - h) < tol],
            rdofs[np.abs(xr[0]) < tol], rdofs[np.abs(xr[0] - self.r_out) < tol]])
        self.fixed = np.unique(fixed)
        # candidate surface nodes, sorted by r
        sz = (np.abs(xz[1]) < tol) & (xz[0] <= r_cand + tol)
        sr = (np.abs(xr[1]) < tol) & (xr[0] <= r_cand + tol)
        oz = np.argsort(xz[0, sz])
        orr = np.argsort(xr[0, sr])
        self.node_r = xz[0, sz][oz]
        node_z = zdofs[sz][oz]
        node_rd = rdofs[sr][orr]
        assert np.allclose(xr[0, sr][orr], self.node_r, atol=tol)
        self.n_nodes = len(self.node_r)
        node_rd = np.where(np.isin(node_rd, self.fixed), -1, node_rd)  # the axis node
        keep_r = node_rd >= 0
        self.cand = np.concatenate([node_z, node_rd[keep_r]])  # global dofs
        self.iz = np.arange(self.n_nodes)
        self.ir = np.full(self.n_nodes, -1)
        self.ir[keep_r] = self.n_nodes + np.arange(keep_r.sum())
        self.nc = len(self.cand)
        self.spacing = float(np.min(np.diff(self.node_r)))
        # the whole surface's P2 trace: nodes sorted by r, vertex-midpoint-vertex-...
        allz, allr = np.abs(xz[1]) < tol, np.abs(xr[1]) < tol
        oz, orr = np.argsort(xz[0, allz]), np.argsort(xr[0, allr])
        self.trace_r = xz[0, allz][oz]
        self.trace_z, self.trace_rd = zdofs[allz][oz], rdofs[allr][orr]
        assert np.allclose(xr[0, allr][orr], self.trace_r, atol=tol)
        assert np.all(np.isin(self.trace_z[::2], ub.nodal_dofs[1]))
        self._condense()

    def _free(self):
        free = np.ones(self.N, dtype=bool)
        free[self.fixed] = False
        return np.nonzero(free)[0]

    def _condense(self):
        t0 = time.time()
        F = self._free()
        pos = np.full(self.N, -1)
        pos[F] = np.arange(len(F))
        lu = spla.splu(self.K[F][:, F].tocsc(), permc_spec="COLAMD")
        pc = pos[self.cand]
        G = np.empty((self.nc, self.nc))
        nb = 128
        for j0 in range(0, self.nc, nb):
            j1 = min(self.nc, j0 + nb)
            Bm = np.zeros((len(F), j1 - j0))
            Bm[pc[j0:j1], np.arange(j1 - j0)] = 1.0
            G[:, j0:j1] = lu.solve(Bm)[pc, :]
        self.G_asym = float(np.abs(G - G.T).max() / np.abs(G).max())
        self.G = 0.5 * (G + G.T)
        self.lu, self.free_pos = lu, pos  # kept for the full displacement field
        self.condense_time = time.time() - t0

    def full_field(self, D_local, f):
        """The whole displacement (all dofs) for the candidate dofs' reactions f on
        D_local as nodal loads (every other surface dof traction free): one back
        substitution with the factorisation kept from the condensation."""
        b = np.zeros(self.lu.shape[0])
        b[self.free_pos[self.cand[D_local]]] = f
        x = np.zeros(self.N)
        x[self.free_pos >= 0] = self.lu.solve(b)
        return x

    def trace(self, x, r):
        """(u_r, u_z) of the P2 field x on z = 0 at radii r (quadratic on each surface
        edge through its two vertices and midpoint)."""
        r = np.atleast_1d(np.asarray(r, dtype=float))
        rv = self.trace_r[::2]
        e = np.clip(np.searchsorted(rv, r) - 1, 0, len(rv) - 2)
        r0, r1 = rv[e], rv[e + 1]
        t = (r - r0) / (r1 - r0)
        w = np.array([2.0 * (t - 0.5) * (t - 1.0), 4.0 * t * (1.0 - t), 2.0 * t * (t - 0.5)])
        idx = np.array([2 * e, 2 * e + 1, 2 * e + 2])
        return ((w * x[self.trace_rd[idx]]).sum(0), (w * x[self.trace_z[idx]]).sum(0))

    def surface(self, rec, profile, r_mm=(), flat=None):
        """Surface displacement / delta of a contact record at R_OVER_A * a_edge and at the
        radii r_mm, from the full field.  a_edge: the contact edge, where a separation
        s ~ (r - a)^1.5 vanishes: a least-squares line through s^(2/3) at the four nodes
        beyond the last contacting node rec["a"] (kept within one node of it; a flat face:
        its radius)."""
        D, f, d = rec["D"], rec["f"], rec["delta"]
        X = self.full_field(D, f)
        uc = self.G[:, D] @ f
        chk = float(np.abs(X[self.cand] - uc).max() / np.abs(uc).max())
        a = a_edge = rec["a"] if flat is None else flat
        i = int(np.searchsorted(self.node_r, rec["a"] - self.tol))
        if flat is None and 0 < i and i + 4 < self.n_nodes:
            rn = self.node_r[i + 1:i + 5]
            s = uc[self.iz[i + 1:i + 5]] - (d - profile(rn))  # separation >= 0
            if np.all(s > 0.0):
                c1, c0 = np.polyfit(rn, s ** (2.0 / 3.0), 1)
                if c1 > 0.0:
                    a_edge = float(np.clip(-c0 / c1, self.node_r[i - 1], rn[0]))
        rr = np.concatenate([np.array(R_OVER_A) * a_edge, np.asarray(r_mm, dtype=float)])
        ur, uz = self.trace(X, rr)
        n = len(R_OVER_A)
        return dict(a_edge=a_edge, ur_rel=list(ur[:n] / d), uz_rel=list(uz[:n] / d),
                    ur_mm=list(ur[n:] / d), uz_mm=list(uz[n:] / d), full_field_check=chk)

    def full_solve(self, D_local, uD):
        """Full sparse solve with u prescribed on candidate dofs D_local (the rest of the
        surface traction free); returns the reactions on D_local (condensation check)."""
        D = self.cand[D_local]
        Dall = np.concatenate([self.fixed, D])
        x = np.zeros(self.N)
        x[D] = uD
        free = np.ones(self.N, dtype=bool)
        free[Dall] = False
        I = np.nonzero(free)[0]
        K = self.K
        x[I] = spla.spsolve(K[I][:, I].tocsc(), -(K[I][:, D] @ uD), permc_spec="COLAMD")
        return (K @ x)[D]

    def contact_path(self, profile, deltas, mode, record=None, catch="previous"):
        """Monotonic loading along deltas (increasing).  mode 'frictionless' or 'stuck'.
        catch (stuck): 'previous' freezes a newly caught node's u_r at the previous
        increment's value; 'interpolated' at the value linearly interpolated (between the
        previous increment and the current trial state) to where the gap closes.
        Returns one record per delta in `record` (default: all)."""
        n, iz, ir, G = self.n_nodes, self.iz, self.ir, self.G
        prof = profile(self.node_r)
        active = np.zeros(n, dtype=bool)
        frozen = np.zeros(n)
        u_prev = np.zeros(self.nc)
        target_prev = -prof
        rec_set = None if record is None else set(np.round(record, 12))
        out = []
        cycles = 0
        worst_tension = 0.0
        max_it = 0
        for delta in deltas:
            target = delta - prof
            seen = set()
            it = 0
            while True:
                it += 1
                dn = np.nonzero(active)[0]
                if mode == "stuck":
                    mr = ir[dn] >= 0
                    D = np.concatenate([iz[dn], ir[dn[mr]]])
                    uD = np.concatenate([target[dn], frozen[dn[mr]]])
                elif mode == "frictionless":
                    D, uD = iz[dn], target[dn]
                else:
                    raise ValueError(mode)
                if D.size:
                    f = sla.cho_solve(sla.cho_factor(G[np.ix_(D, D)]), uD)
                    u = G[:, D] @ f
                else:
                    f = np.zeros(0)
                    u = np.zeros(self.nc)
                fz = np.zeros(n)
                fz[dn] = f[:len(dn)]
                tol_f = 1e-9 * max(np.abs(fz).max(), 1e-300)
                pen = ~active & (target - u[iz] > 1e-9 * delta)  # sphere below the surface
                tens = active & (fz < -tol_f)
                new = (active & ~tens) | pen
                if np.array_equal(new, active):
                    break
                key = new.tobytes()
                if key in seen:  # a cycle: keep the union (see the header)
                    cycles += 1
                    new = active | pen
                    if np.array_equal(new, active):
                        worst_tension = max(worst_tension, -fz.min() / np.abs(fz).max())
                        break
                seen.add(key)
                added = new & ~active
                if mode == "stuck":
                    a_idx = np.nonzero(added & (ir >= 0))[0]
                    frozen[a_idx] = u_prev[ir[a_idx]]
                    if catch == "interpolated":
                        g0 = u_prev[iz[a_idx]] - target_prev[a_idx]
                        g1 = u[iz[a_idx]] - target[a_idx]
                        th = np.clip(g0 / np.maximum(g0 - g1, 1e-300), 0.0, 1.0)
                        frozen[a_idx] += th * (u[ir[a_idx]] - u_prev[ir[a_idx]])
                    elif catch != "previous":
                        raise ValueError(catch)
                active = new
                if it > 200:
                    raise RuntimeError("active set did not settle")
            max_it = max(max_it, it)
            u_prev = u
            target_prev = target
            if rec_set is None or round(delta, 12) in rec_set:
                fr = np.zeros(n)
                if mode == "stuck":
                    fr[dn[mr]] = f[len(dn):]
                out.append(dict(
                    delta=float(delta), P=float(2.0 * math.pi * fz.sum()),
                    a=float(self.node_r[active].max()) if active.any() else 0.0,
                    n_contact_nodes=int(active.sum()),
                    radial_reaction_sum=float(2.0 * math.pi * fr.sum()),
                    min_pressure_reaction=float(fz[active].min()) if active.any() else 0.0,
                    D=D, uD=uD, f=f))
        return out, dict(cycles=cycles, max_active_set_iterations=max_it,
                         cycle_tension_over_max_reaction=worst_tension)


def loading_path(delta_max, K, depths):
    d = list(delta_max * (np.arange(1, K + 1) / K) ** 2) + list(depths)
    d = np.unique(np.round(d, 14))
    return d[d > 0]


# ----------------------------------------------------------------------------- extrapolation
def richardson(vals, nominal_p):
    """Richardson extrapolation of a sequence on meshes whose size halves per level."""
    v = [float(x) for x in vals]
    out = dict(levels=v)
    if len(v) < 2:
        out.update(extrapolated=v[-1], order=None, error_estimate=None)
        return out
    if len(v) >= 3:
        d1, d2 = v[-2] - v[-3], v[-1] - v[-2]
        p = None
        if d1 != 0.0 and d2 != 0.0 and d1 * d2 > 0 and abs(d2) < abs(d1):
            p = math.log2(d1 / d2)
            if not (0.5 <= p <= 8.0):
                p = None
        order_src = "observed" if p is not None else "nominal"
        if p is None:
            p = nominal_p
    else:
        p, order_src = nominal_p, "nominal"
    d = v[-1] - v[-2]
    ext = v[-1] + d / (2.0 ** p - 1.0)
    out.update(extrapolated=ext, order=p, order_source=order_src,
               diff_two_finest=d, diff_finest_to_extrapolated=ext - v[-1],
               error_estimate=max(abs(d), abs(ext - v[-1])))
    return out


# ----------------------------------------------------------------------------- half-space
def sneddon_sphere(R, nu, delta, E=1.0, n=200):
    """Frictionless rigid indenter with the exact spherical profile f(r) = R - sqrt(R^2-r^2)
    on a half-space (Sneddon 1965):  delta(a) = int_0^1 f'(x) / sqrt(1 - x^2) dx,
    P(a) = 2 E* a int_0^1 x^2 f'(x) / sqrt(1 - x^2) dx, x = r/a, f'(x) = d f / d x.
    x = sin(theta) removes the end singularity; Gauss-Legendre in theta.  Returns (P, a)."""
    from scipy.optimize import brentq
    Es = E / (1.0 - nu * nu)
    g, w = np.polynomial.legendre.leggauss(n)
    th = 0.25 * math.pi * (g + 1.0)
    w = 0.25 * math.pi * w
    x = np.sin(th)

    def fp(a):  # df/dx at r = a x
        r = a * x
        return a * r / np.sqrt(R * R - r * r)

    def d_of(a):
        return float(w @ fp(a))

    a = brentq(lambda a: d_of(a) - delta, 1e-9 * R, 0.999 * R, xtol=1e-15 * R)
    P = 2.0 * Es * a * float(w @ (x * x * fp(a)))
    return P, a


# ----------------------------------------------------------------------------- driver
def field_extrapolation(levs, klevs=None):
    """Per point (levs: per level, a list over points) as richardson(); where the last
    three levels are not monotone (the contact radius is quantised) the finest level with
    the change between the two finest as its error ("finest")."""
    out = dict(levels=[list(map(float, v)) for v in levs], extrapolated=[],
               error_estimate=[], method=[])
    for k in range(len(levs[0])):
        rq = richardson([v[k] for v in levs], 2.0)
        if len(levs) >= 3 and rq["order_source"] == "nominal":
            val, err, how = rq["levels"][-1], abs(rq["diff_two_finest"]), "finest"
        else:
            val, err, how = rq["extrapolated"], rq["error_estimate"], "richardson"
        out["extrapolated"].append(val)
        out["error_estimate"].append(err)
        out["method"].append(how)
    if klevs is not None:
        out["K_change"] = [float(x - y) for x, y in zip(levs[-1], klevs[-1])]
        out["error_estimate_total"] = [e + abs(c) for e, c in zip(out["error_estimate"],
                                                                   out["K_change"])]
    return out


def _strip(rec):
    return {k: v for k, v in rec.items() if k not in ("D", "uD", "f")}


def estimate_a_max(profile, R, h, nu, delta_max, flat=None, verbose=False):
    if flat is not None:
        return flat, None
    a_geo = math.sqrt(max(2.0 * R * delta_max - delta_max ** 2, 1e-30))
    r_c = min(0.98 * R, 1.5 * a_geo)
    for _ in range(4):
        r_out = r_c + R_OUT_FACTOR * h
        m = surface_graded_mesh(r_c, 40, h, r_out)
        pr = Problem(m, h, nu, r_c)
        deltas = loading_path(delta_max, 16, [])
        a = 0.0
        for mode in ("frictionless", "stuck"):
            res, _ = pr.contact_path(profile, deltas, mode, record=[deltas[-1]])
            a = max(a, res[-1]["a"])
        if a < 0.9 * r_c:
            a_max = a + 1.5 * r_c / 40
            if verbose:
                print("  pre-pass: a_max = %.4f (contact %.4f)" % (a_max, a), file=sys.stderr)
            return a_max, dict(a_coarse=a, candidate_radius=r_c)
        r_c = min(0.98 * R, 1.5 * r_c)
    raise RuntimeError("pre-pass: contact reaches the candidate region's end")


def run_case(R, h, nu, depths, levels=3, K=64, flat=None, modes=("frictionless", "stuck"),
             name=None, verbose=False, check_condensation=False, ur_at=()):
    t_start = time.time()
    depths = sorted(float(x) for x in depths)
    delta_max = depths[-1]
    profile = flat_profile(flat) if flat is not None else sphere_profile(R)
    a_max, pre = estimate_a_max(profile, R, h, nu, delta_max, flat, verbose)
    mk = dict(MESH_DEFAULTS)
    r_f = mk["r_f_over_a"] * a_max
    r_out = a_max + R_OUT_FACTOR * h
    ur_at = [float(x) for x in ur_at]
    if any(not 0.0 <= x <= r_out for x in ur_at):
        raise ValueError("--ur-at radii must lie in [0, R_out = %.4g]" % r_out)
    base = surface_graded_mesh(r_f, mk["n_base"], h, r_out, mk["gamma"], mk["hmax_rel"])
    paths = {K: loading_path(delta_max, K, depths), 2 * K: loading_path(delta_max, 2 * K, depths)}
    per_level = []
    cond_check = None
    for L in range(levels):
        t0 = time.time()
        mesh = base.refined(L) if L else base
        pr = Problem(mesh, h, nu, r_f)
        rec = dict(level=L, n_triangles=int(mesh.t.shape[1]), n_dofs=int(pr.N),
                   n_candidate_dofs=int(pr.nc), surface_node_spacing=pr.spacing,
                   condense_time_s=round(pr.condense_time, 2), G_asymmetry=pr.G_asym,
                   **{k: v for k, v in mesh_quality(mesh).items() if k != "n_triangles"})
        runs = {}
        if "frictionless" in modes:
            runs["frictionless"] = pr.contact_path(profile, paths[K], "frictionless", depths)
        if "stuck" in modes:
            for cs, suffix in (("previous", ""), ("interpolated", "_interp")):
                runs["stuck" + suffix + "_K"] = pr.contact_path(
                    profile, paths[K], "stuck", depths, catch=cs)
                runs["stuck" + suffix] = pr.contact_path(
                    profile, paths[2 * K], "stuck", depths, catch=cs)
        for key, (res, info) in runs.items():
            for x in res:
                x.update(pr.surface(x, profile, ur_at, flat))
            rec[key] = dict(info, depths=[_strip(x) for x in res])
            amax = max(x["a"] for x in res)
            if amax > 0.95 * r_f:
                raise RuntimeError("contact radius %.4g beyond 0.95 r_f = %.4g" % (amax, 0.95 * r_f))
        rec["full_field_check"] = max(x["full_field_check"] for res, _ in runs.values()
                                      for x in res)
        if check_condensation and L == 0:
            cond_check = {}
            for key, (res, _) in runs.items():
                x = res[-1]
                Rfull = pr.full_solve(x["D"], x["uD"])
                cond_check[key] = float(np.abs(Rfull - x["f"]).max() / np.abs(x["f"]).max())
        rec["time_s"] = round(time.time() - t0, 2)
        per_level.append(rec)
        if verbose:
            print("  level %d: %d dofs, %d candidate dofs, condense %.1f s, total %.1f s"
                  % (L, pr.N, pr.nc, pr.condense_time, rec["time_s"]), file=sys.stderr)

    table = []
    both = "frictionless" in modes and "stuck" in modes
    for j, dlt in enumerate(depths):
        row = dict(delta=dlt)
        lev = {}

        def col(key, q):
            return [r[key]["depths"][j][q] for r in per_level]
        if "frictionless" in modes:
            lev["P_frictionless"] = col("frictionless", "P")
            lev["a_frictionless"] = col("frictionless", "a")
        if "stuck" in modes:
            for sfx in ("", "_interp"):
                lev["P_stuck" + sfx] = col("stuck" + sfx, "P")
                lev["P_stuck" + sfx + "_K"] = col("stuck" + sfx + "_K", "P")
                lev["a_stuck" + sfx] = col("stuck" + sfx, "a")
        if both:
            for sfx in ("", "_interp"):
                for kk in ("", "_K"):
                    lev["ratio" + sfx + kk] = [s_ / f_ for s_, f_ in zip(
                        lev["P_stuck" + sfx + kk], lev["P_frictionless"])]
        row["per_level"] = lev
        ext = {}
        for key in ("P_frictionless", "P_stuck", "ratio", "P_stuck_interp", "ratio_interp"):
            if key in lev:
                ext[key] = richardson(lev[key], 2.0)
        if both:
            for key in ("P_stuck", "ratio", "P_stuck_interp", "ratio_interp"):
                kc = lev[key][-1] - lev[key + "_K"][-1]
                ext[key]["K_change"] = kc
                ext[key]["K_change_rel"] = kc / lev[key][-1]
                ext[key]["error_estimate_total"] = ext[key]["error_estimate"] + abs(kc)
            ext["ratio"]["catch_scheme_difference"] = (ext["ratio"]["extrapolated"]
                                                      - ext["ratio_interp"]["extrapolated"])
        row["extrapolated"] = ext
        surf = dict(r_over_a=list(R_OVER_A), at_mm=dict(r_mm=ur_at))
        for s_, k_ in (("free", "frictionless"), ("stuck", "stuck"),
                       ("stuck_interp", "stuck_interp")):
            if k_ not in per_level[0]:
                continue
            surf["a_edge_" + s_] = richardson(col(k_, "a_edge"), 2.0)
            for c_ in ("ur", "uz"):
                for dst, src in ((surf, "_rel"), (surf["at_mm"], "_mm")):
                    kl = [r[k_ + "_K"]["depths"][j][c_ + src] for r in per_level] \
                        if k_ != "frictionless" else None
                    dst[c_ + "_" + s_] = field_extrapolation(col(k_, c_ + src), kl)
        row["surface"] = surf
        table.append(row)

    res = dict(name=name, kind="flat" if flat is not None else "sphere",
               scikit_fem_version=skfem.__version__, R_mm=R, flat_radius_mm=flat, h_mm=h,
               nu=nu, E=1.0, depths_mm=depths, K=K, K_fine=2 * K, levels=levels,
               a_max_mm=a_max, prepass=pre, r_fine_mm=r_f, R_out_mm=r_out,
               mesh=dict(MESH_DEFAULTS), results=table, condensation_check=cond_check,
               per_level=per_level)
    res["time_s"] = round(time.time() - t_start, 2)
    return res


def case_summary(res):
    """Compact per-depth results: extrapolated values with error estimates."""
    rows = []
    for row in res["results"]:
        ext, lev = row["extrapolated"], row["per_level"]
        q = dict(case=res["name"], R=res["R_mm"], h=res["h_mm"], nu=res["nu"], delta=row["delta"])
        for k in ("P_frictionless", "P_stuck", "ratio", "ratio_interp"):
            if k in ext:
                q[k] = ext[k]["extrapolated"]
                q[k + "_error_estimate"] = ext[k].get("error_estimate_total",
                                                      ext[k]["error_estimate"])
                if "K_change" in ext[k]:
                    q[k + "_K_change"] = ext[k]["K_change"]
        for k in ("a_frictionless", "a_stuck"):
            if k in lev:
                q[k + "_finest"] = lev[k][-1]
        sf = row["surface"]
        q["ur_over_delta"] = dict(r_over_a=sf["r_over_a"], **{
            k: sf["ur_" + k]["extrapolated"] for k in ("free", "stuck_interp") if "ur_" + k in sf})
        rows.append(q)
    return rows


def print_table(res, file=sys.stdout):
    nm = res["name"] or ("flat A=%g" % res["flat_radius_mm"] if res["flat_radius_mm"]
                         else "R=%g" % res["R_mm"])
    shape = ("flat A=%g" % res["flat_radius_mm"]) if res["flat_radius_mm"] else ("R=%g" % res["R_mm"])
    print("# %s: %s h=%g nu=%g  K=%d/%d  a_max=%.4f  (%.1f s)" % (
        nm, shape, res["h_mm"], res["nu"], res["K"], res["K_fine"], res["a_max_mm"],
        res["time_s"]), file=file)
    print("  P at 2K; ratio = P_stuck/P_free (u_r frozen at the previous increment), dK = its "
          "change K -> 2K;\n  ratio_i, dK_i: the same with the interpolated catch "
          "(cross-check of the K -> inf limit)", file=file)
    print("%-7s %-5s %12s %12s %9s %9s %9s %9s %7s %7s" % (
        "delta", "level", "P_free", "P_stuck", "ratio", "dK", "ratio_i", "dK_i", "a_free",
        "a_stuck"), file=file)
    for row in res["results"]:
        lev, ext = row["per_level"], row["extrapolated"]
        nl = len(next(iter(lev.values())))

        def g(k, L, fmt):
            return (fmt % lev[k][L]) if k in lev else "-"

        def dk(k, L):
            return ("%9.1e" % (lev[k][L] - lev[k + "_K"][L])) if k in lev else "-"
        for L in range(nl):
            print("%-7g %-5d %12s %12s %9s %9s %9s %9s %7s %7s" % (
                row["delta"], L, g("P_frictionless", L, "%12.6g"), g("P_stuck", L, "%12.6g"),
                g("ratio", L, "%9.6f"), dk("ratio", L), g("ratio_interp", L, "%9.6f"),
                dk("ratio_interp", L), g("a_frictionless", L, "%7.4f"),
                g("a_stuck", L, "%7.4f")), file=file)

        def e(k, fmt):
            return (fmt % ext[k]["extrapolated"]) if k in ext else "-"
        print("%-7g %-5s %12s %12s %9s %9s %9s" % (
            row["delta"], "ext", e("P_frictionless", "%12.6g"), e("P_stuck", "%12.6g"),
            e("ratio", "%9.6f"), "", e("ratio_interp", "%9.6f")), file=file)
        if "ratio" in ext:
            r, ri = ext["ratio"], ext["ratio_interp"]
            print("        ratio = %.5f +- %.1e (mesh %.1e, order %s %.2f; K->2K %.1e); "
                  "interpolated catch %.5f (K->2K %.1e)" % (
                      r["extrapolated"], r["error_estimate_total"], r["error_estimate"],
                      r["order_source"], r["order"], r["K_change"], ri["extrapolated"],
                      ri["K_change"]), file=file)
    print_surface(res, file)


def print_surface(res, file=sys.stdout):
    """u_r / delta on the surface (u_r > 0 outward): extrapolated +- error estimate (stuck:
    total, with the K -> 2K change)."""
    print("  surface u_r/delta at r/a (a: the contact edge a_edge of each solution)", file=file)
    for row in res["results"]:
        sf = row["surface"]
        for tag, rs, dst in (("r/a", sf["r_over_a"], sf),
                             ("r mm", sf["at_mm"]["r_mm"], sf["at_mm"])):
            if not rs:
                continue
            print("  %-7s %-17s" % ("delta", tag) + "".join("%17g" % x for x in rs), file=file)
            for s_ in ("free", "stuck", "stuck_interp"):
                if "ur_" + s_ not in dst:
                    continue
                q = dst["ur_" + s_]
                err = q.get("error_estimate_total", q["error_estimate"])
                lab = "%s a=%.4f" % (s_.replace("stuck_interp", "stuck_i"),
                                     sf["a_edge_" + s_]["extrapolated"])
                print("  %-7g %-17s" % (row["delta"], lab) + "".join(
                    "%9.5f+-%.0e" % (v, e) for v, e in zip(q["extrapolated"], err)), file=file)


def half_space_surface(r, P, a, nu, E=1.0):
    """Surface (u_r, u_z) of a half-space under the Hertz pressure of total P on radius a,
    u_r > 0 outward, u_z > 0 into the solid (Johnson 1985, eqs. 3.41-3.42).  u_r for r >= a
    is exact for any axisymmetric pressure of total P (Boussinesq's ring loads):
    -(1 - 2 nu)(1 + nu) P / (2 pi E r)."""
    r = np.asarray(r, dtype=float)
    p0 = 1.5 * P / (math.pi * a * a)
    ur = -(1.0 - 2.0 * nu) * (1.0 + nu) * P / (2.0 * math.pi * E * r)
    ur = np.where(r >= a, ur, ur * (1.0 - np.clip(1.0 - r * r / (a * a), 0, 1) ** 1.5))
    x = np.minimum(a / np.maximum(r, 1e-300), 1.0)
    uz_out = (2 * a * a - r * r) * np.arcsin(x) + r * a * np.sqrt(1.0 - x * x)
    uz = (1.0 - nu * nu) / E * p0 / (2.0 * a) * np.where(
        r >= a, uz_out, 0.5 * math.pi * (2 * a * a - r * r))
    return ur, uz


def validation(levels, K, verbose=False):
    out = {}
    t0 = time.time()
    # Hertz, thick layer, frictionless (stuck for information); h = 200, 400, 800 and a
    # quadratic extrapolation in 1/h to the half-space
    R, nu, d = 6.34, 0.3, 0.1
    Es = 1.0 / (1.0 - nu * nu)
    P_hertz = 4.0 / 3.0 * Es * math.sqrt(R) * d ** 1.5
    P_sn, a_sn = sneddon_sphere(R, nu, d)
    rows, cases = [], []
    kf = [0.5, 1.25, 1.5, 2.0, 3.0]  # surface field at r = kf * a_sn (mm)
    for h in (200.0, 400.0, 800.0):
        r = run_case(R, h, nu, [d], levels, K, name="hertz (thick layer h=%g, nu=0.3)" % h,
                     verbose=verbose, check_condensation=(h == 200.0),
                     ur_at=[k * a_sn for k in kf])
        ex = r["results"][0]["extrapolated"]
        sm = r["results"][0]["surface"]["at_mm"]
        rows.append(dict(h=h, a_over_h=a_sn / h, P_frictionless=ex["P_frictionless"]["extrapolated"],
                         P_error_estimate=ex["P_frictionless"]["error_estimate"],
                         a_frictionless_finest=r["results"][0]["per_level"]["a_frictionless"][-1],
                         rel_diff_vs_sneddon_sphere=ex["P_frictionless"]["extrapolated"] / P_sn - 1.0,
                         rel_diff_vs_hertz=ex["P_frictionless"]["extrapolated"] / P_hertz - 1.0,
                         ratio=ex["ratio"]["extrapolated"],
                         ratio_error_estimate=ex["ratio"]["error_estimate_total"],
                         ratio_interpolated_catch=ex["ratio_interp"]["extrapolated"],
                         ur_free=sm["ur_free"]["extrapolated"],
                         ur_free_error_estimate=sm["ur_free"]["error_estimate"],
                         uz_free=sm["uz_free"]["extrapolated"]))
        cases.append(r)
    x = np.array([q["a_over_h"] for q in rows])
    P0 = float(np.polyfit(x, [q["P_frictionless"] for q in rows], 2)[-1])
    rat0 = float(np.polyfit(x, [q["ratio"] for q in rows], 2)[-1])
    rat0i = float(np.polyfit(x, [q["ratio_interpolated_catch"] for q in rows], 2)[-1])
    # surface field vs the half-space (u_r outside: exact for the total P_sn; inside and
    # u_z: Hertz's pressure, information)
    ur_hs, uz_hs = (list(v / d) for v in half_space_surface(np.array(kf) * a_sn, P_sn, a_sn, nu))
    ur0 = np.polyfit(x, [q["ur_free"] for q in rows], 2)[-1]
    uz0 = np.polyfit(x, [q["uz_free"] for q in rows], 2)[-1]
    for q in rows:
        q["ur_rel_diff_vs_half_space"] = [u / v - 1.0 for u, v in zip(q["ur_free"], ur_hs)]
        q["uz_rel_diff_vs_hertz"] = [u / v - 1.0 for u, v in zip(q["uz_free"], uz_hs)]
    chk = [kf.index(1.5), kf.index(2.0)]
    field = dict(
        r_over_a_sneddon=kf, ur_half_space=ur_hs, uz_hertz_pressure=uz_hs,
        ur_half_space_extrapolated=list(ur0), uz_half_space_extrapolated=list(uz0),
        ur_extrapolated_rel_diff=list(ur0 / ur_hs - 1.0),
        uz_extrapolated_rel_diff_info=list(uz0 / uz_hs - 1.0),
        passed=bool(all(abs(rows[0]["ur_rel_diff_vs_half_space"][i]) < 1e-2
                        and abs(ur0[i] / ur_hs[i] - 1.0) < 2e-4 for i in chk)))
    out["hertz"] = dict(
        R=R, nu=nu, delta=d, P_hertz=P_hertz, a_hertz=math.sqrt(R * d),
        P_sneddon_exact_sphere=P_sn, a_sneddon_exact_sphere=a_sn, rows=rows,
        P_half_space_extrapolated=P0, half_space_rel_diff_vs_sneddon_sphere=P0 / P_sn - 1.0,
        half_space_rel_diff_vs_hertz=P0 / P_hertz - 1.0,
        ratio_half_space_extrapolated_info=rat0,
        ratio_half_space_extrapolated_interpolated_catch_info=rat0i,
        surface_field=field, condensation_check=cases[0]["condensation_check"], cases=cases)
    # incompressible thick layer: stuck == frictionless
    r = run_case(6.34, 200.0, 0.5, [0.1], levels, K, name="incompressible thick layer",
                 verbose=verbose)
    ex = r["results"][0]["extrapolated"]
    rat = ex["ratio"]["extrapolated"]
    out["incompressible"] = dict(R=6.34, h=200.0, nu=0.5, delta=0.1, ratio=rat,
                                 ratio_error_estimate=ex["ratio"]["error_estimate_total"],
                                 passed=bool(abs(rat - 1.0) < 5e-3), case=r)
    # flat punch through the incremental stuck path = bonded punch
    r = run_case(0.0, 4.2, 0.49, [1.0], levels, 2, flat=4.75, name="flat punch A=4.75",
                 verbose=verbose)
    ex = r["results"][0]["extrapolated"]
    rat = ex["ratio"]["extrapolated"]
    ref = 1.0893229
    out["flat"] = dict(A=4.75, h=4.2, nu=0.49, ratio=rat,
                       ratio_error_estimate=ex["ratio"]["error_estimate_total"],
                       ratio_levels=ex["ratio"]["levels"],
                       bonded_punch_fe_ratio=ref, rel_diff=rat / ref - 1.0,
                       passed=bool(abs(rat / ref - 1.0) < 2e-3), case=r)
    out["time_s"] = round(time.time() - t0, 2)
    return out


def print_validation(v, file=sys.stdout):
    hz = v["hertz"]
    print("# validation", file=file)
    print("hertz (R=%g, nu=%g, delta=%g, frictionless): Hertz P=%.6g a=%.4f; exact-sphere "
          "half-space (Sneddon) P=%.6g a=%.4f" % (hz["R"], hz["nu"], hz["delta"], hz["P_hertz"],
                                                  hz["a_hertz"], hz["P_sneddon_exact_sphere"],
                                                  hz["a_sneddon_exact_sphere"]), file=file)
    for q in hz["rows"]:
        print("  h=%-5g a/h=%.4f: P_fe=%.6g (+-%.1e)  vs Sneddon %+.2e, vs Hertz %+.2e; a_fe=%.4f;"
              " stuck/free=%.5f (interp. catch %.5f)" % (
                  q["h"], q["a_over_h"], q["P_frictionless"], q["P_error_estimate"],
                  q["rel_diff_vs_sneddon_sphere"], q["rel_diff_vs_hertz"],
                  q["a_frictionless_finest"], q["ratio"], q["ratio_interpolated_catch"]),
              file=file)
    print("  a/h -> 0 (quadratic): P=%.6g  vs Sneddon %+.2e, vs Hertz %+.2e; stuck/free=%.5f "
          "(interp. catch %.5f; information, not checked)" % (
              hz["P_half_space_extrapolated"], hz["half_space_rel_diff_vs_sneddon_sphere"],
              hz["half_space_rel_diff_vs_hertz"], hz["ratio_half_space_extrapolated_info"],
              hz["ratio_half_space_extrapolated_interpolated_catch_info"]), file=file)
    sf = hz["surface_field"]
    print("  surface u_r/delta at r/a_sn = %s: half-space %s" % (
        " ".join("%g" % k for k in sf["r_over_a_sneddon"]),
        " ".join("%.5f" % v for v in sf["ur_half_space"])), file=file)
    for q in hz["rows"]:
        print("    h=%-5g FE %s  rel. diff %s" % (
            q["h"], " ".join("%.5f" % v for v in q["ur_free"]),
            " ".join("%+.1e" % v for v in q["ur_rel_diff_vs_half_space"])), file=file)
    print("    a/h -> 0 %s  rel. diff %s  (r/a 1.5, 2: h=200 < 1e-2, a/h -> 0 < 2e-4: %s;"
          " r/a 0.5 against Hertz's pressure)" % (
              " ".join("%.5f" % v for v in sf["ur_half_space_extrapolated"]),
              " ".join("%+.1e" % v for v in sf["ur_extrapolated_rel_diff"]), sf["passed"]),
          file=file)
    print("    u_z/delta: Hertz pressure %s; FE a/h -> 0 rel. diff %s (information)" % (
        " ".join("%.5f" % v for v in sf["uz_hertz_pressure"]),
        " ".join("%+.1e" % v for v in sf["uz_extrapolated_rel_diff_info"])), file=file)
    print("  condensation check (G vs full sparse solve, rel. max diff of reactions): %s"
          % ", ".join("%s %.1e" % kv for kv in hz["condensation_check"].items()), file=file)
    ic = v["incompressible"]
    print("incompressible (nu=0.5, h=200): stuck/free = %.5f +- %.1e  (|.-1| < 5e-3: %s)" % (
        ic["ratio"], ic["ratio_error_estimate"], ic["passed"]), file=file)
    fl = v["flat"]
    print("flat A=4.75 h=4.2 nu=0.49: stuck/free = %.5f +- %.1e (levels %s) vs bonded_punch_fe "
          "%.5f: %+.2e (< 2e-3: %s)" % (
              fl["ratio"], fl["ratio_error_estimate"],
              " ".join("%.5f" % x for x in fl["ratio_levels"]), fl["bonded_punch_fe_ratio"],
              fl["rel_diff"], fl["passed"]), file=file)


def main(argv=None):
    ap = argparse.ArgumentParser(description=" ".join(__doc__.split("\n\n")[0].split()))
    ap.add_argument("--R", type=float, help="sphere radius (mm)")
    ap.add_argument("--flat", type=float, metavar="A",
                    help="flat face of radius A instead of the sphere (check)")
    ap.add_argument("--h", type=float, help="layer thickness (mm)")
    ap.add_argument("--nu", type=float, default=0.49)
    ap.add_argument("--depths", type=str, help="comma-separated depths (mm)")
    ap.add_argument("--levels", type=int, default=3)
    ap.add_argument("--K", type=int, default=128,
                    help="increments (stuck also at 2K; the K -> 2K change is reported)")
    ap.add_argument("--quick", action="store_true", help="2 levels, K = 16 (smoke test)")
    ap.add_argument("--no-validation", action="store_true")
    ap.add_argument("--out", type=str, help="JSON file (default run: bonded_sphere_fe.json "
                                              "beside this script)")
    ap.add_argument("--ur-at", type=str, metavar="R1,R2,...",
                    help="also report the surface field at these radii (mm)")
    ap.add_argument("--verbose", action="store_true")
    args = ap.parse_args(argv)
    if args.quick:
        args.levels, args.K = 2, 16
    if args.levels < 1 or args.K < 1:
        ap.error("--levels and --K must be >= 1")
    ur_at = [float(x) for x in args.ur_at.split(",")] if args.ur_at else []
    t0 = time.time()
    custom = args.R is not None or args.flat is not None
    if custom:
        if args.h is None:
            ap.error("give --h")
        depths = [float(x) for x in args.depths.split(",")] if args.depths else [1.0]
        res = run_case(args.R or 0.0, args.h, args.nu, depths, args.levels,
                       2 if args.flat is not None and not args.depths else args.K,
                       flat=args.flat, verbose=args.verbose, ur_at=ur_at)
        print_table(res)
        out = res
    else:
        cases = []
        for c in DEFAULT_CASES:
            if args.verbose:
                print("case %s" % c["name"], file=sys.stderr)
            r = run_case(c["R"], c["h"], c["nu"], c["depths"], args.levels, args.K,
                         name=c["name"], verbose=args.verbose, ur_at=ur_at)
            print_table(r)
            sys.stdout.flush()
            cases.append(r)
        out = dict(summary=[case_summary(r) for r in cases], cases=cases)
        if not args.no_validation:
            v = validation(args.levels, args.K, args.verbose)
            print_validation(v)
            out["validation"] = v
        out["total_time_s"] = round(time.time() - t0, 1)
        print("total %.1f s" % out["total_time_s"])
        if args.out is None and not args.quick:
            args.out = os.path.join(os.path.dirname(os.path.abspath(__file__)),
                                    "bonded_sphere_fe.json")
    if args.out:
        with open(args.out, "w") as fh:
            json.dump(out, fh, indent=1)
            fh.write("\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
