//! The plan task's one waiting loop: it services the axes and frame streams, takes the
//! watchdog's readings, and returns when what it waits for has happened — or fails when a
//! deadline passes, the watchdog trips, or the operator interrupts.

use rig::config::AxisRole;
use rig::units::fmt_value;

use super::adaptive::AdaptiveTrack;
use super::exec::Exec;
use super::settle::SettleTrack;
use super::{Stop, watchdog::Monitor};
use experiments::protocol::schema::Channel;

/// Where a move must come to rest, and how it is judged.
#[derive(Debug, Clone)]
pub(super) struct Arrival {
    /// Absolute target, axis unit.
    pub(super) target: f64,
    /// In-position window, axis unit.
    pub(super) window: f64,
    /// Speed it was sent at (to send it again).
    pub(super) speed: f64,
    /// When the move was sent, ns.
    pub(super) sent_ns: u64,
    /// How long it may show no motion, ns.
    pub(super) grace_ns: u64,
    /// The device has reported motion since it was sent.
    pub(super) seen_moving: bool,
    /// Sends left before a miss fails the run.
    pub(super) retries_left: u32,
    /// mm or deg.
    pub(super) unit: &'static str,
}

/// An axis that must come to rest by a deadline.
pub(super) struct Deadline {
    pub(super) axis: AxisRole,
    pub(super) by_ns: u64,
    /// How long it was given, s.
    pub(super) allowed_s: f64,
    /// What it was doing, for the error ("a move from 9 to 10 mm at 2 mm/s").
    pub(super) what: String,
    /// Where it must come to rest; `None` when any rest will do (a stop).
    pub(super) arrival: Option<Arrival>,
}

/// What [`Exec::wait`] waits for.
pub(super) enum Until {
    /// These axes have stopped, each by its deadline.
    Motion(Vec<Deadline>),
    /// The clock reaches this time.
    Time(u64),
    /// The settle criterion holds (or times out).
    Settle(SettleTrack),
    /// F∞ is known within the tolerance (or the settle times out).
    Adaptive(super::adaptive::AdaptiveTrack),
    /// This many more frames have been captured.
    Frames(u32),
    /// |force along `channel`| reaches `threshold` while the axis of `deadline` moves.
    Contact {
        channel: Channel,
        threshold: f64,
        deadline: Deadline,
    },
}

/// Readings are taken (and written to force.csv) at least this often, in run time, while
/// nothing else wakes the plan: a crash loses at most this much of the force stream, and a
/// long settle does not wake the plan at every sample for nothing.
const DRAIN_NS: u64 = 250_000_000;

/// Resolves when the watchdog has a reading (`readings`) or trips; never without a
/// watchdog.
async fn watchdog_news(m: Option<&Monitor>, readings: bool) {
    match m {
        Some(m) if readings => m.reading().await,
        Some(m) => m.tripped().await,
        None => std::future::pending().await,
    }
}

impl Until {
    /// Whether each new reading can end the wait.
    fn needs_readings(&self) -> bool {
        matches!(self, Until::Settle(_) | Until::Contact { .. })
    }
}

/// What one look at the awaited condition decided.
enum Next {
    /// What the wait waits for has happened.
    Done,
    /// Not yet: look again by this time on the run's clock, ns (sooner when a schedule is
    /// due, the watchdog has news or the operator interrupts).
    At(u64),
    /// Not yet: look again at once, without sleeping (a frame was just captured).
    Again,
}

impl Exec<'_> {
    /// Waits for `until`, servicing every due schedule meanwhile.
    pub(super) async fn wait(&mut self, until: &mut Until) -> Result<(), Stop> {
        let mut next_poll_ns: u64 = self.now();
        let mut frames_due_ns: Option<u64> = None;
        loop {
            self.check_stop()?;
            let fresh = self.drain()?;
            let now = self.now();
            self.service_streams(now).await?;
            let next = match until {
                Until::Time(t) => {
                    if now >= *t {
                        Next::Done
                    } else {
                        Next::At(*t)
                    }
                }
                Until::Motion(watch) => self.look_motion(watch, now, &mut next_poll_ns).await?,
                Until::Settle(track) => self.look_settle(track, now, fresh),
                Until::Adaptive(track) => self.look_adaptive(track, now),
                Until::Frames(n) => self.look_frames(n, now, &mut frames_due_ns).await?,
                Until::Contact {
                    channel,
                    threshold,
                    deadline: by,
                } => {
                    self.look_contact(*channel, *threshold, by, now, fresh, &mut next_poll_ns)
                        .await?
                }
            };
            let deadline = match next {
                Next::Done => return Ok(()),
                Next::Again => continue,
                Next::At(t) => t,
            };
            self.sleep_until_due(deadline, now, until.needs_readings())
                .await;
        }
    }

    /// Records the axes and captures a stream frame when their schedules are due at `now`
    /// (ns), and schedules the next of each (a late one is not caught up).
    async fn service_streams(&mut self, now: u64) -> Result<(), Stop> {
        if let (Some(t), Some(hz)) = (self.streams.next_axes_ns, self.streams.active.axes_hz)
            && now >= t
        {
            self.record_axes(now).await?;
            let p = super::period_ns(hz);
            self.streams.next_axes_ns = Some(if t + p <= now { now + p } else { t + p });
        }
        if let (Some(t), Some(hz)) = (self.streams.next_frame_ns, self.streams.active.frames_hz)
            && now >= t
        {
            self.capture_frame().await?;
            let p = super::period_ns(hz);
            let now = self.now();
            self.streams.next_frame_ns = Some(if t + p <= now { now + p } else { t + p });
        }
        Ok(())
    }

    /// Sleeps until `deadline_ns` or the next due schedule or forced drain, whichever is
    /// first, waking early on the watchdog's news (each reading, when `readings` can end
    /// the wait) or an interrupt; the progress display ticks first. Yields once when
    /// something is already due.
    async fn sleep_until_due(&self, deadline_ns: u64, now: u64, readings: bool) {
        let drain = self.monitor.as_ref().map(|_| now + DRAIN_NS);
        let next = [
            Some(deadline_ns),
            self.streams.next_axes_ns,
            self.streams.next_frame_ns,
            drain,
        ]
        .into_iter()
        .flatten()
        .min()
        .unwrap_or(deadline_ns);
        let tick_t = self.t_s();
        self.progress
            .tick(self.step, &self.what, self.phase, tick_t);
        if next > now {
            let seen = self.cancel.count();
            let cancel = self.cancel.clone();
            tokio::select! {
                _ = self.clock.sleep_until_ns(next) => {}
                _ = watchdog_news(self.monitor.as_ref(), readings) => {}
                _ = cancel.interrupted(seen) => {}
            }
        } else {
            tokio::task::yield_now().await;
        }
    }

    /// Axes that must come to rest: done when all have arrived (or a tactile stop was hit);
    /// an axis past its deadline is stopped and fails the wait. Polls at the axes' rate.
    async fn look_motion(
        &mut self,
        watch: &mut [Deadline],
        now: u64,
        next_poll_ns: &mut u64,
    ) -> Result<Next, Stop> {
        if self.slip.hit {
            return Ok(Next::Done);
        }
        if now >= *next_poll_ns {
            if self.arrived(watch, now).await? {
                return Ok(Next::Done);
            }
            if let Some(late) = watch.iter().find(|d| now >= d.by_ns) {
                return Err(self.stuck(late).await);
            }
            *next_poll_ns = now
                + watch
                    .iter()
                    .map(|d| self.poll_ns(d.axis))
                    .min()
                    .unwrap_or(50_000_000);
        }
        let by = watch.iter().map(|d| d.by_ns).min().unwrap_or(*next_poll_ns);
        Ok(Next::At((*next_poll_ns).min(by.max(now + 1))))
    }

    /// The rate settle rule on the newest readings (`fresh`): done when the drift bound
    /// stays below the threshold after the shortest settle and a full window, or at the
    /// longest settle (a timeout). Shows the bound on the live view.
    fn look_settle(&self, track: &mut SettleTrack, now: u64, fresh: bool) -> Next {
        let elapsed = now.saturating_sub(track.start_ns);
        if elapsed >= track.max_ns {
            track.verdict = Some("timeout");
            return Next::Done;
        }
        let bound = fresh
            .then(|| track.drift_bound(&self.readings.window, now))
            .flatten();
        if let (Some(board), Some(b)) = (self.progress.live(), bound) {
            let unit = if track.channel.is_torque() {
                "N·mm/s"
            } else {
                "N/s"
            };
            board.settle(track.start_ns, now, b, track.below, unit);
        }
        if elapsed >= track.min_ns
            && elapsed >= track.window_ns
            && bound.is_some_and(|b| b < track.below)
        {
            track.verdict = Some("converged");
            return Next::Done;
        }
        Next::At(track.start_ns + track.max_ns)
    }

    /// The adaptive settle rule: F∞ fitted when a fit is due (after the shortest settle),
    /// done once it is known within the tolerance; at the longest settle one last fit on the
    /// whole record decides. Shows the estimate's band on the live view.
    fn look_adaptive(&self, track: &mut AdaptiveTrack, now: u64) -> Next {
        let elapsed = now.saturating_sub(track.start_ns);
        if elapsed >= track.max_ns {
            // One last fit on the whole record: the step keeps its F∞ and σ.
            let settled = track.judge(&self.readings.window, now, &self.gel);
            track.verdict = Some(if settled { "converged" } else { "timeout" });
            return Next::Done;
        }
        if elapsed >= track.min_ns && now >= track.next_ns {
            let settled = track.judge(&self.readings.window, now, &self.gel);
            if let (Some(board), Some((stat, band))) = (self.progress.live(), track.band(&self.gel))
            {
                let unit = if track.channel.is_torque() {
                    "N·mm"
                } else {
                    "N"
                };
                board.settle(track.start_ns, now, stat, band, unit);
            }
            if settled {
                track.verdict = Some("converged");
                return Next::Done;
            }
        }
        Next::At(
            track
                .next_ns
                .max(track.start_ns + track.min_ns)
                .min(track.start_ns + track.max_ns),
        )
    }

    /// Frames still to capture (`left`): one each time the previous is done, back to back.
    async fn look_frames(
        &mut self,
        left: &mut u32,
        now: u64,
        frames_due_ns: &mut Option<u64>,
    ) -> Result<Next, Stop> {
        if *left == 0 {
            return Ok(Next::Done);
        }
        let due = *frames_due_ns.get_or_insert(now);
        if now >= due {
            self.capture_frame().await?;
            *left -= 1;
            *frames_due_ns = Some(self.now());
            if *left == 0 {
                return Ok(Next::Done);
            }
            return Ok(Next::Again);
        }
        Ok(Next::At(due))
    }

    /// A creep to contact: done when a fresh reading's |force along `channel`| reaches
    /// `threshold` (N or N·mm); the creep coming to the end of its travel first fails the
    /// wait, and so does its deadline.
    async fn look_contact(
        &mut self,
        channel: Channel,
        threshold: f64,
        by: &mut Deadline,
        now: u64,
        fresh: bool,
        next_poll_ns: &mut u64,
    ) -> Result<Next, Stop> {
        if fresh
            && let Some((_, w)) = self.readings.latest
            && channel.of(&w).abs() >= threshold
        {
            return Ok(Next::Done);
        }
        let axis = by.axis;
        if now >= *next_poll_ns {
            // The end of the creep, judged like any move: a first "at rest" before the stage
            // has shown motion is a late start, not the end.
            if self.arrived(std::slice::from_mut(by), now).await? {
                return Err(Stop::NoContact(format!(
                    "the {axis} axis reached the end of the approach without |{}| reaching {} {}",
                    channel.name(),
                    fmt_value(threshold),
                    if channel.is_torque() { "N·mm" } else { "N" }
                )));
            }
            if now >= by.by_ns {
                return Err(self.stuck(by).await);
            }
            *next_poll_ns = now + self.poll_ns(axis);
        }
        Ok(Next::At((*next_poll_ns).min(by.by_ns.max(now + 1))))
    }

    pub(super) fn poll_ns(&self, axis: AxisRole) -> u64 {
        self.poll_period_ns
            .get(&axis)
            .copied()
            .unwrap_or(50_000_000)
    }

    /// An axis still moving past its deadline: stop it, and say where it was.
    async fn stuck(&mut self, d: &Deadline) -> Stop {
        let axis = d.axis;
        let mut detail = String::new();
        if let Some(ax) = self.rig.axes.get_mut(&axis) {
            let unit = ax.info().unit.symbol();
            if let Err(e) = ax.stop().await {
                detail.push_str(&format!("; stopping it failed too: {e}"));
            }
            match ax.status().await {
                Ok(st) => detail.insert_str(
                    0,
                    &format!(
                        "; it reads {} {unit}{}",
                        fmt_value((st.position * 1e6).round() / 1e6),
                        if st.moving { " and still busy" } else { "" }
                    ),
                ),
                Err(e) => detail.push_str(&format!("; reading it failed: {e}")),
            }
        }
        Stop::Stuck(format!(
            "the {axis} axis did not come to rest within {} s ({}){detail}; it was stopped; \
             fix: check the stage for a jam, a stalled motor or a limit switch, then run `gelrig probe`",
            fmt_value((d.allowed_s * 10.0).round() / 10.0),
            d.what,
        ))
    }
}
