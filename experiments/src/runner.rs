//! Executes a compiled protocol on a rig: move, wait for motion, settle, capture, record.
//!
//! The runner is one task with one loop ([`Exec::wait`]) that services, on the run's clock,
//! everything that must happen while it waits for something: force samples (checked by the
//! safety monitor, recorded when a force stream is on, kept for settle and capture windows),
//! axis positions and frames for active streams, position polls of moving axes. Being one
//! task on one clock makes a dry run deterministic and lets virtual time jump straight from
//! one due event to the next.
//!
//! Every way a run ends goes through the same exit: stop all motion, send each axis with a
//! retract position there, record final positions, write the manifest's final status.
//! Ctrl-C (or SIGTERM) aborts at the next event; a second one gives up the retract.

use std::collections::{BTreeMap, VecDeque};
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicU32, Ordering};

use rig::config::AxisRole;
use rig::units::fmt_value;
use rig::{Clock, ClockMode, ForceRange, OpenRequest, Rig, RigError, STATUS_SATURATED, Wrench};
use serde_json::json;

use crate::plan::Plan;
use crate::progress::{Progress, ProgressMode};
use crate::protocol::compile::{
    Action, ActionKind, ApproachSpec, DisturbSpec, SettleSpec, Step, StreamRates, Target,
};
use crate::protocol::schema::{Channel, OnTimeout};
use crate::protocol::{Loaded, plant_spec};
use crate::record::{DeviceRecord, Manifest, RecordError, Recorder, Status, StepRow};

/// Interrupt requests from signal handlers (count of SIGINT/SIGTERM received).
#[derive(Debug, Clone, Default)]
pub struct Cancel(Arc<AtomicU32>);

impl Cancel {
    /// A fresh token.
    pub fn new() -> Self {
        Self::default()
    }
    /// Records one interrupt request.
    pub fn interrupt(&self) {
        self.0.fetch_add(1, Ordering::SeqCst);
    }
    /// Interrupts requested so far.
    pub fn count(&self) -> u32 {
        self.0.load(Ordering::SeqCst)
    }
}

/// What to run, where, and how.
pub struct RunRequest<'a> {
    /// The checked protocol and rig.
    pub loaded: &'a Loaded,
    /// Its plan (for the manifest's ETA and the progress display).
    pub plan: &'a Plan,
    /// Directory that receives the run directory.
    pub out: PathBuf,
    /// Seed of simulated devices.
    pub seed: u64,
    /// Run clock.
    pub clock: ClockMode,
    /// Progress display.
    pub progress: ProgressMode,
}

/// How a run ended.
#[derive(Debug, Clone, PartialEq)]
pub struct RunOutcome {
    /// The run directory.
    pub dir: PathBuf,
    /// Final status.
    pub status: Status,
    /// Abort reason or error.
    pub message: Option<String>,
}

/// Why execution stopped early.
#[derive(Debug, thiserror::Error)]
enum Stop {
    #[error("interrupted by the operator")]
    Interrupted,
    #[error("safety limit: {0}")]
    Safety(String),
    #[error("{0}")]
    SettleTimeout(String),
    #[error("{0}")]
    NoContact(String),
    #[error(transparent)]
    Device(#[from] RigError),
    #[error("recording failed: {0}")]
    Record(#[from] RecordError),
}

impl Stop {
    fn status(&self) -> Status {
        match self {
            Stop::Interrupted | Stop::Safety(_) | Stop::SettleTimeout(_) => Status::Aborted,
            Stop::NoContact(_) | Stop::Device(_) | Stop::Record(_) => Status::Failed,
        }
    }
}

fn clock_label(mode: ClockMode) -> String {
    match mode {
        ClockMode::Virtual => "virtual".into(),
        ClockMode::Scaled { scale } => format!("scaled x{scale}"),
        ClockMode::Monotonic => "monotonic".into(),
    }
}

/// Runs `req`; returns how it ended. Fails only if the run directory cannot be created.
pub async fn run(req: RunRequest<'_>, cancel: Cancel) -> Result<RunOutcome, RecordError> {
    let loaded = req.loaded;
    let p = &loaded.protocol;
    let clock = Clock::new(req.clock);
    let manifest = Manifest {
        status: Status::Running,
        reason: None,
        error: None,
        protocol: p.name.clone(),
        protocol_file: loaded.path.display().to_string(),
        rig: loaded.rig.name.clone(),
        rig_file: loaded.rig_path.display().to_string(),
        started_utc: jiff::Timestamp::now().to_string(),
        ended_utc: None,
        gelrig_version: env!("CARGO_PKG_VERSION").to_string(),
        seed: req.seed,
        clock: clock_label(req.clock),
        pid: std::process::id(),
        steps_planned: loaded.compiled.steps,
        steps_completed: 0,
        eta_s: [
            (req.plan.duration_s.min * 10.0).round() / 10.0,
            (req.plan.duration_s.max * 10.0).round() / 10.0,
        ],
        devices: Vec::new(),
        tare: None,
        origins: BTreeMap::new(),
        final_positions: BTreeMap::new(),
        safety_events: Vec::new(),
        warnings: loaded
            .warnings
            .iter()
            .map(|d| format!("{}:{}: {}", d.line, d.column, d.message))
            .collect(),
    };
    // The resolved protocol (sensor defaults filled in) is what actually ran.
    let protocol_yaml = serde_yaml::to_string(p).unwrap_or_else(|_| loaded.text.clone());
    let mut rec = Recorder::create(&req.out, manifest, &protocol_yaml, &loaded.rig_text)?;
    let time_scale = match req.clock {
        ClockMode::Virtual => None,
        ClockMode::Scaled { scale } => Some(scale),
        ClockMode::Monotonic => Some(1.0),
    };
    let progress = Progress::new(
        req.progress,
        loaded.compiled.steps,
        req.plan.duration_s.max,
        time_scale,
    );
    rec.journal(
        clock.now_ns(),
        "run_start",
        json!({"protocol": p.name, "rig": loaded.rig.name, "seed": req.seed, "clock": clock_label(req.clock)}),
        true,
    )?;

    let rig = match open_bench(loaded, &clock, req.seed).await {
        Ok(r) => r,
        Err(e) => return finish(rec, &clock, &progress, Status::Failed, Some(e)),
    };
    let devices: Vec<DeviceRecord> = rig
        .opened
        .iter()
        .map(|d| DeviceRecord {
            role: d.role.clone(),
            identity: d.identity.clone(),
        })
        .collect();
    rec.update_manifest(|m| m.devices = devices.clone())?;
    rec.journal(
        clock.now_ns(),
        "devices_opened",
        json!({ "devices": devices }),
        true,
    )?;

    let safety = &p.safety;
    let mut exec = Exec {
        force_range: rig.force.as_ref().map(|f| f.info().range),
        poll_period_ns: loaded
            .rig
            .axes
            .iter()
            .map(|(r, a)| (*r, (1e9 / a.poll_rate_hz()) as u64))
            .collect(),
        rig,
        clock: clock.clone(),
        rec,
        progress: &progress,
        cancel,
        max_fz_n: safety.max_fz.n(),
        max_fxy_n: safety.max_fxy.n(),
        max_tz_nmm: safety.max_tz.nmm(),
        monitor_period_ns: (1e9 / safety.monitor_rate.map(|r| r.hz()).unwrap_or(50.0)) as u64,
        retract_to: safety
            .retract
            .iter()
            .filter_map(|(r, q)| {
                (!matches!(q, rig::units::AxisQuantity::Percent(_))).then_some((*r, q.raw()))
            })
            .collect(),
        tare: Wrench::default(),
        origin: BTreeMap::new(),
        targets: BTreeMap::new(),
        streams: Vec::new(),
        active: StreamRates::default(),
        next_force_stream: None,
        next_monitor: None,
        next_axes: None,
        next_frame_stream: None,
        step: 0,
        trial: 0,
        window: VecDeque::new(),
        keep_ns: 0,
        step_saturated: false,
        retracting: false,
        what: String::new(),
        phase: "starting",
    };
    exec.next_monitor = exec.rig.force.as_ref().map(|_| exec.clock.now_ns());
    let result = exec.run_actions(&loaded.compiled.actions).await;
    let (status, message) = match &result {
        Ok(()) => (Status::Completed, None),
        Err(stop) => {
            let msg = stop.to_string();
            exec.progress.note(&format!("stopping: {msg}"));
            let t = exec.clock.now_ns();
            let _ = exec.rec.journal(
                t,
                "stop",
                json!({ "reason": msg, "status": stop.status().name() }),
                true,
            );
            if let Stop::Safety(m) = stop {
                let m = m.clone();
                let _ = exec.rec.update_manifest(|man| man.safety_events.push(m));
            }
            (stop.status(), Some(msg))
        }
    };
    let retract = exec.retract().await;
    let (status, message) = match (status, retract) {
        (s, Ok(())) => (s, message),
        (Status::Completed, Err(e)) => (
            Status::Failed,
            Some(format!("run completed but the retract failed: {e}")),
        ),
        (s, Err(e)) => (
            s,
            Some(format!(
                "{}; retract failed: {e}",
                message.unwrap_or_default()
            )),
        ),
    };
    let Exec { rec, .. } = exec;
    finish(rec, &clock, &progress, status, message)
}

/// Opens the devices the protocol needs, building the simulated bench if the rig has one.
async fn open_bench(loaded: &Loaded, clock: &Clock, seed: u64) -> Result<Rig, String> {
    let plant = if loaded.rig.uses_sim() {
        Some(
            plant_spec(&loaded.protocol, &loaded.compiled)
                .map_err(|e| format!("simulated bench: {e}"))?,
        )
    } else {
        None
    };
    let needs = &loaded.compiled.needs;
    let open = OpenRequest {
        axes: needs.axes.clone(),
        force: needs.force,
        camera: needs.camera,
        disturber: needs.disturber,
        plant,
        clock: clock.clone(),
        seed,
    };
    rig::open(&loaded.rig, open)
        .await
        .map_err(|e| format!("opening devices: {e}"))
}

fn finish(
    mut rec: Recorder,
    clock: &Clock,
    progress: &Progress,
    status: Status,
    message: Option<String>,
) -> Result<RunOutcome, RecordError> {
    progress.finish();
    let _ = rec.journal(
        clock.now_ns(),
        "run_end",
        json!({ "status": status.name(), "message": message }),
        true,
    );
    rec.update_manifest(|m| {
        m.status = status;
        m.ended_utc = Some(jiff::Timestamp::now().to_string());
        match status {
            Status::Aborted => m.reason = message.clone(),
            Status::Failed => m.error = message.clone(),
            _ => {}
        }
    })?;
    Ok(RunOutcome {
        dir: rec.dir().to_path_buf(),
        status,
        message,
    })
}

/// What [`Exec::wait`] waits for.
enum Until {
    /// All these axes have stopped.
    Motion(Vec<AxisRole>),
    /// The clock reaches this time.
    Time(u64),
    /// The settle criterion holds (or times out).
    Settle(SettleTrack),
    /// This many more frames have been captured.
    Frames(u32),
    /// |force along `channel`| reaches `threshold` while `axis` moves.
    Contact {
        axis: AxisRole,
        channel: Channel,
        threshold: f64,
    },
}

/// State of a rate-based settle.
struct SettleTrack {
    channel: Channel,
    below: f64,
    window_ns: u64,
    start_ns: u64,
    min_ns: u64,
    max_ns: u64,
    verdict: Option<&'static str>,
}

impl SettleTrack {
    /// Upper bound of |slope| of the channel over the last window, per second: the
    /// least-squares slope plus twice its standard error. Judging the bound rather than
    /// the slope itself keeps sensor noise from "settling" a step by chance: a threshold
    /// below what the noise can resolve is never met (and times out) instead of being met
    /// at random.
    fn drift_bound(&self, window: &VecDeque<(u64, Wrench, u32)>, now: u64) -> Option<f64> {
        let from = now.saturating_sub(self.window_ns);
        let pts: Vec<(f64, f64)> = window
            .iter()
            .filter(|(t, _, _)| *t >= from)
            .map(|(t, w, _)| ((*t - from) as f64 * 1e-9, self.channel.of(w)))
            .collect();
        if pts.len() < 3 {
            return None;
        }
        let n = pts.len() as f64;
        let (mx, my) = (
            pts.iter().map(|p| p.0).sum::<f64>() / n,
            pts.iter().map(|p| p.1).sum::<f64>() / n,
        );
        let sxx: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
        if sxx <= 0.0 {
            return None;
        }
        let slope = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum::<f64>() / sxx;
        let rss: f64 = pts
            .iter()
            .map(|p| (p.1 - my - slope * (p.0 - mx)).powi(2))
            .sum();
        let se = (rss / (n - 2.0) / sxx).sqrt();
        Some(slope.abs() + 2.0 * se)
    }
}

struct Exec<'a> {
    rig: Rig,
    clock: Clock,
    rec: Recorder,
    progress: &'a Progress,
    cancel: Cancel,
    force_range: Option<ForceRange>,
    poll_period_ns: BTreeMap<AxisRole, u64>,
    max_fz_n: f64,
    max_fxy_n: f64,
    max_tz_nmm: f64,
    monitor_period_ns: u64,
    retract_to: BTreeMap<AxisRole, f64>,
    tare: Wrench,
    origin: BTreeMap<AxisRole, f64>,
    targets: BTreeMap<AxisRole, f64>,
    streams: Vec<StreamRates>,
    active: StreamRates,
    next_force_stream: Option<u64>,
    next_monitor: Option<u64>,
    next_axes: Option<u64>,
    next_frame_stream: Option<u64>,
    step: u32,
    trial: u32,
    /// Recent tared samples (t, wrench, status), kept for settle and capture windows.
    window: VecDeque<(u64, Wrench, u32)>,
    keep_ns: u64,
    step_saturated: bool,
    retracting: bool,
    what: String,
    phase: &'static str,
}

fn period_ns(hz: f64) -> u64 {
    (1e9 / hz).round().max(1.0) as u64
}

impl Exec<'_> {
    fn now(&self) -> u64 {
        self.clock.now_ns()
    }

    fn t_s(&self) -> f64 {
        self.now() as f64 * 1e-9
    }

    fn check_cancel(&self) -> Result<(), Stop> {
        let n = self.cancel.count();
        if n >= 2 || (n >= 1 && !self.retracting) {
            return Err(Stop::Interrupted);
        }
        Ok(())
    }

    fn set_phase(&mut self, phase: &'static str) {
        self.phase = phase;
        let t = self.t_s();
        self.progress.phase(self.step, &self.what, phase, t);
    }

    async fn run_actions(&mut self, actions: &[Action]) -> Result<(), Stop> {
        for action in actions {
            self.check_cancel()?;
            self.trial = action.trial;
            match &action.kind {
                ActionKind::Home { axes } => self.home(axes).await?,
                ActionKind::Approach(a) => self.approach(a).await?,
                ActionKind::Tare { duration_s } => self.tare(*duration_s).await?,
                ActionKind::Step(s) => self.step(s).await?,
                ActionKind::StreamsBegin(r) => {
                    self.streams.push(*r);
                    self.restream();
                    let t = self.now();
                    self.rec.journal(t, "streams_begin", json!(r), false)?;
                }
                ActionKind::StreamsEnd => {
                    self.streams.pop();
                    self.restream();
                    let t = self.now();
                    self.rec.journal(t, "streams_end", json!({}), false)?;
                }
                ActionKind::TrialBegin => {
                    let t = self.now();
                    self.rec
                        .journal(t, "trial_begin", json!({ "trial": action.trial }), true)?;
                    self.progress
                        .note(&format!("trial {} begins", action.trial));
                }
                ActionKind::TrialEnd => {
                    let t = self.now();
                    self.rec
                        .journal(t, "trial_end", json!({ "trial": action.trial }), true)?;
                }
            }
        }
        Ok(())
    }

    /// Recomputes the active stream rates after a scope change.
    fn restream(&mut self) {
        self.active = self
            .streams
            .iter()
            .fold(StreamRates::default(), |acc, s| acc.overlay(s));
        let now = self.now();
        self.next_force_stream = self
            .active
            .force_hz
            .filter(|_| self.rig.force.is_some())
            .map(|_| now);
        self.next_axes = self.active.axes_hz.map(|_| now);
        self.next_frame_stream = self
            .active
            .frames_hz
            .filter(|_| self.rig.camera.is_some())
            .map(|_| now);
    }

    /// Reads the force sensor once: tare, safety, window, stream. The safety check runs
    /// on every read, recorded or not.
    async fn sample_force(&mut self, now: u64, record: bool) -> Result<(), Stop> {
        let Some(sensor) = self.rig.force.as_mut() else {
            return Ok(());
        };
        let s = sensor.read().await?;
        let w = s.wrench.minus(&self.tare);
        if s.status & STATUS_SATURATED != 0 {
            self.step_saturated = true;
        }
        // With a force stream on, windows use exactly the samples written to force.csv, so
        // the quasistatic values in steps.csv can be recomputed from the run directory.
        if record || self.next_force_stream.is_none() {
            self.window.push_back((s.t_ns, w, s.status));
        }
        let keep_from = now.saturating_sub(self.keep_ns.max(2_000_000_000));
        while self.window.front().is_some_and(|(t, _, _)| *t < keep_from) {
            self.window.pop_front();
        }
        if record {
            self.rec.force(&s, &w, self.step, self.trial)?;
        }
        if !self.retracting {
            let trip = if s.status & STATUS_SATURATED != 0 {
                let range = self.force_range.unwrap_or(ForceRange::NANO17);
                Some(format!(
                    "the force sensor saturated (range {} N axial, {} N tangential, {} N·mm)",
                    range.fz_n, range.fxy_n, range.torque_nmm
                ))
            } else if w.fz_n.abs() > self.max_fz_n {
                Some(format!(
                    "|Fz| = {:.3} N exceeds max_fz {} N",
                    w.fz_n.abs(),
                    fmt_value(self.max_fz_n)
                ))
            } else if w.fx_n.hypot(w.fy_n) > self.max_fxy_n {
                Some(format!(
                    "|Fxy| = {:.3} N exceeds max_fxy {} N",
                    w.fx_n.hypot(w.fy_n),
                    fmt_value(self.max_fxy_n)
                ))
            } else if w.tz_nmm.abs() > self.max_tz_nmm {
                Some(format!(
                    "|Tz| = {:.3} N·mm exceeds max_tz {} N·mm",
                    w.tz_nmm.abs(),
                    fmt_value(self.max_tz_nmm)
                ))
            } else {
                None
            };
            if let Some(msg) = trip {
                let msg = if self.step > 0 {
                    format!("{msg} (step {})", self.step)
                } else {
                    msg
                };
                return Err(Stop::Safety(msg));
            }
        }
        Ok(())
    }

    /// Waits for `until`, servicing every due schedule meanwhile.
    async fn wait(&mut self, until: &mut Until) -> Result<(), Stop> {
        let mut next_poll: u64 = self.now();
        let mut frames_due: Option<u64> = None;
        loop {
            self.check_cancel()?;
            let now = self.now();
            // Force: the stream's schedule and the safety monitor's, one read when either is due.
            let stream_due = self.next_force_stream.is_some_and(|t| now >= t);
            let monitor_due = self.next_monitor.is_some_and(|t| now >= t);
            let mut fresh_force = false;
            if stream_due || monitor_due {
                self.sample_force(now, stream_due).await?;
                fresh_force = true;
                if stream_due
                    && let (Some(t), Some(hz)) = (self.next_force_stream, self.active.force_hz)
                {
                    let p = period_ns(hz);
                    self.next_force_stream = Some(if t + p <= now { now + p } else { t + p });
                }
                if monitor_due && let Some(t) = self.next_monitor {
                    let p = self.monitor_period_ns;
                    self.next_monitor = Some(if t + p <= now { now + p } else { t + p });
                }
            }
            if let (Some(t), Some(hz)) = (self.next_axes, self.active.axes_hz)
                && now >= t
            {
                self.record_axes(now).await?;
                let p = period_ns(hz);
                self.next_axes = Some(if t + p <= now { now + p } else { t + p });
            }
            if let (Some(t), Some(hz)) = (self.next_frame_stream, self.active.frames_hz)
                && now >= t
            {
                self.capture_frame().await?;
                let p = period_ns(hz);
                let now = self.now();
                self.next_frame_stream = Some(if t + p <= now { now + p } else { t + p });
            }
            let deadline: u64;
            match until {
                Until::Time(t) => {
                    if now >= *t {
                        return Ok(());
                    }
                    deadline = *t;
                }
                Until::Motion(axes) => {
                    if now >= next_poll {
                        if self.all_stopped(axes).await? {
                            return Ok(());
                        }
                        next_poll = now
                            + axes
                                .iter()
                                .map(|a| self.poll_ns(*a))
                                .min()
                                .unwrap_or(50_000_000);
                    }
                    deadline = next_poll;
                }
                Until::Settle(track) => {
                    let elapsed = now.saturating_sub(track.start_ns);
                    if elapsed >= track.max_ns {
                        track.verdict = Some("timeout");
                        return Ok(());
                    }
                    if fresh_force
                        && elapsed >= track.min_ns
                        && elapsed >= track.window_ns
                        && track
                            .drift_bound(&self.window, now)
                            .is_some_and(|b| b < track.below)
                    {
                        track.verdict = Some("converged");
                        return Ok(());
                    }
                    deadline = track.start_ns + track.max_ns;
                }
                Until::Frames(n) => {
                    if *n == 0 {
                        return Ok(());
                    }
                    let due = *frames_due.get_or_insert(now);
                    if now >= due {
                        self.capture_frame().await?;
                        *n -= 1;
                        frames_due = Some(self.now());
                        if *n == 0 {
                            return Ok(());
                        }
                        continue;
                    }
                    deadline = due;
                }
                Until::Contact {
                    axis,
                    channel,
                    threshold,
                } => {
                    if fresh_force
                        && let Some((_, w, _)) = self.window.back()
                        && channel.of(w).abs() >= *threshold
                    {
                        return Ok(());
                    }
                    if now >= next_poll {
                        if self.all_stopped(&[*axis]).await? {
                            return Err(Stop::NoContact(format!(
                                "the {axis} axis reached the end of the approach without |{}| reaching {} {}",
                                channel.name(),
                                fmt_value(*threshold),
                                if channel.is_torque() { "N·mm" } else { "N" }
                            )));
                        }
                        next_poll = now + self.poll_ns(*axis);
                    }
                    deadline = next_poll;
                }
            }
            let next = [
                Some(deadline),
                self.next_force_stream,
                self.next_monitor,
                self.next_axes,
                self.next_frame_stream,
            ]
            .into_iter()
            .flatten()
            .min()
            .unwrap_or(deadline);
            let tick_t = self.t_s();
            self.progress
                .tick(self.step, &self.what, self.phase, tick_t);
            if next > now {
                self.clock.sleep_until_ns(next).await;
            } else {
                tokio::task::yield_now().await;
            }
        }
    }

    fn poll_ns(&self, axis: AxisRole) -> u64 {
        self.poll_period_ns
            .get(&axis)
            .copied()
            .unwrap_or(50_000_000)
    }

    async fn all_stopped(&mut self, axes: &[AxisRole]) -> Result<bool, Stop> {
        for a in axes {
            if let Some(ax) = self.rig.axes.get_mut(a)
                && ax.status().await?.moving
            {
                return Ok(false);
            }
        }
        Ok(true)
    }

    async fn record_axes(&mut self, now: u64) -> Result<(), Stop> {
        let mut rows = Vec::new();
        for (role, ax) in self.rig.axes.iter_mut() {
            let st = ax.status().await?;
            rows.push((*role, st.position));
        }
        for (role, pos) in rows {
            let target = self.targets.get(&role).copied();
            self.rec.axis(now, role.name(), target, pos)?;
        }
        Ok(())
    }

    async fn capture_frame(&mut self) -> Result<u64, Stop> {
        let Some(cam) = self.rig.camera.as_mut() else {
            return Ok(0);
        };
        let frame = cam.capture().await?;
        Ok(self.rec.frame(&frame, self.step, self.trial)?)
    }

    async fn move_axis(&mut self, axis: AxisRole, target_abs: f64, speed: f64) -> Result<(), Stop> {
        let Some(ax) = self.rig.axes.get_mut(&axis) else {
            return Err(Stop::Device(RigError::Unsupported {
                device: format!("{axis} axis"),
                detail: "not opened".into(),
            }));
        };
        ax.move_to(target_abs, speed).await?;
        self.targets.insert(axis, target_abs);
        self.wait(&mut Until::Motion(vec![axis])).await
    }

    async fn position(&mut self, axis: AxisRole) -> Result<f64, Stop> {
        match self.rig.axes.get_mut(&axis) {
            Some(ax) => Ok(ax.status().await?.position),
            None => Ok(0.0),
        }
    }

    async fn home(&mut self, axes: &[AxisRole]) -> Result<(), Stop> {
        self.what = format!(
            "home {}",
            axes.iter().map(|a| a.name()).collect::<Vec<_>>().join(", ")
        );
        self.set_phase("homing");
        for a in axes {
            if let Some(ax) = self.rig.axes.get_mut(a) {
                ax.home().await?;
            }
            self.origin.insert(*a, 0.0);
        }
        self.wait(&mut Until::Motion(axes.to_vec())).await?;
        for a in axes {
            if let Some(ax) = self.rig.axes.get_mut(a) {
                let st = ax.status().await?;
                if !st.referenced {
                    return Err(Stop::Device(RigError::Garbled {
                        device: format!("{a} axis"),
                        detail: "homing finished but the axis reports no reference".into(),
                    }));
                }
                self.targets.insert(*a, st.position);
            }
        }
        let t = self.now();
        self.rec.journal(t, "home", json!({ "axes": axes }), true)?;
        Ok(())
    }

    async fn tare(&mut self, duration_s: f64) -> Result<(), Stop> {
        self.what = "tare".into();
        self.set_phase("taring");
        let start = self.now();
        self.keep_ns = self.keep_ns.max((duration_s * 1e9) as u64);
        let end = start + (duration_s * 1e9) as u64;
        self.wait(&mut Until::Time(end)).await?;
        let mean = Wrench::mean(
            self.window
                .iter()
                .filter(|(t, _, _)| *t >= start)
                .map(|(_, w, _)| *w),
        );
        self.tare = Wrench::from_array(
            self.tare
                .as_array()
                .iter()
                .zip(mean.as_array())
                .map(|(a, b)| a + b)
                .collect::<Vec<_>>()
                .try_into()
                .unwrap_or([0.0; 6]),
        );
        // Samples already in the window were taken against the old offset.
        for (_, w, _) in self.window.iter_mut() {
            *w = w.minus(&mean);
        }
        let tare = self.tare.as_array();
        self.rec.update_manifest(|m| m.tare = Some(tare))?;
        let t = self.now();
        self.rec
            .journal(t, "tare", json!({ "offset": tare }), true)?;
        self.progress.note(&format!(
            "tare: offset Fx {:.4} Fy {:.4} Fz {:.4} N, Tz {:.4} N·mm",
            tare[0], tare[1], tare[2], tare[5]
        ));
        Ok(())
    }

    async fn approach(&mut self, a: &ApproachSpec) -> Result<(), Stop> {
        let ApproachSpec {
            axis,
            from,
            speed,
            until_n,
            max_travel,
            reference_frames,
        } = *a;
        self.what = format!("approach {axis}");
        if reference_frames > 0 {
            self.set_phase("reference frames");
            self.wait(&mut Until::Frames(reference_frames)).await?;
        }
        if let Some(f) = from {
            self.set_phase("moving to start");
            let max_speed = self
                .rig
                .axes
                .get(&axis)
                .map(|a| a.info().max_speed)
                .unwrap_or(speed);
            self.move_axis(axis, f, max_speed).await?;
        }
        let start = self.position(axis).await?;
        self.set_phase("creeping to contact");
        let Some(ax) = self.rig.axes.get_mut(&axis) else {
            return Ok(());
        };
        ax.move_to(start + max_travel, speed).await?;
        self.targets.insert(axis, start + max_travel);
        let channel = Channel::along(axis);
        self.wait(&mut Until::Contact {
            axis,
            channel,
            threshold: until_n,
        })
        .await?;
        if let Some(ax) = self.rig.axes.get_mut(&axis) {
            ax.stop().await?;
        }
        self.wait(&mut Until::Motion(vec![axis])).await?;
        let contact = self.position(axis).await?;
        self.origin.insert(axis, contact);
        self.targets.insert(axis, contact);
        let force = self
            .window
            .back()
            .map(|(_, w, _)| channel.of(w))
            .unwrap_or(0.0);
        self.rec.update_manifest(|m| {
            m.origins.insert(axis.to_string(), contact);
        })?;
        let t = self.now();
        self.rec.journal(
            t,
            "contact",
            json!({ "axis": axis, "position": contact, "force": force }),
            true,
        )?;
        self.progress.note(&format!(
            "contact: {axis} axis at {} (|{}| = {:.3})",
            fmt_value(contact),
            channel.name(),
            force.abs()
        ));
        Ok(())
    }

    async fn step(&mut self, s: &Step) -> Result<(), Stop> {
        self.step = s.step;
        self.step_saturated = false;
        let t_start = self.now();
        let unit = s.unit.map(|u| u.symbol()).unwrap_or("");
        self.what = match (s.axis, s.target) {
            (Some(a), Some(Target::To(v))) => {
                format!("{} {a} → {} {unit}", s.phase.name(), fmt_value(v))
            }
            (Some(a), Some(Target::By(v))) => {
                format!("{} {a} by {} {unit}", s.phase.name(), fmt_value(v))
            }
            _ => s.label.clone(),
        };
        let settle_window_ns = match s.settle {
            SettleSpec::Rate { window_s, .. } => (window_s * 1e9) as u64,
            _ => 0,
        };
        self.keep_ns = ((s.force_window_s * 1e9) as u64).max(settle_window_ns) + 1_000_000_000;
        self.rec.journal(
            t_start,
            "step_start",
            json!({ "step": s.step, "phase": s.phase.name(), "what": self.what }),
            false,
        )?;
        if let (Some(axis), Some(target)) = (s.axis, s.target) {
            self.set_phase("moving");
            let origin = self.origin.get(&axis).copied().unwrap_or(0.0);
            let abs = match target {
                Target::To(v) => origin + v,
                Target::By(v) => self.position(axis).await? + v,
            };
            self.move_axis(axis, abs, s.speed).await?;
        }
        if let Some(DisturbSpec {
            force_y_n,
            torque_z_nmm,
            frequency_hz,
            duration_s,
        }) = s.disturb
            && let Some(d) = self.rig.disturber.as_mut()
        {
            d.apply(force_y_n, torque_z_nmm, frequency_hz, duration_s)
                .await?;
        }
        let settle_start = self.now();
        let verdict = match s.settle {
            SettleSpec::None => "none",
            SettleSpec::Fixed { s: secs } => {
                self.set_phase(if s.disturb.is_some() {
                    "disturbing"
                } else {
                    "settling"
                });
                self.wait(&mut Until::Time(settle_start + (secs * 1e9) as u64))
                    .await?;
                "fixed"
            }
            SettleSpec::Rate {
                channel,
                below,
                window_s,
                min_s,
                max_s,
                on_timeout,
            } => {
                self.set_phase("settling");
                let mut track = Until::Settle(SettleTrack {
                    channel,
                    below,
                    window_ns: (window_s * 1e9) as u64,
                    start_ns: settle_start,
                    min_ns: (min_s * 1e9) as u64,
                    max_ns: (max_s * 1e9) as u64,
                    verdict: None,
                });
                self.wait(&mut track).await?;
                let verdict = match track {
                    Until::Settle(t) => t.verdict.unwrap_or("converged"),
                    _ => "converged",
                };
                if verdict == "timeout" {
                    let msg = format!(
                        "step {}: |d{}/dt| stayed above {} for the whole {} s settle",
                        s.step,
                        channel.name(),
                        fmt_value(below),
                        fmt_value(max_s)
                    );
                    if on_timeout == OnTimeout::Abort {
                        return Err(Stop::SettleTimeout(msg));
                    }
                    self.progress.note(&format!("warning: {msg}"));
                    self.rec.update_manifest(|m| m.warnings.push(msg))?;
                }
                verdict
            }
        };
        let settle_end = self.now();
        let settle_s = (settle_end - settle_start) as f64 * 1e-9;
        // Quasistatic value: mean over the last window (thesis §4.3), or the last sample.
        let t_end_window = self.now();
        let from = t_end_window.saturating_sub((s.force_window_s * 1e9) as u64);
        let in_window: Vec<Wrench> = if s.force_window_s > 0.0 {
            self.window
                .iter()
                .filter(|(t, _, _)| *t >= from)
                .map(|(_, w, _)| *w)
                .collect()
        } else {
            self.window.back().map(|(_, w, _)| *w).into_iter().collect()
        };
        let mean = (!in_window.is_empty()).then(|| Wrench::mean(in_window.iter().copied()));
        let channel = s.axis.map(Channel::along).unwrap_or(Channel::Fz);
        let std = mean.map(|m| {
            let c = channel.of(&m);
            (in_window
                .iter()
                .map(|w| (channel.of(w) - c).powi(2))
                .sum::<f64>()
                / in_window.len().max(1) as f64)
                .sqrt()
        });
        if s.frames > 0 {
            self.set_phase("capturing frames");
            self.wait(&mut Until::Frames(s.frames)).await?;
        }
        let (position_abs, position) = match s.axis {
            Some(a) => {
                let p = self.position(a).await?;
                (
                    Some(p),
                    Some(p - self.origin.get(&a).copied().unwrap_or(0.0)),
                )
            }
            None => (None, None),
        };
        let round = |v: f64| (v * 1e6).round() / 1e6 + 0.0;
        let row = StepRow {
            step: s.step,
            trial: self.trial,
            label: s.label.clone(),
            phase: s.phase.name().into(),
            axis: s.axis.map(|a| a.name().to_string()).unwrap_or_default(),
            target: match s.target {
                Some(Target::To(v)) => Some(round(v)),
                Some(Target::By(_)) => position.map(round),
                None => None,
            },
            position: position.map(round),
            unit: unit.into(),
            fx_n: mean.map(|m| round(m.fx_n)),
            fy_n: mean.map(|m| round(m.fy_n)),
            fz_n: mean.map(|m| round(m.fz_n)),
            tx_nmm: mean.map(|m| round(m.tx_nmm)),
            ty_nmm: mean.map(|m| round(m.ty_nmm)),
            tz_nmm: mean.map(|m| round(m.tz_nmm)),
            settle_s: round(settle_s),
            settle_verdict: verdict.into(),
            force_window_s: s.force_window_s,
            window_samples: in_window.len() as u32,
            window_std: std.map(round),
            saturated: self.step_saturated,
            frames: s.frames,
            position_abs: position_abs.map(round),
            t_start_ns: t_start,
            settle_end_ns: settle_end,
            t_end_ns: self.now(),
        };
        self.rec.step(&row)?;
        if let Some(sensor) = self.rig.force.as_mut()
            && let Some(truth) = sensor.truth().await
        {
            self.rec.sim_truth(s.step, self.trial, &truth)?;
        }
        let steps_done = row.step;
        self.rec
            .update_manifest(|m| m.steps_completed = steps_done)?;
        let t = self.now();
        self.rec.journal(t, "step_end", json!(row), true)?;
        let summary = match mean {
            Some(m) => format!(
                "{}: Fz {:.3} N, Fx {:.3} N, Tz {:.3} N·mm; settled {:.0} s ({verdict})",
                self.what, m.fz_n, m.fx_n, m.tz_nmm, settle_s
            ),
            None => format!("{}: settled {:.0} s ({verdict})", self.what, settle_s),
        };
        self.progress.step_done(s.step, &summary);
        self.step = 0;
        Ok(())
    }

    /// Moves `group` to their retract positions together and waits, with a deadline from
    /// distance and speed.
    async fn retract_group(&mut self, group: &[(AxisRole, f64)], errors: &mut Vec<String>) {
        let mut moving = Vec::new();
        let mut deadline_s: f64 = 5.0;
        for &(role, target) in group {
            let Some(ax) = self.rig.axes.get_mut(&role) else {
                continue;
            };
            let info = ax.info().clone();
            let here = match ax.status().await {
                Ok(st) if !st.referenced => {
                    errors.push(format!(
                        "{role} axis is not referenced, so it was left where it is"
                    ));
                    continue;
                }
                Ok(st) => st.position,
                Err(e) => {
                    errors.push(format!("reading {role}: {e}"));
                    continue;
                }
            };
            match ax.move_to(target, info.max_speed).await {
                Ok(()) => {
                    moving.push(role);
                    self.targets.insert(role, target);
                    deadline_s = deadline_s.max(2.0 * (here - target).abs() / info.max_speed + 5.0);
                }
                Err(e) => errors.push(format!("retracting {role}: {e}")),
            }
        }
        if moving.is_empty() {
            return;
        }
        let deadline = self.now() + (deadline_s * 1e9) as u64;
        loop {
            if self.cancel.count() >= 2 {
                errors.push("a second interrupt abandoned the retract".into());
                return;
            }
            match self.all_stopped(&moving).await {
                Ok(true) => return,
                Ok(false) => {}
                Err(e) => {
                    errors.push(e.to_string());
                    return;
                }
            }
            if self.now() >= deadline {
                errors.push(format!(
                    "the retract did not finish within {deadline_s:.0} s"
                ));
                return;
            }
            let now = self.now();
            if self.wait(&mut Until::Time(now + 50_000_000)).await.is_err()
                && self.cancel.count() >= 2
            {
                errors.push("a second interrupt abandoned the retract".into());
                return;
            }
        }
    }

    /// Stops everything and sends each axis with a retract position there.
    async fn retract(&mut self) -> Result<(), String> {
        self.retracting = true;
        self.step = 0;
        self.what = "retract".into();
        self.set_phase("retracting");
        let mut errors = Vec::new();
        let roles: Vec<AxisRole> = self.rig.axes.keys().copied().collect();
        for role in &roles {
            if let Some(ax) = self.rig.axes.get_mut(role)
                && let Err(e) = ax.stop().await
            {
                errors.push(format!("stopping {role}: {e}"));
            }
        }
        // Pressing axes first, to completion: moving a tangential axis while the indenter
        // still touches would drag the elastomer.
        for pressing in [true, false] {
            let order: Vec<(AxisRole, f64)> = self
                .retract_to
                .iter()
                .filter(|(r, _)| r.presses() == pressing)
                .map(|(r, v)| (*r, *v))
                .collect();
            self.retract_group(&order, &mut errors).await;
            if self.cancel.count() >= 2 {
                break;
            }
        }
        let mut finals = BTreeMap::new();
        for role in &roles {
            if let Some(ax) = self.rig.axes.get_mut(role)
                && let Ok(st) = ax.status().await
            {
                finals.insert(role.to_string(), (st.position * 1e6).round() / 1e6);
            }
        }
        let t = self.now();
        let _ = self.rec.journal(
            t,
            "retract",
            json!({ "final_positions": finals, "errors": errors }),
            true,
        );
        let _ = self
            .rec
            .update_manifest(|m| m.final_positions = finals.clone());
        if errors.is_empty() {
            self.progress.note(&format!(
                "retracted: {}",
                finals
                    .iter()
                    .map(|(k, v)| format!("{k} {}", fmt_value(*v)))
                    .collect::<Vec<_>>()
                    .join(", ")
            ));
            Ok(())
        } else {
            Err(errors.join("; "))
        }
    }
}
