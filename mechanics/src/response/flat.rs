//! Pressing with friction: a flat punch's coupled solve and the one-way friction holding any
//! pressed contact ([`crate::pressing`]).

use super::shapes::{face_mask, matched_dx};
use super::tol;
use super::{ModelSpec, Normal};
use crate::{Indenter, punch};

use crate::operator::{Compliance, Grid, LayerOperator};
use crate::pressing::{Pressing, PressingSolution, pressing};
use crate::solve::{Tangential, TangentialSolution, normal_known_area, tangential};

/// A flat punch's face pressed 1 mm (everything scales with depth) against friction `mu`:
/// coupled (`crate::pressing`) when `coupled`, otherwise the frictionless pressure with the
/// friction found on it one way (Goodman).
pub(super) fn flat_pressing(
    op: &LayerOperator,
    mask: &[bool],
    mu: f64,
    coupled: bool,
) -> PressingSolution {
    let g = op.grid();
    let zero = vec![0.0; g.len()];
    let uz = vec![1.0; g.len()];
    if coupled {
        return pressing(&Pressing {
            op,
            mask,
            uz: &uz,
            target: (&zero, &zero),
            mu,
            tol: tol(),
        });
    }
    let n = normal_known_area(op, mask, &uz, tol());
    let t = held_by_friction(op, &n.p, mu).0;
    PressingSolution {
        force_n: n.force_n,
        p: n.p,
        t,
        sweeps: 0,
        converged: n.converged,
    }
}

/// The tangential tractions with which a pressed contact's stuck points hold the outward
/// flow the layer's coupling gives pressure `p`, found on `p` one way (Goodman), and that
/// coupling's displacement (x, y).
pub(super) fn held_by_friction(
    op: &LayerOperator,
    p: &[f64],
    mu: f64,
) -> (TangentialSolution, (Vec<f64>, Vec<f64>)) {
    let len = op.grid().len();
    let (mut sx, mut sy) = (vec![0.0; len], vec![0.0; len]);
    op.tangential_from_normal(p, &mut sx, &mut sy);
    let zero = vec![0.0; len];
    let t = tangential(&Tangential {
        op,
        p,
        mu,
        target: (&zero, &zero),
        source: Some((&sx, &sy)),
        x_only: false,
        initial: None,
        tol: tol(),
    });
    (t, (sx, sy))
}

/// The layer operator for a flat punch's face with `cells` cells across its footprint (the
/// cell size matched so the discretised face has the face's area).
pub(super) fn operator(
    indenter: &Indenter,
    h: f64,
    mu_mod: f64,
    nu: f64,
    cells: usize,
) -> LayerOperator {
    let extent = indenter.footprint_mm();
    let dx = extent / cells as f64;
    let n = LayerOperator::period_for(extent, h, dx);
    LayerOperator::new(
        Grid {
            n,
            dx: matched_dx(indenter, n, dx),
        },
        h,
        mu_mod,
        nu,
    )
}

/// The frictionless force of the face `mask` pressed 1 mm on `op`, N.
pub(super) fn frictionless_force(op: &LayerOperator, mask: &[bool]) -> f64 {
    normal_known_area(op, mask, &vec![1.0; op.grid().len()], tol()).force_n
}

/// A flat punch's normal table on its `cells_flat` operator `op`: pressure and force per mm
/// of depth, pressed with friction or not as the spec says, the force made exact for a
/// circle (κ) and extrapolated across grids for other faces; and its tilting arms when
/// the spec builds shear.
pub(super) fn flat_normal(spec: &ModelSpec, op: &LayerOperator) -> (Normal, (f64, f64)) {
    let c = &spec.contact;
    let (h, nu) = (c.layer.thickness_mm, c.material.poisson_ratio);
    let flat_op = |cells| operator(&c.indenter, h, c.material.shear_modulus_mpa(), nu, cells);
    let grid = op.grid();
    let mask = face_mask(&c.indenter, grid);
    // Pressed with friction: the face holds the gel that the layer's coupling pushes
    // outward, and presses harder for it (`crate::pressing`); or frictionless, with
    // the friction found on that pressure one way.
    let s = flat_pressing(op, &mask, c.material.friction, spec.pressing_friction);
    let mut force = s.force_n;
    let free_on = frictionless_force;
    if spec.quality.extrapolate_flat && !matches!(c.indenter, Indenter::FlatCircle { .. }) {
        // No exact κ for other faces: the frictionless force is extrapolated across
        // grids (Richardson, first order: the face's edge singularity makes the
        // force converge as the cell size), F ≈ 2 F(2n) − F(n), times the grid's
        // ratio of the pressed-with-friction force to its own frictionless one, as
        // for a circle. At 32 cells the grid alone was 2.8 % (ellipse), 3.8 %
        // (rectangle) and 3.5 % (triangle) below the converged force; extrapolated,
        // within 0.5 % (BENCHMARKS.md, "Non-circular punches";
        // `examples/flat_shape_convergence.rs`).
        let fine = flat_op(2 * spec.quality.cells_flat);
        let fine_mask = face_mask(&c.indenter, fine.grid());
        let coarse = free_on(op, &mask);
        let extrapolated = 2.0 * free_on(&fine, &fine_mask) - coarse;
        force = extrapolated * s.force_n / coarse;
    }
    if let Indenter::FlatCircle { diameter_mm } = c.indenter {
        // Exact stiffening (Nyström) for the frictionless force, times the grid's
        // ratio of the pressed-with-friction force to its own frictionless one (the
        // grid's discretisation error cancels in the ratio: 1.0883, 1.0882, 1.0876
        // at 16, 32, 48 cells on the 9.5 mm box punch); the grid gives the shape.
        let a = diameter_mm / 2.0;
        let kappa = punch::layer_kappa(a / h, nu, 48);
        let free = free_on(op, &mask);
        force = 2.0 * c.material.contact_modulus_mpa() * a * kappa * s.force_n / free;
    }
    // (The tangential tables' forces are scaled to this force: `tangential_table`.)
    let arms = if spec.shear {
        super::tilt::flat_tilt_arms(op, &mask)
    } else {
        (0.0, 0.0)
    };
    let normal = Normal::Flat {
        grid,
        mask,
        p_per_mm: s.p,
        force_per_mm: force,
    };
    (normal, arms)
}
