//! The tilting moments a sheared contact carries through the layer's coupling.
//!
//! On the bonded layer a tangential traction pushes the surface up ahead of it and pulls it
//! down behind (the coupling C_zt of [`crate::greens`]). A stuck indenter held at its depth
//! and level resists that, so the pressure rises on its leading side: the tractions on the
//! gel carry a moment about the tangential axes, My = −arm·Fx and Mx = +arm·Fy (z into the
//! gel), which a Nano17 under the indenter reads as Tx, Ty. The full-stick arms are the
//! linear ones: a contact pressed without slip and shifted 1 µm, the change of the
//! pressure's first moment over the change of the tangential force. Under partial slip the
//! arm moves toward its full-slip value ([`SlipTilt`], [`tilt_arms_at`]).
//!
//! A flat punch's arm is one number (everything scales with depth). A curved indenter's
//! grows with its contact: it is solved per depth bucket (0.5 % of the thickness) where a
//! run asks for it, as a flat punch's on the contact's footprint (Barber's incremental
//! stiffness, [`ContactModel::tilt_arms_mm`]), and blended between buckets.

use std::f64::consts::PI;

use std::sync::Arc;

use super::shapes::{face_mask, matched_dx};
use super::{ContactModel, Entry, Kind, Normal, quantise};
use crate::Indenter;
use crate::operator::{Compliance, Grid, LayerOperator};
#[cfg(test)]
use crate::pressing::curved::CurvedPath;
use crate::pressing::{Pressing, PressingSolution, pressing};
#[cfg(test)]
use crate::solve::Tolerance;
use crate::solve::{normal_known_area, normal_unknown_area};

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

/// The tilt functional of a contact held at its depth and level, on `op`'s grid: the
/// (ω_x, ω_y) with ∫x Δp dA = Σ ω_x Δq_x + ω_y Δq_y for any change Δq of the tangential
/// tractions that keeps the contact (`contact`) where it is.
///
/// Held at its depth and level the contact's normal displacement cannot change, so
/// A Δp + C_zt Δq = 0 on it and Δp = −A_c⁻¹ C_zt Δq; then ∫x Δp dA = −dA·wᵀ C_zt Δq with
/// w = A_c⁻¹ x, the pressure of the face tilted by a unit rotation (A is symmetric). So
/// ω = −dA·C_ztᵀ w: one normal solve, and the moment of any tractions is a dot product
/// (Betti's reciprocity: the tilted face's pressure pushes the surface sideways through the
/// coupling, and that sideways displacement weighs each traction's share of the moment).
/// On the layer's operator C_ztᵀ = C_tz: the coupling kernels are odd in r and opposite in
/// sign (unit-tested in `tests.rs`), so `tangential_from_normal` applies the transpose.
pub(super) fn tilt_functional(op: &LayerOperator, contact: &[bool]) -> (Vec<f64>, Vec<f64>) {
    let g = op.grid();
    let x: Vec<f64> = (0..g.len()).map(|i| g.xy(i).0).collect();
    let w = normal_known_area(op, contact, &x, super::tol()).p;
    let (mut wx, mut wy) = (vec![0.0; g.len()], vec![0.0; g.len()]);
    op.tangential_from_normal(&w, &mut wx, &mut wy);
    let a = g.area();
    wx.iter_mut().chain(wy.iter_mut()).for_each(|v| *v *= -a);
    (wx, wy)
}

/// How a sheared contact's tilting arm moves from its stuck value to full slip. The default
/// has no full-slip arm and no progress: the arm stays at its stuck value.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SlipTilt {
    /// The arm at full slip along x, mm: the sliding tractions μp along the shear with the
    /// pressure's own feedback on them ([`full_slip_arm`]). NaN where it was not found.
    pub full_slip_arm_mm: f64,
    /// At each point of the shear backbone, how far the arm has gone from its stuck value
    /// (0) to its full-slip one (1), shaped by the table's tractions ([`slip_tilt`]).
    pub progress: Vec<f64>,
}

impl Default for SlipTilt {
    fn default() -> Self {
        Self {
            full_slip_arm_mm: f64::NAN,
            progress: Vec::new(),
        }
    }
}

/// Fixed-point iterations allowed for [`full_slip_arm`] (the shipped contacts settle in
/// 8–12).
const FULL_SLIP_ITERATIONS: usize = 60;

/// Where a sliding contact presses: a flat punch's face, or a curved indenter's surface
/// (`profile`, mm above its lowest point, per cell) pressed `depth_mm`, whose contact may
/// change as it slides.
pub(super) enum Face<'a> {
    /// The cells of a flat punch's face.
    Fixed(&'a [bool]),
    /// A curved surface and its depth.
    Free {
        /// Height above the lowest point, mm, per cell.
        profile: &'a [f64],
        /// Indentation depth, mm.
        depth_mm: f64,
    },
}

/// The tilting arm of a contact held at its depth and level and sliding along x, mm.
///
/// Sliding, the tractions are μp along x (the pressed state's, `pressing`, from which the
/// moment is counted, are gone), and they push the surface in and out through the
/// coupling, which the held contact answers with its pressure: A p + C_zt (μp, 0) = the
/// face's displacement on the contact. Solved by fixed-point iteration on p from the
/// pressed state `p0`: on a flat face Δp = p − p0 solves A_c Δp = −C_zt Δq on the face (a
/// pressure turning tensile: NaN); on a curved surface the contact is found again each time
/// (Polonsky–Keer with the coupling's displacement added to the surface: the trailing
/// edge lets go where its pressure would turn tensile). NaN when it does not settle.
pub(super) fn full_slip_arm(
    op: &LayerOperator,
    face: &Face<'_>,
    p0: &[f64],
    mu: f64,
    pressing: &(Vec<f64>, Vec<f64>),
) -> f64 {
    let g = op.grid();
    let a = g.area();
    let first_moment = |p: &[f64]| -> f64 {
        p.iter()
            .enumerate()
            .map(|(i, v)| v * g.xy(i).0)
            .sum::<f64>()
            * a
    };
    let (m0, f0) = (first_moment(p0), pressing.0.iter().sum::<f64>() * a);
    let zero = vec![0.0; g.len()];
    let minus_qy: Vec<f64> = pressing.1.iter().map(|v| -v).collect();
    let mut p = p0.to_vec();
    let mut uz = vec![0.0; g.len()];
    let mut last = f64::NAN;
    for _ in 0..FULL_SLIP_ITERATIONS {
        let qx: Vec<f64> = p.iter().map(|v| mu * v.max(0.0)).collect();
        p = match face {
            Face::Fixed(contact) => {
                let dqx: Vec<f64> = qx.iter().zip(&pressing.0).map(|(q, q0)| q - q0).collect();
                op.normal_from_tangential(&dqx, &minus_qy, &mut uz);
                uz.iter_mut().for_each(|v| *v = -*v);
                let dp = normal_known_area(op, contact, &uz, super::tol()).p;
                let p: Vec<f64> = p0.iter().zip(&dp).map(|(a, b)| a + b).collect();
                if (0..g.len()).any(|i| contact[i] && p[i] < 0.0) {
                    return f64::NAN;
                }
                p
            }
            Face::Free { profile, depth_mm } => {
                op.normal_from_tangential(&qx, &zero, &mut uz);
                let surface: Vec<f64> = profile.iter().zip(&uz).map(|(h, u)| h + u).collect();
                let n = normal_unknown_area(op, &surface, *depth_mm, Some(&p), super::tol());
                if !n.converged {
                    return f64::NAN;
                }
                n.p
            }
        };
        let force = mu * p.iter().map(|v| v.max(0.0)).sum::<f64>() * a - f0;
        let arm = (first_moment(&p) - m0) / force;
        if !arm.is_finite() {
            return f64::NAN;
        }
        if (arm - last).abs() <= 1e-6 * arm.abs() {
            return arm;
        }
        last = arm;
    }
    f64::NAN
}

/// How partial slip moves a shear table's tilting arm ([`SlipTilt`]).
///
/// The arm of a level is ⟨ω, Δq⟩ / ΔF_x, with Δq its tractions less the pressed state's
/// ([`tilt_functional`] on the contact where `p` > 0). The tables solve their tractions with
/// the pressure held (one way), so these arms are not the coupled ones: on the box's
/// 12.68 mm punch 0.863 mm stuck and 1.035 mm at full slip, where the coupled arms are 0.898
/// (a 1 µm shift, [`flat_tilt_arms`]) and 0.976 mm ([`full_slip_arm`]; the sliding
/// tractions μp without the pressure's feedback on them carry 1.018 mm). So the ends are the coupled arms and only the path between them is the
/// tables': each level's progress is its arm's change from the first sheared level (still
/// stuck, at a tenth of the linear slip displacement) over the full-slip level's, within
/// [0, 1].
pub(super) fn slip_tilt(
    op: &LayerOperator,
    face: &Face<'_>,
    p: &[f64],
    mu: f64,
    pressing: &(Vec<f64>, Vec<f64>),
    levels: &[(Vec<f64>, Vec<f64>)],
) -> SlipTilt {
    let contact: Vec<bool> = p.iter().map(|v| *v > 0.0).collect();
    let (ox, oy) = tilt_functional(op, &contact);
    let a = op.grid().area();
    let raw: Vec<f64> = levels
        .iter()
        .map(|(qx, qy)| {
            let (mut m, mut f) = (0.0, 0.0);
            for i in 0..qx.len() {
                let (dx, dy) = (qx[i] - pressing.0[i], qy[i] - pressing.1[i]);
                m += ox[i] * dx + oy[i] * dy;
                f += dx;
            }
            m / (f * a)
        })
        .collect();
    let n = raw.len();
    let (first, span) = match (raw.get(1), raw.last()) {
        (Some(r1), Some(rl)) if n > 2 => (*r1, rl - r1),
        _ => (f64::NAN, f64::NAN),
    };
    let progress = raw
        .iter()
        .enumerate()
        .map(|(k, r)| {
            let w = (r - first) / span;
            if k <= 1 || !w.is_finite() || span.abs() < 1e-9 * first.abs() {
                0.0
            } else {
                // The levels near full slip overshoot the last by up to 2 % (their slip
                // directions scatter about x): the arm goes no further than full slip's.
                w.clamp(0.0, 1.0)
            }
        })
        .collect();
    SlipTilt {
        full_slip_arm_mm: full_slip_arm(op, face, p, mu, pressing),
        progress,
    }
}

/// The tilting arms (mm) of a sheared contact whose elastic shear force is `elastic_n` on
/// `backbone`: the full-stick arms `arms_mm`, the one along x moved toward `slip`'s
/// full-slip arm by its progress at that force (interpolated between levels; a contact
/// sliding in full slip is all the way there). The arm along y (a force across the shear
/// stage: a disturbance) keeps its full-stick value: no table is solved across. On an
/// unloading or reversed branch the force is looked up on the virgin backbone (the
/// tractions of a Masing branch are not tabulated). Without a full-slip arm, the stuck one.
pub fn tilt_arms_at(
    arms_mm: (f64, f64),
    backbone: &crate::friction::Backbone,
    slip: &SlipTilt,
    elastic_n: f64,
    sliding: bool,
) -> (f64, f64) {
    let w = &slip.progress;
    let n = backbone.f.len().min(w.len());
    if n == 0 || !slip.full_slip_arm_mm.is_finite() {
        return arms_mm;
    }
    let f = elastic_n.abs();
    let at = if sliding || f >= backbone.f[n - 1] {
        1.0
    } else if n == 1 {
        w[0]
    } else {
        let i = backbone.f[..n].partition_point(|v| *v <= f).clamp(1, n - 1);
        let span = backbone.f[i] - backbone.f[i - 1];
        let t = if span > 0.0 {
            ((f - backbone.f[i - 1]) / span).clamp(0.0, 1.0)
        } else {
            1.0
        };
        w[i - 1] * (1.0 - t) + w[i] * t
    };
    (
        arms_mm.0 + (slip.full_slip_arm_mm - arms_mm.0) * at,
        arms_mm.1,
    )
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
                    let name = format!("tilt/{key}");
                    let a = match self.fetch(&name) {
                        Some(Entry::Tilt(a)) => a,
                        _ => {
                            // Buckets start at 1 (`depth_buckets` leaves out zero depth).
                            let a = self.footprint_tilt_arms(key as f64 / 200.0 * h);
                            self.keep(&name, || Entry::Tilt(a));
                            a
                        }
                    };
                    self.tilt.insert(key, a);
                    a
                }
            };
            ax += w * bx;
            ay += w * by;
        }
        (ax, ay)
    }

    /// How the shear's tilting arm moves from stuck to full slip at `depth_mm` ([`SlipTilt`]),
    /// its progress one per point of [`Self::shear_curve`]'s backbone there (for
    /// [`tilt_arms_at`]); `None` when shear was not built or out of contact. Solved from the
    /// shear table of `depth_mm`'s bucket the first time it is asked for (a tilt functional
    /// and 8–12 normal solves on the table's grid), and cached.
    pub fn shear_slip_tilt(&mut self, depth_mm: f64) -> Option<Arc<SlipTilt>> {
        let table = self.shared_table(depth_mm, Kind::Shear)?;
        let h = self.spec.contact.layer.thickness_mm;
        let key = if self.is_flat() {
            0
        } else {
            quantise(depth_mm, h)
        };
        if let Some(s) = self.slip_tilt.get(&key) {
            return Some(Arc::clone(s));
        }
        let name = format!("slip_tilt/{key}");
        if let Some(Entry::SlipTilt(s)) = self.fetch(&name) {
            let s = Arc::new(s);
            self.slip_tilt.insert(key, Arc::clone(&s));
            return Some(s);
        }
        // The depth the table was solved at: a flat punch's at unit depth.
        let d = if self.is_flat() {
            1.0
        } else {
            (key as f64 / 200.0 * h).max(1e-4 * h)
        };
        let op = self.op_for(d);
        let p = if self.curved_friction() {
            self.pressed(key).p
        } else {
            self.pressure_on(&op, d)
        };
        let mu = self.spec.contact.material.friction;
        let s = if op.grid() != table.grid || p.len() != table.grid.len() {
            // Not the table's grid: nothing to take the path from.
            SlipTilt::default()
        } else if self.is_flat() {
            let mask: Vec<bool> = p.iter().map(|v| *v > 0.0).collect();
            slip_tilt(
                &op,
                &Face::Fixed(&mask),
                &p,
                mu,
                &table.pressing,
                &table.tractions,
            )
        } else {
            let profile = self.profile_on(&op);
            let face = Face::Free {
                profile: &profile,
                depth_mm: d,
            };
            slip_tilt(&op, &face, &p, mu, &table.pressing, &table.tractions)
        };
        self.keep(&name, || Entry::SlipTilt(s.clone()));
        let s = Arc::new(s);
        self.slip_tilt.insert(key, Arc::clone(&s));
        Some(s)
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
