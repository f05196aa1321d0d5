//! The blocks of a protocol as the plan task runs them: home, tare and approach (the step
//! is [`super::step`]).

use rig::config::AxisRole;
use rig::units::fmt_value;
use rig::{RigError, Wrench};
use serde_json::json;

use super::Stop;
use super::exec::Exec;
use super::wait::Until;
use experiments::protocol::compile::ApproachSpec;
use experiments::protocol::schema::Channel;

impl Exec<'_> {
    /// Homes `axes` and takes where each comes to rest as its target (an axis that reports
    /// no reference afterwards fails the run).
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

    /// Takes the mean of `duration_s` of readings as the new zero of the force sensor (added
    /// to the offset so far), and re-tares the samples already kept.
    pub(super) async fn tare(&mut self, duration_s: f64) -> Result<(), Stop> {
        self.what = "tare".into();
        self.set_phase("taring");
        let start = self.now();
        self.readings.keep_ns = self.readings.keep_ns.max((duration_s * 1e9) as u64);
        let end = start + (duration_s * 1e9) as u64;
        self.wait(&mut Until::Time(end)).await?;
        let mean = Wrench::mean(
            self.readings
                .window
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
        for (_, w, _) in self.readings.window.iter_mut() {
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

    /// An approach: reference frames, the move to the start, the creep to contact, and the
    /// contact found taken as the axis's origin (checked against a resumed run's).
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
        let Some((found, gap_s)) = self
            .creep_to_contact(axis, speed, until_n, max_travel)
            .await?
        else {
            return Ok(());
        };
        let contact = self.recheck_origin(axis, found, speed, gap_s)?;
        self.record_contact(axis, contact, found, gap_s)
    }

    /// Creeps `axis` at `speed` (axis unit/s) for up to `max_travel` until |force along it|
    /// reaches `until_n`, stops it, and waits for it to rest. Returns where it rests and how
    /// far past the crossing the reading can have been noticed, s; `None` when the rig has no
    /// such axis.
    async fn creep_to_contact(
        &mut self,
        axis: AxisRole,
        speed: f64,
        until_n: f64,
        max_travel: f64,
    ) -> Result<Option<(f64, f64)>, Stop> {
        let start = self.position(axis).await?;
        self.set_phase("creeping to contact");
        let Some(ax) = self.rig.axes.get_mut(&axis) else {
            return Ok(None);
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
        let gap_s = self
            .readings
            .previous_latest_ns
            .map_or(nominal_s, |before| {
                (self.now().saturating_sub(before) as f64 * 1e-9).max(nominal_s)
            });
        let what = "stopping at contact".to_string();
        let deadline = self.deadline_for(axis, 0.0, speed, what);
        self.wait(&mut Until::Motion(vec![deadline])).await?;
        let found = self.position(axis).await?;
        Ok(Some((found, gap_s)))
    }

    /// The origin a contact `found` on `axis` gives: itself, except in a resumed run outside
    /// trials, where it is compared with the recorded origin (refused beyond the tolerance)
    /// and the recorded one stays when the difference is within the approaches' jitter.
    fn recheck_origin(
        &mut self,
        axis: AxisRole,
        found: f64,
        speed: f64,
        gap_s: f64,
    ) -> Result<f64, Stop> {
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
        Ok(contact)
    }

    /// Takes `contact` as `axis`'s origin (the stage rests at `found`): the tactile path's
    /// reference, the manifest, the journal and the console.
    fn record_contact(
        &mut self,
        axis: AxisRole,
        contact: f64,
        found: f64,
        gap_s: f64,
    ) -> Result<(), Stop> {
        let channel = Channel::along(axis);
        self.origin.insert(axis, contact);
        self.targets.insert(axis, found);
        let force = self
            .readings
            .latest
            .map(|(_, w)| channel.of(&w))
            .unwrap_or(0.0);
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
}
