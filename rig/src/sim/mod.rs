//! The simulated bench: stages, a Nano17 and a camera sharing one simulated elastomer.
//!
//! Every simulated device reads or moves the same [`plant`], on the run's [`Clock`], so a
//! dry run sees the consequences of its own moves: force rises when the normal stage steps,
//! relaxes while it settles, saturates at the Coulomb limit when the shear stage goes too
//! far, and the camera's markers move with it. Everything is seeded and deterministic.
//!
//! Physics here is the spine's: contact laws and fields from [`mechanics`] (closed forms and
//! tabulated layer solutions) with Prony relaxation. Partial slip, the layer field solver and
//! the GelSight shading are the physics issue's work; this module says so where it
//! simplifies.
//!
//! [`Clock`]: crate::Clock

mod axis;
mod camera;
mod force;
pub(crate) mod plant;
mod render;

pub(crate) use axis::SimAxis;
pub(crate) use camera::SimCamera;
pub(crate) use force::{SimDisturber, SimForceSensor};
pub use plant::{MarkerLayout, PlantSpec};
pub use render::marker_reference_positions_mm;
