//! What a run will do and cost, before anything moves.
//!
//! Users of orchestration tools ask first how long a run takes and how much disk it fills
//! (Bluesky #713 and #1277 have been open for years). The planner walks the compiled
//! actions with the rig's speeds and gives every step's earliest and latest end time, the
//! run's duration range (settle bounds and the unknown contact point of an approach make it
//! a range), the frames and samples recorded, and the bytes they take.
//!
//! Timing model (the runner follows it): moves go at their speed from where the axis may
//! be; homing and the rapid move to an approach's `from` go at the axis's maximum speed; an
//! approach creeps between 0 and `max_travel`; frames are one camera period apart; at the
//! end the pressing axes (normal, grip) return to their retract positions at full speed,
//! then the others do.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use rig::config::{AxisRole, RigConfig};
use serde::Serialize;

use crate::protocol::compile::{ActionKind, Compiled, SettleSpec, StreamRates, Target};
use crate::protocol::schema::Protocol;

/// Bytes of one `force.csv` row (typical of dry runs: 13-digit times, 4-decimal values).
pub const FORCE_ROW_BYTES: u64 = 78;
/// Bytes of one `axes.csv` row.
pub const AXES_ROW_BYTES: u64 = 36;
/// Bytes of one `steps.csv` row.
pub const STEP_ROW_BYTES: u64 = 230;
/// Bytes of one `journal.jsonl` line.
pub const JOURNAL_LINE_BYTES: u64 = 160;

/// A closed range [min, max].
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Range {
    /// Lower bound.
    #[serde(serialize_with = "without_noise")]
    pub min: f64,
    /// Upper bound.
    #[serde(serialize_with = "without_noise")]
    pub max: f64,
}

/// Serialises a number rounded to 1 ms of run time (or 12 significant digits), so `plan
/// --json` carries no float noise.
fn without_noise<S: serde::Serializer>(v: &f64, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_f64(round_noise((v * 1e3).round() / 1e3))
}

impl Range {
    fn point(v: f64) -> Self {
        Self { min: v, max: v }
    }
    fn add(self, o: Range) -> Range {
        Range {
            min: self.min + o.min,
            max: self.max + o.max,
        }
    }
    fn scale(self, k: f64) -> Range {
        Range {
            min: self.min * k,
            max: self.max * k,
        }
    }
    fn max_of(self, o: Range) -> Range {
        Range {
            min: self.min.max(o.min),
            max: self.max.max(o.max),
        }
    }
}

/// One step of the plan.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PlannedStep {
    /// Step number.
    pub step: u32,
    /// Trial (0 outside `repeat`).
    pub trial: u32,
    /// Label.
    pub label: String,
    /// Phase name.
    pub phase: String,
    /// Axis, if any.
    pub axis: Option<AxisRole>,
    /// Target as text, e.g. `0.084 mm` or `by -5 mm`.
    pub target: String,
    /// The target as a number (relative for `by` moves), in `target_unit`.
    pub target_value: Option<f64>,
    /// The target's unit (`mm` or `deg`).
    pub target_unit: Option<String>,
    /// Settle as text.
    pub settle: String,
    /// Frames captured.
    pub frames: u32,
    /// Time from run start at which the step ends, s.
    pub ends_s: Range,
}

/// The plan of a run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Plan {
    /// Steps in order.
    pub steps: Vec<PlannedStep>,
    /// Estimated duration of each compiled action (same order), s.
    pub action_s: Vec<Range>,
    /// The closing retract, s.
    pub retract_s: Range,
    /// Whole run, s.
    pub duration_s: Range,
    /// Frames written.
    pub frames: Range,
    /// `force.csv` rows.
    pub force_rows: Range,
    /// `axes.csv` rows.
    pub axes_rows: Range,
    /// Bytes written: CSVs, journal and frames (PNG bounded by raw RGB size).
    pub bytes: Range,
    /// Bytes of one frame, upper bound (its traction maps included, when recorded).
    pub frame_bytes: u64,
    /// What a simulated bench solves and leaves out (none on a real rig).
    pub sim: Option<crate::sim_models::SimModels>,
}

/// Where an axis may be: exactly at an offset from its origin (whose absolute place may be
/// uncertain after an approach), or somewhere in an absolute range. Keeping offsets relative
/// keeps move times exact even when the contact point is not known in advance.
#[derive(Debug, Clone, Copy)]
enum Pos {
    Rel(f64),
    Abs(Range),
}

fn absolute(p: Pos, origin: Range) -> Range {
    match p {
        Pos::Rel(v) => Range {
            min: origin.min + v,
            max: origin.max + v,
        },
        Pos::Abs(r) => r,
    }
}

fn pos_dist(a: Pos, b: Pos, origin: Range) -> Range {
    match (a, b) {
        (Pos::Rel(x), Pos::Rel(y)) => Range::point((x - y).abs()),
        _ => dist(absolute(a, origin), absolute(b, origin)),
    }
}

struct AxisKin {
    max_speed: f64,
    travel: (f64, f64),
}

fn dist(from: Range, to: Range) -> Range {
    let gap = if to.min > from.max {
        to.min - from.max
    } else if from.min > to.max {
        from.min - to.max
    } else {
        0.0
    };
    let far = (to.max - from.min).abs().max((from.max - to.min).abs());
    Range { min: gap, max: far }
}

/// Where every axis may be as the planner walks the actions, with the rig's speeds and the
/// camera's rate.
struct Walk {
    kin: BTreeMap<AxisRole, AxisKin>,
    pos: BTreeMap<AxisRole, Pos>,
    origin: BTreeMap<AxisRole, Range>,
    fps: f64,
}

impl Walk {
    fn new(rig: &RigConfig) -> Self {
        let kin: BTreeMap<AxisRole, AxisKin> = rig
            .axes
            .iter()
            .map(|(r, a)| {
                let k = AxisKin {
                    max_speed: a.max_speed.value,
                    travel: a.travel(),
                };
                (*r, k)
            })
            .collect();
        // Unknown start: an axis may be anywhere in its travel until homed.
        let pos = kin
            .iter()
            .map(|(r, k)| {
                let anywhere = Range {
                    min: k.travel.0,
                    max: k.travel.1,
                };
                (*r, Pos::Abs(anywhere))
            })
            .collect();
        Self {
            kin,
            pos,
            origin: BTreeMap::new(),
            fps: rig.camera.as_ref().map(|c| c.fps.hz()).unwrap_or(25.0),
        }
    }

    fn here(&self, r: &AxisRole) -> Pos {
        self.pos.get(r).copied().unwrap_or(Pos::Rel(0.0))
    }

    fn origin(&self, r: &AxisRole) -> Range {
        self.origin.get(r).copied().unwrap_or_default()
    }

    /// Homing goes at each axis's maximum speed, all at once.
    fn home(&mut self, axes: &[AxisRole]) -> Range {
        let mut d = Range::default();
        for r in axes {
            let Some(k) = self.kin.get(r) else { continue };
            let home = 0.0_f64.max(k.travel.0).min(k.travel.1);
            let to_home = pos_dist(self.here(r), Pos::Abs(Range::point(home)), self.origin(r));
            d = d.max_of(to_home.scale(1.0 / k.max_speed));
            self.pos.insert(*r, Pos::Abs(Range::point(home)));
            self.origin.insert(*r, Range::point(0.0));
        }
        d
    }

    /// A rapid move to `from`, a creep of 0 to `max_travel`, the reference frames; the
    /// contact (the new origin) is anywhere along the creep.
    fn approach(&mut self, a: &crate::protocol::compile::ApproachSpec) -> Range {
        let axis = &a.axis;
        let here = absolute(self.here(axis), self.origin(axis));
        let start = a.from.map(Range::point).unwrap_or(here);
        let speed = self.kin.get(axis).map(|k| k.max_speed).unwrap_or(1.0);
        let creep = Range {
            min: 0.0,
            max: a.max_travel / a.speed,
        };
        let d = dist(here, start)
            .scale(1.0 / speed)
            .add(creep)
            .add(Range::point(a.reference_frames as f64 / self.fps));
        let contact = Range {
            min: start.min,
            max: start.max + a.max_travel,
        };
        self.origin.insert(*axis, contact);
        self.pos.insert(*axis, Pos::Rel(0.0));
        d
    }

    /// A step's move at its speed, its settle bounds and its frames.
    fn step(&mut self, s: &crate::protocol::compile::Step) -> Range {
        let mut d = Range::default();
        if let (Some(axis), Some(target)) = (s.axis, s.target) {
            let here = self.here(&axis);
            let to = match (target, here) {
                (Target::To(v), _) => Pos::Rel(v),
                (Target::By(v), Pos::Rel(x)) => Pos::Rel(x + v),
                (Target::By(v), Pos::Abs(r)) => Pos::Abs(Range {
                    min: r.min + v,
                    max: r.max + v,
                }),
            };
            d = match target {
                Target::By(v) => Range::point(v.abs() / s.speed),
                Target::To(_) => pos_dist(here, to, self.origin(&axis)).scale(1.0 / s.speed),
            };
            if s.until_slip.is_some() {
                // A move that stops on touch may stop at once.
                d.min = 0.0;
            }
            self.pos.insert(axis, to);
        }
        let (smin, smax) = s.settle.bounds_s();
        d.add(Range {
            min: smin,
            max: smax,
        })
        .add(Range::point(s.frames as f64 / self.fps))
    }

    /// The closing retract: the pressing axes (normal, grip) at full speed, then the others.
    fn retract(&self, protocol: &Protocol, compiled: &Compiled) -> Range {
        let mut retract = Range::default();
        for pressing in [true, false] {
            let mut phase = Range::default();
            for (role, q) in &protocol.safety.retract {
                if !compiled.needs.axes.contains(role) || role.presses() != pressing {
                    continue;
                }
                if let (Some(k), Some(here)) = (self.kin.get(role), self.pos.get(role)) {
                    let to = Pos::Abs(Range::point(q.raw()));
                    let d = pos_dist(*here, to, self.origin(role)).scale(1.0 / k.max_speed);
                    phase = phase.max_of(d);
                }
            }
            retract = retract.add(phase);
        }
        retract
    }
}

/// The plan's line for one step, ending at `ends_s`.
fn planned_step(s: &crate::protocol::compile::Step, trial: u32, ends_s: Range) -> PlannedStep {
    PlannedStep {
        step: s.step,
        trial,
        label: s.label.clone(),
        phase: s.phase.name().to_string(),
        axis: s.axis,
        target: match (s.target, s.unit) {
            (Some(Target::To(v)), Some(u)) => {
                format!("{} {}", rig::units::fmt_value(v), u.symbol())
            }
            (Some(Target::By(v)), Some(u)) => {
                format!("by {} {}", rig::units::fmt_value(v), u.symbol())
            }
            _ => String::new(),
        },
        target_value: match s.target {
            Some(Target::To(v) | Target::By(v)) => Some(round_noise(v)),
            None => None,
        },
        target_unit: s.unit.map(|u| u.symbol().to_string()),
        settle: settle_text(&s.settle),
        frames: s.frames,
        ends_s,
    }
}

/// Rows and frames recorded while the streams of `active` run for `d`.
#[derive(Default)]
struct Recorded {
    frames: Range,
    force_rows: Range,
    axes_rows: Range,
}

impl Recorded {
    fn during(&mut self, active: StreamRates, d: Range, n_axes: f64) {
        if let Some(hz) = active.force_hz {
            self.force_rows = self.force_rows.add(d.scale(hz));
        }
        if let Some(hz) = active.axes_hz {
            self.axes_rows = self.axes_rows.add(d.scale(hz * n_axes));
        }
        if let Some(hz) = active.frames_hz {
            self.frames = self.frames.add(d.scale(hz));
        }
    }
}

/// Plans `compiled` (from `protocol`) on `rig`.
pub fn plan(protocol: &Protocol, compiled: &Compiled, rig: &RigConfig) -> Plan {
    let mut walk = Walk::new(rig);
    let frame_bytes = rig
        .camera
        .as_ref()
        .map(|c| {
            // With traction maps, each frame also writes its four float32 maps and a row.
            let maps = protocol.record.traction_maps.map_or(0, |k| {
                let k = u64::from(k.max(1));
                (c.width as u64 / k) * (c.height as u64 / k) * 16 + 256
            });
            c.width as u64 * c.height as u64 * 3 + 1024 + maps
        })
        .unwrap_or(0);
    let n_axes = compiled.needs.axes.len() as f64;
    let mut streams: Vec<StreamRates> = Vec::new();
    let mut t = Range::default();
    let mut rec = Recorded::default();
    let mut steps = Vec::new();
    let mut action_s = Vec::new();
    for action in &compiled.actions {
        let active = streams
            .iter()
            .fold(StreamRates::default(), |acc, s| acc.overlay(s));
        let mut extra_frames = 0.0;
        let d = match &action.kind {
            ActionKind::Home { axes } => walk.home(axes),
            ActionKind::Approach(a) => {
                extra_frames += a.reference_frames as f64;
                walk.approach(a)
            }
            ActionKind::Tare { duration_s } => Range::point(*duration_s),
            ActionKind::Step(s) => {
                let d = walk.step(s);
                extra_frames += s.frames as f64;
                steps.push(planned_step(s, action.trial, t.add(d)));
                d
            }
            ActionKind::StreamsBegin(r) => {
                streams.push(*r);
                Range::default()
            }
            ActionKind::StreamsEnd => {
                streams.pop();
                Range::default()
            }
            ActionKind::TrialBegin | ActionKind::TrialEnd => Range::default(),
        };
        rec.during(active, d, n_axes);
        rec.frames = rec.frames.add(Range::point(extra_frames));
        t = t.add(d);
        action_s.push(d);
    }
    let retract = walk.retract(protocol, compiled);
    t = t.add(retract);
    let rows_bytes = |r: Range, b: u64| r.scale(b as f64);
    let bytes = rows_bytes(rec.force_rows, FORCE_ROW_BYTES)
        .add(rows_bytes(rec.axes_rows, AXES_ROW_BYTES))
        .add(Range::point(
            (compiled.steps as u64 * STEP_ROW_BYTES) as f64,
        ))
        .add(Range::point(
            (compiled.actions.len() as u64 * 2 * JOURNAL_LINE_BYTES) as f64,
        ))
        .add(rec.frames.scale(frame_bytes as f64));
    Plan {
        steps,
        action_s,
        retract_s: retract,
        duration_s: t,
        frames: rec.frames,
        force_rows: rec.force_rows,
        axes_rows: rec.axes_rows,
        bytes,
        frame_bytes,
        sim: crate::sim_models::sim_models(protocol, compiled, rig),
    }
}

/// `v` without float noise (`0.30000000000000004` → 0.3): 12 significant digits.
fn round_noise(v: f64) -> f64 {
    if v == 0.0 || !v.is_finite() {
        return v;
    }
    let scale = 10f64.powi(11 - v.abs().log10().floor() as i32);
    (v * scale).round() / scale
}

fn settle_text(s: &SettleSpec) -> String {
    match s {
        SettleSpec::None => "-".into(),
        SettleSpec::Fixed { s } => format!("{} s", rig::units::fmt_value(*s)),
        SettleSpec::Rate {
            channel,
            below,
            min_s,
            max_s,
            ..
        } => format!(
            "|d{}/dt| < {} {} for {}–{} s",
            channel.label(),
            rig::units::fmt_value(*below),
            channel.rate_unit(),
            rig::units::fmt_value(*min_s),
            rig::units::fmt_value(*max_s)
        ),
        SettleSpec::Adaptive {
            channel,
            tolerance,
            min_s,
            max_s,
            ..
        } => format!(
            "{}∞ known within {} % (adaptive), {}–{} s",
            channel.label(),
            rig::units::fmt_value(tolerance * 100.0),
            rig::units::fmt_value(*min_s),
            rig::units::fmt_value(*max_s)
        ),
    }
}

/// `1 h 02 min 05 s`, `3 min 20 s`, `4.2 s`.
pub fn human_duration(s: f64) -> String {
    if s < 60.0 {
        return format!("{s:.1} s");
    }
    let total = s.round() as u64;
    let (h, m, sec) = (total / 3600, (total % 3600) / 60, total % 60);
    if h > 0 {
        format!("{h} h {m:02} min {sec:02} s")
    } else {
        format!("{m} min {sec:02} s")
    }
}

/// `12.3 MB`, `850 kB`.
pub fn human_bytes(b: f64) -> String {
    if b >= 1e9 {
        format!("{:.2} GB", b / 1e9)
    } else if b >= 1e6 {
        format!("{:.1} MB", b / 1e6)
    } else if b >= 1e3 {
        format!("{:.0} kB", b / 1e3)
    } else {
        format!("{b:.0} B")
    }
}

fn range_text(r: Range, f: impl Fn(f64) -> String) -> String {
    if (r.max - r.min).abs() < 1e-6 * r.max.abs().max(1.0) {
        f(r.min)
    } else {
        format!("{} – {}", f(r.min), f(r.max))
    }
}

impl Plan {
    /// The plan as a table and summary, for `gelrig plan`.
    pub fn render(&self, protocol: &Protocol, rig: &RigConfig) -> String {
        let mut o = String::new();
        let _ = writeln!(o, "protocol {} on rig {}", protocol.name, rig.name);
        let _ = writeln!(
            o,
            "{:>5} {:>5}  {:<12} {:<7} {:<9} {:>14}  {:<28} {:>6}  {:>21}",
            "step", "trial", "label", "phase", "axis", "target", "settle", "frames", "ends at"
        );
        for s in &self.steps {
            let _ = writeln!(
                o,
                "{:>5} {:>5}  {:<12} {:<7} {:<9} {:>14}  {:<28} {:>6}  {:>21}",
                s.step,
                s.trial,
                s.label,
                s.phase,
                s.axis.map(|a| a.name()).unwrap_or("-"),
                s.target,
                s.settle,
                s.frames,
                range_text(s.ends_s, human_duration)
            );
        }
        let _ = writeln!(o);
        let _ = writeln!(o, "steps        {}", self.steps.len());
        let _ = writeln!(
            o,
            "duration     {}",
            range_text(self.duration_s, human_duration)
        );
        let _ = writeln!(
            o,
            "frames       {}",
            range_text(self.frames, |v| format!("{:.0}", v))
        );
        let _ = writeln!(
            o,
            "force rows   {}",
            range_text(self.force_rows, |v| format!("{:.0}", v))
        );
        if self.axes_rows.max > 0.0 {
            let _ = writeln!(
                o,
                "axes rows    {}",
                range_text(self.axes_rows, |v| format!("{:.0}", v))
            );
        }
        let _ = writeln!(
            o,
            "data         {}{}",
            range_text(self.bytes, human_bytes),
            if self.frames.max > 0.0 {
                " (frames counted at their uncompressed size; PNG is smaller)"
            } else {
                ""
            }
        );
        if let Some(sim) = &self.sim {
            let _ = writeln!(o);
            o.push_str(&sim.render());
        }
        o
    }
}
