//! The surface displacement field of a contact state: the pressure and the tangential
//! tractions of the tables around its depth, gathered on the grids they were solved on,
//! resampled once onto the field grid, and one pass of the layer operator.
//!
//! A dry run asks for a field at every camera frame (3 684 in the 10-trial `lifting-can` run), so
//! nothing here copies a table: the tables are shared, a table's levels are blended
//! straight into one sum per source grid, and only the field cells over the tractions'
//! support are resampled (BENCHMARKS.md, "Grasp trials that feel slip": the lifting-can dry
//! run's wall against the per-frame copies and whole-grid resampling this replaced).

use std::sync::Arc;

use super::{
    ContactModel, Entry, Field, Kind, LayerOperator, Normal, State, TangentialTable, Tractions,
    face_mask, flat_pressing,
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
        self.field_and_tractions(state).map(|(f, _)| f)
    }

    /// [`Self::field`] and the surface tractions that make it (pressure and tangential
    /// tractions on the same grid): the displacements are the layer operator applied to
    /// exactly these.
    pub fn field_and_tractions(&mut self, state: State) -> Option<(Field, Tractions)> {
        let op = Arc::clone(self.field_op.as_ref()?);
        let grid = op.grid();
        let d = state.depth_mm;
        if d <= 0.0 {
            let z = vec![0.0; grid.len()];
            let field = Field {
                grid,
                ux: z.clone(),
                uy: z.clone(),
                uz: z.clone(),
            };
            let tractions = Tractions {
                grid,
                pressure_mpa: z.clone(),
                shear_x_mpa: z.clone(),
                shear_y_mpa: z,
            };
            return Some((field, tractions));
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
            // The pressed state, then what each loaded channel adds to it: its table's
            // tractions less the pressed state the table starts from. A flat punch's pressed
            // state is the field grid's own (solved finer and restricted): its table's,
            // resampled from the coarser table grid, put the edge's singular traction
            // outside the face, and the field jumped there by 0.037 mm (box-size punch,
            // 0.23 mm deep, 256 cells) the moment any shear was applied.
            if flat {
                let (px, py, _) = &**self.pressing.get(&u64::MAX)?;
                add_weighted(&mut qx, &mut qy, px, py, d);
            } else {
                let (px, py, g) = &*self.pressing_tractions(db);
                let sum = gathered.on(*g);
                add_weighted(&mut sum.qx, &mut sum.qy, px, py, w);
            }
            let loads = [(&shear, state.shear_n), (&twist, state.torque_nmm)];
            for (table, load) in loads {
                if let Some(t) = table {
                    gathered.add_table(t, load / scale, w * scale);
                    let sum = gathered.on(t.grid);
                    let (px, py) = (&t.pressing.0, &t.pressing.1);
                    add_weighted(&mut sum.qx, &mut sum.qy, px, py, -w * scale);
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
        let tractions = Tractions {
            grid,
            pressure_mpa: p,
            shear_x_mpa: qx,
            shear_y_mpa: qy,
        };
        Some((Field { grid, ux, uy, uz }, tractions))
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
        if let (Some(Entry::FieldPressure(p)), Some(Entry::Pressing(t))) = (
            self.fetch("field_pressure/flat"),
            self.fetch("pressing/flat"),
        ) && p.len() == g.len()
            && t.2 == g
        {
            self.field_pressure.insert(u64::MAX, p);
            self.pressing.insert(u64::MAX, Arc::new(t));
            return Some(());
        }
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
        self.keep("field_pressure/flat", || Entry::FieldPressure(p.clone()));
        self.keep("pressing/flat", || {
            Entry::Pressing((qx.clone(), qy.clone(), g))
        });
        self.field_pressure.insert(u64::MAX, p);
        self.pressing.insert(u64::MAX, Arc::new((qx, qy, g)));
        Some(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Indenter;
    use crate::response::{ModelSpec, Quality};

    /// Resampling only over the support gives what sampling every field cell gives: for an
    /// interior support (the margin below it and above it), a lone cell at either corner of
    /// the source (the clamped edges), on destination grids finer, coarser and aligned
    /// with the source's cells.
    #[test]
    fn resampling_over_the_support_matches_sampling_every_cell() {
        let src_grid = Grid { n: 40, dx: 0.137 };
        let blob = |corner: Option<usize>| {
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
            if let Some(i) = corner {
                src.qx[i] = 3.0;
            }
            src
        };
        let aligned = Grid { n: 80, dx: 0.137 };
        for src in [blob(None), blob(Some(0)), blob(Some(src_grid.len() - 1))] {
            for dst in [Grid { n: 96, dx: 0.071 }, Grid { n: 64, dx: 0.25 }, aligned] {
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

    fn model(indenter: Indenter) -> ContactModel {
        model_with(indenter, 96)
    }

    fn model_with(indenter: Indenter, field_cells: usize) -> ContactModel {
        let contact = crate::response::tests::contact(indenter, 2.0);
        ContactModel::build(ModelSpec {
            contact,
            max_depth_mm: 0.5,
            shear: true,
            twist: true,
            field_view_mm: Some((12.0, 9.0)),
            pressing_friction: true,
            quality: Quality {
                field_cells,
                ..Quality::default()
            },
        })
        .expect("model")
    }

    fn field(m: &mut ContactModel, depth_mm: f64, shear_n: f64, torque_nmm: f64) -> Field {
        m.field(State {
            depth_mm,
            shear_n,
            torque_nmm,
        })
        .expect("built with fields")
    }

    /// Largest difference between `a` and `b`'s components over the largest component.
    fn rel_diff(a: &Field, b: &Field) -> f64 {
        let (mut worst, mut scale) = (0.0f64, 0.0f64);
        for (u, v) in [(&a.ux, &b.ux), (&a.uy, &b.uy), (&a.uz, &b.uz)] {
            for (x, y) in u.iter().zip(v) {
                worst = worst.max((x - y).abs());
                scale = scale.max(x.abs());
            }
        }
        worst / scale
    }

    /// `a + b − c`, component by component.
    fn plus_minus(a: &Field, b: &Field, c: &Field) -> Field {
        let f = |u: &[f64], v: &[f64], w: &[f64]| -> Vec<f64> {
            u.iter()
                .zip(v)
                .zip(w)
                .map(|((x, y), z)| x + y - z)
                .collect()
        };
        Field {
            grid: a.grid,
            ux: f(&a.ux, &b.ux, &c.ux),
            uy: f(&a.uy, &b.uy, &c.uy),
            uz: f(&a.uz, &b.uz, &c.uz),
        }
    }

    /// The field's bookkeeping, against laws the tractions obey: both channels loaded is
    /// the shear field plus the twist field less the pressed state both tables start from
    /// (counted once); the least shear continues the pressed field; a flat punch at depth d under (f, t) is d times the field at unit
    /// depth under (f/d, t/d); a curved indenter between two depth buckets is their fields
    /// blended by the same weights.
    #[test]
    fn fields_obey_superposition_depth_scaling_and_bucket_blending() {
        let mut flat = model(Indenter::FlatCircle { diameter_mm: 6.0 });
        let (d, f, t) = (0.23, 0.05, 0.08);
        let both = field(&mut flat, d, f, t);
        let shear = field(&mut flat, d, f, 0.0);
        let twist = field(&mut flat, d, 0.0, t);
        let pressed = field(&mut flat, d, 0.0, 0.0);
        let sum = plus_minus(&shear, &twist, &pressed);
        // Any shear at all continues the pressed field: no jump where the shear starts.
        let tiny = field(&mut flat, d, 1e-9, 0.0);
        assert!(
            rel_diff(&tiny, &pressed) < 1e-6,
            "{}",
            rel_diff(&tiny, &pressed)
        );
        assert!(rel_diff(&both, &sum) < 1e-12, "{}", rel_diff(&both, &sum));
        // The shear and twist fields differ from the pressed one: the channels were loaded.
        assert!(rel_diff(&shear, &pressed) > 1e-3 && rel_diff(&twist, &pressed) > 1e-3);
        let unit = field(&mut flat, 1.0, f / d, t / d);
        let scaled = Field {
            grid: unit.grid,
            ux: unit.ux.iter().map(|v| v * d).collect(),
            uy: unit.uy.iter().map(|v| v * d).collect(),
            uz: unit.uz.iter().map(|v| v * d).collect(),
        };
        assert!(
            rel_diff(&both, &scaled) < 1e-12,
            "{}",
            rel_diff(&both, &scaled)
        );

        let mut sphere = model(Indenter::Sphere { diameter_mm: 12.68 });
        // Buckets are 0.5 % of the 2 mm thickness: 0.30 and 0.31 mm around 0.3037.
        let (d0, d1, w1) = (0.30, 0.31, 0.37);
        let between = field(&mut sphere, d0 + w1 * (d1 - d0), f, t);
        let (a, b) = (field(&mut sphere, d0, f, t), field(&mut sphere, d1, f, t));
        let blend = |u: &[f64], v: &[f64]| -> Vec<f64> {
            u.iter()
                .zip(v)
                .map(|(x, y)| (1.0 - w1) * x + w1 * y)
                .collect()
        };
        let blended = Field {
            grid: a.grid,
            ux: blend(&a.ux, &b.ux),
            uy: blend(&a.uy, &b.uy),
            uz: blend(&a.uz, &b.uz),
        };
        assert!(
            rel_diff(&between, &blended) < 1e-9,
            "{}",
            rel_diff(&between, &blended)
        );
        assert!(rel_diff(&a, &b) > 1e-3, "the two buckets' fields differ");
        let (tiny, pressed) = (
            field(&mut sphere, d0, 1e-9, 0.0),
            field(&mut sphere, d0, 0.0, 0.0),
        );
        assert!(
            rel_diff(&tiny, &pressed) < 1e-6,
            "{}",
            rel_diff(&tiny, &pressed)
        );
    }

    /// The tractions handed beside a field carry the contact's loads: pressure over the
    /// grid sums to the model's normal force, the tangential traction to the shear applied,
    /// their moment about the centre to the torque (a sphere and a flat punch, each channel
    /// alone and both together). Within 2 %: the normal force is the normal table's, solved on
    /// its own grid, the field's pressure is solved again on the field grid. On a field grid
    /// coarser than the tangential tables' (96 cells over this 30 mm span, 0.31 mm cells
    /// against the tables' 0.17 mm) the bilinear resampling loses 8 % of a small sphere's
    /// shear (contact radius 0.95 mm): hence 192 cells here.
    #[test]
    fn tractions_sum_to_the_loads_they_carry() {
        for indenter in [
            Indenter::Sphere { diameter_mm: 6.0 },
            Indenter::FlatCircle { diameter_mm: 4.0 },
        ] {
            let mut m = model_with(indenter, 192);
            let depth = 0.3;
            let fz = m.normal_force_n(depth);
            // Loads well inside full slip (μ·Fz, and the twist's μ·Fz·a scale).
            let q = 0.4 * m.contact().material.friction * fz;
            let t = 0.2 * q * m.contact_radius_mm(depth);
            for (shear, torque) in [(0.0, 0.0), (q, 0.0), (0.0, t), (0.7 * q, -0.7 * t)] {
                let state = State {
                    depth_mm: depth,
                    shear_n: shear,
                    torque_nmm: torque,
                };
                let (field, t) = m.field_and_tractions(state).expect("fields");
                assert_eq!(field, m.field(state).expect("fields"));
                let g = t.grid;
                let (mut p, mut qx, mut qy, mut tz) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
                for i in 0..g.len() {
                    let (x, y) = g.xy(i);
                    p += t.pressure_mpa[i] * g.area();
                    qx += t.shear_x_mpa[i] * g.area();
                    qy += t.shear_y_mpa[i] * g.area();
                    tz += (x * t.shear_y_mpa[i] - y * t.shear_x_mpa[i]) * g.area();
                }
                let tag = format!("{indenter:?} shear {shear} N torque {torque} N·mm");
                assert!(
                    (p - fz).abs() <= 0.02 * fz,
                    "{tag}: Σp·A {p:.4} vs {fz:.4} N"
                );
                assert!(
                    (qx - shear).abs() <= 0.02 * shear.abs() + 0.001,
                    "{tag}: Σqx·A {qx:.4} N"
                );
                assert!(qy.abs() <= 0.001, "{tag}: Σqy·A {qy:.4} N");
                assert!(
                    (tz - torque).abs() <= 0.02 * torque.abs() + 0.01,
                    "{tag}: moment {tz:.4} N·mm"
                );
            }
        }
    }
}
