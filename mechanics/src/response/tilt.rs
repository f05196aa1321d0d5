//! The tilting moments a sheared contact carries through the layer's coupling.
//!
//! On the bonded layer a tangential traction pushes the surface up ahead of it and pulls it
//! down behind (the coupling C_zt of [`crate::greens`]). A stuck indenter held at its depth
//! and level resists that, so the pressure rises on its leading side: the tractions on the
//! gel carry a moment about the tangential axes, My = −arm·Fx and Mx = +arm·Fy (z into the
//! gel), which a Nano17 under the indenter reads as Tx, Ty. The arms are the linear
//! (full-stick) ones: a contact pressed without slip and shifted 1 µm, the change of the
//! pressure's first moment over the change of the tangential force.
//!
//! A flat punch's arm is one number (everything scales with depth). A curved indenter's
//! grows with its contact: it is solved per depth bucket (0.5 % of the thickness) where a
//! run asks for it, as a flat punch's on the contact's footprint (Barber's incremental
//! stiffness, [`ContactModel::tilt_arms_mm`]), and blended between buckets.

use std::f64::consts::PI;

use super::shapes::{face_mask, matched_dx};
use super::{ContactModel, Normal, quantise};
use crate::Indenter;
use crate::operator::{Compliance, Grid, LayerOperator};
#[cfg(test)]
use crate::pressing::curved::CurvedPath;
use crate::pressing::{Pressing, PressingSolution, pressing};
#[cfg(test)]
use crate::solve::Tolerance;

/// The shift whose response gives the arm, mm: small enough that nothing slips or leaves
/// the contact, large enough against the solver's tolerance.
const SHIFT_MM: f64 = 1e-3;

/// Friction that never slips: the arm is the full-stick one.
const STUCK_MU: f64 = 1e6;

/// The free-area arms' solves stop at a force change of 3e-5 (the shifted pressure's moment
/// is a small difference of two solves).
#[cfg(test)]
fn arm_tol() -> Tolerance {
    Tolerance {
        rel: 1e-9,
        max_iter: 4000,
    }
}

/// The pressure's first moments (∫x p dA, ∫y p dA), N·mm, and the tangential forces
/// (Fx, Fy), N, of a solution on `g`.
fn moments(g: Grid, s: &PressingSolution) -> ((f64, f64), (f64, f64)) {
    let (mut mx, mut my) = (0.0, 0.0);
    for (i, p) in s.p.iter().enumerate() {
        let (x, y) = g.xy(i);
        mx += p * x;
        my += p * y;
    }
    ((mx * g.area(), my * g.area()), (s.t.fx_n, s.t.fy_n))
}

/// The arms (along x, along y), mm, from an unshifted solution and two shifted ones.
fn arms(
    g: Grid,
    base: &PressingSolution,
    along_x: &PressingSolution,
    along_y: &PressingSolution,
) -> (f64, f64) {
    let ((mx0, my0), (fx0, fy0)) = moments(g, base);
    let ((mx1, _), (fx1, _)) = moments(g, along_x);
    let ((_, my2), (_, fy2)) = moments(g, along_y);
    let ratio = |dm: f64, df: f64| {
        if df.abs() > 0.0 && (dm / df).is_finite() {
            dm / df
        } else {
            0.0
        }
    };
    (ratio(mx1 - mx0, fx1 - fx0), ratio(my2 - my0, fy2 - fy0))
}

/// The tilting arms of a stuck flat punch sheared along x and along y, mm: pressed 1 mm and
/// held level, then shifted 1 µm along each axis. The unshifted state is solved once for
/// both.
pub(super) fn flat_tilt_arms(op: &LayerOperator, mask: &[bool]) -> (f64, f64) {
    let g = op.grid();
    let zero = vec![0.0; g.len()];
    let shift = vec![SHIFT_MM; g.len()];
    let solve = |dx: &[f64], dy: &[f64]| {
        pressing(&Pressing {
            op,
            mask,
            uz: &vec![1.0; g.len()],
            target: (dx, dy),
            mu: STUCK_MU,
            tol: super::tol(),
        })
    };
    arms(
        g,
        &solve(&zero, &zero),
        &solve(&shift, &zero),
        &solve(&zero, &shift),
    )
}

/// The tilting arms of a curved indenter (surface `profile` on `op`'s grid) pressed
/// `depth_mm` without slip, the contact area free: the unshifted contact and two displaced
/// by 1 µm, each in one increment from first touch. A check on
/// [`ContactModel::tilt_arms_mm`]'s footprint route, which needs far fewer cells: a contact
/// area that may change by a cell under a 1 µm shift makes this one converge slowly
/// (0.483 / 0.447 mm at 16 / 24 cells for the box sphere at 2 mm).
#[cfg(test)]
pub(super) fn free_area_tilt_arms(
    op: &LayerOperator,
    profile: &[f64],
    depth_mm: f64,
) -> (f64, f64) {
    let press = |offset: (f64, f64)| {
        let mut path = CurvedPath::displaced(op, profile, STUCK_MU, arm_tol(), offset);
        path.press_to(depth_mm).ok()
    };
    match (
        press((0.0, 0.0)),
        press((SHIFT_MM, 0.0)),
        press((0.0, SHIFT_MM)),
    ) {
        (Some(b), Some(x), Some(y)) => arms(op.grid(), &b, &x, &y),
        _ => (0.0, 0.0),
    }
}

/// Largest grid side for a curved contact's footprint: a contact tiny against the layer
/// would otherwise ask for thousands of cells to span 12 thicknesses; its arm is tiny too
/// (a contact small against h sees a nearly incompressible half-space, which hardly couples).
const FOOTPRINT_MAX_SIDE: usize = 512;

/// The tilting moments (Tx, Ty), N·mm, that tangential forces (Fx, Fy) carry with the arms
/// `arms_mm` of [`ContactModel::tilt_arms_mm`], about the contact's centre on the gel surface
/// (z into the gel, the moment of the tractions on the gel): Mx = +arm_y·Fy, My = −arm_x·Fx.
pub fn tilting_moments_nmm(arms_mm: (f64, f64), fx_n: f64, fy_n: f64) -> (f64, f64) {
    let (ax, ay) = arms_mm;
    (ay * fy_n, -ax * fx_n)
}

impl ContactModel {
    /// The tilting-moment arms (along x, along y), mm, of the contact's shear at
    /// `depth_mm`; zero out of contact and when the model was built without shear.
    ///
    /// Linear (full-stick) arms: a flat punch's are 0.520 mm on the box gel's 9.5 mm punch,
    /// 0.898 mm on the 12.68 mm one, 1.302 mm on the portable gel's 12.5 mm punch (the
    /// model's 32-cell grid); a curved indenter's grow with its contact (BENCHMARKS.md,
    /// "Tilting moments of curved indenters";
    /// `cargo run --release -p mechanics --example tilt_arms`). A curved indenter's are
    /// solved at the two depth buckets around `depth_mm` the first time they are asked for
    /// (cached) and blended linearly; below the first bucket (0.5 % of the thickness) they
    /// ramp to zero with the depth, as the field's tables do.
    pub fn tilt_arms_mm(&mut self, depth_mm: f64) -> (f64, f64) {
        if !self.spec.shear || depth_mm.is_nan() || depth_mm <= 0.0 {
            return (0.0, 0.0);
        }
        if matches!(self.normal, Normal::Flat { .. }) {
            return self.flat_tilt_arms_mm;
        }
        let h = self.spec.contact.layer.thickness_mm;
        let (mut ax, mut ay) = (0.0, 0.0);
        for (d, w) in self.depth_buckets(depth_mm) {
            let key = quantise(d, h);
            let (bx, by) = match self.tilt.get(&key) {
                Some(a) => *a,
                None => {
                    // Buckets start at 1 (`depth_buckets` leaves out zero depth).
                    let a = self.footprint_tilt_arms(key as f64 / 200.0 * h);
                    self.tilt.insert(key, a);
                    a
                }
            };
            ax += w * bx;
            ay += w * by;
        }
        (ax, ay)
    }

    /// A curved contact's arms at `depth_mm` as those of a flat punch on its footprint: the
    /// incremental stiffness of a contact whose pressure falls to zero at its edge is that
    /// of a flat punch on its current contact area (Barber 1974, *J. Strain Anal.* 9:230,
    /// "Determining the contact area in elastic-indentation problems": the area's own
    /// change contributes at second order). Used here for the stuck contact's response to
    /// a small shift, and checked against the contact solved with its area free
    /// (`tests.rs`). The shift's response is the flat punch's, solved on a grid with
    /// `cells_flat` cells across the footprint's narrow side. The sphere's footprint is a
    /// circle of the table's contact radius; the can's a strip across the pad, as long as
    /// the pad is wide (its axis along x) and as wide as the table's area makes it.
    fn footprint_tilt_arms(&self, depth_mm: f64) -> (f64, f64) {
        let c = &self.spec.contact;
        let a = self.contact_radius_mm(depth_mm);
        let face = match c.indenter {
            Indenter::Cylinder { length_mm, .. } => {
                let long = length_mm.min(c.layer.width_mm);
                Indenter::FlatRectangle {
                    width_mm: long,
                    length_mm: PI * a * a / long,
                }
            }
            _ => Indenter::FlatCircle {
                diameter_mm: 2.0 * a,
            },
        };
        let (long, narrow) = match face {
            Indenter::FlatRectangle {
                width_mm,
                length_mm,
            } => (width_mm.max(length_mm), width_mm.min(length_mm)),
            _ => (2.0 * a, 2.0 * a),
        };
        if narrow.is_nan() || narrow <= 0.0 {
            return (0.0, 0.0);
        }
        let h = c.layer.thickness_mm;
        let dx = (narrow / self.spec.quality.cells_flat.max(4) as f64)
            .max((long + 12.0 * h) / FOOTPRINT_MAX_SIDE as f64);
        let n = LayerOperator::period_for(long, h, dx);
        let grid = Grid {
            n,
            dx: matched_dx(&face, n, dx),
        };
        let op = LayerOperator::new(
            grid,
            h,
            c.material.shear_modulus_mpa(),
            c.material.poisson_ratio,
        );
        flat_tilt_arms(&op, &face_mask(&face, grid))
    }
}
