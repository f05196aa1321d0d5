//! The rig file: which device plays which role on a bench.
//!
//! A protocol names roles (`normal`, `shear`, `rotation`, `lift`, `grip`, force, camera);
//! a rig file in `protocols/rigs/` binds each role to a driver with its travel, speed and
//! resolution. Keeping the two apart lets one protocol run on the simulated bench in CI and
//! on the real bench in the lab by changing `--rig` only.

use std::collections::BTreeMap;
use std::fmt;

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::units::{AxisQuantity, AxisSpeed, AxisUnit, Duration, Force, Frequency, Length};

mod contact;
mod devices;
mod ranges;
pub use contact::{ContactModelConfig, PRESSING_FRICTION_DEFAULT};
pub use devices::{
    CameraConfig, CameraDriver, DisturberConfig, DisturberDriver, ForceConfig, ForceDriver,
    ForceModel, SimCameraTiming,
};

/// The part an axis plays on the bench.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize, JsonSchema,
)]
#[serde(rename_all = "snake_case")]
pub enum AxisRole {
    /// Presses the indenter into the elastomer (thesis §3.3, vertical micrometer).
    Normal,
    /// Moves the indenter along the elastomer surface (horizontal micrometer).
    Shear,
    /// Rotates the sensor about its normal (the portable rig's tripod joint, §6.2.3).
    Rotation,
    /// Lifts a grasped object (the jig's vertical rail, §6.3.1).
    Lift,
    /// Closes the grasp onto the object (the jig's horizontal rail).
    Grip,
}

impl AxisRole {
    /// All roles, in display order.
    pub const ALL: [AxisRole; 5] = [
        AxisRole::Normal,
        AxisRole::Shear,
        AxisRole::Rotation,
        AxisRole::Lift,
        AxisRole::Grip,
    ];

    /// The role's name as written in YAML.
    pub fn name(self) -> &'static str {
        match self {
            AxisRole::Normal => "normal",
            AxisRole::Shear => "shear",
            AxisRole::Rotation => "rotation",
            AxisRole::Lift => "lift",
            AxisRole::Grip => "grip",
        }
    }

    /// Roles that press into the elastomer, whose depth must stay below its thickness.
    pub fn presses(self) -> bool {
        matches!(self, AxisRole::Normal | AxisRole::Grip)
    }
}

impl fmt::Display for AxisRole {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A rig file.
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct RigConfig {
    /// Short name shown in run manifests.
    pub name: String,
    /// What bench this is.
    #[serde(default)]
    pub description: String,
    /// Stage axes by role.
    #[serde(default)]
    pub axes: BTreeMap<AxisRole, AxisConfig>,
    /// The force/torque sensor.
    #[serde(default)]
    pub force: Option<ForceConfig>,
    /// The camera looking at the elastomer.
    #[serde(default)]
    pub camera: Option<CameraConfig>,
    /// What applies external disturbances to a grasped object.
    #[serde(default)]
    pub disturber: Option<DisturberConfig>,
    /// Geometry of the simulated bench; required when any device is simulated.
    #[serde(default)]
    pub sim: Option<SimConfig>,
    /// How the bench's indenter meets its gel, where a model of the contact is needed (a
    /// real bench's `gelrig fit-material`; the simulated bench presses by it too).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub contact: Option<ContactModelConfig>,
    /// Written by `gelrig sim serve` into the rig file it binds: every device is a twin.
    /// Never write it for a real bench.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub twins: Option<TwinsConfig>,
}

/// The devices are `gelrig sim serve` twins.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct TwinsConfig {
    /// How many times faster than the wall the twins' stages and elastomer run; the run's
    /// clock runs at the same speed, so settles and sample times stay in plant time.
    pub time_scale: f64,
}

/// One stage axis.
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct AxisConfig {
    /// Which driver talks to it.
    pub driver: AxisDriver,
    /// Travel limits `[min, max]`: mm for a linear axis, deg for a rotary one. The unit
    /// written here decides the axis unit.
    pub travel: [AxisQuantity; 2],
    /// Fastest move the axis makes.
    pub max_speed: AxisSpeed,
    /// Smallest position increment (0.002 mm for the thesis's micrometer stages).
    pub resolution: AxisQuantity,
    /// How often to poll position while moving (default 20 Hz).
    #[serde(default)]
    pub poll_rate: Option<Frequency>,
    /// A move is done only at rest within this distance of its target (default: the
    /// resolution; a drive's in-position window, where wider).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub in_position: Option<AxisQuantity>,
    /// How long a move may show no motion before it counts as not started, when it is not
    /// already at its target (default 0.5 s: real drives show motion within milliseconds
    /// to a few hundred of them).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub start_grace: Option<Duration>,
    /// Times a move that ends away from its target (or never starts) is sent again before
    /// the run fails (default 0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub move_retries: Option<u32>,
    /// Serial device of a `zaber` or `smc100` axis (`/dev/ttyUSB0`; a twin's `/dev/pts/N`).
    #[serde(default)]
    pub port: Option<String>,
    /// Zaber device address on the daisy chain, or SMC100 controller address (default 1).
    #[serde(default)]
    pub device: Option<u8>,
    /// Zaber axis number on the device (default 1).
    #[serde(default)]
    pub axis_number: Option<u8>,
    /// Size of one microstep in the axis unit: 0.000047625 mm on Zaber lead-screw stages,
    /// 0.000234375 deg on X-RSW rotary stages.
    #[serde(default)]
    pub microstep: Option<f64>,
    /// Zaber LRC checksums on every message (default true).
    #[serde(default)]
    pub checksum: Option<bool>,
    /// Register map of a `modbus` axis.
    #[serde(default)]
    pub modbus: Option<crate::drivers::modbus::ModbusMap>,
}

impl AxisConfig {
    /// mm or deg, from the unit of `travel`.
    pub fn unit(&self) -> AxisUnit {
        self.travel[0].natural_unit()
    }

    /// Travel limits in the axis unit (percentages are rejected by [`RigConfig::check`]).
    pub fn travel(&self) -> (f64, f64) {
        (self.travel[0].raw(), self.travel[1].raw())
    }

    /// Position poll rate in Hz.
    pub fn poll_rate_hz(&self) -> f64 {
        self.poll_rate.map(|f| f.hz()).unwrap_or(20.0)
    }

    /// How close to its target a move must end, in the axis unit (infinite for a manual
    /// axis: the operator types where it is).
    pub fn in_position_window(&self) -> f64 {
        if matches!(self.driver, AxisDriver::Manual) {
            return f64::INFINITY;
        }
        self.in_position
            .map(|q| q.raw())
            .unwrap_or(self.resolution.raw())
    }

    /// How long a move may show no motion before it counts as not started, s.
    pub fn start_grace_s(&self) -> f64 {
        self.start_grace.map(|d| d.s()).unwrap_or(0.5)
    }
}

/// Axis drivers available in this build.
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum AxisDriver {
    /// The in-process simulated stage (travel, speed, resolution, reference state).
    Sim,
    /// A Zaber stage speaking the ASCII protocol on `port` (needs `microstep`).
    Zaber,
    /// A hand-turned micrometer: gelrig prompts the operator on the terminal.
    Manual,
    /// A Newport SMC100 / CONEX-CC controller on `port` at address `device` (default 1).
    Smc100,
    /// A Modbus TCP drive described by the `modbus:` register map.
    Modbus,
}

/// Geometry of the simulated bench.
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SimConfig {
    /// Normal-axis position at which the indenter touches the elastomer.
    pub normal_contact: Length,
    /// Grip-axis position at which the grasp touches the object.
    #[serde(default)]
    pub grip_contact: Option<Length>,
    /// Largest offset the simulated force sensor reads before a tare (drawn per seed).
    #[serde(default)]
    pub force_bias: Option<Force>,
    /// Add sensor noise at the sensor's resolution (default true).
    #[serde(default)]
    pub noise: Option<bool>,
    /// Press with friction — the coupled normal–tangential contact, in which the indenter
    /// holds the gel's outward flow where it touches and presses harder for it (9–39 % on
    /// the shipped flat punches; a curved indenter along its loading path). Default
    /// [`PRESSING_FRICTION_DEFAULT`] (true); `false` gives the frictionless pressure with
    /// friction found on it one way (Goodman), the round-1 model. The same as
    /// `contact: {pressing_friction}` ([`ContactModelConfig`]), which a real bench uses.
    #[serde(default)]
    pub pressing_friction: Option<bool>,
    /// Press flat punches into a neo-Hookean gel at finite strain: the force times the
    /// reference's stiffening (the mechanics crate's `finite_strain`; 29 % at 20 % strain on the
    /// portable punch; the reference reaches 20 % (box) and 30 % (portable) strain, beyond
    /// which it is extrapolated). Default false: small strain, as the thesis measured its
    /// flat punch (force linear in depth). The same as `contact: {finite_strain}`.
    #[serde(default)]
    pub finite_strain: Option<bool>,
    /// Resolution of the simulated contact — grids, loading path, field — traded against
    /// run time (docs/benchmarks/simulator.md, "Fidelity levels"). Default `default`;
    /// `gelrig run --fidelity` sets it for one run.
    #[serde(default)]
    pub fidelity: Option<Fidelity>,
}

/// How finely the simulated bench solves its contact: error against run time.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Fidelity {
    /// Half the default's resolution: a quick check of a protocol's logic.
    Fast,
    /// The verified model (within 0.3 % of finite elements on the shipped contacts).
    #[default]
    Default,
    /// Twice the default's resolution: the level the others are measured against.
    Reference,
}

impl Fidelity {
    /// Every level, fastest first.
    pub const ALL: [Self; 3] = [Self::Fast, Self::Default, Self::Reference];

    /// The name in a rig file and on the command line.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Fast => "fast",
            Self::Default => "default",
            Self::Reference => "reference",
        }
    }
}

impl std::str::FromStr for Fidelity {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Self::ALL
            .into_iter()
            .find(|f| f.as_str() == s)
            .ok_or_else(|| format!("unknown fidelity `{s}`: use fast, default or reference"))
    }
}

/// One segment of a path into a YAML document, to locate a value for an error message.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum PathSeg {
    /// A mapping key.
    Key(String),
    /// A sequence index.
    Index(usize),
}

/// A path into a YAML document, e.g. `sequence[3].stepped.to`.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct YamlPath(pub Vec<PathSeg>);

impl YamlPath {
    /// The root.
    pub fn root() -> Self {
        Self(Vec::new())
    }
    /// This path extended by a key.
    pub fn key(&self, k: &str) -> Self {
        let mut p = self.clone();
        p.0.push(PathSeg::Key(k.to_string()));
        p
    }
    /// This path extended by an index.
    pub fn index(&self, i: usize) -> Self {
        let mut p = self.clone();
        p.0.push(PathSeg::Index(i));
        p
    }
}

impl fmt::Display for YamlPath {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, seg) in self.0.iter().enumerate() {
            match seg {
                PathSeg::Key(k) if i == 0 => write!(f, "{k}")?,
                PathSeg::Key(k) => write!(f, ".{k}")?,
                PathSeg::Index(n) => write!(f, "[{n}]")?,
            }
        }
        Ok(())
    }
}

/// A problem found in a configuration after it parsed: where, what, and the fix.
#[derive(Debug, Clone, PartialEq)]
pub struct ConfigIssue {
    /// Where in the file.
    pub path: YamlPath,
    /// What is wrong.
    pub message: String,
    /// How to fix it.
    pub fix: String,
}

impl RigConfig {
    /// Parses a rig file.
    pub fn from_yaml_str(text: &str) -> Result<Self, serde_yaml::Error> {
        serde_yaml::from_str(text)
    }

    /// Checks what parsing cannot: units consistent per axis, limits ordered, sim geometry
    /// present where a simulator needs it.
    pub fn check(&self) -> Vec<ConfigIssue> {
        let mut issues = self.check_ranges();
        issues.extend(self.check_contact_model());
        for (role, axis) in &self.axes {
            let at = YamlPath::root().key("axes").key(role.name());
            let unit = axis.unit();
            for (i, q) in axis.travel.iter().enumerate() {
                if matches!(q, AxisQuantity::Percent(_)) || q.natural_unit() != unit {
                    issues.push(ConfigIssue {
                        path: at.key("travel").index(i),
                        message: format!(
                            "travel limit `{q}` does not match the axis unit {}",
                            unit.symbol()
                        ),
                        fix: format!("write both travel limits in {}", unit.symbol()),
                    });
                }
            }
            let (lo, hi) = axis.travel();
            if lo >= hi {
                issues.push(ConfigIssue {
                    path: at.key("travel"),
                    message: format!("travel [{lo}, {hi}] is empty"),
                    fix: "write the travel as [min, max] with min < max".into(),
                });
            }
            if axis.max_speed.unit != unit || axis.max_speed.value <= 0.0 {
                issues.push(ConfigIssue {
                    path: at.key("max_speed"),
                    message: format!(
                        "max_speed `{}` is not a positive {}/s speed",
                        axis.max_speed,
                        unit.symbol()
                    ),
                    fix: format!("write a positive speed in {}/s", unit.symbol()),
                });
            }
            if matches!(axis.resolution, AxisQuantity::Percent(_))
                || axis.resolution.natural_unit() != unit
                || axis.resolution.raw() <= 0.0
            {
                issues.push(ConfigIssue {
                    path: at.key("resolution"),
                    message: format!(
                        "resolution `{}` is not a positive {}",
                        axis.resolution,
                        unit.symbol()
                    ),
                    fix: format!(
                        "write the stage's smallest step in {}, e.g. `0.002 mm`",
                        unit.symbol()
                    ),
                });
            }
        }
        for (role, axis) in &self.axes {
            let at = YamlPath::root().key("axes").key(role.name());
            if matches!(axis.driver, AxisDriver::Modbus) {
                match &axis.modbus {
                    None => issues.push(ConfigIssue {
                        path: at.key("driver"),
                        message: "a modbus axis needs its register map".into(),
                        fix: "add a `modbus:` section (address, slave, steps_per_unit, target, speed, trigger, position, status, bits, home, stop); see docs/how-to/modbus.md".into(),
                    }),
                    Some(map) => {
                        for (field, msg) in map.problems() {
                            issues.push(ConfigIssue {
                                path: at.key("modbus").key(field),
                                message: format!("register map: {msg}"),
                                fix: "use the addresses and bits from the drive's manual".into(),
                            });
                        }
                    }
                }
            }
            if matches!(axis.driver, AxisDriver::Smc100) && axis.port.is_none() {
                issues.push(ConfigIssue {
                    path: at.key("driver"),
                    message: "an smc100 axis needs the serial port it is on".into(),
                    fix: "add `port: /dev/ttyUSB0`".into(),
                });
            }
            if matches!(axis.driver, AxisDriver::Zaber) {
                if axis.port.is_none() {
                    issues.push(ConfigIssue {
                        path: at.key("driver"),
                        message: "a zaber axis needs the serial port it is on".into(),
                        fix: "add `port: /dev/ttyUSB0` (or the path `gelrig sim serve` printed)"
                            .into(),
                    });
                }
                if !axis.microstep.is_some_and(|m| m > 0.0) {
                    issues.push(ConfigIssue {
                        path: at.key("driver"),
                        message: "a zaber axis needs its microstep size".into(),
                        fix: "add `microstep: 0.000047625` (mm, lead-screw stages) or `0.000234375` (deg, X-RSW)".into(),
                    });
                }
            }
        }
        if let Some(f) = &self.force
            && matches!(f.driver, ForceDriver::NetFt)
            && f.address.is_none()
        {
            issues.push(ConfigIssue {
                path: YamlPath::root().key("force").key("driver"),
                message: "a net_ft sensor needs the box's address".into(),
                fix: "add `address: 192.168.1.1` (or `host:port`)".into(),
            });
        }
        if let Some(f) = &self.force
            && matches!(f.driver, ForceDriver::AtiCan)
            && (f.can_interface.is_none()
                || f.base_id.is_none()
                || !f.counts_per_force.is_some_and(|c| c > 0.0)
                || !f.counts_per_torque.is_some_and(|c| c > 0.0))
        {
            issues.push(ConfigIssue {
                path: YamlPath::root().key("force").key("driver"),
                message: "an ati_can sensor needs its interface, base id and counts per unit".into(),
                fix: "add `can_interface: can0, base_id: 0x20, counts_per_force: …, counts_per_torque: …` from the box's configuration page".into(),
            });
        }
        if let Some(c) = &self.camera
            && matches!(c.driver, CameraDriver::ImageFolder)
            && c.path.is_none()
        {
            issues.push(ConfigIssue {
                path: YamlPath::root().key("camera").key("driver"),
                message: "an image_folder camera needs the folder of frames".into(),
                fix: "add `path: ../shared/data/gelsight-mini-press`".into(),
            });
        }
        if self.uses_sim() && self.sim.is_none() {
            issues.push(ConfigIssue {
                path: YamlPath::root().key("name"),
                message: "this rig has simulated devices but no `sim:` section".into(),
                fix: "add `sim: {normal_contact: 10 mm}` giving the simulated bench's geometry"
                    .into(),
            });
        }
        issues
    }

    /// True when any device is simulated in-process.
    pub fn uses_sim(&self) -> bool {
        self.axes
            .values()
            .any(|a| matches!(a.driver, AxisDriver::Sim))
            || self
                .force
                .as_ref()
                .is_some_and(|f| matches!(f.driver, ForceDriver::Sim))
            || self
                .camera
                .as_ref()
                .is_some_and(|c| matches!(c.driver, CameraDriver::Sim))
            || self
                .disturber
                .as_ref()
                .is_some_and(|d| matches!(d.driver, DisturberDriver::Sim))
    }
}
