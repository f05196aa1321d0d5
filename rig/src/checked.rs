//! Device values checked at the boundary: what a device says is data only if it could be.
//!
//! A controller answering `1TPNaN`, a drive reading back 10³⁰⁸, a force sensor sending a
//! non-finite wrench or one a hundred times its range, a sample older than the one before
//! it: each is a device error that names the device and the value, never a number that
//! flows into steps.csv, a settle rule or a safety check. Every axis and force sensor that
//! [`crate::open`] returns is wrapped here, real or simulated, so no driver can forget.

use std::sync::Arc;

use async_trait::async_trait;

use crate::device::{
    Axis, AxisInfo, AxisStatus, AxisStopper, ForceInfo, ForceSample, ForceSensor, SimTruth,
};
use crate::{RigError, quote};

/// How far beyond its travel a referenced axis may read before the reading is absurd:
/// stages overshoot and settle at their limits, and a rig file's travel may be narrower
/// than the stage's, but not by a tenth of the span.
fn travel_margin(info: &AxisInfo) -> f64 {
    0.1 * (info.travel_max - info.travel_min).abs() + 10.0 * info.resolution
}

/// Force and torque beyond this multiple of the sensor's range are not a saturated reading
/// (the status bit says that) but a garbled one.
const FORCE_RANGE_FACTOR: f64 = 20.0;

/// An axis whose positions are checked.
pub struct CheckedAxis {
    inner: Box<dyn Axis>,
}

impl CheckedAxis {
    pub fn new(inner: Box<dyn Axis>) -> Self {
        Self { inner }
    }
}

/// Why `status` cannot be a stage's: `None` if it can.
pub fn implausible_position(info: &AxisInfo, status: &AxisStatus) -> Option<String> {
    let p = status.position;
    let unit = info.unit.symbol();
    if !p.is_finite() {
        return Some(format!("reported position {p}, which is not a number"));
    }
    if !status.referenced {
        return None;
    }
    let margin = travel_margin(info);
    if p < info.travel_min - margin || p > info.travel_max + margin {
        return Some(format!(
            "reported position {p} {unit}, outside its travel [{}, {}] {unit} by more than {margin:.3} {unit}",
            info.travel_min, info.travel_max
        ));
    }
    None
}

#[async_trait]
impl Axis for CheckedAxis {
    fn info(&self) -> &AxisInfo {
        self.inner.info()
    }

    fn stopper(&self) -> Arc<dyn AxisStopper> {
        self.inner.stopper()
    }

    async fn home(&mut self) -> Result<(), RigError> {
        self.inner.home().await
    }

    async fn move_to(&mut self, target: f64, speed: f64) -> Result<(), RigError> {
        self.inner.move_to(target, speed).await
    }

    async fn status(&mut self) -> Result<AxisStatus, RigError> {
        let s = self.inner.status().await?;
        let info = self.inner.info();
        match implausible_position(info, &s) {
            None => Ok(s),
            Some(why) => Err(RigError::Garbled {
                device: format!("{} axis ({})", info.role, quote(&info.identity)),
                detail: format!(
                    "{why}; fix: check the controller's units and reference, then run `gelrig probe`"
                ),
            }),
        }
    }

    async fn stop(&mut self) -> Result<(), RigError> {
        self.inner.stop().await
    }
}

/// A force sensor whose samples are checked.
pub struct CheckedForce {
    inner: Box<dyn ForceSensor>,
    last_t_ns: Option<u64>,
}

impl CheckedForce {
    pub fn new(inner: Box<dyn ForceSensor>) -> Self {
        Self {
            inner,
            last_t_ns: None,
        }
    }
}

/// Why `s` cannot be a sample of a sensor described by `info`: `None` if it can.
pub fn implausible_sample(info: &ForceInfo, s: &ForceSample) -> Option<String> {
    let w = s.wrench.as_array();
    let names = ["Fx", "Fy", "Fz", "Tx", "Ty", "Tz"];
    for (k, v) in w.iter().enumerate() {
        if !v.is_finite() {
            return Some(format!("{} = {v}, which is not a number", names[k]));
        }
        let r = &info.range;
        let (limit, unit) = match k {
            0 | 1 => (r.fxy_n, "N"),
            2 => (r.fz_n, "N"),
            _ => (r.torque_nmm, "N·mm"),
        };
        if v.abs() > FORCE_RANGE_FACTOR * limit {
            return Some(format!(
                "{} = {v} {unit}, {FORCE_RANGE_FACTOR}× beyond the sensor's {limit} {unit} range",
                names[k]
            ));
        }
    }
    None
}

#[async_trait]
impl ForceSensor for CheckedForce {
    fn info(&self) -> &ForceInfo {
        self.inner.info()
    }

    fn records_lost(&self) -> u64 {
        self.inner.records_lost()
    }

    async fn read(&mut self) -> Result<ForceSample, RigError> {
        let s = self.inner.read().await?;
        let info = self.inner.info();
        let device = || format!("force sensor ({})", quote(&info.identity));
        if let Some(why) = implausible_sample(info, &s) {
            return Err(RigError::Garbled {
                device: device(),
                detail: format!("{why}; fix: check the sensor's calibration, cable and power"),
            });
        }
        if let Some(last) = self.last_t_ns
            && s.t_ns < last
        {
            return Err(RigError::Garbled {
                device: device(),
                detail: format!(
                    "a sample stamped {} ns came after one stamped {last} ns",
                    s.t_ns
                ),
            });
        }
        self.last_t_ns = Some(s.t_ns);
        Ok(s)
    }

    async fn truth(&mut self) -> Option<SimTruth> {
        self.inner.truth().await
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::device::{ForceRange, Wrench};
    use crate::units::AxisUnit;

    fn info() -> AxisInfo {
        AxisInfo {
            role: "normal".into(),
            unit: AxisUnit::Mm,
            travel_min: 0.0,
            travel_max: 25.0,
            max_speed: 2.0,
            resolution: 0.002,
            identity: "test stage".into(),
        }
    }

    fn at(position: f64, referenced: bool) -> AxisStatus {
        AxisStatus {
            position,
            moving: false,
            referenced,
            in_position: None,
        }
    }

    #[test]
    fn positions_that_cannot_be_a_stage() {
        let i = info();
        assert!(implausible_position(&i, &at(12.0, true)).is_none());
        // Overshoot at the limits is real.
        assert!(implausible_position(&i, &at(25.1, true)).is_none());
        assert!(implausible_position(&i, &at(-0.5, true)).is_none());
        for bad in [f64::NAN, f64::INFINITY, 1e308, -40.0, 30.0] {
            assert!(implausible_position(&i, &at(bad, true)).is_some(), "{bad}");
        }
        // An unreferenced stage may read anything finite; never NaN.
        assert!(implausible_position(&i, &at(1e6, false)).is_none());
        assert!(implausible_position(&i, &at(f64::NAN, false)).is_some());
    }

    #[test]
    fn samples_that_cannot_be_a_sensor() {
        let info = ForceInfo {
            model: "Nano17".into(),
            range: ForceRange::NANO17,
            max_rate_hz: 1000.0,
            identity: "test".into(),
        };
        let sample = |w: Wrench| ForceSample {
            t_ns: 0,
            ft_seq: 0,
            wrench: w,
            status: 0,
        };
        let ok = Wrench {
            fz_n: 80.0,
            ..Wrench::default()
        };
        assert!(implausible_sample(&info, &sample(ok)).is_none());
        for w in [
            Wrench {
                fz_n: f64::NAN,
                ..Wrench::default()
            },
            Wrench {
                fx_n: 2000.0,
                ..Wrench::default()
            },
            Wrench {
                tz_nmm: -1e12,
                ..Wrench::default()
            },
        ] {
            assert!(implausible_sample(&info, &sample(w)).is_some(), "{w:?}");
        }
    }
}
