//! gelrig's hardware layer.
//!
//! A GelSight force bench has stage axes (normal, shear, rotation; lift and grip on the
//! grasping jig), a six-axis force/torque sensor and a camera. This crate defines one trait
//! per kind of device ([`Axis`], [`ForceSensor`], [`Camera`], [`Disturber`]), the rig file
//! that binds roles to drivers ([`config::RigConfig`]), the run's single timebase
//! ([`Clock`]), and twins of the real devices speaking their wire protocols over real
//! transports ([`twins`]).
//!
//! It knows nothing about protocols or physics: the runner decides what to move and when,
//! the simulated bench (`simbench`) implements these traits over a simulated elastomer and
//! opens a rig file's devices for a run. Quantities with units, shared with the protocol
//! schema, live in `records` ([`units`]).

pub mod checked;
pub mod clock;
pub mod clock_sync;
pub mod config;
pub mod device;
pub mod drivers;
pub mod error;
pub mod twins;

/// Quantities with units ([`records::units`]), shared with the protocol schema.
pub use records::units;
pub use records::{lock, quote};

pub use checked::{implausible_position, implausible_sample};
pub use clock::{Clock, ClockMode};
pub use device::{
    Axis, AxisInfo, AxisStatus, AxisStopper, Camera, CameraInfo, DeviceTiming, Disturber,
    ForceInfo, ForceRange, ForceSample, ForceSensor, Frame, GraspTruth, STATUS_SATURATED, SimTruth,
    Wrench,
};
pub use error::RigError;
