//! A curved indenter's normal table: force and contact radius against depth, each depth
//! solved on a grid adapted to its contact (Polonsky–Keer).

use std::f64::consts::PI;

use super::{ContactModel, Entry, Normal, tol};
use crate::Indenter;
use crate::operator::{Compliance, Grid, LayerOperator, fast_size};
use crate::solve::normal_unknown_area;

impl ContactModel {
    pub(super) fn curved_table(&self, max_depth: f64) -> Normal {
        let c = &self.spec.contact;
        let h = c.layer.thickness_mm;
        let mu_mod = c.material.shear_modulus_mpa();
        let nu = c.material.poisson_ratio;
        let radius = match c.indenter {
            Indenter::Sphere { diameter_mm } | Indenter::Cylinder { diameter_mm, .. } => {
                diameter_mm / 2.0
            }
            _ => 1.0,
        };
        let length = match c.indenter {
            Indenter::Cylinder { length_mm, .. } => length_mm.min(c.layer.width_mm),
            _ => 0.0,
        };
        let fractions = [
            0.005, 0.01, 0.02, 0.035, 0.05, 0.075, 0.1, 0.15, 0.2, 0.25, 0.3, 0.4, 0.5, 0.6, 0.7,
            0.8, 0.9, 0.95,
        ];
        let mut depths = Vec::new();
        let mut forces = Vec::new();
        let mut radii = Vec::new();
        let mut growth: f64 = 1.1;
        for f in fractions {
            let d = f * h;
            if d > max_depth * 1.05 && depths.len() >= 2 {
                break;
            }
            let a_h = (radius * d).sqrt();
            let extent = 2.4 * a_h * growth;
            let dx = extent / self.spec.quality.cells_curved as f64;
            let span = extent.max(length * 1.1) + 8.0 * h;
            let grid = Grid {
                n: fast_size((span / dx).ceil() as usize),
                dx,
            };
            let op = LayerOperator::new(grid, h, mu_mod, nu);
            let s = normal_unknown_area(&op, &self.profile_on(&op), d, None, tol());
            let a = (s.area_mm2 / PI).sqrt();
            growth = (a / a_h).max(1.0) * 1.1;
            depths.push(d);
            forces.push(s.force_n);
            radii.push(a);
        }
        Normal::Curved {
            depths_mm: depths,
            forces_n: forces,
            radii_mm: radii,
        }
    }

    /// The two depth buckets (0.5 % of the thickness) around `depth_mm` with their linear
    /// weights, for the field's tables (as [`Self::curved_field_pressure`] blends the
    /// pressure: one bucket's tractions held until the midpoint made the field stand still
    /// and then jump there). The bucket at zero depth is left out: nothing is pressed there.
    pub(super) fn depth_buckets(&self, depth_mm: f64) -> Vec<(f64, f64)> {
        let h = self.spec.contact.layer.thickness_mm;
        let x = (depth_mm / h * 200.0).max(0.0);
        let lo = x.floor();
        let w = x - lo;
        [(lo, 1.0 - w), (lo + 1.0, w)]
            .into_iter()
            .filter(|&(key, weight)| key > 0.0 && weight > 1e-9)
            .map(|(key, weight)| (key / 200.0 * h, weight))
            .collect()
    }

    /// The pressure a curved indenter puts on the field grid `op` at `depth_mm`: solved at
    /// the two depth buckets (0.5 % of the thickness) around it, each cached, and blended
    /// linearly. The field then follows the depth continuously — a grasp's gel creeps by
    /// less than a bucket in seconds, and snapping to buckets held its field still while
    /// the depth moved.
    pub(super) fn curved_field_pressure(&mut self, op: &LayerOperator, depth_mm: f64) -> Vec<f64> {
        let h = self.spec.contact.layer.thickness_mm;
        let mut out = vec![0.0; op.grid().len()];
        for (d, w) in self.depth_buckets(depth_mm) {
            let key = (d / h * 200.0).round() as u64;
            if !self.field_pressure.contains_key(&key) {
                let name = format!("field_pressure/{key}");
                let p = match self.fetch(&name) {
                    Some(Entry::FieldPressure(p)) if p.len() == out.len() => p,
                    _ => {
                        let mut p = self.pressure_on(op, key as f64 / 200.0 * h);
                        // Pressed with friction: what the loading path adds, once per bucket.
                        if self.curved_friction() {
                            let extra = self.friction_pressure_on(op, key);
                            p.iter_mut().zip(&extra).for_each(|(a, b)| *a += b);
                        }
                        self.keep(&name, || Entry::FieldPressure(p.clone()));
                        p
                    }
                };
                self.field_pressure.insert(key, p);
            }
            if let Some(p) = self.field_pressure.get(&key) {
                out.iter_mut().zip(p).for_each(|(o, v)| *o += w * v);
            }
        }
        out
    }
}
