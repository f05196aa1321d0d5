//! The pressed state's tractions (what holds the surface the layer's coupling pushes
//! outward), and a curved indenter pressed with friction (`ModelSpec::pressing_friction`):
//! its loading path ([`crate::pressing::curved`]) sets the normal table's force, and the pressed state
//! (pressure and the tractions that hold the caught surface) from which fields and
//! tangential tables start.
//!
//! Frictionless, a curved indenter's state is a function of its depth; with friction it is a
//! function of the path, and the model follows the one path a pressing run takes: monotonic
//! loading from first touch. A retracting indenter is given the loading path's state at its
//! depth: backed off along the normal, the path itself gives the same to the solver's floor
//! for the shipped contacts, whose only slip is a thin rim as it is caught
//! (`unloading_friction` example; BENCHMARKS.md, "Curved indenters pressed with friction").

use std::sync::Arc;

use super::{ContactModel, Entry, Normal, PressingTractions, quantise, tol};
use crate::Indenter;
use crate::MechanicsError;
use crate::operator::{Compliance, Grid, LayerOperator};
use crate::pressing::curved::{CurvedPath, path_depths};
use crate::solve::{Tangential, normal_unknown_area, tangential};

// Increments of a loading path, spaced evenly in √δ (each catches about the same width of
// surface), are `Quality::path_steps`. At the default 16 a pressed state's force is 0.2–0.4 %
// high at the shipped sphere's and can's deepest depths (the catch lags one increment); the
// normal table's force is extrapolated across half as many and that many (BENCHMARKS.md,
// "Curved indenters pressed with friction"). The extrapolation pairs the coarse path's
// increment k with the fine one's 2k + 1, so the count is even (at least 2).

/// The paths' inner tolerance: the sweeps stop at a force change of its square root (3e-5),
/// well under the 0.1 % the table's force is checked to (the extrapolation triples that
/// noise).
fn path_tol() -> crate::solve::Tolerance {
    crate::solve::Tolerance {
        rel: 1e-9,
        max_iter: 4000,
    }
}

/// The pressed state of a curved indenter at one depth, on the grid of its tables.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub(super) struct Pressed {
    /// Pressure with friction, MPa.
    pub p: Vec<f64>,
    /// The frictionless pressure at the same depth on the same grid, MPa (the field adds
    /// the difference to its own finer frictionless pressure).
    pub p_free: Vec<f64>,
    /// Tractions that hold the caught surface (x, y), MPa.
    pub qx: Vec<f64>,
    pub qy: Vec<f64>,
    /// Cells of the contact that stick.
    pub stick: Vec<bool>,
    pub grid: Grid,
}

impl ContactModel {
    /// Whether a curved indenter is pressed with friction.
    pub(super) fn curved_friction(&self) -> bool {
        self.spec.pressing_friction
            && self.spec.contact.material.friction > 0.0
            && matches!(self.normal, Normal::Curved { .. })
    }

    /// The indenter's surface on `op`'s grid.
    pub(super) fn profile_on(&self, op: &LayerOperator) -> Vec<f64> {
        let g = op.grid();
        let c = &self.spec.contact;
        (0..g.len())
            .map(|i| {
                let (x, y) = g.xy(i);
                super::shapes::profile(&c.indenter, c.layer.width_mm, x, y)
            })
            .collect()
    }

    /// The grid of the force ratio's path to `depth_mm`: `cells_curved` cells across 2.4
    /// Hertz half-widths √(Rδ) — the contact's narrow width; the tables' grids are sized by
    /// √(A/π), which for the can's long strip gives them 6 cells across it at 0.3 mm, this
    /// grid about 14 — over the tables' span.
    fn ratio_operator(&self, depth_mm: f64) -> LayerOperator {
        let c = &self.spec.contact;
        let table = self.op_for(depth_mm);
        let radius = match c.indenter {
            Indenter::Sphere { diameter_mm } | Indenter::Cylinder { diameter_mm, .. } => {
                diameter_mm / 2.0
            }
            _ => c.indenter.footprint_mm() / 2.0,
        };
        let dx = (2.4 * (radius * depth_mm).sqrt() / self.spec.quality.cells_curved as f64)
            .min(table.grid().dx);
        let span = table.grid().dx * table.grid().n as f64;
        LayerOperator::new(
            Grid {
                n: crate::operator::fast_size((span / dx).ceil() as usize),
                dx,
            },
            c.layer.thickness_mm,
            c.material.shear_modulus_mpa(),
            c.material.poisson_ratio,
        )
    }

    /// Scales the frictionless normal table by the force friction adds along the loading
    /// path: one path to the table's deepest depth on a grid resolving that contact, the
    /// ratio interpolated in √δ between its increments (the ratio converges with the grid
    /// where the force alone does not: the same reasoning as the flat punch's exact κ times
    /// its grid's ratio).
    pub(super) fn press_curved_table_with_friction(&mut self) -> Result<(), MechanicsError> {
        if !self.curved_friction() {
            return Ok(());
        }
        let Normal::Curved {
            depths_mm,
            forces_n,
            ..
        } = &self.normal
        else {
            return Ok(());
        };
        let Some(&deepest) = depths_mm.last() else {
            return Ok(());
        };
        let op = self.ratio_operator(deepest);
        let prof = self.profile_on(&op);
        let mu = self.spec.contact.material.friction;
        // The frictionless force where the ratio is taken, the coarse path's depths (once;
        // it was solved again for each path, 24 solves for these 8).
        let steps = self.path_steps();
        let free: Vec<f64> = path_depths(deepest, steps / 2)
            .into_iter()
            .map(|d| normal_unknown_area(&op, &prof, d, None, path_tol()).force_n)
            .collect();
        // The path's force at its increments' depths; NaN where an increment did not solve
        // (refused below: a silent frictionless force would pass for the answer).
        let held = |steps: usize| -> Vec<f64> {
            let mut path = CurvedPath::new(&op, &prof, mu, path_tol());
            path_depths(deepest, steps)
                .into_iter()
                .map(|d| {
                    path.press_to(d)
                        .ok()
                        .filter(|s| s.converged)
                        .map_or(f64::NAN, |s| s.force_n)
                })
                .collect()
        };
        // The catch lags one increment, so the force errs at first order in the increment:
        // Richardson across steps / 2 and steps increments, at the coarse path's
        // depths (every other one of the fine path's: coarse k is fine 2k + 1). Within
        // 0.09 % of an independent finite-element solution on the box sphere, where 16
        // increments alone were 0.4 % high (BENCHMARKS.md, "Curved indenters pressed with
        // friction").
        let (coarse, fine) = (held(steps / 2), held(steps));
        let mut points = vec![(0.0, 1.0)];
        for (k, d) in path_depths(deepest, steps / 2).into_iter().enumerate() {
            let fine_k = fine.get(2 * k + 1).copied().unwrap_or(f64::NAN);
            let r = (2.0 * fine_k - coarse[k]) / free[k];
            if !(r.is_finite() && r > 0.0) {
                return Err(MechanicsError::OutOfRange {
                    name: "pressing-with-friction force ratio",
                    value: r,
                    allowed: "finite and positive: the loading path did not solve at this \
                              depth; run the bench without `pressing_friction`",
                });
            }
            points.push((d.sqrt(), r));
        }
        let ratio = |d: f64| -> f64 {
            let x = d.sqrt();
            let i = points.partition_point(|(r, _)| *r <= x);
            match (points.get(i.wrapping_sub(1)), points.get(i)) {
                (Some(a), Some(b)) => a.1 + (b.1 - a.1) * (x - a.0) / (b.0 - a.0),
                (Some(a), None) => a.1,
                _ => 1.0,
            }
        };
        let scaled: Vec<f64> = depths_mm
            .iter()
            .zip(forces_n)
            .map(|(d, f)| f * ratio(*d))
            .collect();
        if let Normal::Curved { forces_n, .. } = &mut self.normal {
            *forces_n = scaled;
        }
        Ok(())
    }

    /// The loading path's increments, even and at least 2 (`Quality::path_steps`).
    fn path_steps(&self) -> usize {
        (self.spec.quality.path_steps.max(2) / 2) * 2
    }

    /// The pressed state at the depth bucket `key` (0.5 % of the thickness each) on the grid
    /// of that depth's tangential tables: its loading path followed there in `Quality::path_steps`
    /// increments (cached). The depth comes from the key, so a cached state always lives on
    /// the grid `op_for` gives its depth.
    pub(super) fn pressed(&mut self, key: u64) -> Pressed {
        if let Some(p) = self.pressed.get(&key) {
            return p.clone();
        }
        let name = format!("pressed/{key}");
        if let Some(Entry::Pressed(p)) = self.fetch(&name) {
            self.pressed.insert(key, p.clone());
            return p;
        }
        let h = self.spec.contact.layer.thickness_mm;
        let depth_mm = (key as f64 / 200.0 * h).max(1e-4 * h);
        let op = self.op_for(depth_mm);
        let prof = self.profile_on(&op);
        let mu = self.spec.contact.material.friction;
        let mut path = CurvedPath::new(&op, &prof, mu, path_tol());
        // The path's depths increase from a finite start: no increment is refused.
        let last = path_depths(depth_mm, self.path_steps())
            .into_iter()
            .filter_map(|d| path.press_to(d).ok())
            .last();
        let p_free = normal_unknown_area(&op, &prof, depth_mm, None, path_tol()).p;
        let state = match last {
            Some(s) => Pressed {
                p: s.p,
                p_free,
                qx: s.t.qx,
                qy: s.t.qy,
                stick: s.t.stick,
                grid: op.grid(),
            },
            None => Pressed {
                stick: p_free.iter().map(|v| *v > 0.0).collect(),
                qx: vec![0.0; p_free.len()],
                qy: vec![0.0; p_free.len()],
                p: p_free.clone(),
                p_free,
                grid: op.grid(),
            },
        };
        self.keep(&name, || Entry::Pressed(state.clone()));
        self.pressed.insert(key, state.clone());
        state
    }

    /// What friction adds to a curved indenter's pressure on the field grid `op` at the
    /// bucket `key`: the pressed state's pressure less its frictionless one, resampled from
    /// the table grid (the field keeps its own, finer frictionless pressure).
    pub(super) fn friction_pressure_on(&mut self, op: &LayerOperator, key: u64) -> Vec<f64> {
        let s = self.pressed(key);
        let g = op.grid();
        let src = s.grid;
        let extent = src.dx * src.n as f64 / 2.0;
        let diff: Vec<f64> = s.p.iter().zip(&s.p_free).map(|(a, b)| a - b).collect();
        (0..g.len())
            .map(|i| {
                let (x, y) = g.xy(i);
                if x.abs() < extent && y.abs() < extent {
                    src.sample(&diff, x, y)
                } else {
                    0.0
                }
            })
            .collect()
    }

    /// Friction tractions of a curved indenter's pressed state at `depth_mm`'s bucket
    /// (cached and shared). A flat punch's field takes its pressed state from the field
    /// grid's own (`u64::MAX` in the same map), never from here.
    pub(super) fn pressing_tractions(&mut self, depth_mm: f64) -> Arc<PressingTractions> {
        let h = self.spec.contact.layer.thickness_mm;
        let key = quantise(depth_mm, h);
        if let Some(e) = self.pressing.get(&key) {
            return Arc::clone(e);
        }
        let name = format!("pressing/{key}");
        if let Some(Entry::Pressing(e)) = self.fetch(&name) {
            let e = Arc::new(e);
            self.pressing.insert(key, Arc::clone(&e));
            return e;
        }
        let e = if self.curved_friction() {
            let s = self.pressed(key);
            (s.qx, s.qy, s.grid)
        } else {
            let d = (key as f64 / 200.0 * h).max(1e-4 * h);
            let op = self.op_for(d);
            let p = self.pressure_on(&op, d);
            let g = op.grid();
            let (mut sx, mut sy) = (vec![0.0; g.len()], vec![0.0; g.len()]);
            op.tangential_from_normal(&p, &mut sx, &mut sy);
            let zero = vec![0.0; g.len()];
            let s = tangential(&Tangential {
                op: &op,
                p: &p,
                mu: self.spec.contact.material.friction,
                target: (&zero, &zero),
                source: Some((&sx, &sy)),
                x_only: false,
                initial: None,
                tol: tol(),
            });
            (s.qx, s.qy, g)
        };
        self.keep(&name, || Entry::Pressing(e.clone()));
        let e = Arc::new(e);
        self.pressing.insert(key, Arc::clone(&e));
        e
    }
}
