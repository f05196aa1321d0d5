//! From a parsed protocol and a rig to a checked, flat list of actions.
//!
//! One pass over the sequence does both jobs, so the checks and the behaviour cannot drift
//! apart: it tracks what a run would know at each block (which axes are homed, where each
//! axis origin may be after an approach, which streams record) and emits [`Action`]s for the
//! planner and the runner, and [`Issue`]s, each at the YAML path of the value at fault.

use std::collections::{BTreeMap, BTreeSet};

use rig::config::{AxisRole, RigConfig, YamlPath};
use rig::units::{AxisQuantity, AxisSpeed, AxisUnit, SettleRate, fmt_value};
use serde::Serialize;

use super::schema::{
    Block, Capture, Channel, Direction, IndenterSpec, Markers, OnTimeout, Protocol, Settle, Streams,
};
use crate::diag::Severity;

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
    fn from(s: &Streams) -> Self {
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
}

impl SettleSpec {
    /// Shortest and longest wait, s.
    pub fn bounds_s(&self) -> (f64, f64) {
        match *self {
            SettleSpec::None => (0.0, 0.0),
            SettleSpec::Fixed { s } => (s, s),
            SettleSpec::Rate { min_s, max_s, .. } => (min_s, max_s),
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
    /// Trials started so far.
    trials: u32,
    /// Trial the current block belongs to (0 outside `repeat`).
    trial: u32,
    streams: Vec<StreamRates>,
}

/// Checks `p` against `rig` and expands it into actions. `p.sensor` must have its defaults
/// resolved.
pub fn compile(p: &Protocol, rig: &RigConfig) -> Compiled {
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
        trials: 0,
        trial: 0,
        streams: Vec::new(),
    };
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
    fn issue(&mut self, severity: Severity, path: &YamlPath, message: String, fix: String) {
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

    fn error(&mut self, path: &YamlPath, message: impl Into<String>, fix: impl Into<String>) {
        self.issue(Severity::Error, path, message.into(), fix.into());
    }

    fn warn(&mut self, path: &YamlPath, message: impl Into<String>, fix: impl Into<String>) {
        self.issue(Severity::Warning, path, message.into(), fix.into());
    }

    fn push(&mut self, path: &YamlPath, kind: ActionKind) {
        self.out.actions.push(Action {
            path: path.to_string(),
            trial: self.trial,
            kind,
        });
    }

    fn rig_name(&self) -> &str {
        &self.rig.name
    }

    /// The rig's axis for `role`, or an error at `path` naming the fix.
    fn axis(&mut self, role: AxisRole, path: &YamlPath) -> Option<AxisLite> {
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

    fn need_force(&mut self, path: &YamlPath, why: &str) {
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

    fn need_camera(&mut self, path: &YamlPath, why: &str) {
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
    fn value(
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

    fn speed(&mut self, s: AxisSpeed, role: AxisRole, axis: &AxisLite, path: &YamlPath) -> f64 {
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

    fn homed_before(&mut self, role: AxisRole, path: &YamlPath) {
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
    fn check_travel(&mut self, role: AxisRole, axis: &AxisLite, lo: f64, hi: f64, path: &YamlPath) {
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
    fn check_target(&mut self, role: AxisRole, axis: &AxisLite, rel: f64, path: &YamlPath) {
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

    fn settle(
        &mut self,
        s: &Settle,
        axis: Option<AxisRole>,
        window_s: f64,
        path: &YamlPath,
    ) -> SettleSpec {
        match s {
            Settle::Fixed(d) => {
                if d.s() < 0.0 {
                    self.error(
                        &path.key("fixed"),
                        "a settle time cannot be negative",
                        "write e.g. `180 s`",
                    );
                }
                if window_s > d.s() + EPS {
                    self.error(
                        &path.key("fixed"),
                        format!(
                            "the settle ({}) is shorter than the capture's force window ({} s)",
                            d,
                            fmt_value(window_s)
                        ),
                        "lengthen the settle or shorten `capture.force_window`",
                    );
                }
                SettleSpec::Fixed { s: d.s().max(0.0) }
            }
            Settle::Rate(r) => {
                let at = path.key("rate");
                let channel = r
                    .signal
                    .unwrap_or_else(|| axis.map(Channel::along).unwrap_or(Channel::Fz));
                let unit_ok = matches!(
                    (channel.is_torque(), r.below),
                    (true, SettleRate::Torque(_)) | (false, SettleRate::Force(_))
                );
                if !unit_ok {
                    let want = if channel.is_torque() {
                        "N·mm/s"
                    } else {
                        "N/s"
                    };
                    self.error(
                        &at.key("below"),
                        format!("`{}` does not fit the {} signal", r.below, channel.name()),
                        format!("write the threshold in {want}"),
                    );
                }
                if r.below.value() <= 0.0 {
                    self.error(
                        &at.key("below"),
                        "the threshold must be positive",
                        "write e.g. `0.002 N/s`",
                    );
                }
                if r.window.s() <= 0.0 {
                    self.error(
                        &at.key("window"),
                        "the slope window must be positive",
                        "write e.g. `20 s`",
                    );
                }
                if r.max.s() < r.min.s() {
                    self.error(
                        &at.key("max"),
                        format!("max ({}) is below min ({})", r.max, r.min),
                        "make max at least min",
                    );
                }
                if r.max.s() < r.window.s() {
                    self.error(
                        &at.key("window"),
                        format!(
                            "the window ({}) is longer than max ({}): it can never fill",
                            r.window, r.max
                        ),
                        "shorten the window or raise max",
                    );
                }
                if window_s > r.min.s() + EPS {
                    self.error(
                        &at.key("min"),
                        format!(
                            "min ({}) is shorter than the capture's force window ({} s)",
                            r.min,
                            fmt_value(window_s)
                        ),
                        "raise min to at least the force window",
                    );
                }
                SettleSpec::Rate {
                    channel,
                    below: r.below.value(),
                    window_s: r.window.s(),
                    min_s: r.min.s(),
                    max_s: r.max.s(),
                    on_timeout: r.on_timeout,
                }
            }
        }
    }

    fn capture(&mut self, c: &Capture, path: &YamlPath) -> (f64, u32) {
        if c.force_window.s() < 0.0 {
            self.error(
                &path.key("force_window"),
                "the force window cannot be negative",
                "write e.g. `10 s`",
            );
        }
        if c.force_window.s() > 0.0 {
            self.need_force(path, "a force window");
        }
        if c.frames > 0 {
            self.need_camera(&path.key("frames"), "capturing frames");
        }
        (c.force_window.s().max(0.0), c.frames)
    }

    fn next_step(&mut self) -> u32 {
        self.out.steps += 1;
        self.out.steps
    }

    fn blocks(&mut self, blocks: &[Block], path: &YamlPath) {
        for (i, b) in blocks.iter().enumerate() {
            let at = path.index(i).key(b.keyword());
            self.block(b, &at);
        }
    }

    fn block(&mut self, b: &Block, at: &YamlPath) {
        match b {
            Block::Home(h) => {
                if h.axes.is_empty() {
                    self.error(
                        &at.key("axes"),
                        "no axes to home",
                        "list them, e.g. `axes: [normal, shear]`",
                    );
                }
                for (k, role) in h.axes.iter().enumerate() {
                    if let Some(axis) = self.axis(*role, &at.key("axes").index(k)) {
                        let home = 0.0_f64.clamp(axis.min, axis.max);
                        self.pos.insert(*role, (home, home));
                        self.origin.insert(*role, (0.0, 0.0));
                        self.approached.remove(role);
                    }
                    self.homed.insert(*role);
                    if role.presses() {
                        self.need_force(at, "homing a pressing axis (the safety monitor)");
                    }
                }
                self.push(
                    at,
                    ActionKind::Home {
                        axes: h.axes.clone(),
                    },
                );
            }
            Block::Approach(a) => {
                self.need_force(at, "an approach");
                let Some(axis) = self.axis(a.axis, &at.key("axis")) else {
                    return;
                };
                self.homed_before(a.axis, &at.key("axis"));
                if !self.tared {
                    self.warn(
                        at,
                        "this approach compares force with its threshold before any `tare`: a sensor offset can stop it early or late",
                        "add `- tare: {}` before the approach, with nothing touching the sensor",
                    );
                }
                let from = a
                    .from
                    .and_then(|q| self.value(q, a.axis, &axis, &at.key("from")));
                let max_travel = self
                    .value(a.max_travel, a.axis, &axis, &at.key("max_travel"))
                    .unwrap_or(0.0);
                if max_travel <= 0.0 {
                    self.error(
                        &at.key("max_travel"),
                        "max_travel must be positive",
                        "write e.g. `3 mm`",
                    );
                }
                let speed = self.speed(a.speed, a.axis, &axis, &at.key("speed"));
                let limit = self.p.safety.max_fz.n();
                if a.until.n() <= 0.0 || a.until.n() >= limit {
                    self.error(
                        &at.key("until"),
                        format!(
                            "the contact threshold {} must be between 0 and max_fz ({})",
                            a.until, self.p.safety.max_fz
                        ),
                        "write a small force, e.g. `0.05 N`",
                    );
                }
                if a.reference_frames > 0 {
                    self.need_camera(&at.key("reference_frames"), "reference frames");
                }
                let (olo, ohi) = self.origin.get(&a.axis).copied().unwrap_or((0.0, 0.0));
                let (plo, phi) = self.pos.get(&a.axis).copied().unwrap_or((olo, ohi));
                let _ = (olo, ohi);
                let (slo, shi) = match from {
                    Some(f) => (f, f),
                    None => (plo, phi),
                };
                self.check_travel(a.axis, &axis, slo, shi + max_travel, &at.key("max_travel"));
                self.origin.insert(a.axis, (slo, shi + max_travel));
                self.pos.insert(a.axis, (slo, shi + max_travel));
                self.approached.insert(a.axis);
                self.push(
                    at,
                    ActionKind::Approach(ApproachSpec {
                        axis: a.axis,
                        from,
                        speed,
                        until_n: a.until.n(),
                        max_travel,
                        reference_frames: a.reference_frames,
                    }),
                );
            }
            Block::Tare(t) => {
                self.need_force(at, "a tare");
                let d = t.duration.map(|d| d.s()).unwrap_or(1.0);
                if d <= 0.0 {
                    self.error(
                        &at.key("duration"),
                        "the tare window must be positive",
                        "write e.g. `1 s`",
                    );
                }
                self.tared = true;
                self.push(
                    at,
                    ActionKind::Tare {
                        duration_s: d.max(0.0),
                    },
                );
            }
            Block::Stepped(s) => self.stepped(s, at),
            Block::Hold(h) => {
                if h.duration.s() <= 0.0 {
                    self.error(
                        &at.key("duration"),
                        "a hold needs a positive duration",
                        "write e.g. `5 s`",
                    );
                }
                let (window, frames) = match &h.capture {
                    Some(c) => self.capture(c, &at.key("capture")),
                    None => (h.duration.s().max(0.0), 0),
                };
                if window > h.duration.s() + EPS {
                    self.error(
                        &at.key("capture").key("force_window"),
                        "the force window is longer than the hold",
                        "shorten the window or lengthen the hold",
                    );
                }
                let step = self.next_step();
                self.push(
                    at,
                    ActionKind::Step(Step {
                        step,
                        label: h.label.clone().unwrap_or_else(|| "hold".into()),
                        phase: Phase::Hold,
                        axis: None,
                        unit: None,
                        target: None,
                        speed: 0.0,
                        settle: SettleSpec::Fixed {
                            s: h.duration.s().max(0.0),
                        },
                        force_window_s: window.min(h.duration.s().max(0.0)),
                        frames,
                        disturb: None,
                    }),
                );
            }
            Block::Move(m) => self.move_block(m, at),
            Block::Capture(c) => {
                let window = c.force_window.map(|d| d.s()).unwrap_or(0.0);
                if window < 0.0 {
                    self.error(
                        &at.key("force_window"),
                        "the force window cannot be negative",
                        "write e.g. `1 s`",
                    );
                }
                if window > 0.0 {
                    self.need_force(at, "a force window");
                }
                if c.frames > 0 {
                    self.need_camera(&at.key("frames"), "capturing frames");
                }
                if c.frames == 0 && window <= 0.0 {
                    self.warn(
                        at,
                        "this capture records nothing",
                        "give it `frames:` or `force_window:`",
                    );
                }
                let step = self.next_step();
                self.push(
                    at,
                    ActionKind::Step(Step {
                        step,
                        label: c.label.clone().unwrap_or_else(|| "capture".into()),
                        phase: Phase::Capture,
                        axis: None,
                        unit: None,
                        target: None,
                        speed: 0.0,
                        settle: SettleSpec::Fixed { s: window.max(0.0) },
                        force_window_s: window.max(0.0),
                        frames: c.frames,
                        disturb: None,
                    }),
                );
            }
            Block::Disturb(d) => {
                self.out.needs.disturber = true;
                if self.rig.disturber.is_none() && self.reported_missing.insert("disturber".into())
                {
                    self.error(
                        at,
                        format!(
                            "a disturb block needs a disturber, but rig `{}` binds none",
                            self.rig_name()
                        ),
                        "add `disturber: {driver: sim}` to the rig file",
                    );
                }
                self.need_force(at, "a disturb block");
                if d.force.is_none() && d.torque.is_none() {
                    self.error(
                        at,
                        "a disturbance needs `force:` or `torque:`",
                        "add e.g. `torque: 20 N·mm`",
                    );
                }
                if d.frequency.hz() <= 0.0 {
                    self.error(
                        &at.key("frequency"),
                        "the frequency must be positive",
                        "write e.g. `2 Hz`",
                    );
                }
                if d.duration.s() <= 0.0 {
                    self.error(
                        &at.key("duration"),
                        "the duration must be positive",
                        "write e.g. `2 s`",
                    );
                }
                let step = self.next_step();
                self.push(
                    at,
                    ActionKind::Step(Step {
                        step,
                        label: d.label.clone().unwrap_or_else(|| "disturb".into()),
                        phase: Phase::Disturb,
                        axis: None,
                        unit: None,
                        target: None,
                        speed: 0.0,
                        settle: SettleSpec::Fixed {
                            s: d.duration.s().max(0.0),
                        },
                        force_window_s: d.duration.s().max(0.0),
                        frames: 0,
                        disturb: Some(DisturbSpec {
                            force_y_n: d.force.map(|f| f.n()).unwrap_or(0.0),
                            torque_z_nmm: d.torque.map(|t| t.nmm()).unwrap_or(0.0),
                            frequency_hz: d.frequency.hz(),
                            duration_s: d.duration.s().max(0.0),
                        }),
                    }),
                );
            }
            Block::Record(r) => {
                let rates = StreamRates {
                    force_hz: r.force.map(|f| f.hz()),
                    axes_hz: r.axes.map(|f| f.hz()),
                    frames_hz: r.frames.map(|f| f.hz()),
                };
                if rates.is_empty() {
                    self.warn(
                        at,
                        "this record block names no stream",
                        "add `force:`, `axes:` or `frames:` rates",
                    );
                }
                self.check_streams(&rates, at);
                self.push(at, ActionKind::StreamsBegin(rates));
                self.streams.push(rates);
                self.blocks(&r.blocks, &at.key("blocks"));
                self.streams.pop();
                self.push(at, ActionKind::StreamsEnd);
            }
            Block::Repeat(r) => {
                if r.times == 0 {
                    self.error(
                        &at.key("times"),
                        "`times: 0` runs nothing",
                        "write at least `times: 1`",
                    );
                }
                let (was_quiet, outer_trial) = (self.quiet, self.trial);
                for t in 0..r.times {
                    self.trials += 1;
                    self.trial = self.trials;
                    self.push(at, ActionKind::TrialBegin);
                    self.blocks(&r.blocks, &at.key("blocks"));
                    self.push(at, ActionKind::TrialEnd);
                    if t == 0 {
                        self.quiet = true;
                    }
                }
                self.quiet = was_quiet;
                self.trial = outer_trial;
            }
        }
    }

    fn stepped(&mut self, s: &super::schema::Stepped, at: &YamlPath) {
        let Some(axis) = self.axis(s.axis, &at.key("axis")) else {
            return;
        };
        self.homed_before(s.axis, &at.key("axis"));
        let from = self.value(s.from, s.axis, &axis, &at.key("from"));
        let to = self.value(s.to, s.axis, &axis, &at.key("to"));
        let step = self.value(s.step, s.axis, &axis, &at.key("step"));
        let speed = self.speed(s.speed, s.axis, &axis, &at.key("speed"));
        let (window, frames) = self.capture(&s.capture, &at.key("capture"));
        let settle = self.settle(&s.settle, Some(s.axis), window, &at.key("settle"));
        if matches!(settle, SettleSpec::Rate { .. }) {
            self.need_force(at, "rate settling");
        }
        let (Some(from), Some(to), Some(step)) = (from, to, step) else {
            return;
        };
        let u = axis.unit.symbol();
        if step <= 0.0 {
            self.error(
                &at.key("step"),
                "the step must be positive",
                format!("write e.g. `0.1 {u}`"),
            );
            return;
        }
        if step < axis.resolution - EPS {
            self.error(
                &at.key("step"),
                format!(
                    "step `{}` ({} {u}) is below the {} stage's resolution {} {u}",
                    s.step,
                    fmt_value(step),
                    s.axis,
                    fmt_value(axis.resolution)
                ),
                format!("use a step of at least {} {u}", fmt_value(axis.resolution)),
            );
            return;
        }
        let span = to - from;
        let n = (span.abs() / step).round();
        if n < 1.0 {
            self.error(
                &at.key("to"),
                "`to` equals `from`: there is nothing to step",
                "set `to` at least one step away",
            );
            return;
        }
        if (n * step - span.abs()).abs() > 1e-6 * step.max(1.0) {
            self.error(
                &at.key("step"),
                format!(
                    "the span from `{}` to `{}` ({} {u}) is not a whole number of steps of {} {u}",
                    s.from,
                    s.to,
                    fmt_value(span.abs()),
                    fmt_value(step)
                ),
                format!(
                    "choose `to` = {} {u} or {} {u}, or a step that divides the span",
                    fmt_value(from + span.signum() * n.floor() * step),
                    fmt_value(from + span.signum() * n.ceil() * step)
                ),
            );
            return;
        }
        let ratio = step / axis.resolution;
        if (ratio - ratio.round()).abs() > 1e-6 {
            self.warn(
                &at.key("step"),
                format!(
                    "step {} {u} is not a multiple of the stage resolution {} {u}: targets will be rounded",
                    fmt_value(step),
                    fmt_value(axis.resolution)
                ),
                "use a multiple of the resolution",
            );
        }
        self.check_target(s.axis, &axis, from, &at.key("from"));
        self.check_target(s.axis, &axis, to, &at.key("to"));
        let n = n as u32;
        let dir = span.signum();
        let mut targets: Vec<(Phase, f64)> = Vec::new();
        if matches!(s.direction, Direction::Load | Direction::LoadUnload) {
            targets.extend((1..=n).map(|k| (Phase::Load, from + dir * step * k as f64)));
        }
        if matches!(s.direction, Direction::Unload | Direction::LoadUnload) {
            // Counted from `from`, so the last unloading step lands exactly on it.
            targets.extend((1..=n).map(|k| (Phase::Unload, from + dir * step * (n - k) as f64)));
        }
        let label = s.label.clone().unwrap_or_else(|| "stepped".into());
        for (phase, target) in targets {
            let step_no = self.next_step();
            self.push(
                at,
                ActionKind::Step(Step {
                    step: step_no,
                    label: label.clone(),
                    phase,
                    axis: Some(s.axis),
                    unit: Some(axis.unit),
                    target: Some(Target::To(target)),
                    speed,
                    settle,
                    force_window_s: window,
                    frames,
                    disturb: None,
                }),
            );
        }
        let (olo, ohi) = self.origin.get(&s.axis).copied().unwrap_or((0.0, 0.0));
        let last = if s.direction == Direction::Load {
            to
        } else {
            from
        };
        self.pos.insert(s.axis, (olo + last, ohi + last));
    }

    fn move_block(&mut self, m: &super::schema::Move, at: &YamlPath) {
        let Some(axis) = self.axis(m.axis, &at.key("axis")) else {
            return;
        };
        self.homed_before(m.axis, &at.key("axis"));
        if m.axis.presses() {
            self.need_force(at, "moving a pressing axis (the safety monitor)");
        }
        let speed = self.speed(m.speed, m.axis, &axis, &at.key("speed"));
        let (window, frames) = match &m.capture {
            Some(c) => self.capture(c, &at.key("capture")),
            None => (0.0, 0),
        };
        let settle = match &m.settle {
            Some(s) => self.settle(s, Some(m.axis), window, &at.key("settle")),
            None => {
                if window > 0.0 {
                    self.error(
                        &at.key("capture").key("force_window"),
                        "a force window needs a settle to average over",
                        "add `settle: {fixed: …}` at least as long as the window",
                    );
                }
                SettleSpec::None
            }
        };
        let (olo, ohi) = self.origin.get(&m.axis).copied().unwrap_or((0.0, 0.0));
        let (plo, phi) = self.pos.get(&m.axis).copied().unwrap_or((olo, ohi));
        let target = match (m.to, m.by) {
            (Some(_), Some(_)) | (None, None) => {
                self.error(
                    at,
                    "a move needs exactly one of `to` and `by`",
                    "keep one of them",
                );
                return;
            }
            (Some(q), None) => {
                let Some(v) = self.value(q, m.axis, &axis, &at.key("to")) else {
                    return;
                };
                self.check_target(m.axis, &axis, v, &at.key("to"));
                self.pos.insert(m.axis, (olo + v, ohi + v));
                Target::To(v)
            }
            (None, Some(q)) => {
                let Some(v) = self.value(q, m.axis, &axis, &at.key("by")) else {
                    return;
                };
                self.check_travel(m.axis, &axis, plo + v, phi + v, &at.key("by"));
                if m.axis.presses()
                    && self.approached.contains(&m.axis)
                    && phi + v - olo >= self.thickness_mm - EPS
                {
                    self.error(
                        &at.key("by"),
                        format!(
                            "this move can take the depth to {} mm, reaching the elastomer thickness {} mm",
                            fmt_value(phi + v - olo),
                            fmt_value(self.thickness_mm)
                        ),
                        "move by less",
                    );
                }
                self.pos.insert(m.axis, (plo + v, phi + v));
                Target::By(v)
            }
        };
        let step = self.next_step();
        self.push(
            at,
            ActionKind::Step(Step {
                step,
                label: m.label.clone().unwrap_or_else(|| "move".into()),
                phase: Phase::Move,
                axis: Some(m.axis),
                unit: Some(axis.unit),
                target: Some(target),
                speed,
                settle,
                force_window_s: window,
                frames,
                disturb: None,
            }),
        );
    }

    fn check_streams(&mut self, r: &StreamRates, at: &YamlPath) {
        if let Some(hz) = r.force_hz {
            self.need_force(&at.key("force"), "a force stream");
            let max = self
                .rig
                .force
                .as_ref()
                .map(|f| f.max_rate.map(|r| r.hz()).unwrap_or(1000.0))
                .unwrap_or(f64::INFINITY);
            if hz <= 0.0 || hz > max {
                self.error(
                    &at.key("force"),
                    format!(
                        "force rate {} Hz is outside (0, {}] Hz, what the sensor delivers",
                        fmt_value(hz),
                        fmt_value(max)
                    ),
                    format!("write a rate up to {} Hz", fmt_value(max)),
                );
            }
        }
        if let Some(hz) = r.frames_hz {
            self.need_camera(&at.key("frames"), "a frame stream");
            let fps = self
                .rig
                .camera
                .as_ref()
                .map(|c| c.fps.hz())
                .unwrap_or(f64::INFINITY);
            if hz <= 0.0 || hz > fps + EPS {
                self.error(
                    &at.key("frames"),
                    format!(
                        "frame rate {} Hz is outside (0, {}] Hz, the camera's frame rate",
                        fmt_value(hz),
                        fmt_value(fps)
                    ),
                    format!("write a rate up to {} Hz", fmt_value(fps)),
                );
            }
        }
        if let Some(hz) = r.axes_hz
            && (hz <= 0.0 || hz > 1000.0)
        {
            self.error(
                &at.key("axes"),
                "the axes rate must be in (0, 1000] Hz",
                "write e.g. `10 Hz`",
            );
        }
    }

    fn check_physics(&mut self) {
        let s = &self.p.sensor;
        let at = YamlPath::root().key("sensor");
        if let Some(e) = &s.elastomer {
            for (k, v) in [
                ("width", e.width.mm()),
                ("length", e.length.mm()),
                ("thickness", e.thickness.mm()),
            ] {
                if v <= 0.0 {
                    self.error(
                        &at.key("elastomer").key(k),
                        format!("elastomer {k} must be positive"),
                        "write e.g. `4.2 mm`",
                    );
                }
            }
        }
        if let Some(Markers::Grid {
            columns,
            rows,
            spacing,
            diameter,
        }) = &s.markers
        {
            if *columns == 0 || *rows == 0 {
                self.error(
                    &at.key("markers"),
                    "a marker grid needs at least one row and column",
                    "write e.g. `columns: 18, rows: 16`",
                );
            }
            if diameter.mm() <= 0.0 || diameter.mm() >= spacing.mm() {
                self.error(
                    &at.key("markers").key("diameter"),
                    "markers must be smaller than their spacing",
                    "write a diameter below the spacing, e.g. 1.4 mm at 2.52 mm",
                );
            }
        }
        if let Some(Markers::Random { spacing, size }) = &s.markers
            && (size.mm() <= 0.0 || size.mm() >= spacing.mm())
        {
            self.error(
                &at.key("markers").key("size"),
                "markers must be smaller than their spacing",
                "write a size below the spacing, e.g. 0.7 mm at 2 mm",
            );
        }
        if let Some(v) = &s.view
            && (v.width.mm() <= 0.0 || v.height.mm() <= 0.0)
        {
            self.error(
                &at.key("view"),
                "the view must have a positive size",
                "write e.g. `{width: 45 mm, height: 40 mm}`",
            );
        }
        if let Some(m) = &s.material {
            let mat = at.key("material");
            if m.youngs_modulus.mpa() <= 0.0 {
                self.error(
                    &mat.key("youngs_modulus"),
                    "the modulus must be positive",
                    "write e.g. `0.25 MPa`",
                );
            }
            if !(0.0..=0.5).contains(&m.poisson_ratio) {
                self.error(
                    &mat.key("poisson_ratio"),
                    format!("Poisson ratio {} is outside [0, 0.5]", m.poisson_ratio),
                    "silicone elastomers are nearly incompressible: write 0.49 or 0.5",
                );
            }
            if m.friction < 0.0 {
                self.error(
                    &mat.key("friction"),
                    "friction cannot be negative",
                    "write e.g. `0.6`",
                );
            }
            for (i, t) in m.prony.iter().enumerate() {
                if t.weight < 0.0 {
                    self.error(
                        &mat.key("prony").index(i).key("weight"),
                        "a Prony weight cannot be negative",
                        "write a weight ≥ 0",
                    );
                }
                if t.tau.s() <= 0.0 {
                    self.error(
                        &mat.key("prony").index(i).key("tau"),
                        "a relaxation time must be positive",
                        "write e.g. `20 s`",
                    );
                }
            }
        }
        let dims: Vec<(&str, f64)> = match &self.p.indenter {
            IndenterSpec::FlatCircle { diameter } | IndenterSpec::Sphere { diameter } => {
                vec![("diameter", diameter.mm())]
            }
            IndenterSpec::FlatEllipse { major, minor } => {
                if minor.mm() > major.mm() {
                    self.error(
                        &YamlPath::root().key("indenter").key("minor"),
                        "the minor axis is longer than the major axis",
                        "swap `major` and `minor`",
                    );
                }
                vec![("major", major.mm()), ("minor", minor.mm())]
            }
            IndenterSpec::FlatRectangle { width, length } => {
                vec![("width", width.mm()), ("length", length.mm())]
            }
            IndenterSpec::FlatTriangle { side } => vec![("side", side.mm())],
            IndenterSpec::Cylinder { diameter, length } => {
                vec![("diameter", diameter.mm()), ("length", length.mm())]
            }
        };
        for (k, v) in dims {
            if v <= 0.0 {
                self.error(
                    &YamlPath::root().key("indenter").key(k),
                    format!("indenter {k} must be positive"),
                    "write e.g. `9.5 mm`",
                );
            }
        }
        if let Some(o) = &self.p.object
            && o.mass.g() <= 0.0
        {
            self.error(
                &YamlPath::root().key("object").key("mass"),
                "the object's mass must be positive",
                "write e.g. `100 g`",
            );
        }
    }

    fn check_safety(&mut self) {
        let s = &self.p.safety;
        let at = YamlPath::root().key("safety");
        let range = self
            .rig
            .force
            .as_ref()
            .map(|f| (f.model.name(), f.model.range()));
        let checks = [
            (
                "max_fz",
                s.max_fz.n(),
                range.map(|r| r.1.fz_n),
                "axial",
                "N",
            ),
            (
                "max_fxy",
                s.max_fxy.n(),
                range.map(|r| r.1.fxy_n),
                "tangential",
                "N",
            ),
            (
                "max_tz",
                s.max_tz.nmm(),
                range.map(|r| r.1.torque_nmm),
                "torque",
                "N·mm",
            ),
        ];
        for (key, v, limit, what, unit) in checks {
            if v <= 0.0 {
                self.error(
                    &at.key(key),
                    format!("{key} must be positive"),
                    format!("write the largest load the run may reach, in {unit}"),
                );
            }
            if let (Some(limit), Some((model, _))) = (limit, range)
                && v > limit + EPS
            {
                self.error(
                    &at.key(key),
                    format!(
                        "{key} {} {unit} is above the {model}'s {what} range {} {unit}: the sensor saturates before this limit can trip",
                        fmt_value(v),
                        fmt_value(limit)
                    ),
                    format!("set {key} to at most {} {unit}", fmt_value(limit)),
                );
            }
        }
        if let Some(r) = s.monitor_rate
            && r.hz() <= 0.0
        {
            self.error(
                &at.key("monitor_rate"),
                "the monitor rate must be positive",
                "write e.g. `50 Hz`",
            );
        }
        for (role, [lo, hi]) in &s.travel {
            let path = at.key("travel").key(role.name());
            match self.rig.axes.get(role) {
                None => self.warn(
                    &path,
                    format!(
                        "rig `{}` has no `{role}` axis; this limit does nothing",
                        self.rig.name
                    ),
                    "remove it, or add the axis to the rig",
                ),
                Some(cfg) => {
                    if lo.natural_unit() != cfg.unit()
                        || hi.natural_unit() != cfg.unit()
                        || matches!(lo, AxisQuantity::Percent(_))
                        || matches!(hi, AxisQuantity::Percent(_))
                    {
                        self.error(
                            &path,
                            format!(
                                "travel limits must be in {}, the {role} axis unit",
                                cfg.unit().symbol()
                            ),
                            format!("write them in {}", cfg.unit().symbol()),
                        );
                    } else if lo.raw() >= hi.raw() {
                        self.error(
                            &path,
                            "the travel limits are empty",
                            "write [min, max] with min < max",
                        );
                    }
                }
            }
        }
    }

    fn check_retract(&mut self) {
        let at = YamlPath::root().key("safety").key("retract");
        let used: Vec<AxisRole> = self.out.needs.axes.iter().copied().collect();
        for role in used {
            let Some(cfg) = self.rig.axes.get(&role) else {
                continue;
            };
            match self.p.safety.retract.get(&role) {
                None if role.presses() => self.error(
                    &YamlPath::root().key("safety"),
                    format!("the {role} axis presses into the elastomer but has no retract position"),
                    format!("add `retract: {{{role}: 0 mm}}` (absolute stage position clear of the sensor) to `safety`"),
                ),
                None => {}
                Some(q) => {
                    let (min, max) = cfg.travel();
                    match q.in_axis_unit(cfg.unit(), self.thickness_mm) {
                        Some(v) if matches!(q, AxisQuantity::Percent(_)) => {
                            let _ = v;
                            self.error(
                                &at.key(role.name()),
                                "a retract position is absolute and cannot be a percentage",
                                format!("write it in {}", cfg.unit().symbol()),
                            );
                        }
                        Some(v) if v < min - EPS || v > max + EPS => self.error(
                            &at.key(role.name()),
                            format!("retract position {q} is outside the {role} travel [{}, {}]", fmt_value(min), fmt_value(max)),
                            "choose a position inside the travel, clear of the sensor",
                        ),
                        Some(_) => {}
                        None => self.error(
                            &at.key(role.name()),
                            format!("`{q}` does not fit the {role} axis, which moves in {}", cfg.unit().symbol()),
                            format!("write it in {}", cfg.unit().symbol()),
                        ),
                    }
                }
            }
        }
    }
}
