//! Pressing with friction: a flat punch's coupled solve, the one-way friction holding any
//! pressed contact, and the tilting arm of a flat punch's shear ([`crate::pressing`]).

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

/// The tilting arms of a stuck flat punch sheared along x and along y, mm: pressed 1 mm and
/// held level, then shifted 1 µm along each axis; the change of the pressure's first moment
/// about that axis over the change of the tangential force. The unshifted state is solved
/// once for both.
pub(super) fn tilt_arms(op: &LayerOperator, mask: &[bool]) -> (f64, f64) {
    let g = op.grid();
    let zero = vec![0.0; g.len()];
    let shift = vec![1e-3; g.len()];
    let solve = |dx: &[f64], dy: &[f64]| {
        pressing(&Pressing {
            op,
            mask,
            uz: &vec![1.0; g.len()],
            target: (dx, dy),
            mu: 1e6,
            tol: tol(),
        })
    };
    let moment = |s: &PressingSolution, axis: usize| -> (f64, f64) {
        let m = (0..g.len())
            .map(|i| {
                let (x, y) = g.xy(i);
                s.p[i] * if axis == 0 { x } else { y }
            })
            .sum::<f64>()
            * g.area();
        (m, if axis == 0 { s.t.fx_n } else { s.t.fy_n })
    };
    let base = solve(&zero, &zero);
    let arm = |shifted: &PressingSolution, axis: usize| {
        let ((m0, f0), (m1, f1)) = (moment(&base, axis), moment(shifted, axis));
        if (f1 - f0).abs() > 0.0 {
            (m1 - m0) / (f1 - f0)
        } else {
            0.0
        }
    };
    (arm(&solve(&shift, &zero), 0), arm(&solve(&zero, &shift), 1))
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
