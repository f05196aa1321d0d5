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
                        fix: "add a `modbus:` section (address, slave, steps_per_unit, target, speed, trigger, position, status, bits, home, stop); see the README".into(),
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

    /// Plausible ranges of every value, each with why it ends where it does: a value can be
    /// well-formed and still impossible (`fps: 1e12 Hz` divided a frame period down to zero,
    /// a 100000×65535 camera aborted on allocation, `time_scale: 1e-300` stalled a run).
    /// Non-finite values are outside every range.
    fn check_ranges(&self) -> Vec<ConfigIssue> {
        let mut issues = Vec::new();
        let mut within =
            |path: YamlPath, what: &str, v: f64, lo: f64, hi: f64, unit: &str, why: &str| {
                if !(lo..=hi).contains(&v) {
                    let u = if unit.is_empty() {
                        String::new()
                    } else {
                        format!(" {unit}")
                    };
                    issues.push(ConfigIssue {
                        path,
                        message: format!(
                            "{what} {}{u} is outside the plausible range [{lo}, {hi}]{u}: {why}",
                            crate::units::fmt_any(v)
                        ),
                        fix: format!("write a value between {lo} and {hi}{u}"),
                    });
                }
            };
        for (role, axis) in &self.axes {
            let at = YamlPath::root().key("axes").key(role.name());
            let u = axis.unit().symbol();
            let (travel_limit, speed_limit, res_limit) = match axis.unit() {
                AxisUnit::Mm => (10_000.0, 1_000.0, 10.0),
                AxisUnit::Deg => (36_000.0, 36_000.0, 90.0),
            };
            for (i, q) in axis.travel.iter().enumerate() {
                within(
                    at.key("travel").index(i),
                    "travel limit",
                    q.raw(),
                    -travel_limit,
                    travel_limit,
                    u,
                    "bench stages travel at most 10 m (or 100 turns)",
                );
            }
            within(
                at.key("max_speed"),
                "max_speed",
                axis.max_speed.value,
                1e-6,
                speed_limit,
                &format!("{u}/s"),
                "stages move between 1 nm/s and 1 m/s",
            );
            within(
                at.key("resolution"),
                "resolution",
                axis.resolution.raw(),
                1e-7,
                res_limit,
                u,
                "stage steps lie between 0.1 nm and 10 mm (or 90°)",
            );
            if let Some(r) = axis.poll_rate {
                within(
                    at.key("poll_rate"),
                    "poll_rate",
                    r.hz(),
                    0.1,
                    1000.0,
                    "Hz",
                    "controllers answer between 0.1 and 1000 polls a second",
                );
            }
            if let Some(w) = axis.in_position
                && (matches!(w, AxisQuantity::Percent(_)) || w.natural_unit() != axis.unit())
            {
                // Out of every range: a window in another unit is never right.
                within(
                    at.key("in_position"),
                    "in_position (not in the axis unit)",
                    f64::NAN,
                    0.0,
                    0.0,
                    u,
                    "write it in the axis unit",
                );
            } else if let Some(w) = axis.in_position {
                within(
                    at.key("in_position"),
                    "in_position",
                    w.raw(),
                    axis.resolution.raw() * (1.0 - 1e-9),
                    res_limit * 10.0,
                    u,
                    "an in-position window is at least the resolution and at most a few steps of the stage",
                );
            }
            if let Some(g) = axis.start_grace {
                within(
                    at.key("start_grace"),
                    "start_grace",
                    g.s(),
                    0.0,
                    60.0,
                    "s",
                    "drives show motion within a minute of a command",
                );
            }
            if let Some(n) = axis.move_retries {
                within(
                    at.key("move_retries"),
                    "move_retries",
                    f64::from(n),
                    0.0,
                    10.0,
                    "",
                    "a move that misses ten times will miss again",
                );
            }
            if let Some(m) = axis.microstep {
                within(
                    at.key("microstep"),
                    "microstep",
                    m,
                    1e-9,
                    1.0,
                    u,
                    "microsteps lie between 1 pm and 1 mm (or 1°)",
                );
            }
        }
        if let Some(f) = &self.force {
            let at = YamlPath::root().key("force");
            if let Some(r) = f.max_rate {
                within(
                    at.key("max_rate"),
                    "max_rate",
                    r.hz(),
                    1.0,
                    10_000.0,
                    "Hz",
                    "force sensors stream 1 Hz to 10 kHz (the Net F/T at most 7 kHz)",
                );
            }
            for (key, v) in [
                ("counts_per_force", f.counts_per_force),
                ("counts_per_torque", f.counts_per_torque),
            ] {
                if let Some(v) = v {
                    within(
                        at.key(key),
                        key,
                        v,
                        1e-6,
                        1e12,
                        "",
                        "calibration counts per unit are positive and finite",
                    );
                }
            }
        }
        if let Some(c) = &self.camera {
            let at = YamlPath::root().key("camera");
            within(
                at.key("width"),
                "width",
                f64::from(c.width),
                16.0,
                8192.0,
                "px",
                "cameras deliver 16 to 8192 pixels a side",
            );
            within(
                at.key("height"),
                "height",
                f64::from(c.height),
                16.0,
                8192.0,
                "px",
                "cameras deliver 16 to 8192 pixels a side",
            );
            within(
                at.key("fps"),
                "fps",
                c.fps.hz(),
                0.01,
                1000.0,
                "Hz",
                "cameras run at one frame a minute to 1000 frames a second",
            );
        }
        if let Some(sim) = &self.sim {
            let at = YamlPath::root().key("sim");
            if let Some(b) = sim.force_bias {
                within(
                    at.key("force_bias"),
                    "force_bias",
                    b.n(),
                    0.0,
                    10.0,
                    "N",
                    "a Nano17 reads at most a few newtons before a tare",
                );
            }
            for (key, v) in [
                ("normal_contact", Some(sim.normal_contact)),
                ("grip_contact", sim.grip_contact),
            ] {
                if let Some(v) = v {
                    within(
                        at.key(key),
                        key,
                        v.mm(),
                        -10_000.0,
                        10_000.0,
                        "mm",
                        "a contact position inside any stage's travel",
                    );
                }
            }
        }
        if let Some(t) = &self.twins {
            within(
                YamlPath::root().key("twins").key("time_scale"),
                "time_scale",
                t.time_scale,
                0.01,
                100_000.0,
                "",
                "slower than 1/100 a settle takes days; faster than 10⁵ the wall's millisecond is 100 s of run",
            );
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
