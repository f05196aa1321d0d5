//! The rig file's force sensor, camera and disturber: which driver, where, and how their
//! times are put on the run's timebase.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::device::ForceRange;
use crate::units::{Duration, Frequency};

/// The force/torque sensor.
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ForceConfig {
    /// Which driver talks to it.
    pub driver: ForceDriver,
    /// Sensor model, which fixes its ranges.
    #[serde(default)]
    pub model: ForceModel,
    /// Highest rate the sensor delivers samples at (default 1 kHz).
    #[serde(default)]
    pub max_rate: Option<Frequency>,
    /// Net F/T box address, `host` or `host:rdt_port` (RDT port default 49152).
    #[serde(default)]
    pub address: Option<String>,
    /// Net F/T calibration (TCP) port, default 49151.
    #[serde(default)]
    pub calibration_port: Option<u16>,
    /// The constant delay of the sensor's samples on their way to the host, subtracted from
    /// every sample time (default 0). Arrival times cannot tell it from a clock offset:
    /// calibrate it per setup, with an event the camera and the sensor both see.
    #[serde(default)]
    pub latency: Option<Duration>,
    /// SocketCAN interface of an `ati_can` sensor (`can0`).
    #[serde(default)]
    pub can_interface: Option<String>,
    /// CAN base id of an `ati_can` sensor (DIP switches).
    #[serde(default)]
    pub base_id: Option<u32>,
    /// Counts per N of an `ati_can` sensor's short data (from the box's configuration).
    #[serde(default)]
    pub counts_per_force: Option<f64>,
    /// Counts per N·mm of an `ati_can` sensor's short data.
    #[serde(default)]
    pub counts_per_torque: Option<f64>,
}

/// Force sensor drivers available in this build.
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum ForceDriver {
    /// The in-process simulated Nano17 reading the simulated elastomer.
    Sim,
    /// An ATI Net F/T box: RDT over UDP at `address`, calibration read from the box.
    NetFt,
    /// An ATI Net F/T on a CAN bus (short data) on `can_interface` at `base_id`, with the
    /// box's `counts_per_force` and `counts_per_torque` (needs the `socketcan` feature).
    AtiCan,
}

/// Force/torque sensor models with known ranges.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum ForceModel {
    /// ATI Nano17: 70 N axial, 50 N tangential, 500 N·mm.
    #[default]
    Nano17,
}

impl ForceModel {
    /// Ranges and resolution of the model.
    pub fn range(self) -> ForceRange {
        match self {
            ForceModel::Nano17 => ForceRange::NANO17,
        }
    }

    /// Name for messages and manifests.
    pub fn name(self) -> &'static str {
        match self {
            ForceModel::Nano17 => "ATI Nano17",
        }
    }
}

/// The camera.
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct CameraConfig {
    /// Which driver talks to it.
    pub driver: CameraDriver,
    /// Frame width in pixels.
    pub width: u32,
    /// Frame height in pixels.
    pub height: u32,
    /// Frame rate.
    pub fps: Frequency,
    /// Folder of an `image_folder` camera.
    #[serde(default)]
    pub path: Option<String>,
    /// Loop an `image_folder` camera's frames.
    #[serde(default)]
    pub repeat: Option<bool>,
    /// Exposure time: each frame is matched to the force samples inside its exposure. A
    /// `sim` camera renders an instant unless given one (default 0).
    #[serde(default)]
    pub exposure: Option<Duration>,
    /// The constant delay from the end of a frame's exposure to the host, subtracted from
    /// frame times (default 0; calibrate it per setup, with an event the camera and the
    /// force sensor both see).
    #[serde(default)]
    pub latency: Option<Duration>,
    /// Timing faults a `sim` camera injects, to check synchronization on a dry run.
    #[serde(default)]
    pub simulate: Option<SimCameraTiming>,
}

/// Timing faults of a simulated camera.
#[derive(Debug, Clone, Default, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SimCameraTiming {
    /// Delay of every frame from the end of its exposure to the host.
    #[serde(default)]
    pub latency: Option<Duration>,
    /// Extra delay of each frame, uniform in 0…2× this.
    #[serde(default)]
    pub jitter: Option<Duration>,
    /// The camera's clock runs this many ppm slow.
    #[serde(default)]
    pub drift_ppm: Option<f64>,
}

/// Camera drivers available in this build.
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum CameraDriver {
    /// Renders the simulated elastomer's markers.
    Sim,
    /// Replays the PNG frames of `path` (a recorded sequence) at `fps`.
    ImageFolder,
    /// A V4L2 (USB) camera at `path` (`/dev/video0`); needs the `v4l` feature.
    V4l2,
}

/// What applies disturbances to a grasped object.
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct DisturberConfig {
    /// Which driver applies it.
    pub driver: DisturberDriver,
}

/// Disturbance drivers available in this build.
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum DisturberDriver {
    /// Adds the load to the simulated plant.
    Sim,
}
