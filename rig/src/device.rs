//! The device boundary: one trait per kind of device a GelSight bench has.
//!
//! The runner only ever sees these traits, so the same protocol drives a simulated bench,
//! a simulator speaking a real wire protocol, or real hardware. Methods are async because
//! real devices answer over serial lines and sockets; they take `&mut self` because a
//! device is owned by one runner at a time.

use async_trait::async_trait;
use serde::Serialize;

use crate::RigError;
use crate::units::AxisUnit;
pub use records::{
    DeviceTiming, ForceSample, Frame, GraspTruth, STATUS_SATURATED, SimTruth, SurfaceTruth, Wrench,
};

/// What a runner needs to know about an axis before moving it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AxisInfo {
    /// Role the axis plays on this bench (`normal`, `shear`, …).
    pub role: String,
    /// mm or deg.
    pub unit: AxisUnit,
    /// Travel limits in the axis unit.
    pub travel_min: f64,
    /// Travel limits in the axis unit.
    pub travel_max: f64,
    /// Maximum speed in unit/s.
    pub max_speed: f64,
    /// Smallest position increment in the axis unit.
    pub resolution: f64,
    /// Device identity (model, serial, firmware) for the run manifest.
    pub identity: String,
}

impl AxisInfo {
    /// Refuses a speed outside (0, max_speed].
    pub fn check_speed(&self, speed: f64) -> Result<(), RigError> {
        if speed > 0.0 && speed <= self.max_speed {
            Ok(())
        } else {
            Err(RigError::BadSpeed {
                axis: self.role.clone(),
                speed,
                max: self.max_speed,
                unit: self.unit,
            })
        }
    }

    /// Refuses a target outside the travel before anything is sent to the device.
    pub fn check_target(&self, target: f64) -> Result<(), RigError> {
        if (self.travel_min..=self.travel_max).contains(&target) {
            Ok(())
        } else {
            Err(RigError::OutOfTravel {
                axis: self.role.clone(),
                target,
                min: self.travel_min,
                max: self.travel_max,
                unit: self.unit,
            })
        }
    }
}

/// A snapshot of an axis.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct AxisStatus {
    /// Current position in the axis unit.
    pub position: f64,
    /// True while a move or homing is in progress.
    pub moving: bool,
    /// True once homed; moves are refused before.
    pub referenced: bool,
    /// The drive's in-position flag, where it has one (a Modbus drive's IN-POS bit): a
    /// move is done only once it is set. `None` for devices without such a flag.
    pub in_position: Option<bool>,
}

/// Stops an axis without waiting for whoever owns it.
///
/// The safety watchdog holds one per axis and uses it while the plan task may be inside a
/// driver call on the same axis (a move, a status poll being retried): the stop shares the
/// axis's transport but not its request/reply cycle, so it goes out at once — a second
/// handle on a serial port, the shared plant, or the Modbus context's turn.
#[async_trait]
pub trait AxisStopper: Send + Sync {
    /// Commands the axis to stop as fast as the device allows; returns once the command
    /// has been sent (the axis may still be decelerating).
    async fn stop_now(&self) -> Result<(), RigError>;
}

/// A motorised (or operator-turned) stage axis.
#[async_trait]
pub trait Axis: Send {
    /// Static description.
    fn info(&self) -> &AxisInfo;
    /// A handle that stops this axis from another task (the safety watchdog's).
    fn stopper(&self) -> std::sync::Arc<dyn AxisStopper>;
    /// Starts homing; completion shows as `!moving && referenced` in [`Axis::status`].
    async fn home(&mut self) -> Result<(), RigError>;
    /// Starts a move to `target` at `speed`; returns once the device accepted it.
    async fn move_to(&mut self, target: f64, speed: f64) -> Result<(), RigError>;
    /// Reads position and motion state.
    async fn status(&mut self) -> Result<AxisStatus, RigError>;
    /// Stops any motion as fast as the device allows.
    async fn stop(&mut self) -> Result<(), RigError>;
}

/// Sensing ranges and resolution of a force/torque sensor.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ForceRange {
    /// Axial (z) force range, N.
    pub fz_n: f64,
    /// Tangential (x, y) force range, N.
    pub fxy_n: f64,
    /// Torque range, N·mm.
    pub torque_nmm: f64,
    /// Force resolution, N.
    pub force_resolution_n: f64,
    /// Torque resolution, N·mm.
    pub torque_resolution_nmm: f64,
}

impl ForceRange {
    /// ATI Nano17 (SI-50-0.5 calibration): 70 N axial, 50 N tangential, 500 N·mm, resolution
    /// 1/80 N and 1/16 N·mm (thesis §3.3).
    pub const NANO17: ForceRange = ForceRange {
        fz_n: 70.0,
        fxy_n: 50.0,
        torque_nmm: 500.0,
        force_resolution_n: 1.0 / 80.0,
        torque_resolution_nmm: 1.0 / 16.0,
    };
}

/// What a runner needs to know about a force sensor.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ForceInfo {
    /// Model name.
    pub model: String,
    /// Ranges and resolution.
    pub range: ForceRange,
    /// Highest sample rate the device delivers, Hz.
    pub max_rate_hz: f64,
    /// Identity (serial, calibration) for the run manifest.
    pub identity: String,
}

/// A six-axis force/torque sensor.
#[async_trait]
pub trait ForceSensor: Send {
    /// Static description.
    fn info(&self) -> &ForceInfo;
    /// The most recent sample.
    async fn read(&mut self) -> Result<ForceSample, RigError>;
    /// Records missing from the sensor's own sequence since it was opened (a Net F/T's
    /// `rdt_sequence` gaps); 0 for a sensor that cannot tell.
    fn records_lost(&self) -> u64 {
        0
    }
    /// Every sample received since the last call, oldest first, for matching frames to the
    /// force inside their exposure. A sensor that streams faster than it is read (a Net F/T
    /// at 7 kHz) keeps them; one sampled on demand returns none, and the caller uses what it
    /// read.
    fn take_received(&mut self) -> Vec<ForceSample> {
        Vec::new()
    }
    /// How the sensor's sample times are put on the run's timebase, for the manifest and
    /// the report's timing section; `None` when samples are stamped as they are read.
    fn timing(&self) -> Option<DeviceTiming> {
        None
    }
    /// Ground truth of a simulated bench at the current time; `None` for real sensors.
    async fn truth(&mut self) -> Option<SimTruth> {
        None
    }
}

/// What a runner needs to know about a camera.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CameraInfo {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Frame rate, Hz.
    pub fps: f64,
    /// Exposure, s, when known: a frame is matched to the force inside it (else to the
    /// force within half a frame period of `t_ns`).
    pub exposure_s: Option<f64>,
    /// Identity for the run manifest.
    pub identity: String,
}

/// A camera looking at the elastomer.
#[async_trait]
pub trait Camera: Send {
    /// Static description.
    fn info(&self) -> &CameraInfo;
    /// Waits for and returns the next frame.
    async fn capture(&mut self) -> Result<Frame, RigError>;
    /// How frame times are put on the run's timebase; `None` when the camera's own
    /// timestamps are used as they are.
    fn timing(&self) -> Option<DeviceTiming> {
        None
    }
}

/// An external disturbance applied to a grasped object (thesis §6.3.2: the can swung by
/// hand). On the simulated bench it is a load added to the plant; on a real bench an
/// operator prompt or an actuator.
#[async_trait]
pub trait Disturber: Send {
    /// Applies a sinusoidal disturbance of the given amplitudes starting now.
    async fn apply(
        &mut self,
        force_y_n: f64,
        torque_z_nmm: f64,
        frequency_hz: f64,
        duration_s: f64,
    ) -> Result<(), RigError>;
}
