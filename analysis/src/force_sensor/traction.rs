//! The inverse traction map: the surface traction (tangential and normal, per cell of the
//! contact) that explains the markers' measured in-plane displacement through the bonded
//! layer's Green's tensor ([`mechanics::operator::LayerOperator`]), with Tikhonov
//! regularisation chosen by generalised cross-validation. Force and torque are its
//! integrals; the map itself is the picture inverse-FEM methods show.
//!
//! In-plane markers see the normal traction only through the layer's normal–tangential
//! coupling Ĉ(k), which vanishes at k = 0 (see [`super`]); on its own the problem cannot
//! tell a pressure from a radial shear with the same field. Confining the traction to the
//! contact (a disc around the image's contact region) is what separates them: the shear that
//! would mimic a pressure is not local. The layer is solved at a nominal μ = 1 MPa; a real
//! gel's modulus is unknown, so the integrals are scaled to the force sensor at calibration.

use mechanics::operator::{Compliance, Grid, LayerOperator};
use nalgebra::{DMatrix, DVector};

/// How elongated a contact region is, from its second moments (xx, yy, xy) about its
/// centroid: 1 − λ₂/λ₁ of their matrix's eigenvalues — 0 for a disc (or any contact as wide
/// as it is long), 0.75 for an ellipse of axes 2:1, towards 1 for a strip. Scale-free and
/// unchanged by turns, so a symmetric fit may give it to the normal force. A degenerate
/// region (no extent) is round.
pub fn elongation(second_moments: [f64; 3]) -> f64 {
    let (major, minor, _) = moment_axes(second_moments);
    if !(major.is_finite() && major > 0.0) {
        return 0.0;
    }
    ((major - minor) / major).clamp(0.0, 1.0)
}

/// The principal second moments (λ₁ ≥ λ₂) of a region's central moments [σxx, σyy, σxy]
/// and the angle of the major axis from x, rad: the symmetric 2 × 2 eigenproblem in closed
/// form, shared by the elongation, the map's support and the envelope's ellipse.
pub fn moment_axes(second_moments: [f64; 3]) -> (f64, f64, f64) {
    let [sxx, syy, sxy] = second_moments;
    let mean = 0.5 * (sxx + syy);
    let diff = (0.25 * (sxx - syy) * (sxx - syy) + sxy * sxy).sqrt();
    (mean + diff, mean - diff, 0.5 * (2.0 * sxy).atan2(sxx - syy))
}

/// A contact at least this elongated ([`elongation`]; axes 1.4:1 or longer) is a strip
/// for the calibration: the elongation term is fitted only where such contacts are among the
/// frames ([`ELONGATED_SHARE`]).
pub const ELONGATED: f64 = 0.5;

/// The share of a fit's frames with a contact that must be [`ELONGATED`] for the elongation
/// term to be fitted: with fewer, it has nothing to be fitted on but noise.
pub const ELONGATED_SHARE: f64 = 0.05;

/// Nominal shear modulus the kernels are computed at, MPa.
pub const NOMINAL_MU_MPA: f64 = 1.0;

/// Displacement of the layer's surface under a unit traction on one kernel cell, for each
/// traction component (x, y, z) and displacement component (x, y), sampled around it.
#[derive(Debug, Clone)]
pub struct TractionKernel {
    grid: Grid,
    /// [traction component][displacement component] → field on `grid`, mm per MPa.
    fields: [[Vec<f64>; 2]; 3],
}

impl TractionKernel {
    /// Kernels of a layer `h_mm` thick (ν = ½, incompressible silicone) on cells of
    /// `dx_mm`, covering offsets up to `reach_mm` (the view's diagonal).
    pub fn new(h_mm: f64, dx_mm: f64, reach_mm: f64) -> Self {
        let n = mechanics::operator::fast_size(
            ((2.0 * reach_mm + 12.0 * h_mm) / dx_mm).ceil() as usize
        );
        let n = n + n % 2;
        let grid = Grid { n, dx: dx_mm };
        let op = LayerOperator::new(grid, h_mm, NOMINAL_MU_MPA, 0.5);
        let len = grid.len();
        let centre = (n / 2) * n + n / 2;
        let field = |comp: usize| {
            let mut t = [vec![0.0; len], vec![0.0; len], vec![0.0; len]];
            t[comp][centre] = 1.0;
            let [ux, uy, _] = op.full(&t[0], &t[1], &t[2]);
            [ux, uy]
        };
        Self {
            grid,
            fields: [field(0), field(1), field(2)],
        }
    }

    /// Displacement component `d` at offset (x, y) mm from a cell carrying traction `t` of
    /// component `c` (1 MPa over a kernel cell).
    fn at(&self, c: usize, d: usize, x: f64, y: f64) -> f64 {
        // The loaded cell's centre is half a cell off the grid's origin.
        let h = 0.5 * self.grid.dx;
        self.grid.sample(&self.fields[c][d], x + h, y + h)
    }
}

/// A solved traction map.
#[derive(Debug, Clone, PartialEq)]
pub struct TractionMap {
    /// Cell centres, mm.
    pub cells_mm: Vec<[f64; 2]>,
    /// Cell side, mm.
    pub cell_mm: f64,
    /// Traction per cell (x, y tangential; z normal, compressive positive), MPa at the
    /// nominal modulus.
    pub traction: Vec<[f64; 3]>,
    /// Regularisation used.
    pub lambda: f64,
    /// Integrals at the nominal modulus: Fx, Fy, Fz (N) and Tz about the origin (N·mm).
    pub wrench: [f64; 4],
    /// RMS misfit of the displacement, mm.
    pub misfit_mm: f64,
}

/// Cells of side `cell_mm` inside the disc of `radius_mm` about `centre_mm`.
pub fn disc_cells(centre_mm: [f64; 2], radius_mm: f64, cell_mm: f64) -> Vec<[f64; 2]> {
    if !(radius_mm.is_finite() && cell_mm.is_finite() && cell_mm > 0.0) {
        return Vec::new();
    }
    let k = (radius_mm / cell_mm).ceil() as i64;
    let mut out = Vec::new();
    for j in -k..=k {
        for i in -k..=k {
            let (x, y) = (i as f64 * cell_mm, j as f64 * cell_mm);
            if x * x + y * y <= radius_mm * radius_mm {
                out.push([centre_mm[0] + x, centre_mm[1] + y]);
            }
        }
    }
    out
}

/// Cells of side `cell_mm` inside `support` times the moment-equivalent ellipse of a
/// region centred at `centre_mm` with central second moments `moments_mm2` ([σxx, σyy,
/// σxy], mm²): the points p with (p − c)ᵀ Σ⁻¹ (p − c) ≤ 4·support². For a disc of radius a
/// (moments a²/4, a²/4, 0) this is [`disc_cells`] of `support`·a; an elongated contact keeps
/// its length, and where it runs out of the view the support runs on past the view's edge.
/// A degenerate ellipse (a line) keeps a semi-axis of at least `min_semi_mm`.
pub fn ellipse_cells(
    centre_mm: [f64; 2],
    moments_mm2: [f64; 3],
    support: f64,
    min_semi_mm: f64,
    cell_mm: f64,
) -> Vec<[f64; 2]> {
    let [sxx, syy, sxy] = moments_mm2;
    if !([sxx, syy, sxy, support, min_semi_mm, cell_mm]
        .iter()
        .all(|v| v.is_finite())
        && cell_mm > 0.0)
    {
        return Vec::new();
    }
    let (l1, l2, angle) = moment_axes([sxx, syy, sxy]);
    let floor = (0.5 * min_semi_mm / support.max(1e-9)).powi(2);
    let (l1, l2) = (l1.max(floor), l2.max(floor));
    let (c, s) = (angle.cos(), angle.sin());
    let (a1, a2) = (2.0 * support * l1.sqrt(), 2.0 * support * l2.sqrt());
    let k = (a1.max(a2) / cell_mm).ceil() as i64;
    let mut out = Vec::new();
    for j in -k..=k {
        for i in -k..=k {
            let (x, y) = (i as f64 * cell_mm, j as f64 * cell_mm);
            let (u, v) = (c * x + s * y, -s * x + c * y);
            if (u / a1).powi(2) + (v / a2).powi(2) <= 1.0 {
                out.push([centre_mm[0] + x, centre_mm[1] + y]);
            }
        }
    }
    out
}

/// Points of the λ grid (relative to the largest squared singular value).
const LAMBDA_GRID: usize = 40;

/// Solves for the traction on `cells_mm` (side `cell_mm`) that explains displacements
/// `u_mm` at markers `markers_mm`; `lambda` fixed, or chosen by GCV when `None`.
pub fn solve(
    kernel: &TractionKernel,
    markers_mm: &[[f64; 2]],
    u_mm: &[[f64; 2]],
    cells_mm: &[[f64; 2]],
    cell_mm: f64,
    lambda: Option<f64>,
) -> Option<TractionMap> {
    let (m, c) = (markers_mm.len(), cells_mm.len());
    if m < 3 || c == 0 || u_mm.len() != m {
        return None;
    }
    let scale = cell_mm * cell_mm / (kernel.grid.dx * kernel.grid.dx);
    let a = DMatrix::from_fn(2 * m, 3 * c, |row, col| {
        let (k, d) = (row % m, row / m);
        let (j, comp) = (col % c, col / c);
        let p = markers_mm[k];
        let q = cells_mm[j];
        kernel.at(comp, d, p[0] - q[0], p[1] - q[1]) * scale
    });
    let b = DVector::from_fn(2 * m, |row, _| u_mm[row % m][row / m]);
    let x = match lambda {
        Some(l) => {
            let mut g = a.transpose() * &a;
            for i in 0..3 * c {
                g[(i, i)] += l;
            }
            let rhs = a.transpose() * &b;
            g.cholesky()?.solve(&rhs)
        }
        None => {
            // Bounded and only on finite input: nalgebra's plain `svd` may never return.
            if !a.iter().all(|v| v.is_finite()) {
                return None;
            }
            let svd = a.clone().try_svd(true, true, f64::EPSILON, 1000)?;
            let (u, vt) = (svd.u.as_ref()?, svd.v_t.as_ref()?);
            let s = &svd.singular_values;
            let utb = u.transpose() * &b;
            let rest = (b.norm_squared() - utb.norm_squared()).max(0.0);
            let smax2 = s.iter().fold(0.0f64, |acc, v| acc.max(v * v)).max(1e-300);
            let n = (2 * m) as f64;
            let mut best = (f64::INFINITY, smax2);
            for i in 0..LAMBDA_GRID {
                let l = smax2 * 10f64.powf(-10.0 + 10.0 * i as f64 / (LAMBDA_GRID - 1) as f64);
                let (mut r, mut dof) = (rest, 0.0);
                for (k, sk) in s.iter().enumerate() {
                    let phi = sk * sk / (sk * sk + l);
                    r += ((1.0 - phi) * utb[k]).powi(2);
                    dof += phi;
                }
                let g = n * r / (n - dof).max(1e-9).powi(2);
                if g < best.0 {
                    best = (g, l);
                }
            }
            let l = best.1;
            let mut x = DVector::zeros(3 * c);
            for (k, sk) in s.iter().enumerate() {
                x += vt.row(k).transpose() * (sk / (sk * sk + l) * utb[k]);
            }
            return Some(finish(&a, &b, x, cells_mm, cell_mm, l));
        }
    };
    Some(finish(&a, &b, x, cells_mm, cell_mm, lambda.unwrap_or(0.0)))
}

fn finish(
    a: &DMatrix<f64>,
    b: &DVector<f64>,
    x: DVector<f64>,
    cells_mm: &[[f64; 2]],
    cell_mm: f64,
    lambda: f64,
) -> TractionMap {
    let c = cells_mm.len();
    let area = cell_mm * cell_mm;
    let traction: Vec<[f64; 3]> = (0..c).map(|j| [x[j], x[c + j], x[2 * c + j]]).collect();
    let mut w = [0.0; 4];
    for (t, p) in traction.iter().zip(cells_mm) {
        w[0] += t[0] * area;
        w[1] += t[1] * area;
        w[2] += t[2] * area;
        w[3] += (p[0] * t[1] - p[1] * t[0]) * area;
    }
    let r = a * &x - b;
    TractionMap {
        cells_mm: cells_mm.to_vec(),
        cell_mm,
        traction,
        lambda,
        wrench: w,
        misfit_mm: (r.norm_squared() / b.len().max(1) as f64).sqrt(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A disc is round, a 2:1 ellipse 0.75 at any angle, a 20 × 4 mm strip 0.96; nothing is
    /// round for an empty region rather than NaN.
    #[test]
    fn elongation_is_the_moments_eigenvalue_ratio() {
        assert_eq!(elongation([3.0, 3.0, 0.0]), 0.0);
        for deg in [0.0f64, 30.0, 90.0, 135.0] {
            let (c, s) = (deg.to_radians().cos(), deg.to_radians().sin());
            let (l1, l2) = (4.0, 1.0);
            let m = [
                l1 * c * c + l2 * s * s,
                l1 * s * s + l2 * c * c,
                (l1 - l2) * s * c,
            ];
            assert!(
                (elongation(m) - 0.75).abs() < 1e-12,
                "{deg}°: {}",
                elongation(m)
            );
        }
        assert!((elongation([400.0 / 12.0, 16.0 / 12.0, 0.0]) - 0.96).abs() < 1e-12);
        assert_eq!(elongation([0.0, 0.0, 0.0]), 0.0);
        assert_eq!(elongation([f64::NAN, 1.0, 0.0]), 0.0);
    }

    /// A disc's moments give the disc's cells; an ellipse along a turned axis keeps its
    /// length and width.
    #[test]
    fn the_support_follows_the_regions_shape() {
        let a: f64 = 4.3;
        let disc = ellipse_cells([0.5, -1.0], [a * a / 4.0, a * a / 4.0, 0.0], 1.2, 0.1, 1.0);
        assert_eq!(disc, disc_cells([0.5, -1.0], 1.2 * a, 1.0));
        // A 20 × 4 mm strip's moments (w²/12, h²/12) turned by 30°: its ellipse reaches
        // 2·√(400/12) = 11.5 mm along the strip and 2.3 mm across.
        let (t, l1, l2) = (30f64.to_radians(), 400.0 / 12.0, 16.0 / 12.0);
        let (c, s) = (t.cos(), t.sin());
        let m = [
            l1 * c * c + l2 * s * s,
            l1 * s * s + l2 * c * c,
            (l1 - l2) * s * c,
        ];
        let cells = ellipse_cells([0.0, 0.0], m, 1.0, 0.1, 0.25);
        let along = |p: &[f64; 2]| c * p[0] + s * p[1];
        let across = |p: &[f64; 2]| -s * p[0] + c * p[1];
        let reach = cells.iter().map(along).fold(0.0f64, f64::max);
        let width = cells.iter().map(across).fold(0.0f64, f64::max);
        assert!((reach - 11.55).abs() < 0.3, "{reach}");
        assert!((width - 2.31).abs() < 0.3, "{width}");
        // A line keeps the least semi-axis across.
        let line = ellipse_cells([0.0, 0.0], [10.0, 0.0, 0.0], 1.0, 2.0, 0.25);
        let width = line.iter().map(|p| p[1].abs()).fold(0.0f64, f64::max);
        assert!((1.75..=2.0).contains(&width), "{width}");
    }

    /// A pressure patch and a shear patch on the layer, seen at scattered markers: the map
    /// recovers the force and torque of the load it was made from.
    #[test]
    fn the_map_recovers_the_load_that_made_the_field() {
        let h = 2.0;
        let kernel = TractionKernel::new(h, 0.25, 16.0);
        // The forward field: traction on 1 mm cells of a 3 mm disc, seen at a 0.8 mm grid.
        let cells = disc_cells([0.4, -0.3], 3.0, 1.0);
        let load: Vec<[f64; 3]> = cells
            .iter()
            .map(|p| {
                [
                    0.02 + 0.004 * p[1],
                    -0.01,
                    0.05 * (1.0 - (p[0] * p[0] + p[1] * p[1]) / 16.0),
                ]
            })
            .collect();
        let markers: Vec<[f64; 2]> = (0..400)
            .map(|k| [(k % 20) as f64 * 0.8 - 7.6, (k / 20) as f64 * 0.8 - 7.6])
            .collect();
        let u: Vec<[f64; 2]> = markers
            .iter()
            .map(|p| {
                let mut u = [0.0; 2];
                for (q, t) in cells.iter().zip(&load) {
                    for (comp, tc) in t.iter().enumerate() {
                        for (d, ud) in u.iter_mut().enumerate() {
                            *ud += kernel.at(comp, d, p[0] - q[0], p[1] - q[1]) * tc * 16.0;
                        }
                    }
                }
                u
            })
            .collect();
        let mut want = [0.0; 4];
        for (q, t) in cells.iter().zip(&load) {
            want[0] += t[0];
            want[1] += t[1];
            want[2] += t[2];
            want[3] += q[0] * t[1] - q[1] * t[0];
        }
        let map = solve(&kernel, &markers, &u, &cells, 1.0, None).expect("solved");
        for i in 0..4 {
            let tol = 0.05 * want[i].abs().max(0.05 * want[2].abs());
            assert!(
                (map.wrench[i] - want[i]).abs() < tol,
                "{i}: {:?} vs {want:?}",
                map.wrench
            );
        }
        // A fixed λ (as a calibrated sensor uses) gives the same answer as GCV's.
        let fixed = solve(&kernel, &markers, &u, &cells, 1.0, Some(map.lambda)).expect("fixed");
        for i in 0..4 {
            assert!(
                (fixed.wrench[i] - map.wrench[i]).abs() < 1e-6 * want[2].abs().max(1e-9) + 1e-9
            );
        }
    }
}
