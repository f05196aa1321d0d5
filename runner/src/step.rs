//! One step of a protocol as the plan task runs it, phase by phase: the move (stopped early
//! on a tactile condition), the disturbance, the settle, the quasistatic window, the frames,
//! and the row recorded for it.

use rig::Wrench;
use rig::config::AxisRole;
use rig::units::fmt_value;
use serde_json::json;

use super::Stop;
use super::adaptive::AdaptiveTrack;
use super::exec::Exec;
use super::settle::SettleTrack;
use super::wait::Until;
use analysis::equilibrium::Equilibrium;
use experiments::protocol::compile::{DisturbSpec, SettleSpec, Step, Target};
use experiments::protocol::schema::{Channel, OnTimeout};
use rundir::write::StepRow;

/// Squeeze above which a grip move ends still holding, N.
const GRIPPING_N: f64 = 0.2;

/// `v` rounded to a millionth of its unit, with −0 written as 0: the precision of a step's
/// row.
fn round_micro(v: f64) -> f64 {
    (v * 1e6).round() / 1e6 + 0.0
}

/// The quasistatic window of a step: the samples its values are the mean of.
struct Window {
    /// The tared samples of the last `force_window_s` (or the newest one, for a 0 s window).
    samples: Vec<Wrench>,
    /// Their mean; `None` when there were none.
    mean: Option<Wrench>,
    /// Standard deviation of the step's channel about that mean, N or N·mm.
    std: Option<f64>,
}

/// What a step measured, gathered for its row.
struct Measured {
    /// When the step began, ns.
    t_start_ns: u64,
    /// When its settle ended, ns.
    settle_end_ns: u64,
    /// How long it settled, s.
    settle_s: f64,
    /// How the settle ended (`none`, `fixed`, `converged`, `timeout`).
    verdict: &'static str,
    /// The adaptive settle's last F∞ estimate (adaptive settles only).
    f_inf: Option<Equilibrium>,
    /// The quasistatic window.
    window: Window,
    /// The step's axis position at its end, absolute (axis unit).
    position_abs: Option<f64>,
    /// The same position from the axis's origin (axis unit).
    position: Option<f64>,
}

impl Exec<'_> {
    /// Runs one step: move, disturb, settle, quasistatic window, frames, row.
    pub(super) async fn step(&mut self, s: &Step) -> Result<(), Stop> {
        let t_start_ns = self.begin_step(s)?;
        self.step_move(s).await?;
        self.step_disturb(s).await?;
        let settle_start_ns = self.now();
        let (verdict, f_inf) = self.step_settle(s, settle_start_ns).await?;
        let settle_end_ns = self.now();
        let settle_s = (settle_end_ns - settle_start_ns) as f64 * 1e-9;
        let window = self.quasistatic_window(s);
        if s.frames > 0 {
            self.set_phase("capturing frames");
            self.wait(&mut Until::Frames(s.frames)).await?;
        }
        let (position_abs, position) = self.step_position(s.axis).await?;
        let measured = Measured {
            t_start_ns,
            settle_end_ns,
            settle_s,
            verdict,
            f_inf,
            window,
            position_abs,
            position,
        };
        let (row, mean) = self.step_row(s, &measured);
        self.record_step(s, &row, mean, &measured).await
    }

    /// Starts a step: the watchdog learns its number, its saturation flag is cleared, the
    /// samples kept cover its settle and force windows, and the journal records its start.
    /// Returns when it started, ns.
    fn begin_step(&mut self, s: &Step) -> Result<u64, Stop> {
        self.step = s.step;
        if let Some(m) = &self.monitor {
            m.set_step(s.step);
        }
        self.step_saturated = false;
        let t_start_ns = self.now();
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
            // The whole relaxation is fitted.
            SettleSpec::Adaptive { max_s, .. } => (max_s * 1e9) as u64,
            _ => 0,
        };
        self.readings.keep_ns =
            ((s.force_window_s * 1e9) as u64).max(settle_window_ns) + 1_000_000_000;
        self.rec.journal(
            t_start_ns,
            "step_start",
            json!({ "step": s.step, "phase": s.phase.name(), "what": self.what }),
            false,
        )?;
        Ok(t_start_ns)
    }

    /// The step's move, if it has one: to its target from the axis's origin (or by an
    /// offset from where the axis is), stopped early where the step's tactile condition is
    /// met; after a grip move the tactile path learns whether the grasp still holds.
    async fn step_move(&mut self, s: &Step) -> Result<(), Stop> {
        let (Some(axis), Some(target)) = (s.axis, s.target) else {
            return Ok(());
        };
        self.set_phase("moving");
        let origin = self.origin.get(&axis).copied().unwrap_or(0.0);
        let abs = match target {
            Target::To(v) => origin + v,
            Target::By(v) => self.position(axis).await? + v,
        };
        self.slip.stop_at = s.until_slip.map(|l| l.state());
        self.slip.hit = false;
        let moved = self.move_axis(axis, abs, s.speed).await;
        // The tactile stop is cleared whether or not the move succeeded.
        self.slip.stop_at = None;
        moved?;
        if self.slip.hit {
            self.tactile_stop(axis, s.speed).await?;
        }
        if axis == AxisRole::Grip {
            self.grip_changed();
        }
        Ok(())
    }

    /// The step's disturbance of the grasped object, if it has one and the rig has a
    /// disturber (it runs during the settle that follows).
    async fn step_disturb(&mut self, s: &Step) -> Result<(), Stop> {
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
        Ok(())
    }

    /// A move's tactile condition was met: the axis stops where it is (journaled).
    async fn tactile_stop(&mut self, axis: AxisRole, speed: f64) -> Result<(), Stop> {
        self.slip.hit = false;
        if let Some(ax) = self.rig.axes.get_mut(&axis) {
            ax.stop().await?;
        }
        let deadline = self.deadline_for(axis, 0.0, speed, "stopping on slip".to_string());
        self.wait(&mut Until::Motion(vec![deadline])).await?;
        let here = self.position(axis).await?;
        self.targets.insert(axis, here);
        let state = self
            .tactile
            .as_ref()
            .map(|t| t.state().as_str())
            .unwrap_or("stick");
        let t = self.now();
        self.rec.journal(
            t,
            "tactile_stop",
            json!({ "step": self.step, "axis": axis, "position": here, "state": state }),
            true,
        )?;
        self.progress.note(&format!(
            "{axis} stopped at {} on tactile {state}",
            fmt_value((here * 1e6).round() / 1e6)
        ));
        Ok(())
    }

    /// After a grip move: still squeezing, the field now is the new pressing field (a
    /// regrip); open, the grasp is over.
    fn grip_changed(&mut self) {
        let squeeze = self
            .readings
            .latest
            .map(|(_, w)| w.fz_n.abs())
            .unwrap_or(0.0);
        if let Some(t) = self.tactile.as_mut() {
            if squeeze >= GRIPPING_N {
                t.gripped();
            } else {
                t.released();
            }
        }
    }

    /// The step's settle, from `start_ns` by its rule. Returns how it ended and, for the
    /// adaptive rule, the last F∞ estimate. A timeout fails the run or warns, as the rule
    /// says.
    async fn step_settle(
        &mut self,
        s: &Step,
        start_ns: u64,
    ) -> Result<(&'static str, Option<Equilibrium>), Stop> {
        match s.settle {
            SettleSpec::None => Ok(("none", None)),
            SettleSpec::Adaptive {
                channel,
                tolerance,
                min_s,
                max_s,
                on_timeout,
            } => {
                self.set_phase("settling");
                let track = self
                    .settle_adaptive(AdaptiveTrack {
                        channel,
                        tolerance,
                        start_ns,
                        min_ns: (min_s * 1e9) as u64,
                        max_ns: (max_s * 1e9) as u64,
                        window_s: s.force_window_s.max(1.0),
                        next_ns: start_ns,
                        last: None,
                        verdict: None,
                    })
                    .await?;
                let verdict = track.verdict.unwrap_or("timeout");
                if verdict == "timeout" {
                    let msg = adaptive_timeout_message(
                        s.step,
                        channel,
                        tolerance,
                        max_s,
                        track.last.as_ref(),
                    );
                    self.settle_timed_out(msg, on_timeout)?;
                }
                Ok((verdict, track.last))
            }
            SettleSpec::Fixed { s: secs } => {
                self.set_phase(if s.disturb.is_some() {
                    "disturbing"
                } else {
                    "settling"
                });
                self.wait(&mut Until::Time(start_ns + (secs * 1e9) as u64))
                    .await?;
                Ok(("fixed", None))
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
                let verdict = self
                    .settle_rate(SettleTrack {
                        channel,
                        below,
                        window_ns: (window_s * 1e9) as u64,
                        start_ns,
                        min_ns: (min_s * 1e9) as u64,
                        max_ns: (max_s * 1e9) as u64,
                        verdict: None,
                    })
                    .await?;
                if verdict == "timeout" {
                    let msg = format!(
                        "step {}: |d{}/dt| stayed above {} {} for the whole {} s settle",
                        s.step,
                        channel.label(),
                        fmt_value(below),
                        channel.rate_unit(),
                        fmt_value(max_s)
                    );
                    self.settle_timed_out(msg, on_timeout)?;
                }
                Ok((verdict, None))
            }
        }
    }

    /// Adaptive settling: waits until F∞ is known (or the settle's longest time has passed),
    /// then lets the run's memory of the gel learn from the relaxation it saw (noted and
    /// journaled when it learns something new).
    async fn settle_adaptive(&mut self, track: AdaptiveTrack) -> Result<AdaptiveTrack, Stop> {
        let mut until = Until::Adaptive(track);
        self.wait(&mut until).await?;
        let Until::Adaptive(track) = until else {
            unreachable!("the adaptive wait keeps its kind")
        };
        if let Some(e) = &track.last {
            self.gel.settled_at(
                Some(track.start_s()),
                e,
                track.record(&self.readings.window),
            );
        }
        if let Some(msg) = self.gel.newly_learned() {
            self.progress.note(&msg);
            let t = self.now();
            self.rec
                .journal(t, "gel_time_constants", json!({ "note": msg }), false)?;
        }
        Ok(track)
    }

    /// Rate settling: waits until the channel's drift is confidently below its bound (or
    /// the settle's longest time has passed). Returns the verdict.
    async fn settle_rate(&mut self, track: SettleTrack) -> Result<&'static str, Stop> {
        let mut until = Until::Settle(track);
        self.wait(&mut until).await?;
        Ok(match until {
            Until::Settle(t) => t.verdict.unwrap_or("converged"),
            _ => "converged",
        })
    }

    /// A settle that timed out: `abort` ends the run with `msg`; otherwise it is a warning,
    /// on the console and in the manifest.
    fn settle_timed_out(&mut self, msg: String, on_timeout: OnTimeout) -> Result<(), Stop> {
        if on_timeout == OnTimeout::Abort {
            return Err(Stop::SettleTimeout(msg));
        }
        self.progress.note(&format!("warning: {msg}"));
        self.rec.update_manifest(|m| m.warnings.push(msg))?;
        Ok(())
    }

    /// The quasistatic window ending now: the mean over the last `force_window_s` (thesis
    /// §4.3), or the last sample, and the spread of the step's channel in it.
    fn quasistatic_window(&self, s: &Step) -> Window {
        let t_end_window = self.now();
        let from = t_end_window.saturating_sub((s.force_window_s * 1e9) as u64);
        let samples: Vec<Wrench> = if s.force_window_s > 0.0 {
            self.readings
                .window
                .iter()
                .filter(|(t, _, _)| *t >= from)
                .map(|(_, w, _)| *w)
                .collect()
        } else {
            self.readings
                .window
                .back()
                .map(|(_, w, _)| *w)
                .into_iter()
                .collect()
        };
        let mean = (!samples.is_empty()).then(|| Wrench::mean(samples.iter().copied()));
        let channel = s.axis.map(Channel::along).unwrap_or(Channel::Fz);
        let std = mean.map(|m| {
            let c = channel.of(&m);
            (samples
                .iter()
                .map(|w| (channel.of(w) - c).powi(2))
                .sum::<f64>()
                / samples.len().max(1) as f64)
                .sqrt()
        });
        Window { samples, mean, std }
    }

    /// Where the step's axis ended: absolute, and from its origin (both `None` without an
    /// axis).
    async fn step_position(
        &mut self,
        axis: Option<AxisRole>,
    ) -> Result<(Option<f64>, Option<f64>), Stop> {
        Ok(match axis {
            Some(a) => {
                let p = self.position(a).await?;
                (
                    Some(p),
                    Some(p - self.origin.get(&a).copied().unwrap_or(0.0)),
                )
            }
            None => (None, None),
        })
    }

    /// The step's row, and its quasistatic wrench: the window's mean, with F∞ in place of
    /// the settled channel under adaptive settling (its window mean keeps its own column).
    fn step_row(&self, s: &Step, m: &Measured) -> (StepRow, Option<Wrench>) {
        let round = round_micro;
        let settled_channel = match s.settle {
            SettleSpec::Adaptive { channel, .. } => Some(channel),
            _ => None,
        };
        let window_mean = settled_channel
            .zip(m.window.mean)
            .map(|(c, w)| round(c.of(&w)));
        let mean = match (settled_channel, &m.f_inf, m.window.mean) {
            (Some(c), Some(e), Some(w)) if e.f_inf.is_finite() => Some(c.with(w, e.f_inf)),
            (_, _, w) => w,
        };
        let row = StepRow {
            step: s.step,
            trial: self.trial,
            label: s.label.clone(),
            phase: s.phase.name().into(),
            axis: s.axis.map(|a| a.name().to_string()).unwrap_or_default(),
            target: match s.target {
                Some(Target::To(v)) => Some(round(v)),
                Some(Target::By(_)) => m.position.map(round),
                None => None,
            },
            position: m.position.map(round),
            unit: s.unit.map(|u| u.symbol()).unwrap_or("").into(),
            fx_n: mean.map(|w| round(w.fx_n)),
            fy_n: mean.map(|w| round(w.fy_n)),
            fz_n: mean.map(|w| round(w.fz_n)),
            tx_nmm: mean.map(|w| round(w.tx_nmm)),
            ty_nmm: mean.map(|w| round(w.ty_nmm)),
            tz_nmm: mean.map(|w| round(w.tz_nmm)),
            settle_s: round(m.settle_s),
            settle_verdict: m.verdict.into(),
            force_window_s: s.force_window_s,
            window_samples: m.window.samples.len() as u32,
            window_std: m.window.std.map(round),
            saturated: self.step_saturated,
            frames: s.frames,
            position_abs: m.position_abs.map(round),
            t_start_ns: m.t_start_ns,
            settle_end_ns: m.settle_end_ns,
            t_end_ns: self.now(),
            f_inf: m.f_inf.as_ref().map(|e| round(e.f_inf)),
            f_inf_sigma: m.f_inf.as_ref().map(|e| round(e.sigma)),
            window_mean,
        };
        (row, mean)
    }

    /// Records the finished step: its row (steps.csv, the live view's curve, the simulated
    /// truth, the manifest's count, the journal), a one-line summary, and the step number
    /// cleared.
    async fn record_step(
        &mut self,
        s: &Step,
        row: &StepRow,
        mean: Option<Wrench>,
        measured: &Measured,
    ) -> Result<(), Stop> {
        self.rec.step(row)?;
        if let Some(msg) = self.rec.mcap_failure() {
            self.progress.note(&format!("warning: {msg}"));
            self.rec.update_manifest(|m| m.warnings.push(msg))?;
        }
        if let Some(b) = self.progress.live() {
            let point = liveview::CurvePoint {
                step: row.step,
                label: row.label.clone(),
                axis: row.axis.clone(),
                position: row.position.unwrap_or(f64::NAN),
                unit: row.unit.clone(),
                wrench: [row.fx_n, row.fy_n, row.fz_n, row.tz_nmm].map(|v| v.unwrap_or(f64::NAN)),
            };
            b.step_done(point, row.trial, row.t_start_ns, row.t_end_ns);
        }
        if let Some(m) = &self.monitor
            && let Some(truth) = m.truth().await
        {
            self.rec.sim_truth(s.step, self.trial, &truth)?;
        }
        let steps_done = row.step;
        self.rec
            .update_manifest(|m| m.steps_completed = steps_done)?;
        let t = self.now();
        self.rec.journal(t, "step_end", json!(row), true)?;
        let summary = step_summary(&self.what, mean, measured.verdict, measured.settle_s);
        self.progress.step_done(s.step, &summary);
        self.step = 0;
        if let Some(m) = &self.monitor {
            m.set_step(0);
        }
        Ok(())
    }
}

/// Why an adaptive settle timed out: F∞ of `channel` was not known within `tolerance` after
/// the whole `max_s`, with the last estimate if there was one.
fn adaptive_timeout_message(
    step: u32,
    channel: Channel,
    tolerance: f64,
    max_s: f64,
    last: Option<&Equilibrium>,
) -> String {
    format!(
        "step {}: {}∞ was not known within {} % after the whole {} s settle{}",
        step,
        channel.label(),
        fmt_value(tolerance * 100.0),
        fmt_value(max_s),
        last.map_or(String::new(), |e| format!(
            " (F∞ {} ± {} {}{})",
            fmt_value((e.f_inf * 1e4).round() / 1e4),
            fmt_value((e.sigma * 1e4).round() / 1e4),
            if channel.is_torque() { "N·mm" } else { "N" },
            if e.drifting { ", still drifting" } else { "" }
        ))
    )
}

/// The console's line for a finished step: what it did, its quasistatic wrench, and how
/// long (s) and how it settled.
fn step_summary(what: &str, mean: Option<Wrench>, verdict: &str, settle_s: f64) -> String {
    match mean {
        Some(m) => {
            // The tangential channel that carries something: Fx on the shear stage, Fy in
            // a grasp (the lift's load).
            let (name, t) = if m.fy_n.abs() > m.fx_n.abs() {
                ("Fy", m.fy_n)
            } else {
                ("Fx", m.fx_n)
            };
            format!(
                "{what}: Fz {:.3} N, {name} {:.3} N, Tz {:.3} N·mm; settled {:.0} s ({verdict})",
                m.fz_n, t, m.tz_nmm, settle_s
            )
        }
        None => format!("{what}: settled {:.0} s ({verdict})", settle_s),
    }
}
