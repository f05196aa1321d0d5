//! The safety watchdog: a task of its own that nothing in the plan can starve.
//!
//! It owns the force sensor and reads it on the run's clock at the safety monitor's rate
//! (and at the force stream's rate while one records), whatever the plan task is doing —
//! waiting for a stage that answers slowly, retrying a garbled reply, encoding a frame.
//! Every reading is judged before the plan sees it:
//!
//! - a limit crossed (|Fz|, |Fxy|, |Tz|, or the sensor's own saturation bit) is a safety
//!   trip;
//! - a non-finite value, a sample older than the freshness bound (two monitor periods,
//!   never less than two of the sensor's own sample periods nor, on a scaled clock, 250 ms
//!   of wall time), a read that does not return within that bound, or a read error (a
//!   sequence jump the driver cannot explain, a garbled datagram, a timeout) is a sensor
//!   fault: the monitor is blind, which is as dangerous as a limit.
//!
//! On either, it stops every axis at once through each axis's [`AxisStopper`] — pressing
//! axes first — without waiting for the plan task, records the trip with its timing
//! (sample, detection, last stop sent), and wakes the plan task, which retracts the
//! pressing axes through its normal exit — whose first act is to stop every axis again, so
//! a move the plan had in flight when the trip happened cannot outlive the plan's call
//! (orchestration spec, "a safety envelope checked twice").
//!
//! Readings go to the plan task through a bounded queue; the plan tares, windows and
//! records them. The watchdog judges limits on the same tare, which the plan hands it.

use std::collections::VecDeque;
use std::sync::{Arc, Mutex};

use rig::config::AxisRole;
use rig::units::fmt_value;
use rig::{AxisStopper, Clock, ForceRange, ForceSample, ForceSensor, STATUS_SATURATED, SimTruth};
use rig::{Wrench, lock};
use tokio::sync::Notify;

/// Readings kept for the plan task before the oldest are dropped: 10 minutes at 1 kHz.
/// The plan task drains the queue at every wake-up and every driver call it makes has a
/// deadline, so reaching this means the plan task is stuck, not busy.
const QUEUE_CAP: usize = 600_000;

/// Samples kept for matching frames: 3 s, and at most 3 s at 7 kHz.
const HISTORY_NS: u64 = 3_000_000_000;
const HISTORY_CAP: usize = 21_000;

/// The safety limits of the protocol, on tared values.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Limits {
    pub(crate) max_fz_n: f64,
    pub(crate) max_fxy_n: f64,
    pub(crate) max_tz_nmm: f64,
}

/// How the watchdog reads and judges.
#[derive(Debug, Clone, Copy)]
pub(crate) struct WatchConfig {
    /// Period of the safety monitor, ns (`safety.monitor_rate`).
    pub(crate) monitor_period_ns: u64,
    /// A sample older than this is stale, and a read longer than this is a blind monitor, ns.
    pub(crate) stale_ns: u64,
    /// The sensor's ranges, for the saturation message.
    pub(crate) range: ForceRange,
}

impl WatchConfig {
    /// The freshness bound: two monitor periods, but never less than two of the sensor's
    /// own sample periods (it cannot deliver faster) nor, on a scaled clock, 250 ms of wall
    /// time times the scale. A scaled clock runs only simulated devices — in-process or the
    /// wire twins — whose stream pauses whenever the machine is busy elsewhere; K× faster,
    /// such a pause reads as a sensor silent for K× as long. 50 ms was too little on a
    /// loaded machine: with two test threads and their runs on two cores, scaled runs saw
    /// the wire twin's stream pause 50–85 ms and stopped (docs/benchmarks/ci.md).
    pub(crate) fn stale_bound_ns(
        monitor_period_ns: u64,
        sensor_rate_hz: f64,
        scaled: Option<f64>,
    ) -> u64 {
        let sensor_ns = if sensor_rate_hz > 0.0 {
            (2e9 / sensor_rate_hz) as u64
        } else {
            0
        };
        let wall_ns = scaled.map(|k| (250e6 * k) as u64).unwrap_or(0);
        (2 * monitor_period_ns).max(sensor_ns).max(wall_ns)
    }
}

/// One reading handed to the plan task.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Reading {
    /// The sample, untared.
    pub(crate) sample: ForceSample,
    /// Taken on the force stream's schedule (written to force.csv), not only the monitor's.
    pub(crate) record: bool,
}

/// Why the watchdog stopped the bench.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum TripKind {
    /// A safety limit was crossed.
    Limit,
    /// The monitor went blind: stale, non-finite or failed readings.
    Sensor,
}

/// A trip, with its timing.
#[derive(Debug, Clone)]
pub(crate) struct Trip {
    pub(crate) kind: TripKind,
    pub(crate) message: String,
    /// Host time of the sample that showed the fault (the last good one for a blind
    /// monitor), ns on the run's clock.
    pub(crate) t_sample_ns: u64,
    /// When the watchdog judged it, ns.
    pub(crate) t_detect_ns: u64,
    /// When the last stop command had been sent, ns.
    pub(crate) t_stop_sent_ns: u64,
    /// Wall time from the judgement to the last stop sent, µs: the part of the trip latency
    /// that is gelrig's own (the sampling period bounds the rest).
    pub(crate) detect_to_stop_wall_us: f64,
    /// The tared reading that tripped it (`None` for a sensor fault without a reading).
    pub(crate) reading: Option<Wrench>,
    /// Stops that could not be sent.
    pub(crate) stop_errors: Vec<String>,
    /// Every stop has been sent (the timing above is final).
    pub(crate) stops_sent: bool,
}

struct State {
    readings: VecDeque<Reading>,
    /// Every sample of the last few seconds, untared (the sensor's full stream where it
    /// keeps one, else what was read): frames are matched to the force inside their
    /// exposure from it.
    history: VecDeque<ForceSample>,
    /// The next read is due now (a frame waits for the force of its exposure).
    read_now: bool,
    dropped: u64,
    /// Records the sensor's own sequence lost, as of its last reading.
    sensor_lost: u64,
    stream_hz: Option<f64>,
    stream_epoch: u64,
    tare: Wrench,
    /// Limits and faults are judged (off once tripped and during the final retract).
    armed: bool,
    step: u32,
    trip: Option<Trip>,
    /// Sensor errors after the monitor was disarmed (kept for the journal).
    late_errors: Vec<String>,
    quit: bool,
}

/// Everything the watchdog task owns or shares.
struct Watch {
    state: Arc<Mutex<State>>,
    sensor: Arc<tokio::sync::Mutex<Box<dyn ForceSensor>>>,
    stoppers: Vec<(AxisRole, Arc<dyn AxisStopper>)>,
    limits: Limits,
    config: WatchConfig,
    clock: Clock,
    wake_plan: Arc<Notify>,
    alarm: Arc<Notify>,
    wake_watchdog: Arc<Notify>,
    trip_done: Arc<Notify>,
}

/// The plan task's handle on the running watchdog.
pub(crate) struct Monitor {
    state: Arc<Mutex<State>>,
    sensor: Arc<tokio::sync::Mutex<Box<dyn ForceSensor>>>,
    wake_plan: Arc<Notify>,
    alarm: Arc<Notify>,
    wake_watchdog: Arc<Notify>,
    trip_done: Arc<Notify>,
    task: Option<tokio::task::JoinHandle<()>>,
    /// The longest the plan waits between two readings, ns (the monitor's period).
    reading_period_ns: u64,
}

impl Monitor {
    /// Starts the watchdog on `sensor`, able to stop every axis in `stoppers`.
    pub(crate) fn start(
        sensor: Box<dyn ForceSensor>,
        mut stoppers: Vec<(AxisRole, Arc<dyn AxisStopper>)>,
        limits: Limits,
        config: WatchConfig,
        clock: Clock,
    ) -> Self {
        // Pressing axes first: they are the ones that can hurt the gel.
        stoppers.sort_by_key(|(r, _)| !r.presses());
        let state = Arc::new(Mutex::new(State {
            readings: VecDeque::new(),
            history: VecDeque::new(),
            read_now: false,
            dropped: 0,
            sensor_lost: 0,
            stream_hz: None,
            stream_epoch: 0,
            tare: Wrench::default(),
            armed: true,
            step: 0,
            trip: None,
            late_errors: Vec::new(),
            quit: false,
        }));
        let sensor = Arc::new(tokio::sync::Mutex::new(sensor));
        let wake_plan = Arc::new(Notify::new());
        let alarm = Arc::new(Notify::new());
        let wake_watchdog = Arc::new(Notify::new());
        let trip_done = Arc::new(Notify::new());
        let reading_period_ns = config.monitor_period_ns;
        let watch = Watch {
            state: state.clone(),
            sensor: sensor.clone(),
            stoppers,
            limits,
            config,
            clock,
            wake_plan: wake_plan.clone(),
            alarm: alarm.clone(),
            wake_watchdog: wake_watchdog.clone(),
            trip_done: trip_done.clone(),
        };
        let task = tokio::spawn(watch.run());
        Self {
            state,
            sensor,
            wake_plan,
            alarm,
            wake_watchdog,
            trip_done,
            task: Some(task),
            reading_period_ns,
        }
    }

    /// The longest interval between two readings the plan sees, ns: how late a threshold
    /// crossing can be noticed.
    pub(crate) fn reading_period_ns(&self) -> u64 {
        self.reading_period_ns
    }

    /// Asks for a read now rather than at the next scheduled one.
    pub(crate) fn read_soon(&self) {
        lock(&self.state).read_now = true;
        self.wake_watchdog.notify_one();
    }

    /// The time of the newest sample in the history, ns.
    pub(crate) fn history_until_ns(&self) -> Option<u64> {
        lock(&self.state).history.back().map(|s| s.t_ns)
    }

    /// The samples of the history from `from_ns` to `to_ns`, with the one just before and
    /// the one just after (for interpolation), oldest first.
    pub(crate) fn history_around(&self, from_ns: u64, to_ns: u64) -> Vec<ForceSample> {
        let s = lock(&self.state);
        let h = &s.history;
        let first = h.partition_point(|x| x.t_ns < from_ns).saturating_sub(1);
        let end = (h.partition_point(|x| x.t_ns <= to_ns) + 1).min(h.len());
        h.range(first..end.max(first)).copied().collect()
    }

    /// Takes every reading queued since the last call, oldest first.
    pub(crate) fn take(&self) -> VecDeque<Reading> {
        std::mem::take(&mut lock(&self.state).readings)
    }

    /// Force records lost: missing from the sensor's sequence, or dropped because the plan
    /// task did not take them in time.
    pub(crate) fn records_lost(&self) -> u64 {
        let s = lock(&self.state);
        s.sensor_lost + s.dropped
    }

    /// Readings dropped because the plan task did not take them in time.
    pub(crate) fn dropped(&self) -> u64 {
        lock(&self.state).dropped
    }

    /// Starts (or stops, with `None`) reading on the force stream's schedule, from now.
    pub(crate) fn set_stream(&self, hz: Option<f64>) {
        {
            let mut s = lock(&self.state);
            s.stream_hz = hz;
            s.stream_epoch += 1;
        }
        self.wake_watchdog.notify_one();
    }

    /// The offset limits are judged against (the plan's tare).
    pub(crate) fn set_tare(&self, tare: Wrench) {
        lock(&self.state).tare = tare;
    }

    /// The step in progress, for trip messages.
    pub(crate) fn set_step(&self, step: u32) {
        lock(&self.state).step = step;
    }

    /// The plan task is retracting: limits and faults are no longer judged (the retract is
    /// the response to them), readings keep coming for the record.
    pub(crate) fn begin_retract(&self) {
        lock(&self.state).armed = false;
    }

    /// The trip, if the watchdog tripped.
    pub(crate) fn trip(&self) -> Option<Trip> {
        lock(&self.state).trip.clone()
    }

    /// The trip once its stops have all been sent (so its timing is final); `None` if the
    /// watchdog did not trip. The stops are bounded by the drivers' timeouts.
    pub(crate) async fn settled_trip(&self) -> Option<Trip> {
        loop {
            let done = self.trip_done.notified();
            tokio::pin!(done);
            done.as_mut().enable();
            match self.trip() {
                Some(t) if !t.stops_sent => done.await,
                other => return other,
            }
        }
    }

    /// Sensor errors seen after the monitor was disarmed.
    pub(crate) fn late_errors(&self) -> Vec<String> {
        lock(&self.state).late_errors.clone()
    }

    /// Resolves when the watchdog has a new reading (or a trip). A notification sent
    /// while nobody waits is kept for the next call.
    pub(crate) async fn reading(&self) {
        self.wake_plan.notified().await;
    }

    /// Resolves when the watchdog trips.
    pub(crate) async fn tripped(&self) {
        self.alarm.notified().await;
    }

    /// How the sensor's sample times are put on the run's timebase.
    pub(crate) async fn sensor_timing(&self) -> Option<rig::DeviceTiming> {
        self.sensor.lock().await.timing()
    }

    /// Ground truth of a simulated sensor.
    pub(crate) async fn truth(&self) -> Option<SimTruth> {
        self.sensor.lock().await.truth().await
    }

    /// Ends the watchdog task and waits for it.
    pub(crate) async fn shutdown(&mut self) {
        lock(&self.state).quit = true;
        self.wake_watchdog.notify_one();
        if let Some(t) = self.task.take() {
            let _ = t.await;
        }
    }
}

impl Drop for Monitor {
    fn drop(&mut self) {
        lock(&self.state).quit = true;
        self.wake_watchdog.notify_one();
        if let Some(t) = self.task.take() {
            t.abort();
        }
    }
}

/// What one read produced.
enum Outcome {
    Sample(ForceSample),
    Error(String),
    Silent,
}

impl Watch {
    async fn run(self) {
        let mut next_monitor = self.clock.now_ns();
        let mut next_stream: Option<u64> = None;
        let mut epoch = u64::MAX;
        let mut last_good_ns: Option<u64> = None;
        loop {
            let (stream_hz, e, quit) = {
                let s = lock(&self.state);
                (s.stream_hz, s.stream_epoch, s.quit)
            };
            if quit {
                return;
            }
            let now = self.clock.now_ns();
            if e != epoch {
                epoch = e;
                next_stream = stream_hz.map(|_| now);
                // One phase for both schedules: at equal (or multiple) rates they read
                // together instead of interleaving at twice the rate.
                if stream_hz.is_some() {
                    next_monitor = now;
                }
            }
            let stream_due = next_stream.is_some_and(|t| now >= t);
            let monitor_due = now >= next_monitor;
            // An extra read a frame asked for: the schedules stay as they are.
            let asked = std::mem::take(&mut lock(&self.state).read_now);
            if stream_due || monitor_due || asked {
                let outcome = self.read().await;
                let now = self.clock.now_ns();
                match outcome {
                    Outcome::Sample(s) => {
                        let verdict = self.judge(&s, now);
                        if verdict.is_none() {
                            last_good_ns = Some(s.t_ns);
                        }
                        self.push(Reading {
                            sample: s,
                            record: stream_due,
                        });
                        if let Some((kind, msg)) = verdict {
                            let tare = lock(&self.state).tare;
                            let reading = Some(s.wrench.minus(&tare))
                                .filter(|w| w.as_array().iter().all(|v| v.is_finite()));
                            self.trip(kind, msg, s.t_ns, now, reading).await;
                        }
                    }
                    Outcome::Error(msg) => {
                        let t = last_good_ns.unwrap_or(now);
                        self.fault(msg, t, now).await;
                    }
                    Outcome::Silent => {
                        let msg = format!(
                            "the force sensor gave no sample within {} ms",
                            fmt_value(self.config.stale_ns as f64 * 1e-6)
                        );
                        let t = last_good_ns.unwrap_or(now);
                        self.fault(msg, t, now).await;
                    }
                }
                self.wake_plan.notify_one();
                let now = self.clock.now_ns();
                if stream_due && let (Some(t), Some(hz)) = (next_stream, stream_hz) {
                    let p = super::period_ns(hz);
                    next_stream = Some(if t + p <= now { now + p } else { t + p });
                }
                if monitor_due {
                    let p = self.config.monitor_period_ns;
                    next_monitor = if next_monitor + p <= now {
                        now + p
                    } else {
                        next_monitor + p
                    };
                }
            }
            let next = [Some(next_monitor), next_stream]
                .into_iter()
                .flatten()
                .min()
                .unwrap_or(next_monitor);
            tokio::select! {
                _ = self.clock.sleep_until_ns(next) => {}
                _ = self.wake_watchdog.notified() => {}
            }
        }
    }

    /// One read, bounded by the freshness bound on the run's clock.
    async fn read(&self) -> Outcome {
        let deadline = self.clock.now_ns() + self.config.stale_ns;
        let read = async {
            let mut sensor = self.sensor.lock().await;
            let r = sensor.read().await;
            let received = sensor.take_received();
            let mut s = lock(&self.state);
            s.sensor_lost = sensor.records_lost();
            match (&r, received.is_empty()) {
                (Ok(x), true) => s.history.push_back(*x),
                _ => s.history.extend(received),
            }
            let newest = s.history.back().map_or(0, |x| x.t_ns);
            while s.history.len() > HISTORY_CAP
                || s.history
                    .front()
                    .is_some_and(|x| x.t_ns + HISTORY_NS < newest)
            {
                s.history.pop_front();
            }
            drop(s);
            r
        };
        // Biased: a sensor that answers at once (the simulated one, a queued datagram)
        // never registers the timeout's timer.
        tokio::select! {
            biased;
            r = read => match r {
                Ok(s) => Outcome::Sample(s),
                Err(e) => Outcome::Error(format!("the force sensor failed: {e}")),
            },
            _ = self.clock.sleep_until_ns(deadline) => Outcome::Silent,
        }
    }

    /// A fault of the sensor itself: judged only while armed.
    async fn fault(&self, msg: String, t_sample_ns: u64, now: u64) {
        let armed = lock(&self.state).armed;
        if armed {
            self.trip(TripKind::Sensor, msg, t_sample_ns, now, None)
                .await;
        } else {
            let mut s = lock(&self.state);
            if s.late_errors.len() < 20 {
                s.late_errors.push(msg);
            }
        }
    }

    fn push(&self, r: Reading) {
        let mut s = lock(&self.state);
        if s.readings.len() >= QUEUE_CAP {
            s.readings.pop_front();
            s.dropped += 1;
        }
        s.readings.push_back(r);
    }

    /// What is wrong with this sample, if anything.
    fn judge(&self, s: &ForceSample, now: u64) -> Option<(TripKind, String)> {
        let (armed, tare, step) = {
            let st = lock(&self.state);
            (st.armed, st.tare, st.step)
        };
        if !armed {
            return None;
        }
        let in_step = |m: String| {
            if step > 0 {
                format!("{m} (step {step})")
            } else {
                m
            }
        };
        if let Some(bad) = s.wrench.as_array().iter().find(|v| !v.is_finite()) {
            return Some((
                TripKind::Sensor,
                in_step(format!(
                    "the force sensor reported a non-finite value ({bad})"
                )),
            ));
        }
        let age_ns = now.saturating_sub(s.t_ns);
        if age_ns > self.config.stale_ns {
            return Some((
                TripKind::Sensor,
                in_step(format!(
                    "the newest force sample is {} ms old (bound {} ms): the sensor stopped streaming",
                    fmt_value((age_ns as f64 * 1e-6).round()),
                    fmt_value(self.config.stale_ns as f64 * 1e-6)
                )),
            ));
        }
        let w = s.wrench.minus(&tare);
        let l = &self.limits;
        let range = &self.config.range;
        let msg = if s.status & STATUS_SATURATED != 0 {
            format!(
                "the force sensor saturated (range {} N axial, {} N tangential, {} N·mm)",
                range.fz_n, range.fxy_n, range.torque_nmm
            )
        } else if w.fz_n.abs() > l.max_fz_n {
            format!(
                "|Fz| = {:.3} N exceeds max_fz {} N",
                w.fz_n.abs(),
                fmt_value(l.max_fz_n)
            )
        } else if w.fx_n.hypot(w.fy_n) > l.max_fxy_n {
            format!(
                "|Fxy| = {:.3} N exceeds max_fxy {} N",
                w.fx_n.hypot(w.fy_n),
                fmt_value(l.max_fxy_n)
            )
        } else if w.tz_nmm.abs() > l.max_tz_nmm {
            format!(
                "|Tz| = {:.3} N·mm exceeds max_tz {} N·mm",
                w.tz_nmm.abs(),
                fmt_value(l.max_tz_nmm)
            )
        } else {
            return None;
        };
        Some((TripKind::Limit, in_step(msg)))
    }

    /// Stops every axis, records the trip and disarms.
    async fn trip(
        &self,
        kind: TripKind,
        message: String,
        t_sample_ns: u64,
        t_detect_ns: u64,
        reading: Option<Wrench>,
    ) {
        {
            let mut s = lock(&self.state);
            if s.trip.is_some() || !s.armed {
                return;
            }
            // Disarm first: the plan must see the trip before it sends anything else.
            s.armed = false;
            s.trip = Some(Trip {
                kind,
                message: message.clone(),
                t_sample_ns,
                t_detect_ns,
                t_stop_sent_ns: t_detect_ns,
                detect_to_stop_wall_us: 0.0,
                reading,
                stop_errors: Vec::new(),
                stops_sent: false,
            });
        }
        self.wake_plan.notify_one();
        self.alarm.notify_one();
        let wall = std::time::Instant::now();
        let errors = self.send_stops().await;
        let wall_us = wall.elapsed().as_secs_f64() * 1e6;
        let t_stop = self.clock.now_ns();
        {
            let mut s = lock(&self.state);
            if let Some(t) = s.trip.as_mut() {
                t.t_stop_sent_ns = t_stop;
                t.detect_to_stop_wall_us = wall_us;
                t.stop_errors = errors;
                t.stops_sent = true;
            }
        }
        self.trip_done.notify_waiters();
    }

    /// Sends stop to every axis, pressing axes first; returns the failures.
    async fn send_stops(&self) -> Vec<String> {
        let mut errors = Vec::new();
        for (role, s) in &self.stoppers {
            if let Err(e) = s.stop_now().await {
                errors.push(format!("stopping {role}: {e}"));
            }
        }
        errors
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn freshness_bound_respects_sensor_and_wall() {
        // 50 Hz monitor on a 1 kHz sensor in virtual time: two monitor periods.
        assert_eq!(
            WatchConfig::stale_bound_ns(20_000_000, 1000.0, None),
            40_000_000
        );
        // A 10 Hz sensor cannot be fresher than two of its periods.
        assert_eq!(
            WatchConfig::stale_bound_ns(20_000_000, 10.0, None),
            200_000_000
        );
        // 100× scaled: 250 ms of wall is 25 s of run time.
        assert_eq!(
            WatchConfig::stale_bound_ns(20_000_000, 1000.0, Some(100.0)),
            25_000_000_000
        );
    }
}
