//! A contact model precomputed from the grid solvers, fast enough to evaluate at every
//! force sample of a dry run.
//!
//! A conjugate-gradient solve takes milliseconds to a second; a dry run reads the force
//! sensor hundreds of thousands of times. So the model is solved once, at the start of a run,
//! for exactly what the run needs, and then interpolated:
//!
//! - **normal**: flat punches are linear in depth (fixed contact, frictionless), so one
//!   solve at unit depth gives pressure and force; for a circle the force is calibrated to
//!   the exact semi-analytic κ ([`crate::punch`]) and the grid supplies the shape. Curved
//!   indenters get a table of Polonsky–Keer solves at depths up to the deepest the run can
//!   reach, each on a grid adapted to its contact (16 cells across 1.2 contact diameters,
//!   period 2.4a + 8h: within 0.06 % of a 40-cell, 12h reference).
//! - **shear and twist** (only when the run moves those axes): a partial-slip backbone —
//!   force against displacement, torque against twist — from the spectral-projected-gradient
//!   friction solver, with the layer's normal–tangential coupling as a known source. That
//!   coupling is what makes a flat punch slip from its edge inward on the bonded layer (an
//!   ideal flat punch on a half-space has uniform q/p and slips all at once). For a flat
//!   punch everything scales with depth, so the backbone is computed once; for a curved
//!   indenter it is computed at the depth where it is first needed and cached.
//! - **fields** (only when the run captures frames): the tractions of each solved state are
//!   kept, and the surface displacement field of any state is one pass of the layer
//!   operator over the blended tractions.
//!
//! Everything is in the long-term (relaxed) modulus; the plant adds viscoelasticity.

use std::collections::BTreeMap;
use std::f64::consts::PI;
use std::sync::Arc;

use crate::contact::Contact;
use crate::friction::Backbone;
use crate::operator::{Compliance, Grid, LayerOperator, fast_size};
use crate::solve::{Tolerance, normal_unknown_area};
use crate::{Indenter, MechanicsError};

mod curved;
mod field;
mod flat;
mod pressed;
mod shapes;
mod tables;
mod tangential;
mod tilt;

pub use tables::{TableEntry, TableStore, model_key};
pub use tilt::{SlipTilt, tilt_arms_at, tilting_moments_nmm};

use tables::Entry;

use flat::flat_pressing;
use shapes::{face_mask, matched_dx};

/// What the model must be able to answer.
#[derive(Debug, Clone, PartialEq)]
pub struct ModelSpec {
    /// Layer, material, indenter.
    pub contact: Contact,
    /// Deepest indentation the run can reach, mm (tables stop there).
    pub max_depth_mm: f64,
    /// Build the shear backbone.
    pub shear: bool,
    /// Build the twist backbone.
    pub twist: bool,
    /// Build displacement fields covering a view of this width and height (mm).
    pub field_view_mm: Option<(f64, f64)>,
    /// Press with friction: the coupled normal–tangential problem ([`crate::pressing`]), in
    /// which the indenter holds the gel's outward flow and presses harder for it (+9 % to
    /// +39 % on the shipped flat punches; a curved indenter along its loading path,
    /// [`crate::pressing::curved`]: +5.2 % for the box sphere at 2 mm, +36 % for the can
    /// at 0.4 mm). `false`: the frictionless pressure, with friction found on it one way
    /// (Goodman), as before.
    pub pressing_friction: bool,
    /// Resolution.
    pub quality: Quality,
}

/// Resolution choices (error against cost: see BENCHMARKS.md, "Fidelity levels").
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Quality {
    /// Cells across a flat punch when no field grid is needed.
    pub cells_flat: usize,
    /// Cells across 1.2 contact diameters of a curved indenter.
    pub cells_curved: usize,
    /// Cells per side of the field grid.
    pub field_cells: usize,
    /// A non-circular flat punch's force extrapolated across two grids (`cells_flat` and
    /// twice it); off, the `cells_flat` grid's own force (what the extrapolation corrects).
    pub extrapolate_flat: bool,
    /// Increments a curved indenter's loading path is followed in when it presses with
    /// friction (even; the normal table extrapolates across half as many and this many).
    pub path_steps: usize,
}

impl Default for Quality {
    fn default() -> Self {
        Self {
            cells_flat: 32,
            cells_curved: 16,
            field_cells: 256,
            extrapolate_flat: true,
            path_steps: 16,
        }
    }
}

impl Quality {
    /// Half the default's resolution across a curved contact, its loading path and the field
    /// grid (a quarter of the cells): for dry runs that check a protocol's logic; its error
    /// against [`Self::reference`] is measured per shipped protocol
    /// (docs/benchmarks/simulator.md, "Fidelity levels"). A flat punch keeps the default's
    /// grid: at 16 cells its shear backbone read `box-shear-flat`'s Fx 10 % off the
    /// reference's (and without the two-grid extrapolation the rectangle's Fz 10 %), for
    /// tables that cost a second or less at the default.
    pub fn fast() -> Self {
        Self {
            cells_flat: 32,
            cells_curved: 8,
            field_cells: 128,
            extrapolate_flat: true,
            path_steps: 8,
        }
    }

    /// Twice the default's resolution (1.5 times across a curved contact, whose shallowest
    /// depth's grid would otherwise pass [`MAX_GRID_SIDE`] on the shipped sphere): the level
    /// the others are measured against, itself within the finite-element oracles' own error.
    pub fn reference() -> Self {
        Self {
            cells_flat: 64,
            cells_curved: 24,
            field_cells: 512,
            extrapolate_flat: true,
            path_steps: 32,
        }
    }
}

/// Tangential (shear or twist) behaviour of one contact state.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TangentialTable {
    /// Force (N) against stage displacement (mm), or torque (N·mm) against twist (rad),
    /// on virgin loading, ending at full slip.
    pub backbone: Backbone,
    /// Fraction of the contact that sticks at each backbone point.
    pub stick_fraction: Vec<f64>,
    /// Tractions (q_x, q_y) at each backbone point, on `grid`.
    tractions: Vec<(Vec<f64>, Vec<f64>)>,
    /// Tractions of the pressed state (friction resisting the coupling), on `grid`.
    pressing: (Vec<f64>, Vec<f64>),
    grid: Grid,
}

/// The stick fraction at displacement `x` (either sign) along `backbone`, whose points carry
/// `stick` (interpolated linearly; the last value beyond the table: full slip).
pub fn stick_at(backbone: &Backbone, stick: &[f64], x: f64) -> f64 {
    let b = backbone;
    let x = x.abs();
    let n = b.x.len().min(stick.len());
    if n == 0 || x >= b.x[n - 1] {
        return stick.get(n.wrapping_sub(1)).copied().unwrap_or(0.0);
    }
    let i = b.x.partition_point(|v| *v <= x).clamp(1, n - 1);
    let t = (x - b.x[i - 1]) / (b.x[i] - b.x[i - 1]);
    stick[i - 1] * (1.0 - t) + stick[i] * t
}

impl TangentialTable {
    /// Stick fraction at displacement `x` (interpolated along the backbone).
    pub fn stick_at(&self, x: f64) -> f64 {
        stick_at(&self.backbone, &self.stick_fraction, x)
    }

    /// Adds `weight` × the tractions for force `f` on the backbone (sign carried, blended
    /// between levels) to (qx, qy) on the table's grid, without a copy of any level.
    fn add_tractions_for_force(&self, f: f64, weight: f64, qx: &mut [f64], qy: &mut [f64]) {
        let b = &self.backbone;
        let s = f.signum();
        let fa = f.abs().min(b.limit());
        let n = b.f.len();
        let (i, t) = if n < 2 {
            (1, 0.0)
        } else {
            let i = b.f.partition_point(|v| *v <= fa).clamp(1, n - 1);
            let span = b.f[i] - b.f[i - 1];
            (
                i,
                if span > 0.0 {
                    ((fa - b.f[i - 1]) / span).clamp(0.0, 1.0)
                } else {
                    1.0
                },
            )
        };
        let (a0, a1) = (
            &self.tractions[i - 1],
            &self.tractions[i.min(self.tractions.len() - 1)],
        );
        let blend = |out: &mut [f64], u: &[f64], v: &[f64], p: &[f64]| {
            for (o, ((u, v), p)) in out.iter_mut().zip(u.iter().zip(v).zip(p)) {
                *o += weight * (p + s * ((u - p) * (1.0 - t) + (v - p) * t));
            }
        };
        blend(qx, &a0.0, &a1.0, &self.pressing.0);
        blend(qy, &a0.1, &a1.1, &self.pressing.1);
    }

    /// The tractions for force `f` (see [`Self::add_tractions_for_force`]).
    #[cfg(test)]
    fn tractions_for_force(&self, f: f64) -> (Vec<f64>, Vec<f64>) {
        let (mut qx, mut qy) = (vec![0.0; self.grid.len()], vec![0.0; self.grid.len()]);
        self.add_tractions_for_force(f, 1.0, &mut qx, &mut qy);
        (qx, qy)
    }
}

/// The surface displacement field of one state, on a grid centred on the contact.
#[derive(Debug, Clone, PartialEq)]
pub struct Field {
    /// The grid.
    pub grid: Grid,
    /// In-plane displacement along x, mm.
    pub ux: Vec<f64>,
    /// In-plane displacement along y, mm.
    pub uy: Vec<f64>,
    /// Normal displacement (into the gel), mm.
    pub uz: Vec<f64>,
}

/// The tractions the indenter puts on the gel's surface in one state, on the grid of the
/// [`Field`] they make (cell averages, MPa): what [`ContactModel::field_and_tractions`]
/// hands beside the field, for labels no real bench can measure (a dataset's pressure and
/// shear maps).
#[derive(Debug, Clone, PartialEq)]
pub struct Tractions {
    /// The grid (the field's).
    pub grid: Grid,
    /// Normal pressure, compressive positive, MPa.
    pub pressure_mpa: Vec<f64>,
    /// Tangential traction along x, MPa.
    pub shear_x_mpa: Vec<f64>,
    /// Tangential traction along y, MPa.
    pub shear_y_mpa: Vec<f64>,
}

/// A contact state for [`ContactModel::field`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct State {
    /// Indentation depth, mm.
    pub depth_mm: f64,
    /// Tangential force along x carried by the contact, N (its elastic part).
    pub shear_n: f64,
    /// Twisting moment carried by the contact, N·mm (its elastic part).
    pub torque_nmm: f64,
}

#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
enum Normal {
    /// Linear in depth: pressure and force per mm of depth.
    Flat {
        grid: Grid,
        mask: Vec<bool>,
        p_per_mm: Vec<f64>,
        force_per_mm: f64,
    },
    /// Tabulated.
    Curved {
        depths_mm: Vec<f64>,
        forces_n: Vec<f64>,
        radii_mm: Vec<f64>,
    },
}

/// Tangential tractions (q_x, q_y) of a pressed state, and their grid.
type PressingTractions = (Vec<f64>, Vec<f64>, Grid);

/// The precomputed contact model.
#[derive(Debug, Clone)]
pub struct ContactModel {
    spec: ModelSpec,
    normal: Normal,
    /// The operator on which tangential tables and fields of flat punches live.
    op: Option<LayerOperator>,
    /// Tangential tables by depth bucket (a flat punch's at unit depth, key 0), shared:
    /// a field or a backbone reads one without copying its levels.
    shear: BTreeMap<u64, Arc<TangentialTable>>,
    twist: BTreeMap<u64, Arc<TangentialTable>>,
    field_op: Option<Arc<LayerOperator>>,
    field_pressure: BTreeMap<u64, Vec<f64>>,
    /// The pressed state's friction tractions (q_x, q_y) and their grid: a curved
    /// indenter's by depth bucket, a flat punch's at unit depth on the field grid
    /// (`u64::MAX`).
    pressing: BTreeMap<u64, Arc<PressingTractions>>,
    /// A curved indenter's pressed states with friction, by depth bucket.
    pressed: BTreeMap<u64, pressed::Pressed>,
    /// Tilting-moment arms (mm) of a flat punch's shear along x and along y (zero when
    /// no shear is built, and for curved indenters: theirs are in `tilt`).
    flat_tilt_arms_mm: (f64, f64),
    /// A curved indenter's tilting-moment arms (mm) by depth bucket.
    tilt: BTreeMap<u64, (f64, f64)>,
    /// Where solved tables are kept between models of the same spec, and this spec's key
    /// there ([`tables`]).
    store: Option<Arc<dyn TableStore>>,
    store_key: String,
    /// How the shear's tilting arm moves under partial slip, by the shear tables' key:
    /// solved where a run asks for the arms, not with every table (a grasp reads none).
    slip_tilt: BTreeMap<u64, Arc<SlipTilt>>,
}

fn tol() -> Tolerance {
    Tolerance {
        rel: 1e-7,
        max_iter: 4000,
    }
}

fn quantise(depth_mm: f64, h: f64) -> u64 {
    // Depth buckets of 0.5 % of the thickness.
    ((depth_mm / h) * 200.0).round().max(0.0) as u64
}

/// Largest grid side the model solves on: 1024² cells, a few hundred MB of solver state and
/// minutes of solving. An indenter too small for its layer needs a finer grid over the same
/// reach (the layer's influence extends about 8–12 thicknesses) and is refused instead of
/// allocating until the process is killed.
pub const MAX_GRID_SIDE: usize = 1024;

impl ContactModel {
    /// Side of the largest grid [`ContactModel::build`] would solve on for this contact,
    /// computed without allocating: the field grid (and its double-resolution flat-punch
    /// pressure), the flat punch's table grid, or the curved indenter's grid at its
    /// shallowest tabulated depth (0.5 % of the thickness, where the contact is smallest).
    pub fn grid_side(contact: &Contact, quality: &Quality, fields: bool) -> usize {
        let h = contact.layer.thickness_mm;
        let extent = contact.indenter.footprint_mm();
        let mut side = if fields {
            2 * fast_size(quality.field_cells)
        } else {
            0
        };
        if contact.indenter.is_flat() {
            let dx = extent / quality.cells_flat as f64;
            side = side.max(LayerOperator::period_for(extent, h, dx));
        } else {
            let radius = extent / 2.0;
            let length = match contact.indenter {
                Indenter::Cylinder { length_mm, .. } => length_mm.min(contact.layer.width_mm),
                _ => 0.0,
            };
            let a = (radius * 0.005 * h).sqrt();
            let reach = 2.4 * a * 1.1;
            let dx = reach / quality.cells_curved as f64;
            let span = reach.max(length * 1.1) + 8.0 * h;
            let cells = span / dx;
            side = side.max(if cells < 1e7 {
                fast_size(cells.ceil() as usize)
            } else {
                usize::MAX
            });
        }
        side
    }

    /// Builds the model: every solve the spec asks for happens here (or later, on first
    /// use, for the depth buckets a run reaches).
    pub fn build(spec: ModelSpec) -> Result<Self, MechanicsError> {
        Self::build_stored(spec, None)
    }

    /// [`Self::build`], reading each table from `store` where it was kept by a model of
    /// the same spec and giving it every table it solves ([`TableStore`]): the same model
    /// bit for bit, without solving again.
    pub fn build_stored(
        spec: ModelSpec,
        store: Option<Arc<dyn TableStore>>,
    ) -> Result<Self, MechanicsError> {
        spec.contact.layer.check()?;
        spec.contact.material.check()?;
        spec.contact.indenter.check()?;
        let side = Self::grid_side(&spec.contact, &spec.quality, spec.field_view_mm.is_some());
        if side > MAX_GRID_SIDE {
            return Err(MechanicsError::OutOfRange {
                name: "contact grid side (cells)",
                value: side as f64,
                allowed: "at most 1024: the indenter is too small for this layer to simulate",
            });
        }
        let c = &spec.contact;
        let h = c.layer.thickness_mm;
        let mu_mod = c.material.shear_modulus_mpa();
        let nu = c.material.poisson_ratio;
        let max_depth = spec.max_depth_mm.clamp(1e-6, 0.95 * h);
        let mut model = ContactModel {
            normal: Normal::Curved {
                depths_mm: vec![],
                forces_n: vec![],
                radii_mm: vec![],
            },
            op: None,
            shear: BTreeMap::new(),
            twist: BTreeMap::new(),
            field_op: None,
            field_pressure: BTreeMap::new(),
            pressing: BTreeMap::new(),
            pressed: BTreeMap::new(),
            flat_tilt_arms_mm: (0.0, 0.0),
            tilt: BTreeMap::new(),
            slip_tilt: BTreeMap::new(),
            store_key: if store.is_some() {
                model_key(&spec)
            } else {
                String::new()
            },
            store,
            spec: spec.clone(),
        };
        let extent = c.indenter.footprint_mm();
        if let Some((w, hgt)) = spec.field_view_mm {
            let span = (1.1 * w.max(hgt) + extent).max(extent + 12.0 * h);
            let n = fast_size(spec.quality.field_cells);
            let grid = Grid {
                n,
                dx: matched_dx(&c.indenter, n, span / spec.quality.field_cells as f64),
            };
            model.field_op = Some(Arc::new(LayerOperator::new(grid, h, mu_mod, nu)));
        }
        // The normal table (and a flat punch's tilting arms): kept, or solved and kept.
        let kept = match model.fetch("base") {
            Some(Entry::Base {
                normal,
                flat_tilt_arms_mm,
            }) if matches!(normal, Normal::Flat { .. }) == c.indenter.is_flat() => {
                Some((normal, flat_tilt_arms_mm))
            }
            _ => None,
        };
        if c.indenter.is_flat() {
            // The tangential tables live on a grid with `cells_flat` cells across the punch;
            // the normal pressure for fields is solved on the field grid when there is one.
            let op = flat::operator(&c.indenter, h, mu_mod, nu, spec.quality.cells_flat);
            let (normal, arms) = match kept {
                Some(k) => k,
                None => {
                    let k = flat::flat_normal(&spec, &op);
                    model.keep("base", || Entry::Base {
                        normal: k.0.clone(),
                        flat_tilt_arms_mm: k.1,
                    });
                    k
                }
            };
            model.normal = normal;
            model.flat_tilt_arms_mm = arms;
            model.op = Some(op);
            // A flat punch's tables at unit depth (key 0): everything scales with depth.
            if spec.shear {
                let t = model.solved_table(0, 1.0, Kind::Shear);
                model.shear.insert(0, t);
            }
            if spec.twist {
                let t = model.solved_table(0, 1.0, Kind::Twist);
                model.twist.insert(0, t);
            }
        } else if let Some((normal, _)) = kept {
            model.normal = normal;
        } else {
            model.normal = model.curved_table(max_depth);
            model.press_curved_table_with_friction()?;
            model.keep("base", || Entry::Base {
                normal: model.normal.clone(),
                flat_tilt_arms_mm: (0.0, 0.0),
            });
        }
        Ok(model)
    }

    /// The contact it models.
    pub fn contact(&self) -> &Contact {
        &self.spec.contact
    }

    /// Whether the indenter is a flat punch (its face's area fixed).
    pub fn is_flat(&self) -> bool {
        matches!(self.normal, Normal::Flat { .. })
    }

    /// Long-term elastic normal force at `depth_mm`, N (zero without contact).
    pub fn normal_force_n(&self, depth_mm: f64) -> f64 {
        if depth_mm <= 0.0 {
            return 0.0;
        }
        match &self.normal {
            Normal::Flat { force_per_mm, .. } => force_per_mm * depth_mm,
            Normal::Curved {
                depths_mm,
                forces_n,
                ..
            } => interp_power(depths_mm, forces_n, depth_mm, 1.5),
        }
    }

    /// Effective contact radius √(A/π) at `depth_mm`.
    pub fn contact_radius_mm(&self, depth_mm: f64) -> f64 {
        if depth_mm <= 0.0 {
            return 0.0;
        }
        match &self.normal {
            Normal::Flat { grid, mask, .. } => {
                (mask.iter().filter(|m| **m).count() as f64 * grid.area() / PI).sqrt()
            }
            Normal::Curved {
                depths_mm,
                radii_mm,
                ..
            } => interp_power(depths_mm, radii_mm, depth_mm, 0.5),
        }
    }

    /// Shear backbone and stick fractions at `depth_mm`, without the tractions (cheap).
    pub fn shear_curve(&mut self, depth_mm: f64) -> Option<(Backbone, Vec<f64>)> {
        self.curve(depth_mm, Kind::Shear)
    }

    /// Twist backbone (torque against twist in rad) and stick fractions at `depth_mm`.
    pub fn twist_curve(&mut self, depth_mm: f64) -> Option<(Backbone, Vec<f64>)> {
        self.curve(depth_mm, Kind::Twist)
    }

    fn curve(&mut self, depth_mm: f64, kind: Kind) -> Option<(Backbone, Vec<f64>)> {
        let t = self.shared_table(depth_mm, kind)?;
        // A flat punch's table is at unit depth: force and displacement scale with depth.
        let scale = if self.is_flat() { depth_mm } else { 1.0 };
        let b = Backbone {
            x: t.backbone.x.iter().map(|v| v * scale).collect(),
            f: t.backbone.f.iter().map(|v| v * scale).collect(),
        };
        Some((b, t.stick_fraction.clone()))
    }

    /// Shear backbone at `depth_mm` (force against stage displacement), if built.
    pub fn shear_table(&mut self, depth_mm: f64) -> Option<TangentialTable> {
        self.table(depth_mm, Kind::Shear)
    }

    /// Twist backbone at `depth_mm` (torque against twist in rad), if built.
    pub fn twist_table(&mut self, depth_mm: f64) -> Option<TangentialTable> {
        self.table(depth_mm, Kind::Twist)
    }

    /// The table at `depth_mm` as a copy, a flat punch's scaled to that depth.
    fn table(&mut self, depth_mm: f64, kind: Kind) -> Option<TangentialTable> {
        let shared = self.shared_table(depth_mm, kind)?;
        let mut t = TangentialTable::clone(&shared);
        if self.is_flat() {
            // Everything scales with depth: pressure, coupling and friction limit are ∝ d,
            // so the displacement (or twist) and force (or torque) of each level are too.
            t.backbone.x.iter_mut().for_each(|v| *v *= depth_mm);
            t.backbone.f.iter_mut().for_each(|v| *v *= depth_mm);
            for (qx, qy) in t.tractions.iter_mut() {
                qx.iter_mut().for_each(|v| *v *= depth_mm);
                qy.iter_mut().for_each(|v| *v *= depth_mm);
            }
            t.pressing.0.iter_mut().for_each(|v| *v *= depth_mm);
            t.pressing.1.iter_mut().for_each(|v| *v *= depth_mm);
        }
        Some(t)
    }

    /// The table of `depth_mm`'s bucket, solved on first use and shared after: a flat
    /// punch's at unit depth (everything in it scales with depth), a curved indenter's at
    /// the bucket's depth. `None` when the channel was not built or out of contact.
    fn shared_table(&mut self, depth_mm: f64, kind: Kind) -> Option<Arc<TangentialTable>> {
        let wanted = match kind {
            Kind::Shear => self.spec.shear,
            Kind::Twist => self.spec.twist,
        };
        if !wanted || depth_mm <= 0.0 {
            return None;
        }
        let h = self.spec.contact.layer.thickness_mm;
        let key = if self.is_flat() {
            0
        } else {
            quantise(depth_mm, h)
        };
        let cached = match kind {
            Kind::Shear => self.shear.get(&key),
            Kind::Twist => self.twist.get(&key),
        };
        if let Some(t) = cached {
            return Some(Arc::clone(t));
        }
        let d = (key as f64 / 200.0 * h).max(1e-4 * h);
        let t = self.solved_table(key, d, kind);
        match kind {
            Kind::Shear => self.shear.insert(key, Arc::clone(&t)),
            Kind::Twist => self.twist.insert(key, Arc::clone(&t)),
        };
        Some(t)
    }

    /// The tangential table of bucket `key`, solved at `depth_mm`: kept, or solved and kept.
    fn solved_table(&mut self, key: u64, depth_mm: f64, kind: Kind) -> Arc<TangentialTable> {
        let name = format!("{}/{key}", kind.name());
        if let Some(Entry::Tangential(t)) = self.fetch(&name) {
            return Arc::new(t);
        }
        let t = self.tangential_table(depth_mm, kind);
        self.keep(&name, || Entry::Tangential(t.clone()));
        Arc::new(t)
    }

    /// The operator on which the tangential problem at `depth_mm` is solved: the flat
    /// punch's grid, or a grid adapted to the curved contact at that depth.
    fn op_for(&self, depth_mm: f64) -> LayerOperator {
        if let Some(op) = &self.op {
            return op.clone();
        }
        let c = &self.spec.contact;
        let h = c.layer.thickness_mm;
        let a = self.contact_radius_mm(depth_mm).max(1e-3);
        let length = match c.indenter {
            Indenter::Cylinder { length_mm, .. } => length_mm.min(c.layer.width_mm),
            _ => 0.0,
        };
        let extent = 2.4 * a;
        let dx = extent / self.spec.quality.cells_curved as f64;
        let span = extent.max(length * 1.1) + 8.0 * h;
        LayerOperator::new(
            Grid {
                n: fast_size((span / dx).ceil() as usize),
                dx,
            },
            h,
            c.material.shear_modulus_mpa(),
            c.material.poisson_ratio,
        )
    }

    /// Pressure at `depth_mm` on the grid of `op` (flat: scaled, solved again on another
    /// grid; curved: solved).
    fn pressure_on(&self, op: &LayerOperator, depth_mm: f64) -> Vec<f64> {
        match &self.normal {
            Normal::Flat { p_per_mm, grid, .. } if *grid == op.grid() => {
                p_per_mm.iter().map(|v| v * depth_mm).collect()
            }
            Normal::Flat { .. } => {
                let mask = face_mask(&self.spec.contact.indenter, op.grid());
                let unit = flat_pressing(
                    op,
                    &mask,
                    self.spec.contact.material.friction,
                    self.spec.pressing_friction,
                );
                unit.p.iter().map(|v| v * depth_mm).collect()
            }
            Normal::Curved { .. } => {
                normal_unknown_area(op, &self.profile_on(op), depth_mm, None, tol()).p
            }
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Shear,
    Twist,
}

impl Kind {
    fn name(self) -> &'static str {
        match self {
            Kind::Shear => "shear",
            Kind::Twist => "twist",
        }
    }
}

/// Interpolates y(x) log–log between table points; below the table, a power law with
/// exponent `low_exp` through the first point; above, the last segment's power law.
fn interp_power(xs: &[f64], ys: &[f64], x: f64, low_exp: f64) -> f64 {
    let n = xs.len();
    if n == 0 {
        return 0.0;
    }
    if x <= xs[0] || n == 1 {
        return ys[0] * (x / xs[0]).powf(low_exp);
    }
    let i = xs.partition_point(|v| *v <= x).clamp(1, n - 1);
    let (x0, x1, y0, y1) = (xs[i - 1], xs[i], ys[i - 1].max(1e-300), ys[i].max(1e-300));
    let e = (y1 / y0).ln() / (x1 / x0).ln();
    y0 * (x / x0).powf(e)
}

#[cfg(test)]
mod tests;
