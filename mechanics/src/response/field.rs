//! The surface displacement field of a contact state: the pressure and the tangential
//! tractions of the tables around its depth, gathered on the grids they were solved on,
//! resampled once onto the field grid, and one pass of the layer operator.
//!
//! A dry run asks for a field at every camera frame (3 685 in a 10-trial grasp run), so
//! nothing here copies a table: the tables are shared, a table's levels are blended
//! straight into one sum per source grid, and only the field cells over the tractions'
//! support are resampled (BENCHMARKS.md, "Grasp trials that feel slip": the lifting-can dry
//! run's wall against the per-frame copies and whole-grid resampling this replaced).

use std::sync::Arc;

use super::{
    ContactModel, Field, Kind, LayerOperator, Normal, State, TangentialTable, face_mask,
    flat_pressing,
};
use crate::operator::{Compliance, Grid};

/// Tangential tractions summed on one source grid before they are resampled.
struct OnGrid {
    grid: Grid,
    qx: Vec<f64>,
    qy: Vec<f64>,
}

/// Sums of tractions, one per source grid (a curved indenter's two depth buckets each
/// have their own; a flat punch's tables share one).
#[derive(Default)]
struct Gathered(Vec<OnGrid>);

impl Gathered {
    /// The sum on `grid`, started at zero when it is the first on that grid.
    fn on(&mut self, grid: Grid) -> &mut OnGrid {
        let i = match self.0.iter().position(|s| s.grid == grid) {
            Some(i) => i,
            None => {
                self.0.push(OnGrid {
                    grid,
                    qx: vec![0.0; grid.len()],
                    qy: vec![0.0; grid.len()],
                });
                self.0.len() - 1
            }
        };
        &mut self.0[i]
    }

    /// Adds `weight` × `table`'s tractions for force (or torque) `f` on its grid.
    fn add_table(&mut self, table: &TangentialTable, f: f64, weight: f64) {
        let sum = self.on(table.grid);
        table.add_tractions_for_force(f, weight, &mut sum.qx, &mut sum.qy);
    }
}

/// Adds `weight` × (qx, qy) to (out_x, out_y), cell by cell on one grid.
fn add_weighted(out_x: &mut [f64], out_y: &mut [f64], qx: &[f64], qy: &[f64], weight: f64) {
    for (o, v) in out_x.iter_mut().zip(qx) {
        *o += weight * v;
    }
    for (o, v) in out_y.iter_mut().zip(qy) {
        *o += weight * v;
    }
}

/// Adds the tractions of `src` to (qx, qy) on `dst`, sampled bilinearly at `dst`'s cell
/// centres inside `src`'s period. Only the cells within one source cell of the tractions'
/// support are visited: elsewhere every bilinear sample is exactly zero.
fn resample_add(src: &OnGrid, dst: Grid, qx: &mut [f64], qy: &mut [f64]) {
    let n = src.grid.n;
    let (mut lo, mut hi) = ((n, n), (0, 0));
    for (i, (x, y)) in src.qx.iter().zip(&src.qy).enumerate() {
        if *x != 0.0 || *y != 0.0 {
            let (ix, iy) = (i % n, i / n);
            lo = (lo.0.min(ix), lo.1.min(iy));
            hi = (hi.0.max(ix), hi.1.max(iy));
        }
    }
    if lo.0 > hi.0 {
        return;
    }
    let half = src.grid.dx * n as f64 / 2.0;
    // Source cell i's centre is at (i − n/2 + 0.5)·dx; a sample is nonzero only strictly
    // between the centres of the cells just outside the support.
    let reach = |i: usize, step: f64| src.grid.coord(i) + step * src.grid.dx;
    let x_range = (reach(lo.0, -1.0), reach(hi.0, 1.0));
    let y_range = (reach(lo.1, -1.0), reach(hi.1, 1.0));
    let cells = |(a, b): (f64, f64)| {
        // Destination indices whose centres lie in [a, b].
        let first = (a / dst.dx + (dst.n / 2) as f64 - 0.5).ceil().max(0.0) as usize;
        let last = (b / dst.dx + (dst.n / 2) as f64 - 0.5).floor();
        let last = if last < 0.0 {
            0
        } else {
            (last as usize + 1).min(dst.n)
        };
        first..last.max(first)
    };
    for iy in cells(y_range) {
        let y = dst.coord(iy);
        if y.abs() >= half {
            continue;
        }
        for ix in cells(x_range) {
            let x = dst.coord(ix);
            if x.abs() >= half {
                continue;
            }
            let i = iy * dst.n + ix;
            qx[i] += src.grid.sample(&src.qx, x, y);
            qy[i] += src.grid.sample(&src.qy, x, y);
        }
    }
}

impl ContactModel {
    /// The surface displacement field of `state`, on the field grid (centred on the
    /// contact). `None` if the model was built without fields.
    pub fn field(&mut self, state: State) -> Option<Field> {
        let op = Arc::clone(self.field_op.as_ref()?);
        let grid = op.grid();
        let d = state.depth_mm;
        if d <= 0.0 {
            let z = vec![0.0; grid.len()];
            return Some(Field {
                grid,
                ux: z.clone(),
                uy: z.clone(),
                uz: z,
            });
        }
        let flat = matches!(self.normal, Normal::Flat { .. });
        let p = match flat {
            true => {
                self.flat_field_tractions()?;
                let unit = self.field_pressure.get(&u64::MAX)?;
                unit.iter().map(|v| v * d).collect()
            }
            false => self.curved_field_pressure(&op, d),
        };
        let (mut qx, mut qy) = (vec![0.0; grid.len()], vec![0.0; grid.len()]);
        let mut gathered = Gathered::default();
        // Tangential tractions only for a loaded channel: an unloaded one would cost a
        // backbone solve for nothing. A curved indenter's tables are those of the two depth
        // buckets around the depth, blended as its pressure is (a creeping grasp's field
        // jumped by 3 % where it crossed a bucket's midpoint).
        let buckets = if flat {
            vec![(d, 1.0)]
        } else {
            self.depth_buckets(d)
        };
        for (db, w) in buckets {
            let shear = if state.shear_n != 0.0 {
                self.shared_table(db, Kind::Shear)
            } else {
                None
            };
            let twist = if state.torque_nmm != 0.0 {
                self.shared_table(db, Kind::Twist)
            } else {
                None
            };
            // A flat punch's tables are at unit depth: at depth d every traction is d times
            // the unit table's at force f/d.
            let scale = if flat { db } else { 1.0 };
            let (f_shear, f_twist) = (state.shear_n / scale, state.torque_nmm / scale);
            match (&shear, &twist) {
                (Some(s), _) => {
                    gathered.add_table(s, f_shear, w * scale);
                    if let Some(tw) = &twist {
                        gathered.add_table(tw, f_twist, w * scale);
                        // Both tables start from the same pressed state: count it once.
                        let sum = gathered.on(tw.grid);
                        let (px, py) = (&tw.pressing.0, &tw.pressing.1);
                        add_weighted(&mut sum.qx, &mut sum.qy, px, py, -w * scale);
                    }
                }
                (None, Some(tw)) => gathered.add_table(tw, f_twist, w * scale),
                // Normal load only: friction still holds the pressed surface where it
                // touched against the layer's outward flow.
                (None, None) if flat => {
                    let (px, py, _) = &**self.pressing.get(&u64::MAX)?;
                    add_weighted(&mut qx, &mut qy, px, py, d);
                }
                (None, None) => {
                    let (px, py, g) = &*self.pressing_tractions(db);
                    let sum = gathered.on(*g);
                    add_weighted(&mut sum.qx, &mut sum.qy, px, py, w);
                }
            }
        }
        for sum in &gathered.0 {
            if sum.grid == grid {
                add_weighted(&mut qx, &mut qy, &sum.qx, &sum.qy, 1.0);
            } else {
                resample_add(sum, grid, &mut qx, &mut qy);
            }
        }
        let [ux, uy, uz] = op.full(&qx, &qy, &p);
        Some(Field { grid, ux, uy, uz })
    }

    /// Unit-depth pressure and pressing friction of a flat punch, solved on a grid twice
    /// as fine as the field grid (same period) and restricted to it by 2×2 cell averages:
    /// the edge singularity is resolved where it is solved, and each frame still costs one
    /// field-grid evaluation (BENCHMARKS.md: 256² field error 1.6 % → see there). Cached
    /// under the key `u64::MAX` of `field_pressure` and `pressing`.
    fn flat_field_tractions(&mut self) -> Option<()> {
        if self.field_pressure.contains_key(&u64::MAX) {
            return Some(());
        }
        let op: Arc<LayerOperator> = Arc::clone(self.field_op.as_ref()?);
        let g = op.grid();
        let c = &self.spec.contact;
        let fine_grid = Grid {
            n: 2 * g.n,
            dx: g.dx / 2.0,
        };
        let fine = LayerOperator::new(
            fine_grid,
            c.layer.thickness_mm,
            c.material.shear_modulus_mpa(),
            c.material.poisson_ratio,
        );
        let mask = face_mask(&c.indenter, fine_grid);
        let press = flat_pressing(
            &fine,
            &mask,
            c.material.friction,
            self.spec.pressing_friction,
        );
        let (p, press) = (press.p, press.t);
        let restrict = |f: &[f64]| -> Vec<f64> {
            let (n, m) = (g.n, fine_grid.n);
            (0..g.len())
                .map(|i| {
                    let (ix, iy) = (i % n, i / n);
                    let k = 2 * iy * m + 2 * ix;
                    0.25 * (f[k] + f[k + 1] + f[k + m] + f[k + m + 1])
                })
                .collect()
        };
        let (p, qx, qy) = (restrict(&p), restrict(&press.qx), restrict(&press.qy));
        self.field_pressure.insert(u64::MAX, p);
        self.pressing.insert(u64::MAX, Arc::new((qx, qy, g)));
        Some(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Resampling only over the support gives what sampling every field cell gives, for a
    /// support off centre, at the source's edge cells and on grids of unrelated cell sizes.
    #[test]
    fn resampling_over_the_support_matches_sampling_every_cell() {
        let src_grid = Grid { n: 40, dx: 0.137 };
        let mut src = OnGrid {
            grid: src_grid,
            qx: vec![0.0; src_grid.len()],
            qy: vec![0.0; src_grid.len()],
        };
        for i in 0..src_grid.len() {
            let (x, y) = src_grid.xy(i);
            if (x - 0.9).hypot(y + 0.4) < 1.1 {
                src.qx[i] = 1.0 + x * y;
                src.qy[i] = x - 2.0 * y;
            }
        }
        // A lone cell at the source's corner.
        src.qx[0] = 3.0;
        for dst in [Grid { n: 96, dx: 0.071 }, Grid { n: 64, dx: 0.25 }] {
            let (mut qx, mut qy) = (vec![0.0; dst.len()], vec![0.0; dst.len()]);
            resample_add(&src, dst, &mut qx, &mut qy);
            let half = src_grid.dx * src_grid.n as f64 / 2.0;
            let mut touched = 0;
            for i in 0..dst.len() {
                let (x, y) = dst.xy(i);
                let inside = x.abs() < half && y.abs() < half;
                let (ex, ey) = match inside {
                    true => (
                        src_grid.sample(&src.qx, x, y),
                        src_grid.sample(&src.qy, x, y),
                    ),
                    false => (0.0, 0.0),
                };
                assert_eq!((qx[i], qy[i]), (ex, ey), "cell {i} of {dst:?}");
                touched += usize::from(ex != 0.0 || ey != 0.0);
            }
            assert!(touched > 20, "{touched} cells carry tractions");
        }
    }
}
