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

/// Force in N and torque in N·mm, as the sensor reports them: the load the indenter applies
/// to the elastomer, with z into the gel and x along the shear axis.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct Wrench {
    /// Force along x (shear axis), N.
    pub fx_n: f64,
    /// Force along y, N.
    pub fy_n: f64,
    /// Force along z (into the gel), N.
    pub fz_n: f64,
    /// Torque about x, N·mm.
    pub tx_nmm: f64,
    /// Torque about y, N·mm.
    pub ty_nmm: f64,
    /// Torque about z (normal axis), N·mm.
    pub tz_nmm: f64,
}

impl Wrench {
    /// Component-wise difference (used for tare).
    pub fn minus(&self, o: &Wrench) -> Wrench {
        Wrench {
            fx_n: self.fx_n - o.fx_n,
            fy_n: self.fy_n - o.fy_n,
            fz_n: self.fz_n - o.fz_n,
            tx_nmm: self.tx_nmm - o.tx_nmm,
            ty_nmm: self.ty_nmm - o.ty_nmm,
            tz_nmm: self.tz_nmm - o.tz_nmm,
        }
    }

    /// Component-wise mean of `ws` (zero for an empty slice).
    pub fn mean(ws: impl IntoIterator<Item = Wrench>) -> Wrench {
        let mut sum = [0.0; 6];
        let mut n = 0usize;
        for w in ws {
            for (s, v) in sum.iter_mut().zip(w.as_array()) {
                *s += v;
            }
            n += 1;
        }
        let k = if n == 0 { 0.0 } else { 1.0 / n as f64 };
        Wrench::from_array(sum.map(|s| s * k))
    }

    /// `[fx, fy, fz, tx, ty, tz]`.
    pub fn as_array(&self) -> [f64; 6] {
        [
            self.fx_n,
            self.fy_n,
            self.fz_n,
            self.tx_nmm,
            self.ty_nmm,
            self.tz_nmm,
        ]
    }

    /// Inverse of [`Wrench::as_array`].
    pub fn from_array(a: [f64; 6]) -> Wrench {
        Wrench {
            fx_n: a[0],
            fy_n: a[1],
            fz_n: a[2],
            tx_nmm: a[3],
            ty_nmm: a[4],
            tz_nmm: a[5],
        }
    }
}

/// Status bit: some channel is beyond the sensor's calibrated range (the reading is clipped).
pub const STATUS_SATURATED: u32 = 1 << 30;

/// One force/torque sample.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ForceSample {
    /// Host time of the sample on the run's timebase.
    pub t_ns: u64,
    /// The sensor's own sample counter (Net F/T `ft_sequence`; the simulator's count).
    pub ft_seq: u64,
    /// The reading, before any tare.
    pub wrench: Wrench,
    /// Device status bits; see [`STATUS_SATURATED`].
    pub status: u32,
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

/// What a simulated bench knows that no sensor can: the contact's true state, recorded
/// beside the data of a dry run so analysis can be checked against it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SimTruth {
    /// Indentation depth, mm.
    pub depth_mm: f64,
    /// The wrench without sensor offset, noise or quantisation.
    pub wrench: Wrench,
    /// The long-term (fully relaxed) wrench of the present state.
    pub equilibrium: Wrench,
    /// Effective contact radius √(A/π), mm.
    pub contact_radius_mm: f64,
    /// Fraction of the contact that sticks under shear (None without shear).
    pub shear_stick_fraction: Option<f64>,
    /// Fraction of the contact that sticks under twist (None without twist).
    pub twist_stick_fraction: Option<f64>,
    /// Sliding in full slip under shear.
    pub shear_sliding: bool,
    /// Sliding in full slip under twist.
    pub twist_sliding: bool,
    /// Times the contact went into full slip under shear since it was made.
    pub shear_slips: u32,
    /// Times the contact went into full slip under twist since it was made.
    pub twist_slips: u32,
    /// Times a grasped object slipped out of the grasp.
    pub object_slips: u32,
    /// The grasped can's motion and the gel's stick state (lifting trials only).
    pub grasp: Option<GraspTruth>,
}

/// Ground truth of a simulated grasp (thesis §6.3): what tactile slip detection is scored
/// against.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct GraspTruth {
    /// The can's height above where it stood on the table, mm.
    pub height_mm: f64,
    /// The can's velocity relative to the pads, mm/s (negative: sliding down).
    pub slip_mm_s: f64,
    /// How far the can has slid through the grasp since it was taken, mm.
    pub slid_mm: f64,
    /// The can's rotation in the grasp, degrees.
    pub angle_deg: f64,
    /// Fraction of the gel's contact that sticks under the load along the lift (1 at rest,
    /// 0 in gross slip).
    pub gel_stick_fraction: f64,
    /// Fraction that sticks under the torque about the normal alone. Under both loads the
    /// stuck area is at most the smaller of the two.
    pub gel_twist_stick_fraction: f64,
    /// The gel side's friction margin along the lift, 1 − |Q| / Q_max (Q_max: its full-slip
    /// force at the present squeeze); 1 when it carries nothing.
    pub gel_margin: f64,
    /// The gel side's torsional margin, 1 − |M| / M_max.
    pub gel_twist_margin: f64,
    /// Gross slip on the gel side now.
    pub sliding: bool,
    /// The can turns in the grasp now (the gel's twist in full slip).
    pub rotating: bool,
    /// The can stands on the table.
    pub on_table: bool,
    /// Gross slips through the grasp so far.
    pub slips: u32,
    /// Falls from the air back onto the table so far.
    pub drops: u32,
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

/// How a device's sample times are put on the run's timebase.
#[derive(Debug, Clone, PartialEq, Serialize, serde::Deserialize)]
pub struct DeviceTiming {
    /// The method, in words ("sample counter against arrival times (lower envelope)").
    pub method: String,
    /// The constant latency subtracted, s (calibrated per setup: no model of arrival times
    /// can tell it from a clock offset).
    pub latency_s: f64,
    /// The device clock's rate against the host's, ppm (positive: slow), once fitted.
    pub drift_ppm: Option<f64>,
    /// Samples stamped on arrival, before the model had seen enough.
    pub stamped_on_arrival: u64,
}

/// One RGB frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    /// Host time of the exposure midpoint on the run's timebase.
    pub t_ns: u64,
    /// The camera's frame counter; gaps mean dropped frames.
    pub seq: u64,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Row-major RGB8 pixels, `width * height * 3` bytes.
    pub rgb: Vec<u8>,
    /// Exact marker centres in pixels, when the camera is simulated (ground truth for
    /// tracking tests); `None` from a real camera.
    pub truth_px: Option<Vec<[f64; 2]>>,
    /// The true exposure midpoint, ns, when the camera is simulated (what `t_ns` is
    /// measured against); `None` from a real camera.
    pub truth_t_ns: Option<u64>,
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
