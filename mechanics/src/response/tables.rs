//! Solved tables kept between models of the same contact.
//!
//! Every table a [`ContactModel`] solves — the normal table, a depth bucket's pressed state
//! along its loading path, its shear and twist backbones, field pressures, tilting arms — is
//! a pure function of the model's [`ModelSpec`], the bucket and this crate's code: each
//! entry is solved from scratch (a loading path starts at zero depth every time; a table's
//! levels warm-start only from the same table's previous level), never from another entry.
//! So an entry solved by one run can be read by the next and the results are the same bit
//! for bit. A [`TableStore`] (file I/O lives outside this crate) is asked before each solve
//! and given each new entry after it.
//!
//! The store's key for a model ([`model_key`]) is the full spec (its `Debug` text, which
//! prints every `f64` exactly) and a fingerprint of this crate's source, so a table solved
//! by other code or for another contact, depth range, grid, material or field view is
//! never read.

use serde::{Deserialize, Serialize};

use super::pressed::Pressed;
use super::{ContactModel, ModelSpec, Normal, PressingTractions, SlipTilt, TangentialTable};

/// Where a contact model keeps what it solves, so that another model of the same spec
/// reads it instead of solving again. A store that cannot read an entry (absent, damaged,
/// of another version) answers `None` and the model solves it; one that cannot write
/// keeps the failure to report itself (a run does not fail for a cache).
pub trait TableStore: Send + Sync + std::fmt::Debug {
    /// The entry `name` of the model keyed `model`, if kept and intact.
    fn load(&self, model: &str, name: &str) -> Option<TableEntry>;
    /// Keeps `entry` as `name` of the model keyed `model`.
    fn save(&self, model: &str, name: &str, entry: &TableEntry);
}

/// One solved table, opaque outside this crate; serializable (serde) by the store.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TableEntry(pub(super) Entry);

/// What an entry holds (see the `ContactModel` fields of the same names).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(super) enum Entry {
    /// What `build` solves: the normal table and a flat punch's tilting arms.
    Base {
        normal: Normal,
        flat_tilt_arms_mm: (f64, f64),
    },
    Tangential(TangentialTable),
    Pressed(Pressed),
    Pressing(PressingTractions),
    FieldPressure(Vec<f64>),
    Tilt((f64, f64)),
    SlipTilt(SlipTilt),
}

/// Bumped with any change to what an entry holds that the source fingerprint would not
/// show (a dependency's numerics).
const TABLES_FORMAT: u32 = 1;

/// The store's key for the model of `spec`: the tables' format, this crate's source
/// fingerprint (build.rs) and the whole spec.
pub fn model_key(spec: &ModelSpec) -> String {
    format!(
        "tables v{TABLES_FORMAT}; mechanics {} src {}; {spec:?}",
        env!("CARGO_PKG_VERSION"),
        env!("MECHANICS_SOURCE_SHA256")
    )
}

impl Entry {
    /// Whether the entry's arrays agree with their grids (a store checks its bytes; this
    /// checks that they decode to something the model can index without a panic).
    fn consistent(&self) -> bool {
        let fits = |v: &[f64], g: &crate::operator::Grid| v.len() == g.len();
        match self {
            Entry::Base { normal, .. } => match normal {
                Normal::Flat {
                    grid,
                    mask,
                    p_per_mm,
                    ..
                } => mask.len() == grid.len() && fits(p_per_mm, grid),
                Normal::Curved {
                    depths_mm,
                    forces_n,
                    radii_mm,
                } => depths_mm.len() == forces_n.len() && depths_mm.len() == radii_mm.len(),
            },
            Entry::Tangential(t) => {
                t.backbone.x.len() == t.backbone.f.len()
                    && t.stick_fraction.len() == t.backbone.x.len()
                    && t.tractions.len() == t.backbone.x.len()
                    && t.tractions
                        .iter()
                        .all(|(x, y)| fits(x, &t.grid) && fits(y, &t.grid))
                    && fits(&t.pressing.0, &t.grid)
                    && fits(&t.pressing.1, &t.grid)
            }
            Entry::Pressed(p) => {
                fits(&p.p, &p.grid)
                    && fits(&p.p_free, &p.grid)
                    && fits(&p.qx, &p.grid)
                    && fits(&p.qy, &p.grid)
                    && p.stick.len() == p.grid.len()
            }
            Entry::Pressing((qx, qy, g)) => fits(qx, g) && fits(qy, g),
            Entry::FieldPressure(_) | Entry::Tilt(_) => true,
            Entry::SlipTilt(_) => true,
        }
    }
}

impl ContactModel {
    /// The kept entry `name`, if the model has a store and it holds an intact one.
    pub(super) fn fetch(&self, name: &str) -> Option<Entry> {
        let store = self.store.as_ref()?;
        let e = store.load(&self.store_key, name)?.0;
        e.consistent().then_some(e)
    }

    /// Gives the store a newly solved entry (a copy: only when there is a store).
    pub(super) fn keep(&self, name: &str, entry: impl FnOnce() -> Entry) {
        if let Some(store) = &self.store {
            store.save(&self.store_key, name, &TableEntry(entry()));
        }
    }
}
