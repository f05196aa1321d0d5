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

mod checked;
pub mod clock;
pub mod clock_sync;
pub mod config;
pub mod device;
pub mod drivers;
pub mod error;
pub mod open;
pub mod sim;
pub mod twins;
pub mod units;

pub use checked::{implausible_position, implausible_sample};
pub use clock::{Clock, ClockMode};
pub use device::{
    Axis, AxisInfo, AxisStatus, AxisStopper, Camera, CameraInfo, DeviceTiming, Disturber,
    ForceInfo, ForceRange, ForceSample, ForceSensor, Frame, GraspTruth, STATUS_SATURATED, SimTruth,
    Wrench,
};
pub use error::RigError;
pub use open::{OpenRequest, OpenedDevice, Rig, open};

/// Device text as it may appear in a message: a garbled reply can be megabytes of
/// anything, and a message quoting it whole would flood the terminal, `run.yaml` and the
/// journal. At most 120 characters, control characters escaped, and the full length said
/// when cut.
pub fn quote(text: &str) -> String {
    const MAX_CHARS: usize = 120;
    let mut out = String::new();
    for (shown, c) in text.chars().enumerate() {
        if shown == MAX_CHARS {
            out.push_str(&format!("… ({} bytes)", text.len()));
            return out;
        }
        if c.is_control() {
            out.extend(c.escape_default());
        } else {
            out.push(c);
        }
    }
    out
}

/// Locks a mutex shared between simulated devices, recovering from poisoning: a panic in
/// one device must not take the rest of the bench (and the run's data) down with it.
pub fn lock<T>(m: &std::sync::Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

#[cfg(test)]
mod tests {
    #[test]
    fn quotes_are_short_and_printable() {
        assert_eq!(super::quote("1TPNaN"), "1TPNaN");
        assert_eq!(super::quote("a\r\n\u{7}b"), "a\\r\\n\\u{7}b");
        let flood = "x".repeat(4 << 20);
        let q = super::quote(&flood);
        assert!(
            q.chars().count() < 140 && q.ends_with("(4194304 bytes)"),
            "{q}"
        );
    }
}
