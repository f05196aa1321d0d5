//! Opening a bench: only the devices a protocol uses.
//!
//! A protocol without a camera must not open one (it may be unplugged, or in use by another
//! program), so the caller says which roles it needs and `open` touches nothing else.

use std::collections::{BTreeMap, BTreeSet};
use std::sync::{Arc, Mutex};

use serde::Serialize;

use crate::plant::{BenchGeometry, Plant, PlantNeeds};
use crate::{FollowedAxis, PlantSpec, SimAxis, SimCamera, SimDisturber, SimForceSensor};
use rig::config::{
    AxisConfig, AxisDriver, AxisRole, CameraConfig, CameraDriver, DisturberDriver, ForceConfig,
    ForceDriver, RigConfig,
};
use rig::device::{Axis, AxisInfo, Camera, CameraInfo, Disturber, ForceInfo, ForceSensor};
use rig::{Clock, RigError};

/// Which devices to open.
#[derive(Debug, Clone)]
pub struct OpenRequest {
    /// Axis roles the protocol moves or reads.
    pub axes: BTreeSet<AxisRole>,
    /// Whether the force sensor is needed.
    pub force: bool,
    /// Whether the camera is needed.
    pub camera: bool,
    /// Whether a disturbance source is needed.
    pub disturber: bool,
    /// Physical description for simulated devices (required if any opened device is one).
    pub plant: Option<PlantSpec>,
    /// The run's clock.
    pub clock: Clock,
    /// Seed for everything random in simulated devices.
    pub seed: u64,
    /// A simulated camera hands the simulator's traction maps with each frame, on cells of
    /// this many pixels a side (a dataset run's `record: {traction_maps: …}`); `None`: not.
    pub traction_maps_px: Option<u32>,
}

/// Identity of an opened device, for the run manifest.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OpenedDevice {
    /// Role on the bench (`normal`, `force`, `camera`, …).
    pub role: String,
    /// Driver and identity string.
    pub identity: String,
}

/// The opened devices.
pub struct Rig {
    /// Opened axes by role.
    pub axes: BTreeMap<AxisRole, Box<dyn Axis>>,
    /// The force sensor, if requested.
    pub force: Option<Box<dyn ForceSensor>>,
    /// The camera, if requested.
    pub camera: Option<Box<dyn Camera>>,
    /// The disturbance source, if requested.
    pub disturber: Option<Box<dyn Disturber>>,
    /// What was opened, in order.
    pub opened: Vec<OpenedDevice>,
}

fn missing(what: &str, rig: &RigConfig) -> RigError {
    RigError::Unsupported {
        device: what.to_string(),
        detail: format!("rig `{}` binds no {what}; add it to the rig file", rig.name),
    }
}

/// The simulated elastomer every simulated device of a rig shares: built when the first
/// of them is opened, and only with what the opened devices will ask of it.
struct SharedPlant<'a> {
    config: &'a RigConfig,
    req: &'a OpenRequest,
    plant: Option<Arc<Mutex<Plant>>>,
}

impl<'a> SharedPlant<'a> {
    fn new(config: &'a RigConfig, req: &'a OpenRequest) -> Self {
        Self {
            config,
            req,
            plant: None,
        }
    }

    /// The plant, built now if no simulated device has asked for it yet; `what` names the
    /// device asking, for the error of a rig or request that cannot build it.
    fn get(&mut self, what: &str) -> Result<Arc<Mutex<Plant>>, RigError> {
        if let Some(p) = &self.plant {
            return Ok(p.clone());
        }
        let req = self.req;
        // Any clock will do: on a mixed rig (real stages, a rendered camera) the simulated
        // elastomer runs in real time beside the real devices.
        let mut spec = req.plant.clone().ok_or_else(|| RigError::Unsupported {
            device: what.to_string(),
            detail: "a simulated device needs the sensor and indenter description".into(),
        })?;
        spec.quality = crate::quality_for(self.config.fidelity());
        let geometry = BenchGeometry::of(self.config, what)?;
        // Build only what the opened devices will ask for.
        let needs = PlantNeeds {
            shear: req.axes.contains(&AxisRole::Shear),
            twist: req.axes.contains(&AxisRole::Rotation),
            fields: req.camera,
        };
        let p = Arc::new(Mutex::new(Plant::new(spec, geometry, needs, req.seed)?));
        self.plant = Some(p.clone());
        Ok(p)
    }

    /// The plant, if a simulated device was opened.
    fn built(self) -> Option<Arc<Mutex<Plant>>> {
        self.plant
    }
}

/// Opens the requested devices of `config`.
pub async fn open(config: &RigConfig, req: OpenRequest) -> Result<Rig, RigError> {
    let mut plant = SharedPlant::new(config, &req);
    let mut rig = Rig {
        axes: BTreeMap::new(),
        force: None,
        camera: None,
        disturber: None,
        opened: Vec::new(),
    };
    for role in &req.axes {
        let cfg = config
            .axes
            .get(role)
            .ok_or_else(|| missing(&format!("{role} axis"), config))?;
        let axis = open_axis(*role, cfg, &mut plant).await?;
        rig.opened.push(OpenedDevice {
            role: role.to_string(),
            identity: axis.info().identity.clone(),
        });
        rig.axes
            .insert(*role, Box::new(rig::checked::CheckedAxis::new(axis)));
    }
    if req.force {
        let cfg = config
            .force
            .as_ref()
            .ok_or_else(|| missing("force sensor", config))?;
        let sensor = open_force(cfg, &mut plant).await?;
        rig.opened.push(OpenedDevice {
            role: "force".into(),
            identity: sensor.info().identity.clone(),
        });
        rig.force = Some(Box::new(rig::checked::CheckedForce::new(sensor)));
    }
    if req.camera {
        let cfg = config
            .camera
            .as_ref()
            .ok_or_else(|| missing("camera", config))?;
        let camera = open_camera(cfg, &mut plant)?;
        rig.opened.push(OpenedDevice {
            role: "camera".into(),
            identity: camera.info().identity.clone(),
        });
        rig.camera = Some(camera);
    }
    if req.disturber {
        let cfg = config
            .disturber
            .as_ref()
            .ok_or_else(|| missing("disturber", config))?;
        let d: Box<dyn Disturber> = match cfg.driver {
            DisturberDriver::Sim => Box::new(SimDisturber::new(
                plant.get("disturber")?,
                req.clock.clone(),
            )),
        };
        rig.opened.push(OpenedDevice {
            role: "disturber".into(),
            identity: "simulated disturbance on the grasped object".into(),
        });
        rig.disturber = Some(d);
    }
    if let Some(p) = plant.built() {
        follow_real_stages(&mut rig, config, &p, &req.clock);
    }
    Ok(rig)
}

/// Opens the axis of `role` as its rig file entry `cfg` says: simulated on the shared
/// plant, or through its driver (Zaber, SMC100, Modbus, or the operator's hand).
async fn open_axis(
    role: AxisRole,
    cfg: &AxisConfig,
    plant: &mut SharedPlant<'_>,
) -> Result<Box<dyn Axis>, RigError> {
    let (travel_min, travel_max) = cfg.travel();
    let info = AxisInfo {
        role: role.to_string(),
        unit: cfg.unit(),
        travel_min,
        travel_max,
        max_speed: cfg.max_speed.value,
        resolution: cfg.resolution.raw(),
        identity: String::new(),
    };
    let axis: Box<dyn Axis> = match cfg.driver {
        AxisDriver::Sim => {
            let p = plant.get(&format!("{role} axis"))?;
            let info = AxisInfo {
                identity: format!(
                    "simulated stage, {} {}, travel [{travel_min}, {travel_max}]",
                    info.resolution,
                    info.unit.symbol()
                ),
                ..info
            };
            Box::new(SimAxis::new(role, info, p, plant.req.clock.clone()))
        }
        AxisDriver::Zaber => {
            // `RigConfig::check` guarantees port and microstep.
            let settings = rig::drivers::zaber::ZaberSettings {
                port: cfg.port.clone().unwrap_or_default(),
                device: cfg.device.unwrap_or(1),
                axis: cfg.axis_number.unwrap_or(1),
                microstep: cfg.microstep.unwrap_or(f64::NAN),
                checksum: cfg.checksum.unwrap_or(true),
                timeout: std::time::Duration::from_millis(300),
                retries: 2,
            };
            Box::new(rig::drivers::zaber::ZaberAxis::open(settings, info).await?)
        }
        AxisDriver::Smc100 => Box::new(
            rig::drivers::smc100::Smc100Axis::open(
                rig::drivers::smc100::Smc100Settings {
                    port: cfg.port.clone().unwrap_or_default(),
                    address: cfg.device.unwrap_or(1),
                    timeout: std::time::Duration::from_millis(300),
                    retries: 2,
                },
                info,
            )
            .await?,
        ),
        AxisDriver::Modbus => match cfg.modbus.clone() {
            Some(map) => Box::new(rig::drivers::modbus::ModbusAxis::open(map, info).await?),
            None => return Err(missing(&format!("{role} axis register map"), plant.config)),
        },
        AxisDriver::Manual => Box::new(rig::drivers::manual::ManualAxis::new(
            info,
            Arc::new(Mutex::new((
                Box::new(std::io::BufReader::new(std::io::stdin())),
                Box::new(std::io::stderr()),
            ))),
        )),
    };
    Ok(axis)
}

/// Opens the force sensor of rig file entry `cfg`: simulated on the shared plant, a Net
/// F/T box, or an ATI sensor on a CAN bus.
async fn open_force(
    cfg: &ForceConfig,
    plant: &mut SharedPlant<'_>,
) -> Result<Box<dyn ForceSensor>, RigError> {
    let req = plant.req;
    let sensor: Box<dyn ForceSensor> = match cfg.driver {
        ForceDriver::Sim => {
            let p = plant.get("force sensor")?;
            let info = ForceInfo {
                model: cfg.model.name().into(),
                range: cfg.model.range(),
                max_rate_hz: cfg.max_rate.map(|f| f.hz()).unwrap_or(1000.0),
                identity: format!("simulated {} (seed {})", cfg.model.name(), req.seed),
            };
            Box::new(SimForceSensor::new(info, p, req.clock.clone()))
        }
        ForceDriver::NetFt => {
            let address = cfg.address.clone().unwrap_or_default();
            let rdt = rig::drivers::netft::resolve(&address, 49152)?;
            let mut calibration = rdt;
            calibration.set_port(cfg.calibration_port.unwrap_or(49151));
            let settings = rig::drivers::netft::NetFtSettings {
                rdt,
                calibration,
                timeout: std::time::Duration::from_millis(500),
                retries: 9,
                range: cfg.model.range(),
                latency_s: cfg.latency.map_or(0.0, |d| d.s()),
            };
            Box::new(rig::drivers::netft::NetFtSensor::open(settings, req.clock.clone()).await?)
        }
        ForceDriver::AtiCan => {
            let bus = can_bus(cfg.can_interface.as_deref().unwrap_or("can0"))?;
            let settings = rig::drivers::ati_can::AtiCanSettings {
                base_id: cfg.base_id.unwrap_or(0),
                counts_per_n: cfg.counts_per_force.unwrap_or(f64::NAN),
                counts_per_nmm: cfg.counts_per_torque.unwrap_or(f64::NAN),
                timeout: std::time::Duration::from_millis(100),
                retries: 3,
                range: cfg.model.range(),
            };
            Box::new(
                rig::drivers::ati_can::AtiCanSensor::open(settings, bus, req.clock.clone()).await?,
            )
        }
    };
    Ok(sensor)
}

/// Opens the camera of rig file entry `cfg`: simulated on the shared plant (with the frame
/// timing faults it is told to inject), a folder of images, or a V4L2 device.
fn open_camera(
    cfg: &CameraConfig,
    plant: &mut SharedPlant<'_>,
) -> Result<Box<dyn Camera>, RigError> {
    let req = plant.req;
    let camera: Box<dyn Camera> = match cfg.driver {
        CameraDriver::Sim => {
            let p = plant.get("camera")?;
            let sim = cfg.simulate.clone().unwrap_or_default();
            let timing = crate::frame_timing::FrameTiming::new(
                cfg.fps.hz(),
                cfg.exposure.map_or(0.0, |d| d.s()),
                crate::frame_timing::Injected {
                    latency_s: sim.latency.map_or(0.0, |d| d.s()),
                    jitter_s: sim.jitter.map_or(0.0, |d| d.s()),
                    drift_ppm: sim.drift_ppm.unwrap_or(0.0),
                },
                cfg.latency.map_or(0.0, |d| d.s()),
                req.seed,
            );
            let info = CameraInfo {
                width: cfg.width,
                height: cfg.height,
                fps: cfg.fps.hz(),
                exposure_s: Some(timing.exposure_s()),
                identity: format!(
                    "simulated camera {}×{} at {} Hz",
                    cfg.width,
                    cfg.height,
                    cfg.fps.hz()
                ),
            };
            Box::new(SimCamera::new(
                info,
                timing,
                p,
                req.clock.clone(),
                req.seed,
                req.traction_maps_px,
            ))
        }
        CameraDriver::ImageFolder => {
            let path = std::path::PathBuf::from(cfg.path.clone().unwrap_or_default());
            let mut cam = rig::drivers::image_folder::ImageFolderCamera::open(
                &path,
                cfg.fps.hz(),
                req.clock.clone(),
            )?;
            cam.repeat = cfg.repeat.unwrap_or(false);
            Box::new(cam)
        }
        CameraDriver::V4l2 => v4l2_camera(cfg, req.clock.clone())?,
    };
    Ok(camera)
}

/// Real stages on a rig with simulated devices (the wire twins' rig with its rendered
/// camera): the simulated elastomer `plant` follows where the drivers say the stages are.
fn follow_real_stages(rig: &mut Rig, config: &RigConfig, plant: &Arc<Mutex<Plant>>, clock: &Clock) {
    let real: Vec<AxisRole> = rig
        .axes
        .keys()
        .filter(|r| {
            config
                .axes
                .get(r)
                .is_some_and(|a| !matches!(a.driver, AxisDriver::Sim))
        })
        .copied()
        .collect();
    for role in real {
        if let Some(inner) = rig.axes.remove(&role) {
            let followed = FollowedAxis::new(role, inner, plant.clone(), clock.clone());
            rig.axes.insert(role, Box::new(followed));
        }
    }
}

#[cfg(feature = "socketcan")]
fn can_bus(interface: &str) -> Result<Box<dyn rig::drivers::can::CanBus>, RigError> {
    Ok(Box::new(rig::drivers::can::SocketCanBus::open(interface)?))
}

#[cfg(not(feature = "socketcan"))]
fn can_bus(interface: &str) -> Result<Box<dyn rig::drivers::can::CanBus>, RigError> {
    Err(RigError::Unsupported {
        device: format!("CAN interface {interface}"),
        detail: "this gelrig was built without SocketCAN; fix: rebuild with `--features socketcan`"
            .into(),
    })
}

#[cfg(feature = "v4l")]
fn v4l2_camera(cfg: &rig::config::CameraConfig, clock: Clock) -> Result<Box<dyn Camera>, RigError> {
    let path = cfg.path.clone().unwrap_or_else(|| "/dev/video0".into());
    Ok(Box::new(rig::drivers::v4l2::V4l2Camera::open(
        &path,
        cfg.width,
        cfg.height,
        cfg.fps.hz(),
        cfg.latency.map_or(0.0, |d| d.s()),
        clock,
    )?))
}

#[cfg(not(feature = "v4l"))]
fn v4l2_camera(
    cfg: &rig::config::CameraConfig,
    _clock: Clock,
) -> Result<Box<dyn Camera>, RigError> {
    Err(RigError::Unsupported {
        device: format!("camera {}", cfg.path.as_deref().unwrap_or("/dev/video0")),
        detail: "this gelrig was built without V4L2; fix: install libclang-dev and rebuild with `--features v4l`".into(),
    })
}
