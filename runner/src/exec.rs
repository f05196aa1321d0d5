//! The plan task's state, the action loop, and how it takes the watchdog's readings.

use std::collections::{BTreeMap, VecDeque};

use rig::config::AxisRole;
use rig::{Clock, STATUS_SATURATED, Wrench};
use serde_json::json;
use simbench::Rig;

use super::watchdog::{Monitor, TripKind};
use super::{Cancel, Stop, trip_record};
use crate::progress::Progress;
use experiments::load::Loaded;
use experiments::protocol::compile::{Action, ActionKind, StreamRates};
use rundir::write::{Recorder, Status};

/// The scopes of stream rates the plan is inside, and the schedules they give.
#[derive(Default)]
pub(super) struct Streams {
    /// The rates of each open scope, outermost first.
    pub(super) scopes: Vec<StreamRates>,
    /// The rates in force: the scopes overlaid.
    pub(super) active: StreamRates,
    /// When the axes are next recorded, ns; `None` without an axes stream.
    pub(super) next_axes_ns: Option<u64>,
    /// When the next stream frame is due, ns; `None` without a frame stream (or camera).
    pub(super) next_frame_ns: Option<u64>,
}

/// The watchdog's readings as the plan keeps them.
#[derive(Default)]
pub(super) struct Readings {
    /// Recent tared samples (t, wrench, status), kept for settle and capture windows. With
    /// a force stream on, only the samples written to force.csv, so the quasistatic values
    /// in steps.csv can be recomputed from the run directory.
    pub(super) window: VecDeque<(u64, Wrench, u32)>,
    /// The newest tared sample, recorded or not (contact detection uses every reading).
    pub(super) latest: Option<(u64, Wrench)>,
    /// The time of the newest sample the plan had before `latest`'s batch, ns: with it, how
    /// late the plan can have noticed a threshold crossed (a scaled clock's loop latency, a
    /// slow reader).
    pub(super) previous_latest_ns: Option<u64>,
    /// How far back `window` must reach, ns (at least 2 s are kept).
    pub(super) keep_ns: u64,
}

/// A move that stops on a tactile condition.
#[derive(Default)]
pub(super) struct SlipStop {
    /// The running move stops when the tactile state reaches this.
    pub(super) stop_at: Option<analysis::tactile::SlipState>,
    /// The tactile stop was reached during the current move.
    pub(super) hit: bool,
}

/// The plan task.
pub(super) struct Exec<'a> {
    pub(super) rig: Rig,
    /// The watchdog, when the protocol uses a force sensor.
    pub(super) monitor: Option<Monitor>,
    pub(super) clock: Clock,
    pub(super) rec: Recorder,
    pub(super) progress: &'a Progress,
    pub(super) cancel: Cancel,
    pub(super) poll_period_ns: BTreeMap<AxisRole, u64>,
    /// The rig file's axes (in-position windows, start grace, retries).
    pub(super) loaded_axes: BTreeMap<AxisRole, rig::config::AxisConfig>,
    /// Trials of the protocol's repeated blocks, all told.
    pub(super) trials_total: u32,
    pub(super) retract_to: BTreeMap<AxisRole, f64>,
    pub(super) tare: Wrench,
    pub(super) origin: BTreeMap<AxisRole, f64>,
    pub(super) targets: BTreeMap<AxisRole, f64>,
    /// The streams' rates and when each is next due.
    pub(super) streams: Streams,
    pub(super) step: u32,
    pub(super) trial: u32,
    /// The watchdog's readings as the plan keeps them.
    pub(super) readings: Readings,
    /// What the run has learned of the gel's relaxation (adaptive settling).
    pub(super) gel: super::adaptive::GelMemory,
    pub(super) step_saturated: bool,
    pub(super) retracting: bool,
    pub(super) what: String,
    pub(super) phase: &'static str,
    /// The live tactile path, while a record block captures frames.
    pub(super) tactile: Option<super::tactile::LiveTactile>,
    /// The camera's image scale, mm/px (for contact areas), when the protocol gives a view.
    pub(super) mm_per_px: Option<f64>,
    /// The sensor file of `record.gelsight_force`, read before the run starts.
    pub(super) gelsight: Option<std::sync::Arc<sensing::sensor::SensorFile>>,
    /// The running move's tactile stop.
    pub(super) slip: SlipStop,
    /// Where a resumed run continues, and what it replays first.
    pub(super) resume: Option<super::Resume>,
}

impl<'a> Exec<'a> {
    pub(super) fn new(
        rig: Rig,
        monitor: Option<Monitor>,
        clock: Clock,
        rec: Recorder,
        progress: &'a Progress,
        cancel: Cancel,
        loaded: &Loaded,
    ) -> Self {
        Self {
            poll_period_ns: loaded
                .rig
                .axes
                .iter()
                .map(|(r, a)| (*r, super::period_ns(a.poll_rate_hz())))
                .collect(),
            loaded_axes: loaded.rig.axes.clone(),
            trials_total: loaded
                .compiled
                .actions
                .iter()
                .filter(|a| matches!(a.kind, ActionKind::TrialBegin))
                .count() as u32,
            retract_to: loaded
                .protocol
                .safety
                .retract
                .iter()
                .filter_map(|(r, q)| {
                    (!matches!(q, rig::units::AxisQuantity::Percent(_))).then_some((*r, q.raw()))
                })
                .collect(),
            rig,
            monitor,
            clock,
            rec,
            progress,
            cancel,
            tare: Wrench::default(),
            origin: BTreeMap::new(),
            targets: BTreeMap::new(),
            streams: Streams::default(),
            step: 0,
            trial: 0,
            readings: Readings::default(),
            gel: Default::default(),
            step_saturated: false,
            retracting: false,
            what: String::new(),
            phase: "starting",
            tactile: None,
            mm_per_px: None,
            gelsight: None,
            slip: SlipStop::default(),
            resume: None,
        }
    }

    pub(super) fn now(&self) -> u64 {
        self.clock.now_ns()
    }

    pub(super) fn t_s(&self) -> f64 {
        self.now() as f64 * 1e-9
    }

    /// An interrupt, or a watchdog trip, ends the plan (during the retract only a second
    /// interrupt does).
    pub(super) fn check_stop(&self) -> Result<(), Stop> {
        let n = self.cancel.count();
        if n >= 2 || (n >= 1 && !self.retracting) {
            return Err(Stop::Interrupted);
        }
        if !self.retracting
            && let Some(t) = self.monitor.as_ref().and_then(|m| m.trip())
        {
            return Err(match t.kind {
                TripKind::Limit => Stop::Safety(t.message),
                TripKind::Sensor => Stop::Blind(t.message),
            });
        }
        Ok(())
    }

    pub(super) fn set_phase(&mut self, phase: &'static str) {
        self.phase = phase;
        let t = self.t_s();
        self.progress.phase(self.step, &self.what, phase, t);
    }

    /// Takes the watchdog's readings: tare, saturation, window, record. True if any came.
    pub(super) fn drain(&mut self) -> Result<bool, Stop> {
        let Some(m) = &self.monitor else {
            return Ok(false);
        };
        let readings = m.take();
        if readings.is_empty() {
            return Ok(false);
        }
        let stream_on = self.streams.active.force_hz.is_some();
        self.readings.previous_latest_ns = self.readings.latest.map(|(t, _)| t);
        for r in readings {
            let s = r.sample;
            let w = s.wrench.minus(&self.tare);
            if s.status & STATUS_SATURATED != 0 {
                self.step_saturated = true;
            }
            if r.record || !stream_on {
                self.readings.window.push_back((s.t_ns, w, s.status));
            }
            self.readings.latest = Some((s.t_ns, w));
            if r.record {
                self.progress
                    .force(s.t_ns, [w.fx_n, w.fy_n, w.fz_n, w.tz_nmm]);
            } else if let Some(b) = self.progress.live() {
                b.force(s.t_ns, [w.fx_n, w.fy_n, w.fz_n, w.tz_nmm]);
            }
            if r.record {
                self.rec.force(&s, &w, self.step, self.trial)?;
            }
        }
        if let Some(b) = self.progress.live() {
            b.lost_records(m.records_lost());
        }
        let keep_from = self
            .now()
            .saturating_sub(self.readings.keep_ns.max(2_000_000_000));
        while self
            .readings
            .window
            .front()
            .is_some_and(|(t, _, _)| *t < keep_from)
        {
            self.readings.window.pop_front();
        }
        Ok(true)
    }

    pub(super) async fn run_actions(&mut self, actions: &[Action]) -> Result<(), Stop> {
        for action in actions {
            self.check_stop()?;
            // A resumed run does not repeat a trial it completed.
            if self
                .resume
                .as_ref()
                .is_some_and(|r| r.skips_trial(action.trial))
            {
                continue;
            }
            self.trial = action.trial;
            match &action.kind {
                ActionKind::Home { axes } => self.home(axes).await?,
                ActionKind::Approach(a) => self.approach(a).await?,
                ActionKind::Tare { duration_s } => self.tare(*duration_s).await?,
                ActionKind::Step(s) if self.before_resume(s.step) => self.replay(s).await?,
                ActionKind::Step(s) => self.step(s).await?,
                ActionKind::StreamsBegin(r) => {
                    self.streams.scopes.push(*r);
                    self.restream();
                    let t = self.now();
                    self.rec.journal(t, "streams_begin", json!(r), false)?;
                }
                ActionKind::StreamsEnd => {
                    self.streams.scopes.pop();
                    self.restream();
                    let t = self.now();
                    self.rec.journal(t, "streams_end", json!({}), false)?;
                }
                ActionKind::TrialBegin => {
                    let t = self.now();
                    self.rec
                        .journal(t, "trial_begin", json!({ "trial": action.trial }), true)?;
                    let of = self.trials_total;
                    self.progress.set_trial(action.trial, of);
                    self.progress
                        .note(&format!("trial {}/{of} begins", action.trial));
                }
                ActionKind::TrialEnd => {
                    let t = self.now();
                    self.rec
                        .journal(t, "trial_end", json!({ "trial": action.trial }), true)?;
                    self.progress.set_trial(0, self.trials_total);
                }
            }
        }
        Ok(())
    }

    /// Recomputes the active stream rates after a scope change.
    fn restream(&mut self) {
        self.streams.active = self
            .streams
            .scopes
            .iter()
            .fold(StreamRates::default(), |acc, s| acc.overlay(s));
        let now = self.now();
        if let Some(m) = &self.monitor {
            m.set_stream(self.streams.active.force_hz);
        }
        self.streams.next_axes_ns = self.streams.active.axes_hz.map(|_| now);
        self.streams.next_frame_ns = self
            .streams
            .active
            .frames_hz
            .filter(|_| self.rig.camera.is_some())
            .map(|_| now);
        // Continuous frames feed the live tactile path; a new block starts a new reference.
        if self.streams.next_frame_ns.is_some() {
            if self.tactile.is_none() {
                let mut t =
                    super::tactile::LiveTactile::new(self.mm_per_px, self.gelsight.as_deref());
                t.want_overlay = self.progress.live().is_some();
                self.tactile = Some(t);
            }
        } else if self.tactile.take().is_some() {
            self.progress.set_tactile(None);
        }
    }

    /// How the plan ended: journals the stop and the watchdog's trip, if any.
    pub(super) async fn stopped(&mut self, result: Result<(), Stop>) -> (Status, Option<String>) {
        let trip = match &self.monitor {
            Some(m) => m.settled_trip().await,
            None => None,
        };
        let t = self.now();
        if let Some(trip) = &trip {
            let record = trip_record(trip);
            let _ = self.rec.journal(t, "safety_trip", record, true);
            let event = format!(
                "{} (sample at {:.3} s, stop sent at {:.3} s, {:.0} µs after detection)",
                trip.message,
                trip.t_sample_ns as f64 * 1e-9,
                trip.t_stop_sent_ns as f64 * 1e-9,
                trip.detect_to_stop_wall_us
            );
            let _ = self.rec.update_manifest(|m| m.safety_events.push(event));
        }
        match result {
            Ok(()) => (Status::Completed, None),
            Err(stop) => {
                let msg = stop.to_string();
                self.progress.note(&format!("stopping: {msg}"));
                let _ = self.rec.journal(
                    t,
                    "stop",
                    json!({ "reason": msg, "status": stop.status().name() }),
                    true,
                );
                (stop.status(), Some(msg))
            }
        }
    }

    /// Ends the watchdog and hands back the recorder, journaling what the watchdog saw
    /// after it was disarmed.
    pub(super) async fn close(mut self) -> Recorder {
        let mut timing = BTreeMap::new();
        if let Some(t) = self.rig.camera.as_ref().and_then(|c| c.timing()) {
            timing.insert("camera".to_string(), t);
        }
        if let Some(t) = match &self.monitor {
            Some(m) => m.sensor_timing().await,
            None => None,
        } {
            timing.insert("force".to_string(), t);
        }
        if !timing.is_empty() {
            let _ = self.rec.update_manifest(|m| m.timing = timing);
        }
        if let Some(mut m) = self.monitor.take() {
            m.shutdown().await;
            let late = m.late_errors();
            let dropped = m.dropped();
            if !late.is_empty() || dropped > 0 {
                let t = self.clock.now_ns();
                let _ = self.rec.journal(
                    t,
                    "watchdog",
                    json!({ "errors_after_stop": late, "readings_dropped": dropped }),
                    true,
                );
            }
        }
        self.rec
    }
}
