//! gelrig's hardware layer.
//!
//! A GelSight force bench has stage axes (normal, shear, rotation; lift and grip on the
//! grasping jig), a six-axis force/torque sensor and a camera. This crate defines one trait
//! per kind of device ([`Axis`], [`ForceSensor`], [`Camera`], [`Disturber`]), the rig file
//! that binds roles to drivers ([`config::RigConfig`]), the run's single timebase
//! ([`Clock`]), and a simulated bench ([`sim`]) whose devices share one simulated elastomer.
//!
//! It knows nothing about protocols: the `experiments` crate decides what to move and when,
//! and opens only the devices a protocol uses ([`open`]). Quantities with units, shared
//! with the protocol schema, live in [`units`].

pub mod clock;
pub mod config;
pub mod device;
pub mod drivers;
pub mod error;
pub mod open;
pub mod sim;
pub mod twins;
pub mod units;

pub use clock::{Clock, ClockMode};
pub use device::{
    Axis, AxisInfo, AxisStatus, AxisStopper, Camera, CameraInfo, Disturber, ForceInfo, ForceRange,
    ForceSample, ForceSensor, Frame, STATUS_SATURATED, SimTruth, Wrench,
};
pub use error::RigError;
pub use open::{OpenRequest, OpenedDevice, Rig, open};

/// Locks a mutex shared between simulated devices, recovering from poisoning: a panic in
/// one device must not take the rest of the bench (and the run's data) down with it.
pub fn lock<T>(m: &std::sync::Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}
