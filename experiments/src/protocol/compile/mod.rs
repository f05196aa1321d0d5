//! From a parsed protocol and a rig to a checked, flat list of actions.
//!
//! One pass over the sequence does both jobs, so the checks and the behaviour cannot drift
//! apart: it tracks what a run would know at each block (which axes are homed, where each
//! axis origin may be after an approach, which streams record) and emits [`Action`]s for the
//! planner and the runner, and [`Issue`]s, each at the YAML path of the value at fault.

use std::collections::{BTreeMap, BTreeSet};

use rig::config::{AxisRole, RigConfig, YamlPath};
use rig::units::{AxisQuantity, AxisSpeed, AxisUnit, fmt_value};
use serde::Serialize;

use crate::diag::Severity;
use crate::protocol::schema::{Block, Channel, OnTimeout, Protocol, SlipLevel, Streams};

mod blocks;
pub(crate) mod bounds;
mod checks;
mod count;
mod timing;

pub use count::Budget;

/// A problem found by the compiler.
#[derive(Debug, Clone, PartialEq)]
pub struct Issue {
    /// Error or warning.
    pub severity: Severity,
    /// Which file: the protocol or the rig.
    pub in_rig: bool,
    /// Where.
    pub path: YamlPath,
    /// What is wrong.
    pub message: String,
    /// How to fix it.
    pub fix: String,
}

/// What a protocol needs opened.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Needs {
    /// Axes moved or read.
    pub axes: BTreeSet<AxisRole>,
    /// The force sensor.
    pub force: bool,
    /// The camera.
    pub camera: bool,
    /// A disturbance source.
    pub disturber: bool,
}

/// One thing a run does.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Action {
    /// Where in the protocol it comes from, e.g. `sequence[3].stepped`.
    pub path: String,
    /// Trial number (1-based inside `repeat`, 0 outside).
    pub trial: u32,
    /// What to do.
    pub kind: ActionKind,
}

/// What an action does.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "action", rename_all = "snake_case")]
pub enum ActionKind {
    /// Home these axes together.
    Home {
        /// Axes.
        axes: Vec<AxisRole>,
    },
    /// Move until a force threshold; the contact becomes the axis origin.
    Approach(ApproachSpec),
    /// Zero the force sensor on the mean over `duration_s`.
    Tare {
        /// Averaging window, s.
        duration_s: f64,
    },
    /// A step: a row in `steps.csv`.
    Step(Step),
    /// Start recording these streams (nested scopes stack).
    StreamsBegin(StreamRates),
    /// End the innermost stream scope.
    StreamsEnd,
    /// A trial starts.
    TrialBegin,
    /// A trial ends.
    TrialEnd,
}

/// Move at `speed` until |force along the axis| ≥ `until_n`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ApproachSpec {
    /// Axis.
    pub axis: AxisRole,
    /// Absolute start position (rapid move), if given.
    pub from: Option<f64>,
    /// Creep speed, axis unit/s.
    pub speed: f64,
    /// Threshold, N.
    pub until_n: f64,
    /// Creep distance before giving up, axis unit.
    pub max_travel: f64,
    /// Reference frames before moving.
    pub reference_frames: u32,
}

/// Rates of continuous streams, Hz.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct StreamRates {
    /// Force/torque.
    pub force_hz: Option<f64>,
    /// Axis positions.
    pub axes_hz: Option<f64>,
    /// Frames.
    pub frames_hz: Option<f64>,
}

impl StreamRates {
    pub(super) fn from(s: &Streams) -> Self {
        Self {
            force_hz: s.force.map(|f| f.hz()),
            axes_hz: s.axes.map(|f| f.hz()),
            frames_hz: s.frames.map(|f| f.hz()),
        }
    }

    /// True if no stream is set.
    pub fn is_empty(&self) -> bool {
        self.force_hz.is_none() && self.axes_hz.is_none() && self.frames_hz.is_none()
    }

    /// `inner` on top of `self`: set rates override.
    pub fn overlay(&self, inner: &StreamRates) -> StreamRates {
        StreamRates {
            force_hz: inner.force_hz.or(self.force_hz),
            axes_hz: inner.axes_hz.or(self.axes_hz),
            frames_hz: inner.frames_hz.or(self.frames_hz),
        }
    }
}

/// The phase column of `steps.csv`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Phase {
    /// A loading step of a stepped block.
    Load,
    /// An unloading step of a stepped block.
    Unload,
    /// A `move` block.
    Move,
    /// A `hold` block.
    Hold,
    /// A `capture` block.
    Capture,
    /// A `disturb` block.
    Disturb,
}

impl Phase {
    /// Name as written to CSV.
    pub fn name(self) -> &'static str {
        match self {
            Phase::Load => "load",
            Phase::Unload => "unload",
            Phase::Move => "move",
            Phase::Hold => "hold",
            Phase::Capture => "capture",
            Phase::Disturb => "disturb",
        }
    }
}

/// Where a step moves its axis.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Target {
    /// To this value relative to the axis origin.
    To(f64),
    /// By this distance from where the axis is.
    By(f64),
}

/// How a step waits.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum SettleSpec {
    /// No wait.
    None,
    /// A fixed wait.
    Fixed {
        /// Seconds.
        s: f64,
    },
    /// Until |slope| of `channel` over `window_s` < `below`, within [min_s, max_s].
    Rate {
        /// Signal.
        channel: Channel,
        /// Threshold, N/s or N·mm/s.
        below: f64,
        /// Slope window, s.
        window_s: f64,
        /// Shortest settle, s.
        min_s: f64,
        /// Longest settle, s.
        max_s: f64,
        /// What a timeout does.
        on_timeout: OnTimeout,
    },
    /// Until F∞ of `channel` is known within `tolerance` (fraction), within [min_s, max_s].
    Adaptive {
        /// Signal.
        channel: Channel,
        /// Twice F∞'s standard uncertainty, as a fraction of |F∞|.
        tolerance: f64,
        /// Shortest settle, s.
        min_s: f64,
        /// Longest settle, s.
        max_s: f64,
        /// What a timeout does.
        on_timeout: OnTimeout,
    },
}

impl SettleSpec {
    /// Shortest and longest wait, s.
    pub fn bounds_s(&self) -> (f64, f64) {
        match *self {
            SettleSpec::None => (0.0, 0.0),
            SettleSpec::Fixed { s } => (s, s),
            SettleSpec::Rate { min_s, max_s, .. } | SettleSpec::Adaptive { min_s, max_s, .. } => {
                (min_s, max_s)
            }
        }
    }
}

/// A step.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Step {
    /// 1-based step number over the whole run.
    pub step: u32,
    /// Label from the protocol, or the block keyword.
    pub label: String,
    /// Phase.
    pub phase: Phase,
    /// Axis moved, if any.
    pub axis: Option<AxisRole>,
    /// Unit of `target` (mm or deg).
    pub unit: Option<AxisUnit>,
    /// Where it moves.
    pub target: Option<Target>,
    /// Move speed, axis unit/s.
    pub speed: f64,
    /// Wait after the move.
    pub settle: SettleSpec,
    /// Force averaging window at the end of the wait, s (0: the last sample).
    pub force_window_s: f64,
    /// Frames captured after the wait.
    pub frames: u32,
    /// Disturbance applied at the start of the wait.
    pub disturb: Option<DisturbSpec>,
    /// Stop the move as soon as the tactile slip state reaches this level.
    pub until_slip: Option<SlipLevel>,
}

/// A disturbance.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct DisturbSpec {
    /// Vertical force amplitude, N.
    pub force_y_n: f64,
    /// Torque amplitude, N·mm.
    pub torque_z_nmm: f64,
    /// Frequency, Hz.
    pub frequency_hz: f64,
    /// Duration, s.
    pub duration_s: f64,
}

/// The compiler's result.
#[derive(Debug, Clone, Default)]
pub struct Compiled {
    /// The run, in order.
    pub actions: Vec<Action>,
    /// Problems found.
    pub issues: Vec<Issue>,
    /// Devices needed.
    pub needs: Needs,
    /// Number of steps (rows of `steps.csv`).
    pub steps: u32,
}

impl Compiled {
    /// True if any issue is an error.
    pub fn has_errors(&self) -> bool {
        self.issues.iter().any(|i| i.severity == Severity::Error)
    }

    /// The deepest indentation (mm, relative to contact) any step of a pressing axis asks
    /// for after an approach, or `fallback` when an approach's own creep decides it
    /// (a grasp closing to a squeeze force).
    pub fn max_depth_mm(&self, fallback: f64) -> f64 {
        let mut deepest: f64 = 0.0;
        let mut creep_decides = false;
        for a in &self.actions {
            match &a.kind {
                ActionKind::Step(s) => {
                    if let (Some(axis), Some(Target::To(v))) = (s.axis, s.target)
                        && axis.presses()
                    {
                        deepest = deepest.max(v);
                    }
                    if let (Some(axis), Some(Target::By(_))) = (s.axis, s.target)
                        && axis.presses()
                    {
                        creep_decides = true;
                    }
                }
                ActionKind::Approach(ap) if ap.axis == AxisRole::Grip => creep_decides = true,
                _ => {}
            }
        }
        if creep_decides {
            deepest.max(fallback)
        } else {
            deepest
        }
    }
}

/// The rig's view of an axis, for checks.
#[derive(Debug, Clone, Copy)]
struct AxisLite {
    unit: AxisUnit,
    min: f64,
    max: f64,
    soft_min: f64,
    soft_max: f64,
    max_speed: f64,
    resolution: f64,
}

const EPS: f64 = 1e-9;

struct Compiler<'a> {
    p: &'a Protocol,
    rig: &'a RigConfig,
    thickness_mm: f64,
    out: Compiled,
    quiet: bool,
    reported_missing: BTreeSet<String>,
    homed: BTreeSet<AxisRole>,
    tared: bool,
    approached: BTreeSet<AxisRole>,
    /// Possible range of each axis origin, absolute.
    origin: BTreeMap<AxisRole, (f64, f64)>,
    /// Possible range of each axis position, absolute.
    pos: BTreeMap<AxisRole, (f64, f64)>,
    /// Position relative to the axis origin (the depth of a pressing axis after an
    /// approach): exact where `pos` and `origin` are uncertain together.
    rel: BTreeMap<AxisRole, (f64, f64)>,
    /// Trials started so far.
    trials: u32,
    /// Trial the current block belongs to (0 outside `repeat`).
    trial: u32,
    streams: Vec<StreamRates>,
    /// Steps one block may expand into (the budget's).
    max_steps: u64,
}

/// Checks `p` against `rig` and expands it into actions, within the default [`Budget`].
/// `p.sensor` must have its defaults resolved.
pub fn compile(p: &Protocol, rig: &RigConfig) -> Compiled {
    compile_with(p, rig, &Budget::default())
}

/// Checks `p` against `rig` and expands it into actions — unless the expansion, counted
/// first without expanding anything, exceeds `budget`: then the result holds that error
/// and no actions.
pub fn compile_with(p: &Protocol, rig: &RigConfig, budget: &Budget) -> Compiled {
    let mut c = Compiler {
        p,
        rig,
        thickness_mm: p.sensor.thickness_mm(),
        out: Compiled::default(),
        quiet: false,
        reported_missing: BTreeSet::new(),
        homed: BTreeSet::new(),
        tared: false,
        approached: BTreeSet::new(),
        origin: BTreeMap::new(),
        pos: BTreeMap::new(),
        rel: BTreeMap::new(),
        trials: 0,
        trial: 0,
        streams: Vec::new(),
        max_steps: budget.max_steps,
    };
    c.check_bounds();
    if !c.within_budget(budget) {
        return c.out;
    }
    c.check_physics();
    c.check_safety();
    let root = YamlPath::root();
    let record = StreamRates::from(&p.record);
    c.check_streams(&record, &root.key("record"));
    if !record.is_empty() {
        c.push(&root.key("record"), ActionKind::StreamsBegin(record));
        c.streams.push(record);
    }
    c.blocks(&p.sequence, &root.key("sequence"));
    if !record.is_empty() {
        c.push(&root.key("record"), ActionKind::StreamsEnd);
    }
    c.check_retract();
    c.out
}

impl Compiler<'_> {
    pub(super) fn issue(
        &mut self,
        severity: Severity,
        path: &YamlPath,
        message: String,
        fix: String,
    ) {
        if self.quiet {
            return;
        }
        let issue = Issue {
            severity,
            in_rig: false,
            path: path.clone(),
            message,
            fix,
        };
        if !self.out.issues.contains(&issue) {
            self.out.issues.push(issue);
        }
    }

    pub(super) fn error(
        &mut self,
        path: &YamlPath,
        message: impl Into<String>,
        fix: impl Into<String>,
    ) {
        self.issue(Severity::Error, path, message.into(), fix.into());
    }

    pub(super) fn warn(
        &mut self,
        path: &YamlPath,
        message: impl Into<String>,
        fix: impl Into<String>,
    ) {
        self.issue(Severity::Warning, path, message.into(), fix.into());
    }

    pub(super) fn push(&mut self, path: &YamlPath, kind: ActionKind) {
        self.out.actions.push(Action {
            path: path.to_string(),
            trial: self.trial,
            kind,
        });
    }

    pub(super) fn rig_name(&self) -> &str {
        &self.rig.name
    }

    /// The rig's axis for `role`, or an error at `path` naming the fix.
    pub(super) fn axis(&mut self, role: AxisRole, path: &YamlPath) -> Option<AxisLite> {
        self.out.needs.axes.insert(role);
        let Some(cfg) = self.rig.axes.get(&role) else {
            if self.reported_missing.insert(role.to_string()) {
                let have: Vec<&str> = self.rig.axes.keys().map(|r| r.name()).collect();
                self.error(
                    path,
                    format!(
                        "the sequence uses the `{role}` axis, but rig `{}` binds no `{role}` axis",
                        self.rig_name()
                    ),
                    format!(
                        "add `axes.{role}` to the rig file, or use an axis it has ({})",
                        if have.is_empty() {
                            "none".to_string()
                        } else {
                            have.join(", ")
                        }
                    ),
                );
            }
            return None;
        };
        let (min, max) = cfg.travel();
        let (mut soft_min, mut soft_max) = (min, max);
        if let Some([lo, hi]) = self.p.safety.travel.get(&role) {
            soft_min = soft_min.max(lo.raw());
            soft_max = soft_max.min(hi.raw());
        }
        Some(AxisLite {
            unit: cfg.unit(),
            min,
            max,
            soft_min,
            soft_max,
            max_speed: cfg.max_speed.value,
            resolution: cfg.resolution.raw(),
        })
    }

    pub(super) fn need_force(&mut self, path: &YamlPath, why: &str) {
        self.out.needs.force = true;
        if self.rig.force.is_none() && self.reported_missing.insert("force".into()) {
            self.error(
                path,
                format!(
                    "{why} needs a force sensor, but rig `{}` binds none",
                    self.rig_name()
                ),
                "add a `force:` section to the rig file",
            );
        }
    }

    pub(super) fn need_camera(&mut self, path: &YamlPath, why: &str) {
        self.out.needs.camera = true;
        if self.rig.camera.is_none() && self.reported_missing.insert("camera".into()) {
            self.error(
                path,
                format!(
                    "{why} needs a camera, but rig `{}` binds none",
                    self.rig_name()
                ),
                "add a `camera:` section to the rig file, or capture no frames",
            );
        }
    }

    /// A quantity in the axis unit, or an error naming the units that fit.
    pub(super) fn value(
        &mut self,
        q: AxisQuantity,
        role: AxisRole,
        axis: &AxisLite,
        path: &YamlPath,
    ) -> Option<f64> {
        match q.in_axis_unit(axis.unit, self.thickness_mm) {
            Some(v) => Some(v),
            None => {
                let fits = match axis.unit {
                    AxisUnit::Mm => "mm, µm or % of the elastomer thickness",
                    AxisUnit::Deg => "deg",
                };
                self.error(
                    path,
                    format!(
                        "`{q}` does not fit the {role} axis, which moves in {}",
                        axis.unit.symbol()
                    ),
                    format!("write it in {fits}"),
                );
                None
            }
        }
    }

    pub(super) fn speed(
        &mut self,
        s: AxisSpeed,
        role: AxisRole,
        axis: &AxisLite,
        path: &YamlPath,
    ) -> f64 {
        let u = axis.unit.symbol();
        if s.unit != axis.unit {
            self.error(
                path,
                format!("speed `{s}` does not fit the {role} axis, which moves in {u}"),
                format!("write it in {u}/s"),
            );
        } else if s.value <= 0.0 {
            self.error(
                path,
                format!("speed `{s}` must be positive"),
                format!("write e.g. `0.5 {u}/s`"),
            );
        } else if s.value > axis.max_speed * (1.0 + EPS) {
            self.error(
                path,
                format!(
                    "speed `{s}` is above the {role} axis's maximum {} {u}/s",
                    fmt_value(axis.max_speed)
                ),
                format!("lower it to at most {} {u}/s", fmt_value(axis.max_speed)),
            );
        }
        s.value.clamp(1e-9, axis.max_speed.max(1e-9))
    }

    pub(super) fn homed_before(&mut self, role: AxisRole, path: &YamlPath) {
        if !self.homed.contains(&role) {
            self.error(
                path,
                format!("the {role} axis moves here before any `home` block homes it"),
                format!("add `- home: {{axes: [{role}]}}` before this block"),
            );
            // Report once per axis.
            self.homed.insert(role);
        }
    }

    /// Checks that an absolute position range is inside the axis's hard and soft travel.
    pub(super) fn check_travel(
        &mut self,
        role: AxisRole,
        axis: &AxisLite,
        lo: f64,
        hi: f64,
        path: &YamlPath,
    ) {
        let u = axis.unit.symbol();
        let (min, max, what) = if axis.soft_min > axis.min + EPS || axis.soft_max < axis.max - EPS {
            (axis.soft_min, axis.soft_max, "safety travel limits")
        } else {
            (axis.min, axis.max, "travel")
        };
        if hi > max + EPS || lo < min - EPS {
            let (bad, limit) = if hi > max + EPS { (hi, max) } else { (lo, min) };
            self.error(
                path,
                format!(
                    "this target can put the {role} axis at {} {u}, beyond its {what} [{}, {}] {u}",
                    fmt_value(bad),
                    fmt_value(min),
                    fmt_value(max)
                ),
                format!(
                    "move the target by {} {u} or more so the axis stays within {}",
                    fmt_value((bad - limit).abs()),
                    fmt_value(limit)
                ),
            );
        }
    }

    /// Checks a target relative to the origin: travel, and depth below the thickness for
    /// pressing axes after an approach.
    pub(super) fn check_target(
        &mut self,
        role: AxisRole,
        axis: &AxisLite,
        rel: f64,
        path: &YamlPath,
    ) {
        let (olo, ohi) = self.origin.get(&role).copied().unwrap_or((0.0, 0.0));
        self.check_travel(role, axis, olo + rel, ohi + rel, path);
        if role.presses() && self.approached.contains(&role) && rel >= self.thickness_mm - EPS {
            let h = self.thickness_mm;
            self.error(
                path,
                format!(
                    "depth {} mm reaches the elastomer thickness {} mm: the indenter would press on the rigid base",
                    fmt_value(rel),
                    fmt_value(h)
                ),
                format!(
                    "keep the depth below {} mm (the thesis went to 20 % of thickness, {} mm, with flat punches)",
                    fmt_value(h),
                    fmt_value(0.2 * h)
                ),
            );
        }
    }

    pub(super) fn next_step(&mut self) -> u32 {
        self.out.steps += 1;
        self.out.steps
    }

    pub(super) fn blocks(&mut self, blocks: &[Block], path: &YamlPath) {
        for (i, b) in blocks.iter().enumerate() {
            let at = path.index(i).key(b.keyword());
            self.block(b, &at);
        }
    }
}
