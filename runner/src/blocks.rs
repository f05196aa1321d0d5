//! The blocks of a protocol as the plan task runs them: home, tare, approach, and the step
//! (move, disturb, settle, quasistatic window, frames, row).

use rig::config::AxisRole;
use rig::units::fmt_value;
use rig::{RigError, Wrench};
use serde_json::json;

use super::Stop;
use super::exec::Exec;
use super::settle::SettleTrack;
use super::wait::Until;
use experiments::protocol::compile::{ApproachSpec, DisturbSpec, SettleSpec, Step, Target};
use experiments::protocol::schema::{Channel, OnTimeout};
use rundir::write::StepRow;

/// Squeeze above which a grip move ends still holding, N.
const GRIPPING_N: f64 = 0.2;

impl Exec<'_> {
    pub(super) async fn home(&mut self, axes: &[AxisRole]) -> Result<(), Stop> {
        self.what = format!(
            "home {}",
            axes.iter().map(|a| a.name()).collect::<Vec<_>>().join(", ")
        );
        self.set_phase("homing");
        self.home_axes(axes).await?;
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

    pub(super) async fn tare(&mut self, duration_s: f64) -> Result<(), Stop> {
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
        if let Some(m) = &self.monitor {
            m.set_tare(self.tare);
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

    pub(super) async fn approach(&mut self, a: &ApproachSpec) -> Result<(), Stop> {
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
        let unit = ax.info().unit.symbol();
        ax.move_to(start + max_travel, speed).await?;
        self.targets.insert(axis, start + max_travel);
        let channel = Channel::along(axis);
        let what = format!(
            "an approach creeping {} {unit} from {} {unit} at {} {unit}/s",
            fmt_value(max_travel),
            fmt_value((start * 1e6).round() / 1e6),
            fmt_value(speed)
        );
        let mut deadline = self.deadline_for(axis, max_travel, speed, what);
        deadline.arrival = Some(self.arrival(axis, start + max_travel, speed));
        self.wait(&mut Until::Contact {
            channel,
            threshold: until_n,
            deadline,
        })
        .await?;
        if let Some(ax) = self.rig.axes.get_mut(&axis) {
            ax.stop().await?;
        }
        // How far past the crossing the stage can have crept: from the reading before the
        // one that crossed to the stop (a scaled clock's loop latency, a slow reader on a
        // bench), and never less than the plan's reading period.
        let nominal_s = self
            .monitor
            .as_ref()
            .map_or(0.0, |m| m.reading_period_ns() as f64 * 1e-9);
        let gap_s = self.previous_latest_ns.map_or(nominal_s, |before| {
            (self.now().saturating_sub(before) as f64 * 1e-9).max(nominal_s)
        });
        let what = "stopping at contact".to_string();
        let deadline = self.deadline_for(axis, 0.0, speed, what);
        self.wait(&mut Until::Motion(vec![deadline])).await?;
        let found = self.position(axis).await?;
        let resolution = self
            .rig
            .axes
            .get(&axis)
            .map_or(0.0, |a| a.info().resolution);
        let mut contact = found;
        // Inside a trial every approach finds its own contact (a grasp's is where the
        // object happens to be): only the bench's origin, outside trials, is checked.
        if self.trial == 0
            && let Some(r) = self.resume.as_mut()
            && let Some((recorded, jitter)) =
                r.check_origin(axis, found, speed, gap_s, resolution)?
        {
            // Within that jitter the difference says nothing about the bench: the recorded
            // origin stays, so the resumed steps go to the stage positions the run's first
            // segment used. Beyond it (and within the tolerance) the sensor or stage has
            // moved that much, and the depths are kept from the new contact.
            let moved = (found - recorded).abs() > jitter + 1e-9;
            if !moved {
                contact = recorded;
            }
            let tolerance = r.origin_tolerance;
            let t = self.now();
            self.rec.journal(
                t,
                "contact_rechecked",
                json!({ "axis": axis, "recorded": recorded, "found": found, "difference": found - recorded, "jitter": jitter, "origin": contact, "tolerance": tolerance }),
                true,
            )?;
            self.progress.note(&format!(
                "resume: contact {} from the recorded origin (the approaches' jitter {}, tolerance ±{}); {}{}",
                fmt_value(((found - recorded) * 1e6).round() / 1e6),
                fmt_value((jitter * 1e6).round() / 1e6),
                fmt_value(tolerance),
                if moved {
                    "beyond the jitter: the new contact is the origin"
                } else {
                    "within the jitter: the recorded origin stays"
                },
                if jitter >= tolerance {
                    "; the jitter is as wide as the tolerance, so a moved surface cannot be told from it: approach more slowly (or on a slower clock) to check the origin"
                } else {
                    ""
                }
            ));
        }
        self.origin.insert(axis, contact);
        self.targets.insert(axis, found);
        let force = self.latest.map(|(_, w)| channel.of(&w)).unwrap_or(0.0);
        if let Some(t) = self.tactile.as_mut() {
            t.gripped();
        }
        self.rec.update_manifest(|m| {
            m.origins.insert(axis.to_string(), contact);
        })?;
        let t = self.now();
        self.rec.journal(
            t,
            "contact",
            json!({ "axis": axis, "position": contact, "found": found, "force": force, "reading_gap_s": gap_s }),
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

    /// A move's tactile condition was met: the axis stops where it is (journaled).
    async fn tactile_stop(&mut self, axis: AxisRole, speed: f64) -> Result<(), Stop> {
        self.slip_hit = false;
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
        let squeeze = self.latest.map(|(_, w)| w.fz_n.abs()).unwrap_or(0.0);
        if let Some(t) = self.tactile.as_mut() {
            if squeeze >= GRIPPING_N {
                t.gripped();
            } else {
                t.released();
            }
        }
    }

    pub(super) async fn step(&mut self, s: &Step) -> Result<(), Stop> {
        self.step = s.step;
        if let Some(m) = &self.monitor {
            m.set_step(s.step);
        }
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
            // The whole relaxation is fitted.
            SettleSpec::Adaptive { max_s, .. } => (max_s * 1e9) as u64,
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
            self.slip_stop = s.until_slip.map(|l| l.state());
            self.slip_hit = false;
            let moved = self.move_axis(axis, abs, s.speed).await;
            self.slip_stop = None;
            moved?;
            if self.slip_hit {
                self.tactile_stop(axis, s.speed).await?;
            }
            if axis == AxisRole::Grip {
                self.grip_changed();
            }
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
        let mut adaptive = None;
        let verdict = match s.settle {
            SettleSpec::None => "none",
            SettleSpec::Adaptive {
                channel,
                tolerance,
                min_s,
                max_s,
                on_timeout,
            } => {
                self.set_phase("settling");
                let mut until = Until::Adaptive(super::adaptive::AdaptiveTrack {
                    channel,
                    tolerance,
                    start_ns: settle_start,
                    min_ns: (min_s * 1e9) as u64,
                    max_ns: (max_s * 1e9) as u64,
                    window_s: s.force_window_s.max(1.0),
                    next_ns: settle_start,
                    last: None,
                    verdict: None,
                });
                self.wait(&mut until).await?;
                let Until::Adaptive(track) = until else {
                    unreachable!("the adaptive wait keeps its kind")
                };
                let verdict = track.verdict.unwrap_or("timeout");
                if let Some(e) = &track.last {
                    self.gel
                        .settled_at(Some(track.start_s()), e, track.record(&self.window));
                }
                if let Some(msg) = self.gel.newly_learned() {
                    self.progress.note(&msg);
                    let t = self.now();
                    self.rec
                        .journal(t, "gel_time_constants", json!({ "note": msg }), false)?;
                }
                if verdict == "timeout" {
                    let msg = format!(
                        "step {}: {}∞ was not known within {} % after the whole {} s settle{}",
                        s.step,
                        channel.label(),
                        fmt_value(tolerance * 100.0),
                        fmt_value(max_s),
                        track.last.as_ref().map_or(String::new(), |e| format!(
                            " (F∞ {} ± {} {}{})",
                            fmt_value((e.f_inf * 1e4).round() / 1e4),
                            fmt_value((e.sigma * 1e4).round() / 1e4),
                            if channel.is_torque() { "N·mm" } else { "N" },
                            if e.drifting { ", still drifting" } else { "" }
                        ))
                    );
                    if on_timeout == OnTimeout::Abort {
                        return Err(Stop::SettleTimeout(msg));
                    }
                    self.progress.note(&format!("warning: {msg}"));
                    self.rec.update_manifest(|m| m.warnings.push(msg))?;
                }
                adaptive = Some(track);
                verdict
            }
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
                        "step {}: |d{}/dt| stayed above {} {} for the whole {} s settle",
                        s.step,
                        channel.label(),
                        fmt_value(below),
                        channel.rate_unit(),
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
        let f_inf = adaptive.as_ref().and_then(|a| a.last.clone());
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
        // Adaptive settling: the quasistatic value of the settled channel is F∞; its window
        // mean stays in its own column.
        let settled_channel = match s.settle {
            SettleSpec::Adaptive { channel, .. } => Some(channel),
            _ => None,
        };
        let window_mean = settled_channel.zip(mean).map(|(c, m)| round(c.of(&m)));
        let mean = match (settled_channel, &f_inf, mean) {
            (Some(c), Some(e), Some(m)) if e.f_inf.is_finite() => Some(c.with(m, e.f_inf)),
            (_, _, m) => m,
        };
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
            f_inf: f_inf.as_ref().map(|e| round(e.f_inf)),
            f_inf_sigma: f_inf.as_ref().map(|e| round(e.sigma)),
            window_mean,
        };
        self.rec.step(&row)?;
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
        let summary = match mean {
            Some(m) => {
                // The tangential channel that carries something: Fx on the shear stage, Fy in
                // a grasp (the lift's load).
                let (name, t) = if m.fy_n.abs() > m.fx_n.abs() {
                    ("Fy", m.fy_n)
                } else {
                    ("Fx", m.fx_n)
                };
                format!(
                    "{}: Fz {:.3} N, {name} {:.3} N, Tz {:.3} N·mm; settled {:.0} s ({verdict})",
                    self.what, m.fz_n, t, m.tz_nmm, settle_s
                )
            }
            None => format!("{}: settled {:.0} s ({verdict})", self.what, settle_s),
        };
        self.progress.step_done(s.step, &summary);
        self.step = 0;
        if let Some(m) = &self.monitor {
            m.set_step(0);
        }
        Ok(())
    }
}
