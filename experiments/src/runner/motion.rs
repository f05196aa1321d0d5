//! Moving axes with deadlines, reading them, and the axes and frame streams.
//!
//! A move's deadline is its nominal duration (distance / speed) times 1.5 plus a grace of
//! [`MOVE_GRACE_S`]: real stages accelerate and settle, and serial polling adds latency, but
//! a stage still busy long after that is stuck (a jam, a stalled motor, a controller that
//! never leaves BUSY) and is stopped and reported instead of being waited on forever.

use rig::RigError;
use rig::config::AxisRole;
use rig::units::fmt_value;

use super::Stop;
use super::exec::Exec;
use super::wait::{Deadline, Until};

/// Slack on every move's deadline, s: acceleration, settling and polling latency.
pub(super) const MOVE_GRACE_S: f64 = 5.0;

/// Homing has no known distance: the whole travel at a quarter of the axis's maximum
/// speed (homing runs slower than moves on most controllers), plus a minute.
fn home_allowance_s(span: f64, max_speed: f64) -> f64 {
    4.0 * span.abs() / max_speed.max(1e-9) + 60.0
}

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
        }
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
        let deadline = self.deadline_for(axis, target_abs - here, speed, what);
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
                watch.push(Deadline {
                    axis: *a,
                    by_ns: self.now() + (allowed_s * 1e9) as u64,
                    allowed_s,
                    what: "homing".into(),
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
        self.rec.frame(&frame, self.step, self.trial)?;
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
