//! The simulated bench: stages, a Nano17 and a camera sharing one simulated elastomer, and
//! the opening of a rig file's devices for a run ([`open`]) — real drivers from `rig`, or
//! the simulated ones here.
//!
//! Every simulated device reads or moves the same [`plant`], on the run's [`Clock`], so a
//! dry run sees the consequences of its own moves: force rises when the normal stage steps,
//! relaxes while it settles, saturates at the Coulomb limit when the shear stage goes too
//! far, and the camera's markers move with it. Everything is seeded and deterministic.
//!
//! Physics: a contact model precomputed by the bonded-layer solvers of [`mechanics`]
//! (normal contact, partial slip in shear and twist, surface fields), Prony relaxation,
//! Masing friction elements, and a GelSight-like renderer — which also draws a frame for a
//! contact given by hand ([`ContactCamera`]).
//!
//! [`Clock`]: rig::Clock

mod axis;
mod camera;
pub mod contact_frame;
mod follow;
mod force;
pub mod frame_timing;
mod grasp;
pub(crate) mod plant;
pub mod render;
pub mod scenes;
pub mod surface_truth;
mod twin_plant;

pub mod bench;
pub mod open;

pub(crate) use axis::SimAxis;
pub(crate) use camera::SimCamera;
pub use contact_frame::{ContactCamera, ContactFrame, ContactPose};
pub(crate) use follow::FollowedAxis;
pub(crate) use force::{SimDisturber, SimForceSensor};
pub use mechanics::response::Quality;
pub use open::{OpenRequest, OpenedDevice, Rig, open};
pub use plant::{MarkerLayout, PlantSpec};
pub use render::{Renderer, SurfaceView, marker_reference_positions_mm};
pub use rig::config::Fidelity;
pub use scenes::{Look, Motion, Scene};
pub use twin_plant::TwinPlant;

/// The contact model's resolution at a fidelity level (a rig's `sim: {fidelity}`).
pub fn quality_for(fidelity: Fidelity) -> Quality {
    match fidelity {
        Fidelity::Fast => Quality::fast(),
        Fidelity::Default => Quality::default(),
        Fidelity::Reference => Quality::reference(),
    }
}
