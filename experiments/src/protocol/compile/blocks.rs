//! The blocks of a sequence: each one checked where it stands and expanded into actions.

use rig::config::YamlPath;
use rig::units::{AxisQuantity, fmt_value};

use super::{
    ActionKind, ApproachSpec, AxisLite, Compiler, DisturbSpec, EPS, Phase, SettleSpec, Step,
    StreamRates, Target,
};
use crate::protocol::schema::{self, Block, Direction};

impl Compiler<'_> {
    /// Checks one block where it stands (what the run knows at this point) and expands it
    /// into its actions.
    pub(super) fn block(&mut self, b: &Block, at: &YamlPath) {
        match b {
            Block::Home(h) => self.home_block(h, at),
            Block::Approach(a) => self.approach_block(a, at),
            Block::Tare(t) => self.tare_block(t, at),
            Block::Stepped(s) => self.stepped(s, at),
            Block::Hold(h) => self.hold_block(h, at),
            Block::Move(m) => self.move_block(m, at),
            Block::Capture(c) => self.capture_block(c, at),
            Block::Disturb(d) => self.disturb_block(d, at),
            Block::Record(r) => self.record_block(r, at),
            Block::Repeat(r) => self.repeat_block(r, at),
        }
    }

    /// `home`: every listed axis is bound and now sits at its home (0 clamped into its
    /// travel), with no origin or depth left from an earlier approach; homing a pressing axis
    /// opens the force sensor for the safety monitor.
    fn home_block(&mut self, h: &schema::Home, at: &YamlPath) {
        if h.axes.is_empty() {
            self.error(
                &at.key("axes"),
                "no axes to home",
                "list them, e.g. `axes: [normal, shear]`",
            );
        }
        for (k, role) in h.axes.iter().enumerate() {
            if let Some(axis) = self.axis(*role, &at.key("axes").index(k)) {
                let home = 0.0_f64.max(axis.min).min(axis.max);
                self.pos.insert(*role, (home, home));
                self.origin.insert(*role, (0.0, 0.0));
                self.rel.remove(role);
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

    /// `approach`: creeps until the contact threshold, so the contact point (the axis origin
    /// from here on) is known only within `[start, start + max_travel]`; checks the travel,
    /// the threshold against `max_fz`, and warns when nothing was tared before it.
    fn approach_block(&mut self, a: &schema::Approach, at: &YamlPath) {
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
        self.rel.insert(a.axis, (0.0, 0.0));
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

    /// `tare`: a positive averaging window (1 s by default); later approaches compare force
    /// with their threshold on a zeroed sensor.
    fn tare_block(&mut self, t: &schema::Tare, at: &YamlPath) {
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

    /// `hold`: one step that waits its duration, with a force window no longer than the
    /// hold.
    fn hold_block(&mut self, h: &schema::Hold, at: &YamlPath) {
        if h.duration.s() <= 0.0 {
            self.error(
                &at.key("duration"),
                "a hold needs a positive duration",
                "write e.g. `5 s`",
            );
        }
        let (window, frames) = match &h.capture {
            Some(c) => self.capture(c, &at.key("capture"), true),
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
                until_slip: None,
            }),
        );
    }

    /// `capture`: one step that records frames and/or a force window where things stand;
    /// warns when it records nothing.
    fn capture_block(&mut self, c: &schema::CaptureBlock, at: &YamlPath) {
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
                until_slip: None,
            }),
        );
    }

    /// `disturb`: one step that shakes the grasped object; needs a disturber and a force
    /// sensor, a force or torque amplitude, and a positive frequency and duration.
    fn disturb_block(&mut self, d: &schema::Disturb, at: &YamlPath) {
        self.out.needs.disturber = true;
        if self.rig.disturber.is_none() && self.reported_missing.insert("disturber".into()) {
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
                until_slip: None,
            }),
        );
    }

    /// `record`: the inner blocks run inside a scope of continuous streams, whose rates are
    /// checked against the devices.
    fn record_block(&mut self, r: &schema::Record, at: &YamlPath) {
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

    /// `repeat`: the inner blocks expanded once per trial; only the first trial reports
    /// issues (the others are the same blocks again).
    fn repeat_block(&mut self, r: &schema::Repeat, at: &YamlPath) {
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

    /// `stepped`: checks the axis, values, speed, capture and settle, then the span (see
    /// [`Self::stepped_step_count`]), and expands into one step per target; the axis ends at
    /// `to` after loading only, at `from` otherwise.
    pub(super) fn stepped(&mut self, s: &schema::Stepped, at: &YamlPath) {
        let Some(axis) = self.axis(s.axis, &at.key("axis")) else {
            return;
        };
        self.homed_before(s.axis, &at.key("axis"));
        let from = self.value(s.from, s.axis, &axis, &at.key("from"));
        let to = self.value(s.to, s.axis, &axis, &at.key("to"));
        let step = self.value(s.step, s.axis, &axis, &at.key("step"));
        let speed = self.speed(s.speed, s.axis, &axis, &at.key("speed"));
        let (window, frames) = self.capture(&s.capture, &at.key("capture"), true);
        let settle = self.settle(&s.settle, Some(s.axis), window, &at.key("settle"));
        match settle {
            SettleSpec::Rate { .. } => self.need_force(at, "rate settling"),
            SettleSpec::Adaptive { .. } => self.need_force(at, "adaptive settling"),
            _ => {}
        }
        let (Some(from), Some(to), Some(step)) = (from, to, step) else {
            return;
        };
        let Some(n) = self.stepped_step_count(s, &axis, from, to, step, at) else {
            return;
        };
        let label = s.label.clone().unwrap_or_else(|| "stepped".into());
        for (phase, target) in stepped_targets(s.direction, from, to - from, step, n) {
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
                    until_slip: None,
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
        self.rel.insert(s.axis, (last, last));
    }

    /// How many steps of `step` (axis unit) span `from`..`to`, or `None` after an error: the
    /// step must be positive and at least the stage's resolution, the span a whole number of
    /// steps (at least one), both ends reachable, and the count within the step budget. A
    /// step that is not a multiple of the resolution only warns (targets are rounded).
    fn stepped_step_count(
        &mut self,
        s: &schema::Stepped,
        axis: &AxisLite,
        from: f64,
        to: f64,
        step: f64,
        at: &YamlPath,
    ) -> Option<u32> {
        let u = axis.unit.symbol();
        if step <= 0.0 {
            self.error(
                &at.key("step"),
                "the step must be positive",
                format!("write e.g. `0.1 {u}`"),
            );
            return None;
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
            return None;
        }
        let span = to - from;
        let n = (span.abs() / step).round();
        if n < 1.0 {
            self.error(
                &at.key("to"),
                "`to` equals `from`: there is nothing to step",
                "set `to` at least one step away",
            );
            return None;
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
                self.whole_steps_fix(s, u, from, span, step),
            );
            return None;
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
        self.check_target(s.axis, axis, from, &at.key("from"));
        self.check_target(s.axis, axis, to, &at.key("to"));
        if n > self.max_steps as f64 {
            // The budget check counts before expanding; this keeps a block alone in bounds.
            self.error(
                &at.key("step"),
                format!(
                    "this block steps {} times, over the step budget",
                    fmt_value(n)
                ),
                "check `from`, `to` and `step`",
            );
            return None;
        }
        Some(n as u32)
    }

    /// The fix for a span that is not a whole number of steps: the two whole numbers of
    /// steps either side of the span, written in the unit `to` was written in (18 % or
    /// 21 %, not 0.756 mm or 0.882 mm). `unit` is the axis unit's symbol.
    fn whole_steps_fix(
        &self,
        s: &schema::Stepped,
        unit: &str,
        from: f64,
        span: f64,
        step: f64,
    ) -> String {
        let u = unit;
        let q = span.abs() / step;
        let (lo, hi) = (q.floor().max(1.0), q.ceil().max(q.floor() + 1.0));
        let in_user_unit = |k: f64| {
            let v = from + span.signum() * k * step;
            match s.to {
                AxisQuantity::Percent(_) if self.thickness_mm > 0.0 => {
                    format!("{} %", fmt_value(v / self.thickness_mm * 100.0))
                }
                _ => format!("{} {u}", fmt_value(v)),
            }
        };
        format!(
            "choose `to` = {} or {}, or a step that divides the span",
            in_user_unit(lo),
            in_user_unit(hi)
        )
    }

    pub(super) fn move_block(&mut self, m: &schema::Move, at: &YamlPath) {
        let Some(axis) = self.axis(m.axis, &at.key("axis")) else {
            return;
        };
        self.homed_before(m.axis, &at.key("axis"));
        if m.axis.presses() {
            self.need_force(at, "moving a pressing axis (the safety monitor)");
        }
        let speed = self.speed(m.speed, m.axis, &axis, &at.key("speed"));
        let (window, frames) = match &m.capture {
            Some(c) => self.capture(c, &at.key("capture"), false),
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
                self.rel.insert(m.axis, (v, v));
                Target::To(v)
            }
            (None, Some(q)) => {
                let Some(v) = self.value(q, m.axis, &axis, &at.key("by")) else {
                    return;
                };
                self.check_travel(m.axis, &axis, plo + v, phi + v, &at.key("by"));
                let (rlo, rhi) = self
                    .rel
                    .get(&m.axis)
                    .copied()
                    .unwrap_or((plo - ohi, phi - olo));
                if m.axis.presses()
                    && self.approached.contains(&m.axis)
                    && rhi + v >= self.thickness_mm - EPS
                {
                    self.error(
                        &at.key("by"),
                        format!(
                            "this move can take the depth to {} mm, reaching the elastomer thickness {} mm",
                            fmt_value(rhi + v),
                            fmt_value(self.thickness_mm)
                        ),
                        "move by less",
                    );
                }
                self.pos.insert(m.axis, (plo + v, phi + v));
                self.rel.insert(m.axis, (rlo + v, rhi + v));
                Target::By(v)
            }
        };
        let until_slip = m.until.as_ref().map(|u| {
            let path = at.key("until").key("slip");
            self.need_camera(&path, "stopping a move on the tactile slip state");
            if !self.streams.iter().any(|r| r.frames_hz.is_some()) {
                self.error(
                    &path,
                    "the tactile slip state comes from continuous frames, and this move records none",
                    "put the move inside a `record:` block with `frames: 25 Hz` (the thesis's rate)",
                );
            }
            u.slip
        });
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
                until_slip,
            }),
        );
    }
}

/// The targets of a stepped block of `n` steps of `step` over `span` (`to - from`), in
/// order, relative to the axis origin: loading counts up from `from`, unloading counts back
/// from `n` steps away so its last step lands exactly on `from`.
fn stepped_targets(
    direction: Direction,
    from: f64,
    span: f64,
    step: f64,
    n: u32,
) -> Vec<(Phase, f64)> {
    let dir = span.signum();
    let mut targets: Vec<(Phase, f64)> = Vec::new();
    if matches!(direction, Direction::Load | Direction::LoadUnload) {
        targets.extend((1..=n).map(|k| (Phase::Load, from + dir * step * k as f64)));
    }
    if matches!(direction, Direction::Unload | Direction::LoadUnload) {
        // Counted from `from`, so the last unloading step lands exactly on it.
        targets.extend((1..=n).map(|k| (Phase::Unload, from + dir * step * (n - k) as f64)));
    }
    targets
}
