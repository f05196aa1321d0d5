#!/usr/bin/env python3
# Tested with: python 3.11, scikit-fem==12.0.2, numpy==2.4.6, scipy==1.17.1
#   (python3 -m pip install --root-user-action=ignore scikit-fem==12.0.2)
"""Rigid flat circular punch on an elastic layer bonded to a rigid base: an axisymmetric
finite-element oracle, independent of gelrig's solver.

gelrig's mechanics uses a Fourier-space surface Green's tensor of the bonded layer; this
script solves the same boundary-value problem in the (r, z) half-plane with finite
elements (scikit-fem), so an error shared by the Green's tensor and its use shows up here.
It shares no code or tables with the Rust side.

Problem
  Layer 0 <= z <= h (z points into the layer, z = 0 is the free surface), 0 <= r <= R_out,
  R_out = a + 15 h.  Linear isotropic elasticity, E = 1 (results are normalised), Poisson
  ratio nu.  A rigid flat-ended punch of radius a is pressed to depth delta = 1 (linear
  problem: every reported quantity is divided by delta).
  Boundary conditions:
    z = h (rigid base, bonded):   u_r = u_z = 0
    r = 0 (axis):                 u_r = 0
    r = R_out (truncation, or with --r-out a finite pad's side):
                                  u_r = 0 (default) or traction free (--outer free);
                                  the kernel decays like exp(-0.739 r/h), the two agree
                                  to < 1e-4 (reported as "truncation_check").
    z = 0, r <= a (punch):        u_z = delta and
                                    frictionless: sigma_rz = 0 (u_r free), or
                                    stuck:        u_r = 0;
    z = 0, r > a:                 traction free.

Formulation
  Mixed Taylor-Hood u-p: continuous P2 displacement (u_r, u_z), continuous P1 pressure
  p = lambda div u (sigma = 2 mu eps + p I), which is free of volumetric locking as nu ->
  1/2.  In cylindrical coordinates with axisymmetry the weak form is, with dV ~ r dr dz
  (the common factor 2 pi is dropped and restored for the force),
      int [ 2 mu eps(u):eps(v) + p div v ] r dr dz = 0
      int [ div u q - p q / lambda ]      r dr dz = 0
  eps = [[du_r/dr, (du_r/dz + du_z/dr)/2], [., du_z/dz]] plus the hoop strain
  eps_tt = u_r/r, and div u = du_r/dr + u_r/r + du_z/dz.  The hoop terms are written
  r-weighted (u_r v_r / r, q u_r), evaluated at interior quadrature points only.
  The saddle-point system is solved directly (SuperLU).

Outputs (per level, and Richardson-extrapolated)
  P = 2 pi * (sum of the consistent nodal reactions R = K x on the punch's u_z dofs)
    = int sigma_zz dA over the punch; kappa = P / (2 E* a delta), E* = E / (1 - nu^2)
    (Hayes et al. 1972 write the same as P = 4 a G delta kappa / (1 - nu)).
    Cross-check: P delta = 2 U with U = pi * x^T K x (the strain energy); for the
    discrete solution this is an identity, so its residual (~1e-12) checks the assembly,
    the reactions and the solve, not the discretisation.
  Surface u_r(r, 0)/delta outside the punch (P2 trace) at r/a = 1.05 ... 3.0; sign:
    u_r > 0 is outward (away from the axis); u_z > 0 is into the layer.
  Stuck punch: q/p = |sigma_rz| / sigma_zz at the surface, at r/a = 0, .25, .5, .75, .9,
    .95 (and 0.98 ... 0.999 near the edge), from the FE stresses (P2 gradient + P1
    pressure) in the surface elements; cross-checked by tractions recovered from the
    reactions (r-weighted P2 boundary mass matrix on the punch, M t = R).  The signed
    ratio is extrapolated, then |.| taken.  Also p(r)/p_mean, p_mean = P / (pi a^2).
  truncation_check: at level 1 the problem is re-solved with the other outer condition
    (u_r = 0 <-> traction free); relative change of kappa and of the u_r values.

Mesh and refinement
  Base mesh, graded toward the punch edge (r, z) = (a, 0); size function
  s(rho) = min(beta rho, c L + gamma rho, hmax), rho = distance to the edge,
  L = min(a, h), beta = 0.25, c = 0.25, gamma = 0.2, hmax = h/4 (MESH_DEFAULTS).
  Within rho <= L/2 it is a structured polar mesh: ceil(pi/beta) = 13 sectors, rings in
  geometric progression (ratio ~1.25) from rho_min = 1e-5 L, a fan of triangles at the
  edge point.  Outside, points on concentric arcs about the edge (spaced s in radius and
  along the arc, clipped to the rectangle) and on the boundary lines, Delaunay-
  triangulated (angles between 13.8 deg, the 13-sector fan at the edge point, and
  < 120 deg).  Level L is the base mesh
  uniformly refined L times (each triangle into 4): the levels are nested and the mesh
  size halves per level.  Because of the geometric grading the edge singularity
  (u ~ rho^(1/2)) costs only O(rho_min), and kappa converges like h^p with observed
  p ~ 3.7 (nominally 4 for the energy of P2/P1).
  Richardson extrapolation from the last three levels f0, f1, f2: observed order
  p = log2((f1 - f0) / (f2 - f1)) when the differences are monotone and p is in
  [0.5, 8], else a nominal order (4 for kappa, 2 for point values);
  f_ext = f2 + (f2 - f1) / (2^p - 1).  error_estimate = max(|f2 - f1|, |f_ext - f2|)
  (the two finest levels' difference, and the finest level's distance to f_ext).
  Default 3 levels: about 9e3, 3.6e4 and 1.4e5 unknowns, ~10 s per punch case.

Also computed (frictionless only), a semi-analytic check independent of the FE: the
Fredholm integral equation of the second kind for a frictionless punch on a bonded layer
(Copson/Sneddon reduction of the dual integral equations, as used by Hayes et al. 1972),
solved by Gauss-Legendre Nystrom; kernel from the bonded-layer surface compliance
  L(t) = (2k sinh 2t - 4t) / (2k cosh 2t + 1 + k^2 + 4t^2),  k = 3 - 4 nu
(u_z(xi) = 2 p(xi) L(xi h) / (E* xi) in Hankel space; L -> 1 half-space, L ~ oedometer
h/M for a thin layer).  With p's Hankel transform written as int_0^a g(t) cos(xi t) dt:
  phi(x) + int_0^1 k(x,y) phi(y) dy = 1,
  k(x,y) = (1/pi) int_0^inf (L(u h/a) - 1) [cos u(x-y) + cos u(x+y)] du,
  kappa = int_0^1 phi dx.
It agrees with the FE kappa to ~1e-7 (summary.kappa_frictionless_fredholm).

Sanity checks (--selftest, and the last entry of --cases default)
  * uniform confined compression (whole top pressed, u_r = 0 at R_out): exact solution
    u = (0, delta (1 - z/h)), P = M delta pi R_out^2 / h, M the oedometric modulus;
    reproduced to ~1e-15 for both contact conditions.
  * half-space limit: kappa at a/h = 0.1, 0.05, 0.025 extrapolated (quadratic) to
    a/h -> 0 gives Sneddon's kappa = 1; the stuck/frictionless ratio extrapolates to
    Mossakovskii's ln(3 - 4 nu) (1 - nu) / (1 - 2 nu) (1.02863 at nu = 0.3).

Usage
  python3 tests/peers/bonded_punch_fe.py --a 4.75 --h 4.2 --nu 0.49 [--levels 3] [--json]
  python3 tests/peers/bonded_punch_fe.py --a 6.25 --h 2.0 --outer free --r-out 11.3
                                        (a finite disc-shaped pad with free sides; only
                                         the surface points on it are reported)
  python3 tests/peers/bonded_punch_fe.py --cases default       (JSON list)
  python3 tests/peers/bonded_punch_fe.py --selftest            (sanity checks)
"""

import argparse
import json
import math
import sys
import time

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

import skfem
from skfem import (Basis, BilinearForm, ElementTriP1, ElementTriP2, ElementVector,
                   FacetBasis, MeshTri, asm)
from skfem.helpers import ddot, sym_grad

R_OUT_FACTOR = 15.0
UR_POINTS = [1.05, 1.1, 1.25, 1.5, 2.0, 3.0]
Q_OVER_P_POINTS = [0.0, 0.25, 0.5, 0.75, 0.9, 0.95]


# ----------------------------------------------------------------------------- mesh
def graded_mesh(a, h, r_out, beta=0.25, rho_min_rel=1e-5, c_near=0.25, gamma=0.2,
                hmax_rel=0.25, rho_in_rel=0.5):
    """Base mesh of [0, r_out] x [0, h] graded toward the punch edge (a, 0).

    Size function s(rho) = min(beta rho, c_near L + gamma rho, hmax_rel h), L = min(a, h),
    rho = distance to the edge.  Inside rho <= rho_in = rho_in_rel L: a structured polar
    mesh (n_theta = ceil(pi / beta) sectors, geometric rings from rho_min = rho_min_rel L,
    a fan of triangles at the edge point).  Outside: points on concentric arcs about the
    edge (spaced s(rho) in radius and along the arc, clipped to the rectangle) and on
    the boundary lines, Delaunay-triangulated (scipy.spatial.Delaunay)."""
    from scipy.spatial import Delaunay

    L = min(a, h)
    rho_min = rho_min_rel * L
    rho_in = rho_in_rel * L
    hmax = hmax_rel * h

    def s_of(rho):
        rho = np.asarray(rho, dtype=float)
        return np.minimum(np.minimum(beta * rho, c_near * L + gamma * rho), hmax)

    # -- inner structured polar mesh about (a, 0)
    nth = int(math.ceil(math.pi / beta))
    K = max(1, int(math.ceil(math.log(rho_in / rho_min) / math.log(1.0 + beta))))
    radii = rho_min * (rho_in / rho_min) ** (np.arange(K + 1) / K)
    th = np.linspace(0.0, math.pi, nth + 1)
    pin = [(a, 0.0)]
    for rk in radii:
        for t in th:
            pin.append((a + rk * math.cos(t), rk * math.sin(t)))
    pin = np.array(pin)
    pin[:, 1] = np.where(np.abs(pin[:, 1]) < 1e-14 * L, 0.0, pin[:, 1])

    def idx(k, j):
        return 1 + k * (nth + 1) + j

    tin = [(0, idx(0, j), idx(0, j + 1)) for j in range(nth)]
    for k in range(K):
        for j in range(nth):
            p00, p01, p10, p11 = idx(k, j), idx(k, j + 1), idx(k + 1, j), idx(k + 1, j + 1)
            # alternate the diagonal so the mesh has no preferred direction
            if (j + k) % 2 == 0:
                tin += [(p00, p10, p11), (p00, p11, p01)]
            else:
                tin += [(p00, p10, p01), (p10, p11, p01)]
    tin = np.array(tin)
    ring = np.array([idx(K, j) for j in range(nth + 1)])

    # -- outer points
    pts = [pin[ring]]
    corners = np.array([(0.0, 0.0), (r_out, 0.0), (0.0, h), (r_out, h)])
    pts.append(corners)
    rho_max = max(math.hypot(a, h), math.hypot(r_out - a, h))
    thf = np.linspace(0.0, math.pi, 40001)
    rho = rho_in + float(s_of(rho_in))
    while rho < rho_max:
        s = float(s_of(rho))
        x = a + rho * np.cos(thf)
        z = rho * np.sin(thf)
        m = 0.5 * s
        ok = (x >= m) & (x <= r_out - m) & (z <= h - m)
        sel = np.nonzero(ok)[0]
        if sel.size:
            brk = np.nonzero(np.diff(sel) > 1)[0]
            starts = np.concatenate([[sel[0]], sel[brk + 1]])
            ends = np.concatenate([sel[brk], [sel[-1]]])
            for i0, i1 in zip(starts, ends):
                t0, t1 = thf[i0], thf[i1]
                arclen = rho * (t1 - t0)
                on_surface = i0 == 0 or i1 == len(thf) - 1
                if arclen < 0.3 * s and not on_surface:
                    continue
                n = max(1, int(math.ceil(arclen / s - 1e-9)))
                tt = np.linspace(t0, t1, n + 1)
                pts.append(np.column_stack([a + rho * np.cos(tt), rho * np.sin(tt)]))
        rho += s

    def line(p0, p1):
        p0 = np.asarray(p0, dtype=float)
        p1 = np.asarray(p1, dtype=float)
        tt = np.linspace(0.0, 1.0, 40001)
        P = p0[:, None] + (p1 - p0)[:, None] * tt
        dens = 1.0 / s_of(np.maximum(np.hypot(P[0] - a, P[1]), rho_in))
        ln = float(np.linalg.norm(p1 - p0))
        cum = np.concatenate([[0.0], np.cumsum(0.5 * (dens[1:] + dens[:-1]) * np.diff(tt) * ln)])
        n = max(1, int(math.ceil(cum[-1])))
        tq = np.interp(np.linspace(0.0, cum[-1], n + 1), cum, tt)[1:-1]
        pts.append(p0[None, :] + (p1 - p0)[None, :] * tq[:, None])

    line((0.0, 0.0), (0.0, h))
    line((0.0, h), (r_out, h))
    line((r_out, 0.0), (r_out, h))
    pout = np.vstack(pts)
    pout[:, 1] = np.where(np.abs(pout[:, 1]) < 1e-14 * h, 0.0, pout[:, 1])
    tri = Delaunay(pout - np.array([a, 0.0]))
    tout = tri.simplices
    nring = len(ring)
    keep = ~np.all(tout < nring, axis=1)  # drop the triangles inside the polar patch
    tout = tout[keep]
    # merge: outer point i < nring is inner ring point ring[i]
    npin = len(pin)
    mapping = np.concatenate([ring, npin + np.arange(len(pout) - nring)])
    P = np.vstack([pin, pout[nring:]])
    T = np.vstack([tin, mapping[tout]])
    d = ((P[T[:, 1], 0] - P[T[:, 0], 0]) * (P[T[:, 2], 1] - P[T[:, 0], 1])
         - (P[T[:, 2], 0] - P[T[:, 0], 0]) * (P[T[:, 1], 1] - P[T[:, 0], 1]))
    T[d < 0] = T[d < 0][:, [0, 2, 1]]
    area = 0.5 * np.abs(d).sum()
    if abs(area / (r_out * h) - 1.0) > 1e-9 or np.min(np.abs(d)) <= 0.0:
        raise RuntimeError("mesh generation failed (area %.12g vs %.12g)" % (area, r_out * h))
    return MeshTri(P.T.copy(), T.T.copy())


# ----------------------------------------------------------------------------- forms
def make_forms(mu, lam):
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
        return p.value * q.value * w.x[0] / lam

    return a_form, b_form, c_form


@BilinearForm
def surface_mass_r(u, v, w):
    return u.value * v.value * w.x[0]


# ----------------------------------------------------------------------------- solver
class Problem:
    """One mesh: assembled once, solved for several contact conditions."""

    def __init__(self, mesh, a, h, nu, E=1.0):
        self.mesh, self.a, self.h, self.nu, self.E = mesh, a, h, nu, E
        self.mu = E / (2.0 * (1.0 + nu))
        self.lam = E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))
        self.r_out = mesh.p[0].max()
        self.ub = Basis(mesh, ElementVector(ElementTriP2()), intorder=5)
        self.pb = self.ub.with_element(ElementTriP1())
        a_form, b_form, c_form = make_forms(self.mu, self.lam)
        A = asm(a_form, self.ub)
        B = asm(b_form, self.ub, self.pb)
        C = asm(c_form, self.pb)
        self.nu_dofs = self.ub.N
        self.K = sp.bmat([[A, B.T], [B, -C]], format="csr")
        self.N = self.K.shape[0]

        ub = self.ub
        self.rdofs = np.concatenate([ub.nodal_dofs[0], ub.facet_dofs[0]])
        self.zdofs = np.concatenate([ub.nodal_dofs[1], ub.facet_dofs[1]])
        self.tol = 1e-9 * max(a, h)
        # surface facets (z = 0) sorted by r
        f = mesh.facets
        fz = mesh.p[1, f]
        surf = np.nonzero((np.abs(fz[0]) < self.tol) & (np.abs(fz[1]) < self.tol))[0]
        fr = mesh.p[0, f[:, surf]]
        swap = fr[0] > fr[1]
        v0 = np.where(swap, f[1, surf], f[0, surf])
        v1 = np.where(swap, f[0, surf], f[1, surf])
        order = np.argsort(mesh.p[0, v0])
        self.surf_facets = surf[order]
        self.surf_v0, self.surf_v1 = v0[order], v1[order]
        self.surf_r0 = mesh.p[0, self.surf_v0]
        self.surf_r1 = mesh.p[0, self.surf_v1]
        assert np.allclose(self.surf_r1[:-1], self.surf_r0[1:])
        assert np.any(np.abs(self.surf_r0 - a) < self.tol), "no vertex at the punch edge"

    def _dof_sel(self, comp, pred):
        d = self.rdofs if comp == 0 else self.zdofs
        x = self.ub.doflocs[:, d]
        return d[pred(x[0], x[1])]

    def solve(self, contact, outer="fixed", top_all=False, delta=1.0):
        """contact: 'frictionless' or 'stuck'.  top_all: punch covers the whole top
        (uniform-compression sanity check)."""
        a, h, tol = self.a, self.h, self.tol
        on_punch = (lambda r, z: np.abs(z) < tol) if top_all else \
            (lambda r, z: (np.abs(z) < tol) & (r <= a + tol))
        fixed = {}
        for c in (0, 1):
            for d in self._dof_sel(c, lambda r, z: np.abs(z - h) < tol):
                fixed[d] = 0.0
        for d in self._dof_sel(0, lambda r, z: np.abs(r) < tol):
            fixed[d] = 0.0
        if outer == "fixed":
            for d in self._dof_sel(0, lambda r, z: np.abs(r - self.r_out) < tol):
                fixed[d] = 0.0
        punch_z = self._dof_sel(1, on_punch)
        for d in punch_z:
            if d in fixed:
                raise RuntimeError("punch dof on the base")
            fixed[d] = delta
        if contact == "stuck":
            for d in self._dof_sel(0, on_punch):
                fixed[d] = 0.0
        elif contact != "frictionless":
            raise ValueError(contact)
        D = np.fromiter(fixed.keys(), dtype=np.int64)
        xD = np.fromiter(fixed.values(), dtype=float)
        x = np.zeros(self.N)
        x[D] = xD
        free = np.ones(self.N, dtype=bool)
        free[D] = False
        I = np.nonzero(free)[0]
        K = self.K
        rhs = -(K[I][:, D] @ xD)
        x[I] = spla.spsolve(K[I][:, I].tocsc(), rhs, permc_spec="COLAMD")
        R = K @ x
        res_free = np.abs(R[I]).max() / max(np.abs(R[D]).max(), 1e-300)
        P = 2.0 * math.pi * R[punch_z].sum()
        U = math.pi * (x @ R)  # pi x^T K x = strain energy (2 pi r dr dz / 2)
        return dict(x=x, R=R, P=P, U=U, delta=delta, res_free=res_free, contact=contact)

    # -- post-processing along z = 0
    def _surface_p2(self, vec, comp, r_query):
        """Evaluate the P2 trace of displacement component comp (or a per-dof array if
        comp is None) at surface points r_query."""
        ub = self.ub
        out = []
        for rq in r_query:
            k = np.searchsorted(self.surf_r1, rq - 1e-14)
            k = min(max(k, 0), len(self.surf_r1) - 1)
            r0, r1 = self.surf_r0[k], self.surf_r1[k]
            f = self.surf_facets[k]
            d0 = ub.nodal_dofs[comp, self.surf_v0[k]]
            d1 = ub.nodal_dofs[comp, self.surf_v1[k]]
            dm = ub.facet_dofs[comp, f]
            s = (rq - r0) / (r1 - r0)
            N0 = (1 - s) * (1 - 2 * s)
            N1 = s * (2 * s - 1)
            Nm = 4 * s * (1 - s)
            out.append(N0 * vec[d0] + N1 * vec[d1] + Nm * vec[dm])
        return np.array(out)

    def surface_ur(self, sol, r_over_a):
        rq = np.asarray(r_over_a) * self.a
        return self._surface_p2(sol["x"], 0, rq) / sol["delta"]

    def punch_tractions(self, sol, r_over_a):
        """Variationally consistent surface tractions under the punch from the reactions:
        M t = R on the punch dofs, M the r-weighted P2 mass matrix of the punch facets.
        Returns (t_r, t_z) = traction exerted by the punch on the layer, t = sigma.n
        with n = -e_z, i.e. t_r = -sigma_rz, t_z = -sigma_zz (> 0 in compression)."""
        mesh, a, tol = self.mesh, self.a, self.tol
        punch_f = self.surf_facets[self.surf_r1 <= a + tol]
        sb = Basis(mesh, ElementTriP2())
        fb = FacetBasis(mesh, ElementTriP2(), facets=punch_f, intorder=6)
        M = asm(surface_mass_r, fb).tocsr()
        sdofs = np.unique(np.concatenate([sb.nodal_dofs[0, mesh.facets[:, punch_f]].ravel(),
                                          sb.facet_dofs[0, punch_f]]))
        Mp = M[sdofs][:, sdofs].tocsc()
        # map scalar dofs -> vector dofs (same vertex / facet)
        nv = mesh.p.shape[1]
        res = []
        for comp in (0, 1):
            vmap = np.empty(sb.N, dtype=np.int64)
            vmap[sb.nodal_dofs[0]] = self.ub.nodal_dofs[comp]
            vmap[sb.facet_dofs[0]] = self.ub.facet_dofs[comp]
            Rp = sol["R"][vmap[sdofs]]
            t = np.zeros(sb.N)
            t[sdofs] = spla.spsolve(Mp, Rp)
            # evaluate the scalar P2 trace on the surface
            tv = np.zeros(self.ub.N)
            tv[vmap] = t
            res.append(self._surface_p2(tv, comp, np.asarray(r_over_a) * a))
        return res[0], res[1]


    def surface_stress(self, sol, r_over_a):
        """sigma_zz and sigma_rz at surface points z = 0 evaluated directly from the
        FE fields (P2 displacement gradient, P1 pressure) in the element adjacent to
        the surface."""
        mesh, ub = self.mesh, self.ub
        mapping = mesh._mapping() if hasattr(mesh, "_mapping") else mesh.mapping()
        x = sol["x"]
        xu, xp = x[:ub.N], x[ub.N:]
        szz, srz = [], []
        for rq in np.asarray(r_over_a, dtype=float) * self.a:
            k = np.searchsorted(self.surf_r1, rq - 1e-14)
            k = min(max(k, 0), len(self.surf_r1) - 1)
            t = int(mesh.f2t[0, self.surf_facets[k]])
            X = mapping.invF(np.array([[[rq]], [[0.0]]]), tind=np.array([t]))
            quad = (X[:, 0, :], np.ones(1))
            bu = Basis(mesh, ElementVector(ElementTriP2()), elements=np.array([t]),
                       quadrature=quad)
            bp = Basis(mesh, ElementTriP1(), elements=np.array([t]), quadrature=quad)
            gu = bu.interpolate(xu).grad
            pv = bp.interpolate(xp).value
            szz.append(float(2.0 * self.mu * gu[1, 1].ravel()[0] + pv.ravel()[0]))
            srz.append(float(self.mu * (gu[0, 1].ravel()[0] + gu[1, 0].ravel()[0])))
        return np.array(szz), np.array(srz)


def kappa_of(P, a, nu, E=1.0, delta=1.0):
    Estar = E / (1.0 - nu * nu)
    return P / (2.0 * Estar * a * delta)


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


# ----------------------------------------------------------------------------- semi-analytic
def bonded_layer_L(t, nu):
    k = 3.0 - 4.0 * nu
    t = np.asarray(t, dtype=float)
    out = np.ones_like(t)
    small = t < 20.0
    ts = t[small]
    num = 2 * k * np.sinh(2 * ts) - 4 * ts
    den = 2 * k * np.cosh(2 * ts) + 1 + k * k + 4 * ts * ts
    out[small] = num / den
    big = ~small  # 1 - L ~ (k^2 + 1 + 4t^2 + 4t... ) e^{-2t}/k: negligible but keep exact form
    tb = t[big]
    e = np.exp(-2 * tb)
    out[big] = (k * (1 - e * e) - 4 * tb * e) / (k * (1 + e * e) + (1 + k * k + 4 * tb * tb) * e)
    return out


def fredholm_kappa(a_over_h, nu, n=64, nu_quad=4000):
    """Frictionless flat punch on a bonded layer: phi(x) + int_0^1 k(x,y) phi(y) dy = 1,
    k(x,y) = (1/pi) int_0^inf (L(u h/a) - 1) [cos u(x-y) + cos u(x+y)] du, kappa = int phi."""
    hr = 1.0 / a_over_h  # h / a
    # u-integral: (L - 1) decays like exp(-2 u h/a); integrate to u h/a = 40
    umax = 40.0 / hr
    # Gauss-Legendre on panels
    npan = 200
    gx, gw = np.polynomial.legendre.leggauss(20)
    edges = np.linspace(0.0, umax, npan + 1)
    uu = (0.5 * (edges[1:] - edges[:-1])[:, None] * (gx[None, :] + 1) + edges[:-1, None]).ravel()
    ww = (0.5 * (edges[1:] - edges[:-1])[:, None] * gw[None, :]).ravel()
    g = (bonded_layer_L(uu * hr, nu) - 1.0) * ww
    xg, wg = np.polynomial.legendre.leggauss(n)
    x = 0.5 * (xg + 1)
    w = 0.5 * wg
    def Kint(s):
        return (np.cos(np.outer(s, uu)) @ g) / math.pi
    dif = (x[:, None] - x[None, :]).ravel()
    sm = (x[:, None] + x[None, :]).ravel()
    kmat = (Kint(dif) + Kint(sm)).reshape(n, n)
    A = np.eye(n) + kmat * w[None, :]
    phi = np.linalg.solve(A, np.ones(n))
    return float(phi @ w)


# ----------------------------------------------------------------------------- mesh quality
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
    e = [np.linalg.norm(P[(i + 1) % 3] - P[i], axis=0) for i in range(3)]
    return dict(n_triangles=int(t.shape[1]), min_angle_deg=float(angs.min()),
                max_angle_deg=float(angs.max()), min_edge=float(np.min(e)),
                max_edge=float(np.max(e)))


# ----------------------------------------------------------------------------- driver
Q_NEAR_EDGE_POINTS = [0.98, 0.99, 0.995, 0.999]
MESH_DEFAULTS = dict(beta=0.25, rho_min_rel=1e-5, c_near=0.25, gamma=0.2, hmax_rel=0.25,
                     rho_in_rel=0.5)


def _f(x):
    return [float(v) for v in np.ravel(x)]


def _rich_list(per_level, nominal_p):
    arr = np.array(per_level, dtype=float)  # (levels, npoints)
    out = []
    for j in range(arr.shape[1]):
        rj = richardson(arr[:, j], nominal_p)
        out.append(rj)
    return dict(extrapolated=[o["extrapolated"] for o in out],
                error_estimate=[o["error_estimate"] for o in out],
                order=[o["order"] for o in out])


def run_case(a, h, nu, levels=3, contacts=("frictionless", "stuck"), outer="fixed",
             truncation_check=True, kind="punch", mesh_kw=None, verbose=False, r_out=None):
    t_start = time.time()
    E = 1.0
    r_out = a + R_OUT_FACTOR * h if r_out is None else r_out
    # A finite pad: only the surface points on it.
    ur_points = [x for x in UR_POINTS if x * a < r_out]
    mk = dict(MESH_DEFAULTS)
    mk.update(mesh_kw or {})
    base = graded_mesh(a, h, r_out, **mk)
    per_level = []
    trunc = None
    for L in range(levels):
        t0 = time.time()
        mesh = base.refined(L) if L else base
        pr = Problem(mesh, a, h, nu, E)
        rec = dict(level=L, n_triangles=int(mesh.t.shape[1]), n_dofs=int(pr.N),
                   min_edge_over_a=float(mesh_quality(mesh)["min_edge"] / a))
        sols = {}
        for c in contacts:
            s = pr.solve(c, outer=outer)
            sols[c] = s
            d = dict(kappa=kappa_of(s["P"], a, nu, E), P=float(s["P"]),
                     energy_identity_residual=float(s["P"] * s["delta"] / (2.0 * s["U"]) - 1.0),
                     free_residual=float(s["res_free"]),
                     ur_over_delta=_f(pr.surface_ur(s, ur_points)))
            if c == "stuck":
                pts = Q_OVER_P_POINTS + Q_NEAR_EDGE_POINTS
                szz, srz = pr.surface_stress(s, pts)
                tr, tz = pr.punch_tractions(s, pts)
                pmean = s["P"] / (math.pi * a * a)
                n = len(Q_OVER_P_POINTS)
                d["q_over_p"] = _f(np.abs(srz[:n]) / -szz[:n])
                d["q_over_p_signed"] = _f(srz[:n] / szz[:n])
                d["q_over_p_near_edge"] = _f(np.abs(srz[n:]) / -szz[n:])
                d["q_over_p_near_edge_signed"] = _f(srz[n:] / szz[n:])
                d["q_over_p_from_reactions"] = _f(np.abs(tr[:n]) / tz[:n])
                d["p_over_pmean"] = _f(-szz[:n] / pmean)
            rec[c] = d
        if "frictionless" in sols and "stuck" in sols:
            rec["kappa_ratio_stuck_over_frictionless"] = rec["stuck"]["kappa"] / rec["frictionless"]["kappa"]
            rec["ur_ratio_stuck_over_frictionless"] = _f(
                np.array(rec["stuck"]["ur_over_delta"]) / np.array(rec["frictionless"]["ur_over_delta"]))
        if truncation_check and L == max(0, levels - 2):
            other = "free" if outer == "fixed" else "fixed"
            trunc = dict(level=L, compared=[outer, other])
            for c in contacts:
                s2 = pr.solve(c, outer=other)
                k2 = kappa_of(s2["P"], a, nu, E)
                ur2 = pr.surface_ur(s2, ur_points)
                trunc[c] = dict(
                    kappa_rel_diff=float(k2 / rec[c]["kappa"] - 1.0),
                    ur_max_abs_diff=float(np.max(np.abs(ur2 - np.array(rec[c]["ur_over_delta"])))))
        rec["time_s"] = round(time.time() - t0, 3)
        per_level.append(rec)
        if verbose:
            print("  level %d: %d dofs, %.1f s" % (L, pr.N, rec["time_s"]), file=sys.stderr)

    res = dict(kind=kind, scikit_fem_version=skfem.__version__, a_mm=a, h_mm=h, a_over_h=a / h, nu=nu, E=E, delta=1.0,
               R_out_mm=r_out, outer_bc=("u_r=0" if outer == "fixed" else "traction free"),
               contacts=list(contacts), ur_points_r_over_a=ur_points,
               q_over_p_points_r_over_a=Q_OVER_P_POINTS,
               q_over_p_near_edge_points_r_over_a=Q_NEAR_EDGE_POINTS)
    ext = {}
    for c in contacts:
        ext["kappa_" + c] = richardson([r[c]["kappa"] for r in per_level], 4.0)
        ext["ur_over_delta_" + c] = _rich_list([r[c]["ur_over_delta"] for r in per_level], 2.0)
    if "frictionless" in contacts and "stuck" in contacts:
        ext["kappa_ratio_stuck_over_frictionless"] = richardson(
            [r["kappa_ratio_stuck_over_frictionless"] for r in per_level], 4.0)
        ext["ur_ratio_stuck_over_frictionless"] = _rich_list(
            [r["ur_ratio_stuck_over_frictionless"] for r in per_level], 2.0)
    if "stuck" in contacts:
        # |q|/p: extrapolate the signed ratio sigma_rz/sigma_zz, then take |.|
        for key in ("q_over_p_signed", "q_over_p_near_edge_signed", "p_over_pmean"):
            ext[key + "_stuck"] = _rich_list([r["stuck"][key] for r in per_level], 2.0)
        for key in ("q_over_p", "q_over_p_near_edge"):
            e = dict(ext[key + "_signed_stuck"])
            e["extrapolated"] = [abs(v) for v in e["extrapolated"]]
            ext[key + "_stuck"] = e
    res["extrapolated"] = ext
    summary = {}
    for c in contacts:
        e = ext["kappa_" + c]
        summary["kappa_" + c] = e["extrapolated"]
        summary["kappa_" + c + "_error_estimate"] = e["error_estimate"]
        summary["kappa_" + c + "_rel_error_estimate"] = e["error_estimate"] / e["extrapolated"]
        summary["ur_over_delta_" + c] = ext["ur_over_delta_" + c]["extrapolated"]
    if "kappa_ratio_stuck_over_frictionless" in ext:
        e = ext["kappa_ratio_stuck_over_frictionless"]
        summary["kappa_ratio_stuck_over_frictionless"] = e["extrapolated"]
        summary["kappa_ratio_error_estimate"] = e["error_estimate"]
        summary["ur_ratio_stuck_over_frictionless"] = ext["ur_ratio_stuck_over_frictionless"]["extrapolated"]
    if "stuck" in contacts:
        q = ext["q_over_p_stuck"]["extrapolated"]
        summary["q_over_p_stuck"] = q
        summary["q_over_p_stuck_near_edge"] = ext["q_over_p_near_edge_stuck"]["extrapolated"]
        summary["full_stick_with_mu_0.6_at_listed_points"] = bool(max(q) < 0.6)
    if "frictionless" in contacts:
        kf = fredholm_kappa(a / h, nu)
        summary["kappa_frictionless_fredholm"] = kf
        summary["kappa_frictionless_fe_minus_fredholm_rel"] = ext["kappa_frictionless"]["extrapolated"] / kf - 1.0
    res["summary"] = summary
    res["truncation_check"] = trunc
    res["levels"] = per_level
    res["time_s"] = round(time.time() - t_start, 2)
    return res


# ----------------------------------------------------------------------------- sanity checks
def sanity_checks(verbose=False):
    out = dict(kind="sanity")
    t0 = time.time()
    # 1. uniform confined compression: u_r = 0, u_z = delta (1 - z/h) is exact for either
    #    contact condition when the whole top is pressed and u_r = 0 on r = R_out.
    a, h, nu = 4.75, 4.2, 0.49
    m = graded_mesh(a, h, a + R_OUT_FACTOR * h, **MESH_DEFAULTS)
    pr = Problem(m, a, h, nu)
    Mod = (1 - nu) / ((1 + nu) * (1 - 2 * nu))  # oedometric modulus, E = 1
    Pex = Mod / h * math.pi * pr.r_out ** 2
    uc = {}
    for c in ("frictionless", "stuck"):
        s = pr.solve(c, top_all=True)
        uc[c] = float(s["P"] / Pex - 1.0)
    out["uniform_compression_force_rel_error"] = uc
    # 2. thick layer -> half-space: kappa -> 1 (Sneddon) and, for the stuck punch,
    #    kappa_stuck / kappa_frictionless -> ln(3 - 4 nu) (1 - nu) / (1 - 2 nu)
    #    (Mossakovskii / Spence, bonded flat punch on a half-space).
    thick = []
    for nu in (0.3, 0.49):
        rows = []
        for ah in (0.1, 0.05, 0.025):
            r = run_case(1.0, 1.0 / ah, nu, levels=3, truncation_check=False, kind="thick")
            rows.append(dict(a_over_h=ah, kappa_frictionless=r["summary"]["kappa_frictionless"],
                             kappa_frictionless_fredholm=r["summary"]["kappa_frictionless_fredholm"],
                             kappa_stuck=r["summary"]["kappa_stuck"],
                             ratio=r["summary"]["kappa_ratio_stuck_over_frictionless"]))
        x = np.array([q["a_over_h"] for q in rows])
        kf = np.polyfit(x, [q["kappa_frictionless"] for q in rows], 2)[-1]
        rt = np.polyfit(x, [q["ratio"] for q in rows], 2)[-1]
        exact_ratio = math.log(3 - 4 * nu) * (1 - nu) / (1 - 2 * nu)
        thick.append(dict(nu=nu, rows=rows, kappa_frictionless_at_a_over_h_0=float(kf),
                          sneddon=1.0, ratio_at_a_over_h_0=float(rt),
                          mossakovskii_ratio=exact_ratio,
                          ratio_rel_diff=float(rt / exact_ratio - 1.0)))
    out["half_space_limit"] = thick
    out["time_s"] = round(time.time() - t0, 2)
    return out


DEFAULT_CASES = [(4.75, 4.2), (6.34, 4.2), (6.25, 2.0)]
VALIDATION = [(ah, nu) for nu in (0.49, 0.3) for ah in (0.5, 1.0, 2.0)]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--a", type=float, help="punch radius (mm)")
    ap.add_argument("--h", type=float, help="layer thickness (mm)")
    ap.add_argument("--nu", type=float, default=0.49)
    ap.add_argument("--levels", type=int, default=3)
    ap.add_argument("--outer", choices=["fixed", "free"], default="fixed",
                    help="condition on r = R_out: u_r = 0 (fixed) or traction free")
    ap.add_argument("--r-out", type=float,
                    help="outer radius of the layer, mm (default a + 15 h: an infinite "
                         "layer); with --outer free, a finite disc-shaped pad")
    ap.add_argument("--frictionless-only", action="store_true")
    ap.add_argument("--json", action="store_true", help="(output is always JSON)")
    ap.add_argument("--cases", choices=["default"])
    ap.add_argument("--selftest", action="store_true")
    ap.add_argument("--verbose", action="store_true")
    args = ap.parse_args(argv)
    if args.levels < 1:
        ap.error("--levels must be >= 1")
    if args.selftest:
        print(json.dumps(sanity_checks(args.verbose), indent=1))
        return 0
    if args.cases == "default":
        out = []
        for a, h in DEFAULT_CASES:
            if args.verbose:
                print("case a=%g h=%g" % (a, h), file=sys.stderr)
            out.append(run_case(a, h, args.nu, args.levels, outer=args.outer, verbose=args.verbose))
        for ah, nu in VALIDATION:
            if args.verbose:
                print("validation a/h=%g nu=%g" % (ah, nu), file=sys.stderr)
            out.append(run_case(1.0, 1.0 / ah, nu, args.levels, contacts=("frictionless",),
                                outer=args.outer, kind="validation", verbose=args.verbose))
        if args.verbose:
            print("sanity checks", file=sys.stderr)
        out.append(sanity_checks(args.verbose))
        print(json.dumps(out, indent=1))
        return 0
    if args.a is None or args.h is None:
        ap.error("give --a and --h, or --cases default, or --selftest")
    contacts = ("frictionless",) if args.frictionless_only else ("frictionless", "stuck")
    if args.r_out is not None and args.r_out <= args.a + 0.5 * args.h:
        ap.error("--r-out must exceed the punch radius by at least half the thickness")
    print(json.dumps(run_case(args.a, args.h, args.nu, args.levels, contacts=contacts,
                              outer=args.outer, verbose=args.verbose, r_out=args.r_out),
                     indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
