//! The protocol file: what a run does, in the lab's words and units.
//!
//! One schema covers every experiment of the thesis (stepped normal, shear and rotational
//! indentation with loading and unloading, chapters 4–6) and the repeated grasp trials of
//! §6.3, so new behaviour never needs new syntax. Every struct denies unknown keys (a typo
//! must not silently drop a safety limit) and every physical value carries its unit
//! ([`rig::units`]). `gelrig schema` prints the JSON Schema generated from these types.
//!
//! Coordinates: a position on an axis is relative to the axis *origin*, which is the stage
//! zero until an `approach` block sets it to the contact point. So after an approach on the
//! normal axis, `to: 20 %` means an indentation of 20 % of the elastomer thickness. Safety
//! travel limits and retract positions are absolute stage coordinates, valid before any
//! contact is found, as is an approach's `from`.

use std::collections::BTreeMap;

use rig::config::AxisRole;
use rig::units::{
    AxisQuantity, AxisSpeed, Duration, Force, Frequency, Length, Mass, Pressure, SettleRate, Torque,
};
use schemars::JsonSchema;

pub use super::material::{MaterialEntry, MaterialFrom, MaterialSpec, PronySpec};
use serde::{Deserialize, Serialize};

/// A protocol file.
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Protocol {
    /// Short name; names the run directory.
    pub name: String,
    /// What the experiment measures, and its source (thesis section, figure).
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub description: String,
    /// Default rig file, relative to this file's directory; `--rig` overrides it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rig: Option<String>,
    /// The GelSight sensor under test.
    pub sensor: Sensor,
    /// What presses on the elastomer.
    pub indenter: IndenterSpec,
    /// A grasped object (lifting trials).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub object: Option<ObjectSpec>,
    /// Limits that stop the run.
    pub safety: Safety,
    /// Streams recorded for the whole run.
    #[serde(default)]
    pub record: Streams,
    /// What the run does, in order. Blocks are written as one-key maps (`- home: {…}`),
    /// which serde_yaml 0.9 spells with YAML tags unless told otherwise.
    #[serde(with = "serde_yaml::with::singleton_map_recursive")]
    #[schemars(with = "Vec<Block>")]
    pub sequence: Vec<Block>,
}

/// The GelSight sensor; omitted parts take the thesis's values for its kind.
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Sensor {
    /// `box` (thesis §3.3: 125×70×4.2 mm, 18×16 dot grid) or `portable` (§6.2: 22.6×23.4×2.0
    /// mm, random triangles).
    pub kind: SensorKind,
    /// Pad dimensions.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub elastomer: Option<Elastomer>,
    /// Marker pattern.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub markers: Option<Markers>,
    /// The camera's field of view on the pad.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub view: Option<View>,
    /// Elastomer material, used by the simulated bench and the reference fields: its
    /// values, or `{from: MATERIAL.yaml}` (a file `gelrig fit-material` wrote, relative to
    /// the protocol), which loading replaces by the file's values.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub material: Option<MaterialEntry>,
}

/// Sensor design.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum SensorKind {
    /// The box-setting research sensor.
    Box,
    /// The portable (fingertip) sensor.
    Portable,
}

/// Pad dimensions.
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Elastomer {
    /// Along x.
    pub width: Length,
    /// Along y.
    pub length: Length,
    /// Layer thickness.
    pub thickness: Length,
}

/// Marker pattern printed on the pad.
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(tag = "layout", rename_all = "snake_case", deny_unknown_fields)]
pub enum Markers {
    /// A regular grid of round dots.
    Grid {
        /// Markers per row.
        columns: u32,
        /// Rows.
        rows: u32,
        /// Centre-to-centre spacing.
        spacing: Length,
        /// Dot diameter.
        diameter: Length,
    },
    /// Randomly placed triangles.
    Random {
        /// Mean spacing.
        spacing: Length,
        /// Triangle side.
        size: Length,
    },
}

/// Camera field of view on the pad.
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct View {
    /// Along x.
    pub width: Length,
    /// Along y.
    pub height: Length,
}

/// The indenter (thesis Fig. 3-11), or the grasped object's shape.
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(tag = "shape", rename_all = "snake_case", deny_unknown_fields)]
pub enum IndenterSpec {
    /// Flat-ended circle.
    FlatCircle {
        /// Diameter.
        diameter: Length,
    },
    /// Flat-ended ellipse, major axis along x.
    FlatEllipse {
        /// Full major axis.
        major: Length,
        /// Full minor axis.
        minor: Length,
    },
    /// Flat-ended rectangle.
    FlatRectangle {
        /// Side along x.
        width: Length,
        /// Side along y.
        length: Length,
    },
    /// Flat-ended equilateral triangle.
    FlatTriangle {
        /// Side.
        side: Length,
    },
    /// Sphere.
    Sphere {
        /// Diameter.
        diameter: Length,
    },
    /// Cylinder lying along x (a can in a grasp; its weight pulls along the axis).
    Cylinder {
        /// Diameter.
        diameter: Length,
        /// Length.
        length: Length,
    },
}

/// A grasped object.
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ObjectSpec {
    /// Total mass (thesis §6.3.2: a half-full can, 100 g).
    pub mass: Mass,
}

/// Limits that stop a run: motion stops, the pressing axis retracts, the run is `aborted`.
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Safety {
    /// Largest |Fz| allowed.
    pub max_fz: Force,
    /// Largest |(Fx, Fy)| allowed.
    pub max_fxy: Force,
    /// Largest |Tz| allowed.
    pub max_tz: Torque,
    /// Soft travel limits `[min, max]` per axis, in absolute stage coordinates.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub travel: BTreeMap<AxisRole, [AxisQuantity; 2]>,
    /// Where each axis goes on abort and at the end of the run, absolute.
    #[serde(default)]
    pub retract: BTreeMap<AxisRole, AxisQuantity>,
    /// How often force is checked against the limits (default 50 Hz).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub monitor_rate: Option<Frequency>,
}

/// Continuous streams and their rates. Unset streams are not recorded.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Streams {
    /// Force/torque samples to `force.csv`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub force: Option<Frequency>,
    /// Axis positions to `axes.csv`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub axes: Option<Frequency>,
    /// Camera frames to `frames/`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub frames: Option<Frequency>,
    /// A calibrated sensor file (`gelrig calibrate`), relative to this file: the wrench read
    /// from the markers of every frame the live path tracks (continuous frames in `record`
    /// blocks), beside the force sensor, in `tactile.csv`'s `gelsight_*` columns.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gelsight_force: Option<String>,
    /// The simulator's pressure and shear-traction maps and contact mask under every
    /// recorded frame, on cells of this many frame pixels a side (`4`: 160 × 120 maps of a
    /// 640 × 480 frame), to `sim_maps/` and `sim_frames.csv`: labels for a learning dataset
    /// (`gelrig export --format dataset`). Simulated cameras only.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub traction_maps: Option<u32>,
}

/// One block of the sequence.
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Block {
    /// Home axes (they refuse to move before).
    Home(Home),
    /// Move until a force threshold: finds contact, or closes a grasp to a squeeze force.
    Approach(Approach),
    /// Zero the force sensor on the mean of a short unloaded window.
    Tare(Tare),
    /// Step an axis from one value to another, settling and capturing at each step.
    Stepped(Stepped),
    /// Wait, recording.
    Hold(Hold),
    /// Move one axis.
    Move(Move),
    /// Capture frames and a force window where things stand.
    Capture(CaptureBlock),
    /// Apply an external disturbance to a grasped object.
    Disturb(Disturb),
    /// Record continuous streams while the inner blocks run.
    Record(Record),
    /// Run the inner blocks N times; each iteration is a trial.
    Repeat(Repeat),
}

/// `home`.
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Home {
    /// Axes to home, together.
    pub axes: Vec<AxisRole>,
}

/// `approach`.
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Approach {
    /// The axis that moves (normal to find contact, grip to squeeze).
    pub axis: AxisRole,
    /// Absolute stage position to start creeping from (reached at full speed). Absolute,
    /// because each approach sets a new origin: repeated trials start from the same place.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub from: Option<AxisQuantity>,
    /// Creep speed.
    pub speed: AxisSpeed,
    /// Stop when |force| along the axis reaches this.
    pub until: Force,
    /// Give up (run fails) after creeping this far.
    pub max_travel: AxisQuantity,
    /// Frames to capture before moving, as the no-contact tracking reference.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub reference_frames: u32,
}

fn is_zero(n: &u32) -> bool {
    *n == 0
}

/// `tare`.
#[derive(Debug, Clone, Default, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Tare {
    /// Averaging window (default 1 s).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub duration: Option<Duration>,
}

/// `stepped`: the thesis's quasistatic loading (Fig. 4-5a, 6-4a).
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Stepped {
    /// Axis stepped.
    pub axis: AxisRole,
    /// Start value (not itself a step).
    pub from: AxisQuantity,
    /// Final value (the last loading step).
    pub to: AxisQuantity,
    /// Step size: mm, µm, % of thickness, or deg.
    pub step: AxisQuantity,
    /// Load only, unload only, or load then unload back to `from`.
    #[serde(default)]
    pub direction: Direction,
    /// Speed of each step move.
    pub speed: AxisSpeed,
    /// Wait after each step.
    pub settle: Settle,
    /// What to record at the end of each step.
    pub capture: Capture,
    /// Label written to `steps.csv`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub label: Option<String>,
}

/// Which way a stepped block goes.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Direction {
    /// from → to.
    #[default]
    Load,
    /// to → from (starting where the axis is, at `to`).
    Unload,
    /// from → to → from.
    LoadUnload,
}

/// How long to wait after a step for the elastomer to relax (thesis §4.2: ~3 min).
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Settle {
    /// A fixed wait.
    Fixed(Duration),
    /// Until the signal's rate of change stays below a threshold over a window.
    Rate(RateSettle),
    /// Until the equilibrium value F∞, fitted to the relaxation as it goes, is known within
    /// a tolerance (with an honest uncertainty; docs/reference/protocol.md, "Choosing a settle rule").
    Adaptive(AdaptiveSettle),
}

/// Adaptive settling: stop once F∞ is known within `tolerance`.
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct AdaptiveSettle {
    /// Signal watched; default: the component along the stepped axis.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub signal: Option<Channel>,
    /// How well F∞ must be known: twice its standard uncertainty, as a percentage of |F∞|
    /// (e.g. `1 %`).
    pub tolerance: Tolerance,
    /// Never settle sooner than this.
    pub min: Duration,
    /// Give up waiting after this (the step keeps its F∞ and uncertainty, verdict `timeout`).
    pub max: Duration,
    /// What a timeout does.
    #[serde(default)]
    pub on_timeout: OnTimeout,
}

/// A relative tolerance written as a percentage (`1 %`); the value is the fraction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tolerance(f64);

impl Tolerance {
    /// The tolerance as a fraction (1 % → 0.01).
    pub fn fraction(self) -> f64 {
        self.0
    }
}

impl std::fmt::Display for Tolerance {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} %", rig::units::fmt_value(self.0 * 100.0))
    }
}

impl Serialize for Tolerance {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

impl<'de> Deserialize<'de> for Tolerance {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let text = String::deserialize(d)?;
        let number = text.trim().strip_suffix('%').map(str::trim);
        match number.and_then(|n| n.parse::<f64>().ok()) {
            Some(v) if v.is_finite() => Ok(Self(v / 100.0)),
            _ => Err(serde::de::Error::custom(format!(
                "`{text}` is not a percentage; fix: write it like `1 %`"
            ))),
        }
    }
}

impl JsonSchema for Tolerance {
    fn schema_name() -> std::borrow::Cow<'static, str> {
        "Tolerance".into()
    }
    fn json_schema(_: &mut schemars::SchemaGenerator) -> schemars::Schema {
        schemars::json_schema!({
            "type": "string",
            "title": "Tolerance",
            "description": "a relative tolerance as a percentage, e.g. `1 %`",
            "pattern": r"^\s*[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?\s*%\s*$",
            "examples": ["1 %"],
        })
    }
}

/// Rate-based settling.
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct RateSettle {
    /// Signal watched; default: the component along the stepped axis.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub signal: Option<Channel>,
    /// Settled when the drift |d signal/dt| is below this with ~95 % confidence: the
    /// least-squares slope over `window` plus twice its standard error.
    pub below: SettleRate,
    /// Slope window.
    pub window: Duration,
    /// Never settle sooner than this.
    pub min: Duration,
    /// Give up waiting after this.
    pub max: Duration,
    /// What a timeout does.
    #[serde(default)]
    pub on_timeout: OnTimeout,
}

/// A force/torque channel.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Channel {
    /// Fx, N.
    Fx,
    /// Fy, N.
    Fy,
    /// Fz, N.
    Fz,
    /// Tz, N·mm.
    Tz,
}

impl Channel {
    /// The channel that loads along `axis`.
    pub fn along(axis: AxisRole) -> Channel {
        match axis {
            AxisRole::Normal | AxisRole::Grip => Channel::Fz,
            AxisRole::Shear => Channel::Fx,
            AxisRole::Lift => Channel::Fy,
            AxisRole::Rotation => Channel::Tz,
        }
    }

    /// True for the torque channel.
    pub fn is_torque(self) -> bool {
        self == Channel::Tz
    }

    /// The channel's value in a wrench.
    pub fn of(self, w: &rig::Wrench) -> f64 {
        match self {
            Channel::Fx => w.fx_n,
            Channel::Fy => w.fy_n,
            Channel::Fz => w.fz_n,
            Channel::Tz => w.tz_nmm,
        }
    }

    /// `w` with this channel's component replaced by `v`.
    pub fn with(self, mut w: rig::Wrench, v: f64) -> rig::Wrench {
        match self {
            Channel::Fx => w.fx_n = v,
            Channel::Fy => w.fy_n = v,
            Channel::Fz => w.fz_n = v,
            Channel::Tz => w.tz_nmm = v,
        }
        w
    }

    /// As written in the lab: `Fz`, `Tz`.
    pub fn label(self) -> &'static str {
        match self {
            Channel::Fx => "Fx",
            Channel::Fy => "Fy",
            Channel::Fz => "Fz",
            Channel::Tz => "Tz",
        }
    }

    /// The unit of its rate of change.
    pub fn rate_unit(self) -> &'static str {
        if self == Channel::Tz {
            "N·mm/s"
        } else {
            "N/s"
        }
    }

    /// Lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            Channel::Fx => "fx",
            Channel::Fy => "fy",
            Channel::Fz => "fz",
            Channel::Tz => "tz",
        }
    }
}

/// What a settle timeout does.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum OnTimeout {
    /// Record the step as `timeout` and go on.
    #[default]
    Warn,
    /// Abort the run.
    Abort,
}

/// What to record at the end of a step.
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Capture {
    /// The quasistatic force is the mean over the last `force_window` of the settle
    /// (thesis §4.3: "the average value of a short period of the last part").
    pub force_window: Duration,
    /// Camera frames captured after settling.
    #[serde(default)]
    pub frames: u32,
}

/// `hold`.
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Hold {
    /// How long.
    pub duration: Duration,
    /// What to record at the end.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub capture: Option<Capture>,
    /// Label written to `steps.csv`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub label: Option<String>,
}

/// `move`.
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Move {
    /// Axis moved.
    pub axis: AxisRole,
    /// Target relative to the axis origin (one of `to`, `by`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub to: Option<AxisQuantity>,
    /// Distance from where the axis is (one of `to`, `by`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub by: Option<AxisQuantity>,
    /// Move speed.
    pub speed: AxisSpeed,
    /// Wait after the move.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub settle: Option<Settle>,
    /// What to record at the end.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub capture: Option<Capture>,
    /// Stop early on a tactile condition, e.g. `until: {slip: incipient}` (needs frames).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub until: Option<MoveUntil>,
    /// Label written to `steps.csv`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub label: Option<String>,
}

/// A move's early stop on what the GelSight feels.
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct MoveUntil {
    /// Stop when the grasp's slip state reaches this level.
    pub slip: SlipLevel,
}

/// A slip state a move can stop at (thesis §6.3: the markers feel slip coming).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum SlipLevel {
    /// Part of the contact slips: the grasp is about to lose the object.
    Incipient,
    /// The object slides through the grasp.
    Slip,
}

impl SlipLevel {
    /// The slip state this level is reached at.
    pub fn state(self) -> analysis::tactile::SlipState {
        match self {
            SlipLevel::Incipient => analysis::tactile::SlipState::Incipient,
            SlipLevel::Slip => analysis::tactile::SlipState::Slip,
        }
    }
}

/// `capture`.
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct CaptureBlock {
    /// Frames to capture.
    #[serde(default)]
    pub frames: u32,
    /// Force averaging window (waited before the frames).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub force_window: Option<Duration>,
    /// Label written to `steps.csv`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub label: Option<String>,
}

/// `disturb`: a sinusoidal push or twist on the grasped object (thesis §6.3.2, Fig. 6-24).
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Disturb {
    /// Amplitude of the vertical force.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub force: Option<Force>,
    /// Amplitude of the torque about the normal.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub torque: Option<Torque>,
    /// Frequency.
    pub frequency: Frequency,
    /// Duration.
    pub duration: Duration,
    /// Label written to `steps.csv`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub label: Option<String>,
}

/// `record`.
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Record {
    /// Force/torque rate.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub force: Option<Frequency>,
    /// Axis position rate.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub axes: Option<Frequency>,
    /// Frame rate.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub frames: Option<Frequency>,
    /// Blocks run while recording.
    pub blocks: Vec<Block>,
}

/// `repeat`.
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Repeat {
    /// Number of trials.
    pub times: u32,
    /// Blocks of one trial.
    pub blocks: Vec<Block>,
}

impl IndenterSpec {
    /// Flat punches (circle, ellipse, rectangle, triangle), whose face must fit the pad.
    pub fn is_flat(&self) -> bool {
        matches!(
            self,
            IndenterSpec::FlatCircle { .. }
                | IndenterSpec::FlatEllipse { .. }
                | IndenterSpec::FlatRectangle { .. }
                | IndenterSpec::FlatTriangle { .. }
        )
    }
}

impl Block {
    /// The block's keyword.
    pub fn keyword(&self) -> &'static str {
        match self {
            Block::Home(_) => "home",
            Block::Approach(_) => "approach",
            Block::Tare(_) => "tare",
            Block::Stepped(_) => "stepped",
            Block::Hold(_) => "hold",
            Block::Move(_) => "move",
            Block::Capture(_) => "capture",
            Block::Disturb(_) => "disturb",
            Block::Record(_) => "record",
            Block::Repeat(_) => "repeat",
        }
    }
}

/// Thesis values per sensor kind, filled in for anything the protocol leaves out.
pub mod defaults {
    use super::*;

    fn layer(kind: SensorKind) -> mechanics::Layer {
        match kind {
            SensorKind::Box => mechanics::geometry::presets::BOX_LAYER,
            SensorKind::Portable => mechanics::geometry::presets::PORTABLE_LAYER,
        }
    }

    /// Pad dimensions of the thesis's sensors ([`mechanics::geometry::presets`]).
    pub fn elastomer(kind: SensorKind) -> Elastomer {
        let l = layer(kind);
        Elastomer {
            width: Length::new(l.width_mm),
            length: Length::new(l.length_mm),
            thickness: Length::new(l.thickness_mm),
        }
    }

    /// Box: 18 × 16 dots of 1.4 mm at 2.52 mm (§3.3); portable: 0.7 mm triangles about
    /// 2 mm apart (§6.2).
    pub fn markers(kind: SensorKind) -> Markers {
        match kind {
            SensorKind::Box => Markers::Grid {
                columns: 18,
                rows: 16,
                spacing: Length::new(2.52),
                diameter: Length::new(1.4),
            },
            SensorKind::Portable => Markers::Random {
                spacing: Length::new(2.0),
                size: Length::new(0.7),
            },
        }
    }

    /// Box: the 18 × 16 marker field (45.36 × 40.32 mm); portable: 20 × 15 mm of the pad.
    pub fn view(kind: SensorKind) -> View {
        match kind {
            SensorKind::Box => View {
                width: Length::new(45.36),
                height: Length::new(40.32),
            },
            SensorKind::Portable => View {
                width: Length::new(20.0),
                height: Length::new(15.0),
            },
        }
    }

    /// Material of the thesis's sensors ([`mechanics::geometry::presets`], where the
    /// choice of values is explained).
    pub fn material(kind: SensorKind) -> MaterialSpec {
        let m = match kind {
            SensorKind::Box => mechanics::geometry::presets::box_material(),
            SensorKind::Portable => mechanics::geometry::presets::portable_material(),
        };
        MaterialSpec {
            youngs_modulus: Pressure::new(m.youngs_modulus_mpa),
            poisson_ratio: m.poisson_ratio,
            friction: m.friction,
            kinetic_friction: Some(mechanics::geometry::presets::KINETIC_RATIO * m.friction),
            prony: m
                .prony
                .iter()
                .map(|t| PronySpec {
                    weight: t.weight,
                    tau: Duration::new(t.tau_s),
                })
                .collect(),
        }
    }
}

impl Sensor {
    /// Fills every omitted part with its kind's default, so the run directory's
    /// `protocol.yaml` states exactly what was simulated or assumed.
    pub fn resolve_defaults(&mut self) {
        let kind = self.kind;
        self.elastomer
            .get_or_insert_with(|| defaults::elastomer(kind));
        self.markers.get_or_insert_with(|| defaults::markers(kind));
        self.view.get_or_insert_with(|| defaults::view(kind));
        self.material
            .get_or_insert_with(|| MaterialEntry::Inline(defaults::material(kind)));
    }

    /// Layer thickness in mm (after [`Sensor::resolve_defaults`]).
    pub fn thickness_mm(&self) -> f64 {
        self.elastomer
            .as_ref()
            .map(|e| e.thickness.mm())
            .unwrap_or_else(|| defaults::elastomer(self.kind).thickness.mm())
    }
}
