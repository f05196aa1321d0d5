//! Plausible ranges of every value of a rig file, each with why it ends where it does: a
//! value can be well-formed and still impossible (`fps: 1e12 Hz` divided a frame period down
//! to zero, a 100000×65535 camera aborted on allocation, `time_scale: 1e-300` stalled a run).
//! Non-finite values are outside every range.

use super::{
    AxisConfig, AxisUnit, ConfigIssue, ForceConfig, RigConfig, SimConfig, TwinsConfig, YamlPath,
};
use crate::config::CameraConfig;
use crate::units::AxisQuantity;

/// The issues found so far; `within` adds one when a value is outside its range.
#[derive(Default)]
struct Ranges {
    issues: Vec<ConfigIssue>,
}

/// One range: `[lo, hi]` in `unit`, and why a real bench stays inside it.
struct Range<'a> {
    lo: f64,
    hi: f64,
    unit: &'a str,
    why: &'a str,
}

impl Ranges {
    fn within(&mut self, path: YamlPath, what: &str, v: f64, range: Range<'_>) {
        let Range { lo, hi, unit, why } = range;
        if (lo..=hi).contains(&v) {
            return;
        }
        let u = if unit.is_empty() {
            String::new()
        } else {
            format!(" {unit}")
        };
        self.issues.push(ConfigIssue {
            path,
            message: format!(
                "{what} {}{u} is outside the plausible range [{lo}, {hi}]{u}: {why}",
                crate::units::fmt_any(v)
            ),
            fix: format!("write a value between {lo} and {hi}{u}"),
        });
    }

    fn axis(&mut self, at: &YamlPath, axis: &AxisConfig) {
        let u = axis.unit().symbol();
        let (travel_limit, speed_limit, res_limit) = match axis.unit() {
            AxisUnit::Mm => (10_000.0, 1_000.0, 10.0),
            AxisUnit::Deg => (36_000.0, 36_000.0, 90.0),
        };
        let r = |lo, hi, unit, why| Range { lo, hi, unit, why };
        for (i, q) in axis.travel.iter().enumerate() {
            let why = "bench stages travel at most 10 m (or 100 turns)";
            let range = r(-travel_limit, travel_limit, u, why);
            self.within(at.key("travel").index(i), "travel limit", q.raw(), range);
        }
        let speed_unit = format!("{u}/s");
        let why = "stages move between 1 nm/s and 1 m/s";
        let range = r(1e-6, speed_limit, &speed_unit, why);
        self.within(
            at.key("max_speed"),
            "max_speed",
            axis.max_speed.value,
            range,
        );
        let why = "stage steps lie between 0.1 nm and 10 mm (or 90°)";
        let range = r(1e-7, res_limit, u, why);
        self.within(
            at.key("resolution"),
            "resolution",
            axis.resolution.raw(),
            range,
        );
        if let Some(rate) = axis.poll_rate {
            let why = "controllers answer between 0.1 and 1000 polls a second";
            self.within(
                at.key("poll_rate"),
                "poll_rate",
                rate.hz(),
                r(0.1, 1000.0, "Hz", why),
            );
        }
        self.in_position(at, axis, res_limit);
        if let Some(g) = axis.start_grace {
            let why = "drives show motion within a minute of a command";
            self.within(
                at.key("start_grace"),
                "start_grace",
                g.s(),
                r(0.0, 60.0, "s", why),
            );
        }
        if let Some(n) = axis.move_retries {
            let why = "a move that misses ten times will miss again";
            let range = r(0.0, 10.0, "", why);
            self.within(at.key("move_retries"), "move_retries", f64::from(n), range);
        }
        if let Some(m) = axis.microstep {
            let why = "microsteps lie between 1 pm and 1 mm (or 1°)";
            self.within(at.key("microstep"), "microstep", m, r(1e-9, 1.0, u, why));
        }
    }

    fn in_position(&mut self, at: &YamlPath, axis: &AxisConfig, res_limit: f64) {
        let Some(w) = axis.in_position else { return };
        let u = axis.unit().symbol();
        if matches!(w, AxisQuantity::Percent(_)) || w.natural_unit() != axis.unit() {
            // Out of every range: a window in another unit is never right.
            let range = Range {
                lo: 0.0,
                hi: 0.0,
                unit: u,
                why: "write it in the axis unit",
            };
            let what = "in_position (not in the axis unit)";
            self.within(at.key("in_position"), what, f64::NAN, range);
        } else {
            let range = Range {
                lo: axis.resolution.raw() * (1.0 - 1e-9),
                hi: res_limit * 10.0,
                unit: u,
                why: "an in-position window is at least the resolution and at most a few steps of the stage",
            };
            self.within(at.key("in_position"), "in_position", w.raw(), range);
        }
    }

    fn force(&mut self, f: &ForceConfig) {
        let at = YamlPath::root().key("force");
        if let Some(r) = f.max_rate {
            let range = Range {
                lo: 1.0,
                hi: 10_000.0,
                unit: "Hz",
                why: "force sensors stream 1 Hz to 10 kHz (the Net F/T at most 7 kHz)",
            };
            self.within(at.key("max_rate"), "max_rate", r.hz(), range);
        }
        for (key, v) in [
            ("counts_per_force", f.counts_per_force),
            ("counts_per_torque", f.counts_per_torque),
        ] {
            if let Some(v) = v {
                let range = Range {
                    lo: 1e-6,
                    hi: 1e12,
                    unit: "",
                    why: "calibration counts per unit are positive and finite",
                };
                self.within(at.key(key), key, v, range);
            }
        }
    }

    fn camera(&mut self, c: &CameraConfig) {
        let at = YamlPath::root().key("camera");
        let side = "cameras deliver 16 to 8192 pixels a side";
        for (key, v) in [("width", c.width), ("height", c.height)] {
            let range = Range {
                lo: 16.0,
                hi: 8192.0,
                unit: "px",
                why: side,
            };
            self.within(at.key(key), key, f64::from(v), range);
        }
        let range = Range {
            lo: 0.01,
            hi: 1000.0,
            unit: "Hz",
            why: "cameras run at one frame a minute to 1000 frames a second",
        };
        self.within(at.key("fps"), "fps", c.fps.hz(), range);
    }

    fn sim(&mut self, sim: &SimConfig) {
        let at = YamlPath::root().key("sim");
        if let Some(b) = sim.force_bias {
            let range = Range {
                lo: 0.0,
                hi: 10.0,
                unit: "N",
                why: "a Nano17 reads at most a few newtons before a tare",
            };
            self.within(at.key("force_bias"), "force_bias", b.n(), range);
        }
        for (key, v) in [
            ("normal_contact", Some(sim.normal_contact)),
            ("grip_contact", sim.grip_contact),
        ] {
            if let Some(v) = v {
                let range = Range {
                    lo: -10_000.0,
                    hi: 10_000.0,
                    unit: "mm",
                    why: "a contact position inside any stage's travel",
                };
                self.within(at.key(key), key, v.mm(), range);
            }
        }
    }

    fn twins(&mut self, t: &TwinsConfig) {
        let range = Range {
            lo: 0.01,
            hi: 100_000.0,
            unit: "",
            why: "slower than 1/100 a settle takes days; faster than 10⁵ the wall's millisecond is 100 s of run",
        };
        let at = YamlPath::root().key("twins").key("time_scale");
        self.within(at, "time_scale", t.time_scale, range);
    }
}

impl RigConfig {
    /// Every value outside its plausible range, as issues naming its place and the fix.
    pub(super) fn check_ranges(&self) -> Vec<ConfigIssue> {
        let mut ranges = Ranges::default();
        for (role, axis) in &self.axes {
            ranges.axis(&YamlPath::root().key("axes").key(role.name()), axis);
        }
        if let Some(f) = &self.force {
            ranges.force(f);
        }
        if let Some(c) = &self.camera {
            ranges.camera(c);
        }
        if let Some(sim) = &self.sim {
            ranges.sim(sim);
        }
        if let Some(t) = &self.twins {
            ranges.twins(t);
        }
        ranges.issues
    }
}
