//! Settling and capture: the settle rule of a step, its quasistatic force window and
//! frames, and whether a window can hold the samples it averages.

use rig::config::{AxisRole, YamlPath};
use rig::units::{SettleRate, fmt_value};

use super::{Compiler, EPS, SettleSpec, StreamRates};
use crate::protocol::schema::{Capture, Channel, Settle};

impl Compiler<'_> {
    pub(super) fn settle(
        &mut self,
        s: &Settle,
        axis: Option<AxisRole>,
        window_s: f64,
        path: &YamlPath,
    ) -> SettleSpec {
        match s {
            Settle::Fixed(d) => {
                if d.s() < 0.0 {
                    self.error(
                        &path.key("fixed"),
                        "a settle time cannot be negative",
                        "write e.g. `180 s`",
                    );
                }
                if window_s > d.s() + EPS {
                    self.error(
                        &path.key("fixed"),
                        format!(
                            "the settle ({}) is shorter than the capture's force window ({} s)",
                            d,
                            fmt_value(window_s)
                        ),
                        "lengthen the settle or shorten `capture.force_window`",
                    );
                }
                SettleSpec::Fixed { s: d.s().max(0.0) }
            }
            Settle::Rate(r) => {
                let at = path.key("rate");
                let channel = r
                    .signal
                    .unwrap_or_else(|| axis.map(Channel::along).unwrap_or(Channel::Fz));
                let unit_ok = matches!(
                    (channel.is_torque(), r.below),
                    (true, SettleRate::Torque(_)) | (false, SettleRate::Force(_))
                );
                if !unit_ok {
                    let want = if channel.is_torque() {
                        "N·mm/s"
                    } else {
                        "N/s"
                    };
                    self.error(
                        &at.key("below"),
                        format!("`{}` does not fit the {} signal", r.below, channel.name()),
                        format!("write the threshold in {want}"),
                    );
                }
                if r.below.value() <= 0.0 {
                    self.error(
                        &at.key("below"),
                        "the threshold must be positive",
                        "write e.g. `0.002 N/s`",
                    );
                }
                if r.window.s() <= 0.0 {
                    self.error(
                        &at.key("window"),
                        "the slope window must be positive",
                        "write e.g. `20 s`",
                    );
                }
                if r.max.s() < r.min.s() {
                    self.error(
                        &at.key("max"),
                        format!("max ({}) is below min ({})", r.max, r.min),
                        "make max at least min",
                    );
                }
                if r.max.s() < r.window.s() {
                    self.error(
                        &at.key("window"),
                        format!(
                            "the window ({}) is longer than max ({}): it can never fill",
                            r.window, r.max
                        ),
                        "shorten the window or raise max",
                    );
                }
                if window_s > r.min.s() + EPS {
                    self.error(
                        &at.key("min"),
                        format!(
                            "min ({}) is shorter than the capture's force window ({} s)",
                            r.min,
                            fmt_value(window_s)
                        ),
                        "raise min to at least the force window",
                    );
                }
                self.enough_samples(r.window.s(), 3.0, &at.key("window"), "a slope window");
                SettleSpec::Rate {
                    channel,
                    below: r.below.value(),
                    window_s: r.window.s(),
                    min_s: r.min.s(),
                    max_s: r.max.s(),
                    on_timeout: r.on_timeout,
                }
            }
            Settle::Adaptive(a) => {
                let at = path.key("adaptive");
                let channel = a
                    .signal
                    .unwrap_or_else(|| axis.map(Channel::along).unwrap_or(Channel::Fz));
                let tol = a.tolerance.fraction();
                if !(tol > 0.0 && tol <= 0.5) {
                    self.error(
                        &at.key("tolerance"),
                        format!(
                            "a tolerance of {} cannot be met or means nothing",
                            a.tolerance
                        ),
                        "write a percentage above 0 and at most 50, e.g. `1 %`",
                    );
                }
                if a.max.s() < a.min.s() {
                    self.error(
                        &at.key("max"),
                        format!("max ({}) is below min ({})", a.max, a.min),
                        "make max at least min",
                    );
                }
                if window_s > a.min.s() + EPS {
                    self.error(
                        &at.key("min"),
                        format!(
                            "min ({}) is shorter than the capture's force window ({} s)",
                            a.min,
                            fmt_value(window_s)
                        ),
                        "raise min to at least the force window",
                    );
                }
                // The fit needs a dozen samples in the shortest settle.
                self.enough_samples(a.min.s(), 12.0, &at.key("min"), "an adaptive settle");
                SettleSpec::Adaptive {
                    channel,
                    tolerance: tol,
                    min_s: a.min.s(),
                    max_s: a.max.s(),
                    on_timeout: a.on_timeout,
                }
            }
        }
    }

    /// The rate force samples fill windows at here: the innermost force stream's (windows
    /// use exactly the recorded samples), or the safety monitor's when nothing records.
    pub(super) fn window_rate_hz(&self) -> f64 {
        let mut rate = StreamRates::from(&self.p.record).force_hz;
        for s in &self.streams {
            if s.force_hz.is_some() {
                rate = s.force_hz;
            }
        }
        rate.unwrap_or_else(|| self.p.safety.monitor_rate.map(|r| r.hz()).unwrap_or(50.0))
    }

    /// Errors unless a window of `window_s` holds at least `needed` samples here.
    pub(super) fn enough_samples(&mut self, window_s: f64, needed: f64, at: &YamlPath, what: &str) {
        let rate = self.window_rate_hz();
        let n = window_s * rate;
        if n.is_finite() && n < needed {
            self.error(
                at,
                format!(
                    "{what} of {} s holds {} force samples at {} Hz: its values would be empty or a single sample",
                    fmt_value(window_s),
                    fmt_value(n.floor()),
                    rig::units::fmt_any(rate)
                ),
                format!(
                    "make it at least {} s, or record force faster (`record: {{force: …}}`)",
                    fmt_value(needed / rate)
                ),
            );
        }
    }

    /// A capture's force window and frames. `quasistatic`: the window gives a step's
    /// quasistatic value (a `stepped` or `hold` capture: the mean of the settle's last
    /// part, thesis §4.3), so on a rig with a force sensor a zero window — a single sample —
    /// is refused; on a rig without one, `0 s` says there is no force to average (motion
    /// alone). A `move`'s capture may ask for `0 s`, the latest reading.
    pub(super) fn capture(
        &mut self,
        c: &Capture,
        path: &YamlPath,
        quasistatic: bool,
    ) -> (f64, u32) {
        if c.force_window.s() < 0.0 {
            self.error(
                &path.key("force_window"),
                "the force window cannot be negative",
                "write e.g. `10 s`",
            );
        }
        if quasistatic && c.force_window.s() == 0.0 && self.rig.force.is_some() {
            self.error(
                &path.key("force_window"),
                "a force window of 0 s makes a single sample the step's quasistatic value",
                "average the settle's last part, e.g. `force_window: 10 s` (thesis §4.3)",
            );
        }
        if c.force_window.s() > 0.0 {
            self.need_force(path, "a force window");
            self.enough_samples(
                c.force_window.s(),
                2.0,
                &path.key("force_window"),
                "a force window",
            );
        }
        if c.frames > 0 {
            self.need_camera(&path.key("frames"), "capturing frames");
        }
        (c.force_window.s().max(0.0), c.frames)
    }
}
