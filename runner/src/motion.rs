//! Moving axes with deadlines, reading them, and the axes and frame streams.
//!
//! **A move ends only where it was sent.** It is done when the device reports rest (and
//! in-position, where it has such a flag) *and* the position it reads is within the axis's
//! in-position window of the target (its resolution unless the rig file says `in_position`).
//! Real drives take milliseconds to show motion after a trigger: a first status of "not
//! busy" away from the target is not an arrival but a move that has not started yet, and it
//! is polled again for the axis's `start_grace` (0.5 s). A move that never shows motion, or
//! comes to rest elsewhere, is sent again `move_retries` times (rig file, default 0) and then
//! fails the run naming axis, target and position — the step is never recorded as reached.
//! (A drive once raised BUSY 20 ms after its trigger and a run recorded 0.28 deg for a 1 deg
//! step.)
//!
//! A move's deadline is its nominal duration (distance / speed) times 1.5 plus a grace of
//! [`MOVE_GRACE_S`]: real stages accelerate and settle, and serial polling adds latency, but
//! a stage still busy long after that is stuck (a jam, a stalled motor, a controller that
//! never leaves BUSY) and is stopped and reported instead of being waited on forever.

use rig::RigError;
use rig::config::AxisRole;
use rig::units::fmt_value;
use serde_json::json;

use super::Stop;
use super::exec::Exec;
use super::wait::{Arrival, Deadline, Until};

/// Slack on every move's deadline, s: acceleration, settling and polling latency.
pub(super) const MOVE_GRACE_S: f64 = 5.0;

/// Homing has no known distance: the whole travel at a quarter of the axis's maximum
/// speed (homing runs slower than moves on most controllers), plus a minute.
fn home_allowance_s(span: f64, max_speed: f64) -> f64 {
    4.0 * span.abs() / max_speed.max(1e-9) + 60.0
}

/// How long a frame waits for the force samples of its exposure, ns of run time: past it,
/// the frame is matched with what has come (interpolated, or no force).
const FRAME_FORCE_WAIT_NS: u64 = 200_000_000;

impl Exec<'_> {
    /// The deadline of an axis that must cover `distance` at `speed` from now.
    pub(super) fn deadline_for(
        &self,
        axis: AxisRole,
        distance: f64,
        speed: f64,
        what: String,
    ) -> Deadline {
        let allowed_s = 1.5 * distance.abs() / speed.max(1e-12) + MOVE_GRACE_S;
        Deadline {
            axis,
            by_ns: self.now() + (allowed_s * 1e9) as u64,
            allowed_s,
            what,
            arrival: None,
        }
    }

    /// How `axis` judges arrivals: its rig file's window, grace and retries.
    pub(super) fn arrival(&self, axis: AxisRole, target: f64, speed: f64) -> Arrival {
        let cfg = self.loaded_axes.get(&axis);
        Arrival {
            target,
            window: cfg.map(|c| c.in_position_window()).unwrap_or(0.0) * (1.0 + 1e-9) + 1e-12,
            speed,
            sent_ns: self.now(),
            grace_ns: (cfg.map(|c| c.start_grace_s()).unwrap_or(0.5) * 1e9) as u64,
            seen_moving: false,
            retries_left: cfg.and_then(|c| c.move_retries).unwrap_or(0),
            unit: cfg.map(|c| c.unit().symbol()).unwrap_or(""),
        }
    }

    /// Polls every axis of `watch` once: `true` when all have arrived (at rest, in
    /// position, within the window of their target). A move that shows no motion past its
    /// grace away from its target, or comes to rest elsewhere, is sent again while retries
    /// are left, then fails the run.
    pub(super) async fn arrived(&mut self, watch: &mut [Deadline], now: u64) -> Result<bool, Stop> {
        let mut all = true;
        for d in watch.iter_mut() {
            let Some(ax) = self.rig.axes.get_mut(&d.axis) else {
                continue;
            };
            let st = ax.status().await?;
            let Some(a) = d.arrival.as_mut() else {
                all &= !st.moving;
                continue;
            };
            if st.moving {
                a.seen_moving = true;
                all = false;
                continue;
            }
            let off = (st.position - a.target).abs();
            let settled = st.in_position != Some(false);
            if off <= a.window {
                all &= settled;
                continue;
            }
            if !a.seen_moving && now.saturating_sub(a.sent_ns) < a.grace_ns {
                // Not started yet: real drives take a moment to show motion.
                all = false;
                continue;
            }
            let why = if a.seen_moving {
                format!(
                    "came to rest at {} {u}, not at its target {} {u} (in-position window {} {u})",
                    fmt_value((st.position * 1e6).round() / 1e6),
                    fmt_value(a.target),
                    fmt_value(a.window),
                    u = a.unit
                )
            } else {
                format!(
                    "showed no motion {} s after the move to {} {u} was sent and rests at {} {u}",
                    fmt_value(a.grace_ns as f64 * 1e-9),
                    fmt_value(a.target),
                    fmt_value((st.position * 1e6).round() / 1e6),
                    u = a.unit
                )
            };
            if a.retries_left > 0 {
                a.retries_left -= 1;
                a.seen_moving = false;
                a.sent_ns = now;
                let (target, speed) = (a.target, a.speed);
                let axis = d.axis;
                self.progress
                    .note(&format!("the {axis} axis {why}; sending the move again"));
                self.rec.journal(
                    now,
                    "move_retry",
                    json!({ "axis": axis, "target": target, "position": st.position, "why": why }),
                    true,
                )?;
                if let Some(ax) = self.rig.axes.get_mut(&axis) {
                    ax.move_to(target, speed).await?;
                }
                all = false;
                continue;
            }
            return Err(Stop::Missed(format!(
                "the {} axis {why} ({}); nothing is recorded as reached; fix: check the drive's \
                 register map and in-position settings, the rig file's `in_position` and \
                 `start_grace`, or allow `move_retries`",
                d.axis, d.what
            )));
        }
        Ok(all)
    }

    /// Moves `axis` to `target_abs` at `speed` and waits until it is at rest, by its deadline.
    pub(super) async fn move_axis(
        &mut self,
        axis: AxisRole,
        target_abs: f64,
        speed: f64,
    ) -> Result<(), Stop> {
        let here = self.position(axis).await?;
        let Some(ax) = self.rig.axes.get_mut(&axis) else {
            return Err(Stop::Device(RigError::Unsupported {
                device: format!("{axis} axis"),
                detail: "not opened".into(),
            }));
        };
        let unit = ax.info().unit.symbol();
        ax.move_to(target_abs, speed).await?;
        self.targets.insert(axis, target_abs);
        let what = format!(
            "a move from {} to {} {unit} at {} {unit}/s",
            fmt_value((here * 1e6).round() / 1e6),
            fmt_value((target_abs * 1e6).round() / 1e6),
            fmt_value(speed)
        );
        let mut deadline = self.deadline_for(axis, target_abs - here, speed, what);
        deadline.arrival = Some(self.arrival(axis, target_abs, speed));
        self.wait(&mut Until::Motion(vec![deadline])).await
    }

    /// Homes `axes` together, each by its homing deadline.
    pub(super) async fn home_axes(&mut self, axes: &[AxisRole]) -> Result<(), Stop> {
        let mut watch = Vec::new();
        for a in axes {
            if let Some(ax) = self.rig.axes.get_mut(a) {
                let info = ax.info().clone();
                ax.home().await?;
                let allowed_s = home_allowance_s(info.travel_max - info.travel_min, info.max_speed);
                // Homing ends at the stage zero, the axis origin from here on.
                let home = 0.0_f64.max(info.travel_min).min(info.travel_max);
                watch.push(Deadline {
                    axis: *a,
                    by_ns: self.now() + (allowed_s * 1e9) as u64,
                    allowed_s,
                    what: "homing".into(),
                    arrival: Some(self.arrival(*a, home, info.max_speed)),
                });
            }
            self.origin.insert(*a, 0.0);
        }
        self.wait(&mut Until::Motion(watch)).await
    }

    pub(super) async fn position(&mut self, axis: AxisRole) -> Result<f64, Stop> {
        match self.rig.axes.get_mut(&axis) {
            Some(ax) => Ok(ax.status().await?.position),
            None => Ok(0.0),
        }
    }

    pub(super) async fn record_axes(&mut self, now: u64) -> Result<(), Stop> {
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

    pub(super) async fn capture_frame(&mut self) -> Result<(), Stop> {
        let Some(cam) = self.rig.camera.as_mut() else {
            return Ok(());
        };
        let frame = cam.capture().await?;
        let (fps, exposure_s) = (cam.info().fps, cam.info().exposure_s);
        let force = self.frame_force(&frame, exposure_s, fps).await;
        let index = self.rec.frame(&frame, self.step, self.trial, force)?;
        if let Some(i) = index {
            self.progress.emit(crate::events::Event::Frame {
                index: i,
                t_ns: frame.t_ns,
            });
        }
        if let (Some(b), Some(i)) = (self.progress.live(), index) {
            // In a frame stream the camera's counter steps by its rate over the stream's.
            let stride = (self.streams.next_frame_ns.is_some())
                .then_some(self.streams.active.frames_hz)
                .flatten()
                .map(|hz| (fps / hz).round().max(1.0) as u64);
            let size = (frame.width, frame.height);
            b.frame(i, frame.t_ns, (frame.seq, stride), size, &frame.rgb);
        }
        if self.tactile.is_some() {
            let truth = match &self.monitor {
                Some(m) => m.truth().await,
                None => None,
            };
            self.tactile_frame(&frame, index.unwrap_or(0), truth.as_ref())?;
        }
        Ok(())
    }

    /// The force during the frame's exposure (`frames.csv`): waits, boundedly, until the
    /// watchdog has samples past the exposure's end, asking it for a read now.
    async fn frame_force(
        &mut self,
        frame: &rig::Frame,
        exposure_s: Option<f64>,
        fps: f64,
    ) -> Option<rundir::write::FrameForce> {
        let m = self.monitor.as_ref()?;
        let window = super::frame_force::window_ns(frame.t_ns, exposure_s, fps);
        let deadline = self.clock.now_ns() + FRAME_FORCE_WAIT_NS;
        // One read now, if the samples do not reach the exposure's end yet; after it, the
        // scheduled reads (asking again and again would spin without letting the clock
        // move on).
        if m.history_until_ns().is_none_or(|t| t < window.1) {
            m.read_soon();
        }
        while m.history_until_ns().is_none_or(|t| t < window.1) && self.clock.now_ns() < deadline {
            tokio::select! {
                _ = m.reading() => {}
                _ = self.clock.sleep_until_ns(deadline) => {}
            }
        }
        let samples = m.history_around(window.0, window.1);
        super::frame_force::match_window(&samples, &self.tare, window, frame.t_ns)
    }

    /// Judges a frame of a record block: `tactile.csv`, the progress line, the move's stop.
    fn tactile_frame(
        &mut self,
        frame: &rig::Frame,
        index: u64,
        truth: Option<&rig::SimTruth>,
    ) -> Result<(), Stop> {
        let Some(live) = self.tactile.as_mut() else {
            return Ok(());
        };
        let row = live.frame(frame, index, self.step, self.trial, truth);
        let state = live.state();
        if let Some(msg) = live.gelsight_failure() {
            self.progress.note(&format!("warning: {msg}"));
            self.rec.update_manifest(|m| m.warnings.push(msg))?;
        }
        let Some(live) = self.tactile.as_mut() else {
            return Ok(());
        };
        if let Some(why) = live.new_failure() {
            // The block's remaining frames are recorded untracked, not retried one by one.
            let msg = format!("live tactile tracking stopped for this record block: {why}");
            self.progress.note(&format!("warning: {msg}"));
            self.rec.update_manifest(|m| m.warnings.push(msg))?;
        }
        if let Some(row) = row {
            self.progress.set_tactile(Some(format!(
                "slip: {}{}",
                row.state,
                if row.gripping {
                    format!(" (stuck {:.0} %)", row.stuck_fraction * 100.0)
                } else {
                    String::new()
                }
            )));
            self.progress.emit(crate::events::Event::Tactile {
                t_ns: row.t_ns,
                state: row.state.clone(),
                gripping: row.gripping,
                stuck_fraction: row.stuck_fraction,
                gelsight_fz_n: row.gelsight_fz_n,
            });
            if let Some(b) = self.progress.live() {
                b.tactile(liveview::Tactile {
                    state: row.state.clone(),
                    gripping: row.gripping,
                    stuck_fraction: row.stuck_fraction,
                    t_s: row.t_ns as f64 * 1e-9,
                    gelsight_fz_n: row.gelsight_fz_n,
                });
                if let Some(o) = self.tactile.as_ref().and_then(|t| t.overlay(index)) {
                    b.overlay(o);
                }
            }
            self.rec.tactile(&row)?;
        }
        if let Some(level) = self.slip.stop_at
            && state >= level
        {
            self.slip.hit = true;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn homing_allowance_grows_with_travel() {
        // 25 mm at 2 mm/s: 50 s + a minute.
        assert!((home_allowance_s(25.0, 2.0) - 110.0).abs() < 1e-9);
        assert!(home_allowance_s(360.0, 10.0) > home_allowance_s(25.0, 2.0));
    }
}
