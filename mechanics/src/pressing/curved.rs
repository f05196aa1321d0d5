//! A curved indenter (a sphere, a can lying across the pad) pressed into the bonded layer
//! with Coulomb friction, along its loading path.
//!
//! Unlike a flat punch, a curved indenter's contact grows as it presses. A point of the
//! surface that the layer's coupling has already pushed outward is caught by the indenter
//! where it is when it first touches; while it sticks it stays there (relative to the
//! indenter, which only moves along the normal), and if friction cannot hold it, it slides
//! with |q| = μp against its slip. So the tractions depend on the path, not on the depth
//! alone: Spence (1975, *J. Elasticity* 5:297, "The Hertz contact problem with finite
//! friction") solved this for a half-space, where the solution is self-similar; on a layer
//! it is not (a/h changes), so the path is followed in depth increments.
//!
//! Each increment k solves, by the same block Gauss–Seidel as the flat punch
//! ([`super::pressing`]):
//!
//!   p ← Polonsky–Keer on the profile raised by C_zt q        (contact area unknown)
//!   q ← tangential(p, source C_tz p, stick target u_t^(k−1)) (projected gradient, |q| ≤ μp)
//!
//! where u_t^(k−1) is the surface's tangential displacement at the last increment: the
//! stick condition is "no slip during the increment" (the backward-Euler step of Coulomb's
//! law), and the convex subproblem's slip cells slide against their increment's slip. A
//! point's displacement when it is caught is that of the last increment before it touched,
//! so the increments must be small against the contact's growth (the error falls with the
//! increment: BENCHMARKS.md, "Curved indenters pressed with friction"). With μ = 0 each
//! increment is the frictionless solution of its depth, whatever the path.
//!
//! An increment may also back off: the contact recedes, cells that leave it carry no
//! traction (|q| ≤ μp = 0), and the stuck ones keep their place as on loading.

use crate::operator::Compliance;
use crate::solve::{Tangential, TangentialSolution, Tolerance, normal_unknown_area, tangential};

use super::PressingSolution;

/// A curved indenter's loading path, one increment at a time.
pub struct CurvedPath<'a> {
    op: &'a dyn Compliance,
    /// The indenter's surface, mm above its lowest point, per cell.
    profile: &'a [f64],
    mu: f64,
    tol: Tolerance,
    depth_mm: f64,
    p: Vec<f64>,
    qx: Vec<f64>,
    qy: Vec<f64>,
    /// The surface's tangential displacement after the last increment (x, y), mm.
    ux: Vec<f64>,
    uy: Vec<f64>,
}

/// Why an increment was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PathError {
    /// A depth that is not a number would poison every later increment.
    #[error("the path cannot press to a depth of {0} mm")]
    NotFinite(f64),
}

impl<'a> CurvedPath<'a> {
    /// The indenter just touching an undeformed surface, pressed against friction `mu`.
    pub fn new(op: &'a dyn Compliance, profile: &'a [f64], mu: f64, tol: Tolerance) -> Self {
        let len = op.grid().len();
        Self {
            op,
            profile,
            mu,
            tol,
            depth_mm: 0.0,
            p: vec![0.0; len],
            qx: vec![0.0; len],
            qy: vec![0.0; len],
            ux: vec![0.0; len],
            uy: vec![0.0; len],
        }
    }

    /// The indenter placed sideways by (`dx_mm`, `dy_mm`) before it touches: every point it
    /// catches is held that far from where it rests, so pressed with friction that never
    /// slips (μ → ∞) in one increment it is a bonded contact sheared by that offset. Its
    /// difference from the unshifted contact is the linear (full-stick) response to a small
    /// shift, e.g. the tilting moment a sheared contact carries through the layer's
    /// coupling. (Shifting a contact already pressed is a different problem: a sweep that
    /// sees only a microscopic change stops before the pressure has felt it.)
    pub fn displaced(
        op: &'a dyn Compliance,
        profile: &'a [f64],
        mu: f64,
        tol: Tolerance,
        (dx_mm, dy_mm): (f64, f64),
    ) -> Self {
        let mut path = Self::new(op, profile, mu, tol);
        path.ux.iter_mut().for_each(|u| *u = dx_mm);
        path.uy.iter_mut().for_each(|u| *u = dy_mm);
        path
    }

    /// The depth the path has reached, mm.
    pub fn depth_mm(&self) -> f64 {
        self.depth_mm
    }

    /// Presses on to `depth_mm` in one increment (module docs).
    pub fn press_to(&mut self, depth_mm: f64) -> Result<PressingSolution, PathError> {
        if !depth_mm.is_finite() {
            return Err(PathError::NotFinite(depth_mm));
        }
        let len = self.op.grid().len();
        let area = self.op.grid().area();
        let stop = self.tol.rel.sqrt().max(1e-9);
        let max_sweeps = self.tol.max_iter.clamp(1, 200);
        let (mut cz, mut raised) = (vec![0.0; len], vec![0.0; len]);
        let (mut sx, mut sy) = (vec![0.0; len], vec![0.0; len]);
        let mut force = f64::NAN;
        let (mut sweeps, mut converged) = (0, false);
        let t = loop {
            sweeps += 1;
            self.op.normal_from_tangential(&self.qx, &self.qy, &mut cz);
            for i in 0..len {
                raised[i] = self.profile[i] + cz[i];
            }
            // Warm start from the last pressure once there is one; the first touch starts
            // from the geometric overlap.
            let initial = self.p.iter().any(|v| *v > 0.0).then_some(&self.p[..]);
            let n = normal_unknown_area(self.op, &raised, depth_mm, initial, self.tol);
            self.p = n.p;
            self.op.tangential_from_normal(&self.p, &mut sx, &mut sy);
            let t = tangential(&Tangential {
                op: self.op,
                p: &self.p,
                mu: self.mu,
                target: (&self.ux, &self.uy),
                source: Some((&sx, &sy)),
                x_only: false,
                initial: Some((&self.qx, &self.qy)),
                tol: self.tol,
            });
            self.qx.copy_from_slice(&t.qx);
            self.qy.copy_from_slice(&t.qy);
            let new_force = n.force_n;
            let change = (new_force - force).abs() / new_force.abs().max(1e-300);
            force = new_force;
            if self.mu == 0.0 || change <= stop {
                converged = n.converged && t.converged;
                break t;
            }
            if sweeps >= max_sweeps {
                break t;
            }
        };
        // The surface's tangential displacement now: what the next increment's stuck points
        // keep.
        let (mut tx, mut ty) = (vec![0.0; len], vec![0.0; len]);
        self.op.tangential(&self.qx, &self.qy, &mut tx, &mut ty);
        for i in 0..len {
            self.ux[i] = tx[i] + sx[i];
            self.uy[i] = ty[i] + sy[i];
        }
        self.depth_mm = depth_mm;
        let t = TangentialSolution {
            fx_n: self.qx.iter().sum::<f64>() * area,
            fy_n: self.qy.iter().sum::<f64>() * area,
            ..t
        };
        Ok(PressingSolution {
            force_n: self.p.iter().sum::<f64>() * area,
            p: self.p.clone(),
            t,
            sweeps,
            converged,
        })
    }

    /// The surface's tangential displacement after the last increment (x, y), mm.
    pub fn tangential_displacement(&self) -> (&[f64], &[f64]) {
        (&self.ux, &self.uy)
    }
}

/// Depths from first touch to `max_depth_mm` in `steps` increments that catch the contact's
/// growth evenly: a curved contact's radius grows as √δ (Hertz), so the depths are spaced
/// evenly in √δ and each increment adds about the same width of newly caught surface.
pub fn path_depths(max_depth_mm: f64, steps: usize) -> Vec<f64> {
    let steps = steps.max(1);
    (1..=steps)
        .map(|k| max_depth_mm * (k as f64 / steps as f64).powi(2))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::operator::{Grid, LayerOperator};
    use crate::pressing::{Pressing, pressing};

    /// A 12 mm sphere on a 2 mm layer (ν = 0.49), pressed until its contact is about 1.8 h
    /// wide: the layer's coupling is what friction holds, and on a thin layer it is strong
    /// (a contact small against h sees a nearly incompressible half-space, and nothing).
    const R_MM: f64 = 6.0;
    const H_MM: f64 = 2.0;
    const DEPTH_MM: f64 = 0.3;

    fn sphere(g: Grid) -> Vec<f64> {
        (0..g.len())
            .map(|i| {
                let (x, y) = g.xy(i);
                let r2 = x * x + y * y;
                if r2 < R_MM * R_MM {
                    R_MM - (R_MM * R_MM - r2).sqrt()
                } else {
                    1e3
                }
            })
            .collect()
    }

    fn layer(cells_across: usize) -> LayerOperator {
        let a = (R_MM * DEPTH_MM).sqrt() * 1.1;
        let dx = 2.0 * a / cells_across as f64;
        let n = LayerOperator::period_for(2.0 * a, H_MM, dx);
        LayerOperator::new(Grid { n, dx }, H_MM, 0.15 / 2.98, 0.49)
    }

    fn tol() -> Tolerance {
        Tolerance {
            rel: 1e-9,
            max_iter: 2000,
        }
    }

    fn press(op: &dyn Compliance, mu: f64, steps: usize) -> Vec<PressingSolution> {
        let prof = sphere(op.grid());
        let mut path = CurvedPath::new(op, &prof, mu, tol());
        path_depths(DEPTH_MM, steps)
            .into_iter()
            .map(|d| path.press_to(d).expect("forward"))
            .collect()
    }

    #[test]
    fn frictionless_increments_are_the_frictionless_contact_at_each_depth() {
        let op = layer(16);
        let prof = sphere(op.grid());
        let steps = press(&op, 0.0, 4);
        for (s, d) in steps.iter().zip(path_depths(DEPTH_MM, 4)) {
            let free = normal_unknown_area(&op, &prof, d, None, tol());
            assert!(
                (s.force_n - free.force_n).abs() < 1e-6 * free.force_n,
                "{d} mm: {} vs {}",
                s.force_n,
                free.force_n
            );
            assert!(s.t.qx.iter().chain(&s.t.qy).all(|q| *q == 0.0));
        }
    }

    #[test]
    fn friction_on_the_layer_presses_harder_holds_inward_and_balances() {
        let op = layer(16);
        let free = press(&op, 0.0, 8);
        let held = press(&op, 0.6, 8);
        let stuck = press(&op, 1e3, 8);
        let (f0, f1, f2) = (
            free.last().expect("steps").force_n,
            held.last().expect("steps").force_n,
            stuck.last().expect("steps").force_n,
        );
        // The held outward flow pushes the surface back into the indenter: more force, and
        // more with more friction.
        assert!(f1 > 1.03 * f0, "μ 0.6 {f1} vs frictionless {f0}");
        assert!(f2 >= f1 * (1.0 - 1e-6), "stuck {f2} vs μ 0.6 {f1}");
        let s = held.last().expect("steps");
        assert!(s.converged, "{} sweeps", s.sweeps);
        let g = op.grid();
        let inward: f64 = (0..g.len())
            .map(|i| {
                let (x, y) = g.xy(i);
                -(x * s.t.qx[i] + y * s.t.qy[i])
            })
            .sum();
        assert!(inward > 0.0, "tractions point outward: {inward}");
        assert!(s.t.fx_n.abs() < 1e-6 * s.force_n && s.t.fy_n.abs() < 1e-6 * s.force_n);
        for q in [&held, &stuck] {
            let last = q.last().expect("steps");
            for i in 0..g.len() {
                assert!(last.t.qx[i].hypot(last.t.qy[i]) <= 1e3 * last.p[i].max(0.0) + 1e-12);
            }
        }
    }

    #[test]
    fn caught_where_it_was_holds_less_than_held_from_the_undeformed_surface() {
        // Points caught already displaced outward need less traction than the one-way
        // (Goodman) solution, which pulls every contact point back to where it started.
        let op = layer(16);
        let path = press(&op, 1e3, 8);
        let last = path.last().expect("steps");
        let (one_way, _) = one_way(&op, &last.p);
        let sum =
            |qx: &[f64], qy: &[f64]| -> f64 { qx.iter().zip(qy).map(|(a, b)| a.hypot(*b)).sum() };
        let incremental = sum(&last.t.qx, &last.t.qy);
        let goodman = sum(&one_way.qx, &one_way.qy);
        assert!(
            incremental < 0.9 * goodman,
            "incremental {incremental} vs one-way {goodman}"
        );
    }

    fn one_way(op: &dyn Compliance, p: &[f64]) -> (TangentialSolution, ()) {
        let len = op.grid().len();
        let (mut sx, mut sy) = (vec![0.0; len], vec![0.0; len]);
        op.tangential_from_normal(p, &mut sx, &mut sy);
        let zero = vec![0.0; len];
        let t = tangential(&Tangential {
            op,
            p,
            mu: 1e3,
            target: (&zero, &zero),
            source: Some((&sx, &sy)),
            x_only: false,
            initial: None,
            tol: tol(),
        });
        (t, ())
    }

    #[test]
    fn a_shifts_moment_and_a_tilts_shear_force_are_reciprocal() {
        // Betti's theorem on the contact held without slip (the coupled operator is
        // symmetric): the pressure's first moment per unit shift along x equals the shear
        // force per unit tilt about y, θ·∫x Δp_shift dA = s·ΔFx_tilt, the tilt pressing
        // the indenter deeper by θx. The two sides come from different loadings, so a sign
        // or a factor lost in the coupling or in the displaced stick targets breaks it.
        let op = layer(16);
        let g = op.grid();
        let prof = sphere(g);
        let (shift_mm, theta) = (1e-3, 1e-4);
        let tilted: Vec<f64> = (0..g.len()).map(|i| prof[i] - theta * g.xy(i).0).collect();
        let solve = |prof: &[f64], offset| {
            CurvedPath::displaced(&op, prof, 1e6, tol(), offset)
                .press_to(DEPTH_MM)
                .expect("forward")
        };
        let (base, shifted, tilt) = (
            solve(&prof, (0.0, 0.0)),
            solve(&prof, (shift_mm, 0.0)),
            solve(&tilted, (0.0, 0.0)),
        );
        let moment = |s: &PressingSolution| -> f64 {
            (0..g.len()).map(|i| g.xy(i).0 * s.p[i]).sum::<f64>() * g.area()
        };
        let per_shift = (moment(&shifted) - moment(&base)) / shift_mm;
        let per_tilt = (tilt.t.fx_n - base.t.fx_n) / theta;
        assert!(
            per_shift > 0.0,
            "the leading side presses harder: {per_shift}"
        );
        assert!(
            (per_tilt / per_shift - 1.0).abs() < 0.02,
            "moment per shift {per_shift} N, shear per tilt {per_tilt} N"
        );
        // The shift itself is a plain shear: Fx along it, nothing across.
        assert!(shifted.t.fx_n > 0.0 && shifted.t.fy_n.abs() < 1e-6 * shifted.t.fx_n);
    }

    #[test]
    fn finer_increments_converge() {
        let op = layer(16);
        let force = |steps| press(&op, 0.6, steps).last().expect("steps").force_n;
        let (f4, f8, f16) = (force(4), force(8), force(16));
        let (d1, d2) = ((f8 - f4).abs(), (f16 - f8).abs());
        assert!(d2 < d1, "{f4} {f8} {f16}");
        assert!(d2 < 2e-3 * f16, "{f4} {f8} {f16}");
    }

    #[test]
    fn a_flat_face_loads_proportionally_whatever_the_increments() {
        // A flat punch touches everywhere at once: the path's stuck points all start at
        // zero, so any number of increments gives the flat punch's coupled solution.
        let op = layer(16);
        let g = op.grid();
        let a = 1.5;
        let mask: Vec<bool> = (0..g.len())
            .map(|i| {
                let (x, y) = g.xy(i);
                x * x + y * y <= a * a
            })
            .collect();
        let prof: Vec<f64> = mask.iter().map(|m| if *m { 0.0 } else { 1e3 }).collect();
        let zero = vec![0.0; g.len()];
        let once = pressing(&Pressing {
            op: &op,
            mask: &mask,
            uz: &vec![0.1; g.len()],
            target: (&zero, &zero),
            mu: 1e3,
            tol: tol(),
        });
        let mut path = CurvedPath::new(&op, &prof, 1e3, tol());
        let mut last = None;
        for d in [0.02, 0.05, 0.1] {
            last = Some(path.press_to(d).expect("forward"));
        }
        let last = last.expect("steps");
        let rel = (last.force_n - once.force_n).abs() / once.force_n;
        assert!(rel < 1e-4, "{} vs {}", last.force_n, once.force_n);
        // Backed off, the path is accepted and solved: a flat face caught everywhere at
        // first touch holds every point at zero displacement throughout, so at 0.05 mm it
        // is the loading state (this checks the increment backwards, not friction's memory:
        // the sphere's test below does that).
        let back = path.press_to(0.05).expect("unloads");
        let mut fresh = CurvedPath::new(&op, &prof, 1e3, tol());
        let ahead = fresh.press_to(0.05).expect("forward");
        let rel = (back.force_n - ahead.force_n).abs() / ahead.force_n;
        assert!(rel < 1e-4, "{} vs {}", back.force_n, ahead.force_n);
        assert!(matches!(
            path.press_to(f64::NAN),
            Err(PathError::NotFinite(_))
        ));
        assert_eq!(
            path.depth_mm(),
            0.05,
            "a refused increment leaves the path where it was"
        );
    }

    #[test]
    fn a_sphere_backed_off_retraces_its_loading_path() {
        // Loaded to 0.3 mm and backed off along the same depths: frictionless, the path
        // retraces itself (each increment is the frictionless contact of its depth). With
        // friction the stuck points keep where they were caught as the contact recedes, and
        // a point caught without slipping has kept that displacement since, so the way back
        // is the way there; the rim that slips as it is caught (μ = 0.6) leaves no gap
        // beyond the sweeps' stop (a force change of √1e-9 = 3.2e-5): as μ = 1000, which
        // sticks everywhere.
        let op = layer(16);
        let depths = path_depths(DEPTH_MM, 8);
        for mu in [0.0, 0.6, 1e3] {
            let prof = sphere(op.grid());
            let mut path = CurvedPath::new(&op, &prof, mu, tol());
            let up: Vec<f64> = depths
                .iter()
                .map(|d| path.press_to(*d).expect("forward").force_n)
                .collect();
            let down: Vec<f64> = depths
                .iter()
                .rev()
                .skip(1)
                .map(|d| path.press_to(*d).expect("back").force_n)
                .collect();
            let gaps: Vec<f64> = down
                .iter()
                .zip(up.iter().rev().skip(1))
                .map(|(d, u)| d / u - 1.0)
                .collect();
            let bound = if mu == 0.0 { 1e-6 } else { 1e-4 };
            assert!(gaps.iter().all(|g| g.abs() < bound), "μ {mu}: {gaps:?}");
            // Backed off to where it started: nothing is pressed.
            let gone = path.press_to(0.0).expect("back to first touch");
            assert!(gone.force_n.abs() < 1e-9, "μ {mu}: {}", gone.force_n);
        }
    }
}
