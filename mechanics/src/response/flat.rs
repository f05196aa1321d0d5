//! Pressing with friction: a flat punch's coupled solve and the one-way friction holding any
//! pressed contact ([`crate::pressing`]).

use super::shapes::matched_dx;
use super::tol;
use crate::Indenter;

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
