//! Errors of the hardware layer.
//!
//! Variants are what a runner must tell apart to react correctly: a move outside travel is
//! a protocol bug (stop before anything moves), a timeout is a device that stopped answering
//! (retract what can be retracted, keep the data), a plant error is a simulated bench pushed
//! outside physics.

use crate::units::AxisUnit;

/// Failure of a device or of the simulated bench.
#[derive(Debug, thiserror::Error)]
pub enum RigError {
    /// A move target outside the axis's travel; nothing moved.
    #[error(
        "{axis} axis: target {target} {unit} is outside its travel [{min}, {max}] {unit}; nothing moved",
        unit = unit.symbol()
    )]
    OutOfTravel {
        /// Axis role name.
        axis: String,
        /// Requested target.
        target: f64,
        /// Travel minimum.
        min: f64,
        /// Travel maximum.
        max: f64,
        /// Axis unit.
        unit: AxisUnit,
    },
    /// A move faster than the axis can go.
    #[error(
        "{axis} axis: speed {speed} {unit}/s is not in (0, {max}] {unit}/s",
        unit = unit.symbol()
    )]
    BadSpeed {
        /// Axis role name.
        axis: String,
        /// Requested speed.
        speed: f64,
        /// Maximum speed.
        max: f64,
        /// Axis unit.
        unit: AxisUnit,
    },
    /// A move on an axis that has lost or never had its reference.
    #[error(
        "{axis} axis is not referenced: home it before moving it (add `- home: {{axes: [{axis}]}}` before this block)"
    )]
    NotReferenced {
        /// Axis role name.
        axis: String,
    },
    /// A device did not answer in time.
    #[error(
        "{device} did not answer within {timeout_ms} ms: check its cable and power, then run `gelrig probe`"
    )]
    Timeout {
        /// Device description.
        device: String,
        /// How long we waited.
        timeout_ms: u64,
    },
    /// A device answered with something the driver cannot parse.
    #[error("{device} sent a reply the driver cannot read: {detail}")]
    Garbled {
        /// Device description.
        device: String,
        /// What was wrong.
        detail: String,
    },
    /// A device refused a command (Zaber `RJ`, SMC100 `TE`, a Modbus exception).
    #[error(
        "{device} refused `{command}`: {reason}; fix: check the axis limits and state with `gelrig probe`"
    )]
    Rejected {
        /// Device description.
        device: String,
        /// The command.
        command: String,
        /// The device's reason.
        reason: String,
    },
    /// The rig file asks for something this build or this bench cannot do.
    #[error("{device}: {detail}")]
    Unsupported {
        /// Device description.
        device: String,
        /// What is missing and how to get it.
        detail: String,
    },
    /// The simulated bench was driven outside what its physics can represent.
    #[error("simulated bench: {0}")]
    Plant(String),
    /// Operating-system I/O failure talking to a device.
    #[error("{device}: {source}")]
    Io {
        /// Device description.
        device: String,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
}
