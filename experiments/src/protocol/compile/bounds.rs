//! Plausible ranges for every physical value of a protocol.
//!
//! A value can be well-formed and still impossible for a GelSight bench: `fps: 1e12 Hz`, a
//! 0.03 mm sphere, a settle of 4294967296 s, `record: {force: 1e-320 Hz}`. Such values
//! used to validate and then crash or run away (a frame period of zero, a contact grid that
//! allocates until killed, a clock that never advances, a disk filled). Each value here gets
//! a range that covers every real tactile bench with room to spare and says why it ends
//! where it does; a value outside it is an error naming the range. Non-finite values (`.nan`,
//! `.inf`) are outside every range. The table in docs/reference/validation.md is generated from the same numbers
//! (`gelrig validate --help` points there).

use rig::config::YamlPath;
use rig::units::{fmt_any, fmt_value};

use super::Compiler;
use crate::protocol::schema::{Block, IndenterSpec, Markers, Settle};

/// A closed range and why it ends where it does.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Bound {
    /// Smallest plausible value.
    pub(crate) lo: f64,
    /// Largest plausible value.
    pub(crate) hi: f64,
    /// Unit the bounds are in.
    pub(crate) unit: &'static str,
    /// Why.
    pub(crate) why: &'static str,
}

const fn b(lo: f64, hi: f64, unit: &'static str, why: &'static str) -> Bound {
    Bound { lo, hi, unit, why }
}

/// Every bound, by the name used in messages and docs/reference/validation.md.
pub(crate) const PAD_SIDE: Bound = b(
    1.0,
    500.0,
    "mm",
    "a GelSight pad is a few mm to a few hundred mm across",
);
pub(crate) const PAD_THICKNESS: Bound = b(0.1, 50.0, "mm", "elastomer layers are 0.1–50 mm thick");
pub(crate) const MARKER_COUNT: Bound = b(
    1.0,
    200.0,
    "",
    "a marker grid has at most a few hundred per side",
);
pub(crate) const MARKER_SPACING: Bound = b(0.1, 50.0, "mm", "markers are 0.1–50 mm apart");
pub(crate) const MARKER_SIZE: Bound =
    b(0.01, 50.0, "mm", "markers are printed at 0.01 mm or larger");
pub(crate) const VIEW_SIDE: Bound = b(
    1.0,
    500.0,
    "mm",
    "the camera sees a few mm to a few hundred mm of pad",
);
pub(crate) const MODULUS: Bound = b(0.001, 1000.0, "MPa", "elastomers span about 1 kPa to 1 GPa");
pub(crate) const FRICTION: Bound = b(
    0.01,
    5.0,
    "",
    "measured rubber friction coefficients stay below 5",
);
pub(crate) const PRONY_TAU: Bound = b(0.001, 1e5, "s", "relaxation times from 1 ms to about a day");
pub(crate) const PRONY_TERMS: Bound = b(
    0.0,
    8.0,
    "",
    "more than 8 Prony terms cannot be identified from a bench",
);
pub(crate) const FLAT_SIZE: Bound = b(
    0.5,
    500.0,
    "mm",
    "the contact model resolves punches of 0.5 mm and up",
);
pub(crate) const CURVED_SIZE: Bound = b(1.0, 1000.0, "mm", "spheres and cylinders of 1 mm to 1 m");
pub(crate) const MASS: Bound = b(1.0, 10_000.0, "g", "a grasped object of 1 g to 10 kg");
pub(crate) const FORCE_LIMIT: Bound =
    b(0.001, 1000.0, "N", "tactile loads stay below a kilonewton");
pub(crate) const TORQUE_LIMIT: Bound = b(0.001, 1e5, "N·mm", "tactile torques stay below 100 N·m");
pub(crate) const MONITOR_RATE: Bound = b(
    1.0,
    10_000.0,
    "Hz",
    "a safety monitor slower than 1 Hz is no monitor",
);
pub(crate) const FORCE_RATE: Bound = b(0.1, 10_000.0, "Hz", "force streams of 0.1 Hz to 10 kHz");
pub(crate) const FRAME_RATE: Bound = b(
    0.01,
    1000.0,
    "Hz",
    "frame streams of one a minute to 1000 Hz",
);
pub(crate) const AXES_RATE: Bound = b(0.1, 1000.0, "Hz", "position logging of 0.1 Hz to 1 kHz");
pub(crate) const SPEED: Bound = b(
    0.001,
    1000.0,
    "unit/s",
    "1 µm/s (or 0.001 deg/s) moves 1 mm in 17 minutes; slower never settles a step",
);
pub(crate) const TARE: Bound = b(
    0.01,
    600.0,
    "s",
    "a tare averages 10 ms to 10 minutes of an unloaded sensor",
);
pub(crate) const SETTLE: Bound = b(
    0.0,
    86_400.0,
    "s",
    "a step settles within a day (the thesis waited 3–5 minutes)",
);
pub(crate) const SETTLE_WINDOW: Bound = b(0.1, 3600.0, "s", "a slope window of 0.1 s to an hour");
pub(crate) const SETTLE_SLOPE: Bound = b(
    1e-6,
    100.0,
    "N/s",
    "drift thresholds between 1 µN/s and 100 N/s",
);
pub(crate) const FORCE_WINDOW: Bound = b(0.0, 3600.0, "s", "a quasistatic window of up to an hour");
pub(crate) const FRAMES: Bound = b(0.0, 10_000.0, "", "at most 10,000 frames per capture");
pub(crate) const REFERENCE_FRAMES: Bound = b(
    0.0,
    100.0,
    "",
    "a reference needs a few frames, not hundreds",
);
pub(crate) const HOLD: Bound = b(0.001, 86_400.0, "s", "a hold of 1 ms to a day");
pub(crate) const DISTURB_FORCE: Bound = b(
    0.0,
    100.0,
    "N",
    "a hand swinging a grasped can pushes well below 100 N",
);
pub(crate) const DISTURB_TORQUE: Bound = b(0.0, 10_000.0, "N·mm", "a twist of up to 10 N·m");
pub(crate) const DISTURB_FREQUENCY: Bound = b(
    0.01,
    100.0,
    "Hz",
    "hand and actuator disturbances of 0.01–100 Hz",
);
pub(crate) const DISTURB_DURATION: Bound = b(0.001, 3600.0, "s", "a disturbance of up to an hour");
pub(crate) const REPEAT: Bound = b(1.0, 100_000.0, "", "at most 100,000 trials");
/// Nested `record` and `repeat` blocks.
pub(crate) const NESTING: usize = 16;
/// Characters of a protocol name: it names the run directory (and file systems cap a name
/// at 255 bytes, which a UTF-8 name can reach in 64 characters).
pub(crate) const NAME_CHARS: usize = 64;
/// Characters of a step label: a column of steps.csv and a line of the progress display.
pub(crate) const LABEL_CHARS: usize = 200;

/// [`SPEED`] in the unit of an axis.
fn speed_bound(unit: rig::units::AxisUnit) -> Bound {
    Bound {
        unit: match unit {
            rig::units::AxisUnit::Mm => "mm/s",
            rig::units::AxisUnit::Deg => "deg/s",
        },
        ..SPEED
    }
}

impl Compiler<'_> {
    /// Errors at `path` unless `v` is within `bound`; `true` if it is.
    pub(super) fn within(&mut self, path: &YamlPath, what: &str, v: f64, bound: Bound) -> bool {
        if (bound.lo..=bound.hi).contains(&v) {
            return true;
        }
        let u = if bound.unit.is_empty() {
            String::new()
        } else {
            format!(" {}", bound.unit)
        };
        self.error(
            path,
            format!(
                "{what} {}{u} is outside the plausible range [{}, {}]{u}: {}",
                fmt_any(v),
                fmt_value(bound.lo),
                fmt_value(bound.hi),
                bound.why
            ),
            format!(
                "write a value between {} and {}{u}",
                fmt_value(bound.lo),
                fmt_value(bound.hi)
            ),
        );
        false
    }

    /// The protocol's name and its top-level sections, then every block of the sequence.
    pub(super) fn check_bounds(&mut self) {
        let p = self.p;
        let root = YamlPath::root();
        self.name_bound();
        self.elastomer_bounds();
        self.marker_bounds();
        self.view_bounds();
        self.material_bounds();
        self.indenter_bounds();
        if let Some(o) = &p.object {
            self.within(
                &root.key("object").key("mass"),
                "object mass",
                o.mass.g(),
                MASS,
            );
        }
        self.safety_bounds();
        self.block_bounds(&p.sequence, &root.key("sequence"), 0);
    }

    /// The protocol name: 1 to [`NAME_CHARS`] characters, since it names the run directory.
    fn name_bound(&mut self) {
        let p = self.p;
        let root = YamlPath::root();
        let name_chars = p.name.chars().count();
        if p.name.trim().is_empty() || name_chars > NAME_CHARS {
            self.error(
                &root.key("name"),
                format!(
                    "the protocol name has {name_chars} characters; it names the run directory and must have 1 to {NAME_CHARS}"
                ),
                "write a short name, e.g. `box-normal-flat`, and put the rest in `description:`",
            );
        }
    }

    /// `sensor.elastomer`: the pad's width and length ([`PAD_SIDE`]) and thickness
    /// ([`PAD_THICKNESS`]).
    fn elastomer_bounds(&mut self) {
        let s = &self.p.sensor;
        let at = YamlPath::root().key("sensor");
        if let Some(e) = &s.elastomer {
            let e_at = at.key("elastomer");
            self.within(
                &e_at.key("width"),
                "elastomer width",
                e.width.mm(),
                PAD_SIDE,
            );
            self.within(
                &e_at.key("length"),
                "elastomer length",
                e.length.mm(),
                PAD_SIDE,
            );
            self.within(
                &e_at.key("thickness"),
                "elastomer thickness",
                e.thickness.mm(),
                PAD_THICKNESS,
            );
        }
    }

    /// `sensor.markers`: a grid's counts, spacing and dot diameter, or a random pattern's
    /// spacing and dot size.
    fn marker_bounds(&mut self) {
        let s = &self.p.sensor;
        let at = YamlPath::root().key("sensor");
        match &s.markers {
            Some(Markers::Grid {
                columns,
                rows,
                spacing,
                diameter,
            }) => {
                let m = at.key("markers");
                self.within(
                    &m.key("columns"),
                    "columns",
                    f64::from(*columns),
                    MARKER_COUNT,
                );
                self.within(&m.key("rows"), "rows", f64::from(*rows), MARKER_COUNT);
                self.within(
                    &m.key("spacing"),
                    "marker spacing",
                    spacing.mm(),
                    MARKER_SPACING,
                );
                self.within(
                    &m.key("diameter"),
                    "marker diameter",
                    diameter.mm(),
                    MARKER_SIZE,
                );
            }
            Some(Markers::Random { spacing, size }) => {
                let m = at.key("markers");
                self.within(
                    &m.key("spacing"),
                    "marker spacing",
                    spacing.mm(),
                    MARKER_SPACING,
                );
                self.within(&m.key("size"), "marker size", size.mm(), MARKER_SIZE);
            }
            None => {}
        }
    }

    /// `sensor.view`: the size of pad the camera sees ([`VIEW_SIDE`]).
    fn view_bounds(&mut self) {
        let s = &self.p.sensor;
        let at = YamlPath::root().key("sensor");
        if let Some(v) = &s.view {
            self.within(
                &at.key("view").key("width"),
                "view width",
                v.width.mm(),
                VIEW_SIDE,
            );
            self.within(
                &at.key("view").key("height"),
                "view height",
                v.height.mm(),
                VIEW_SIDE,
            );
        }
    }

    /// `sensor.material` (inline or read from its file): modulus, static and kinetic friction
    /// (kinetic at most static), and the Prony series — few enough terms, plausible
    /// relaxation times, each weight in [0, 1) and their sum below 1 (a long-term modulus
    /// left).
    fn material_bounds(&mut self) {
        let s = &self.p.sensor;
        let at = YamlPath::root().key("sensor");
        if let Some(m) = s.material.as_ref().and_then(|m| m.values()) {
            let mat = at.key("material");
            self.within(
                &mat.key("youngs_modulus"),
                "Young's modulus",
                m.youngs_modulus.mpa(),
                MODULUS,
            );
            self.within(&mat.key("friction"), "friction", m.friction, FRICTION);
            if let Some(k) = m.kinetic_friction
                && self.within(
                    &mat.key("kinetic_friction"),
                    "kinetic friction",
                    k,
                    FRICTION,
                )
                && k > m.friction
            {
                self.error(
                    &mat.key("kinetic_friction"),
                    format!(
                        "kinetic friction {} is above the static friction {}: a sliding contact would hold more than a sticking one",
                        fmt_value(k),
                        fmt_value(m.friction)
                    ),
                    "write a kinetic friction at most the static one (about 0.9 × for silicone)",
                );
            }
            self.within(
                &mat.key("prony"),
                "the number of Prony terms",
                m.prony.len() as f64,
                PRONY_TERMS,
            );
            let mut total = 0.0;
            for (i, t) in m.prony.iter().enumerate() {
                let term = mat.key("prony").index(i);
                self.within(&term.key("tau"), "relaxation time", t.tau.s(), PRONY_TAU);
                if t.weight.is_finite() {
                    total += t.weight;
                }
                if !(0.0..1.0).contains(&t.weight) {
                    self.error(
                        &term.key("weight"),
                        format!("Prony weight {} is outside [0, 1)", fmt_value(t.weight)),
                        "write the fraction of the instantaneous modulus that relaxes, e.g. 0.2",
                    );
                }
            }
            if total >= 1.0 {
                self.error(
                    &mat.key("prony"),
                    format!(
                        "the Prony weights add up to {}: the long-term modulus would vanish",
                        fmt_value(total)
                    ),
                    "make the weights add up to less than 1",
                );
            }
        }
    }

    /// `indenter`: every dimension of its shape ([`FLAT_SIZE`] for punches, [`CURVED_SIZE`]
    /// for spheres and cylinders), and a flat punch no wider than the pad's narrower side.
    fn indenter_bounds(&mut self) {
        let p = self.p;
        let s = &p.sensor;
        let root = YamlPath::root();
        let ind = root.key("indenter");
        let dims: Vec<(&str, f64, Bound)> = match &p.indenter {
            IndenterSpec::FlatCircle { diameter } => vec![("diameter", diameter.mm(), FLAT_SIZE)],
            IndenterSpec::FlatEllipse { major, minor } => vec![
                ("major", major.mm(), FLAT_SIZE),
                ("minor", minor.mm(), FLAT_SIZE),
            ],
            IndenterSpec::FlatRectangle { width, length } => vec![
                ("width", width.mm(), FLAT_SIZE),
                ("length", length.mm(), FLAT_SIZE),
            ],
            IndenterSpec::FlatTriangle { side } => vec![("side", side.mm(), FLAT_SIZE)],
            IndenterSpec::Sphere { diameter } => vec![("diameter", diameter.mm(), CURVED_SIZE)],
            IndenterSpec::Cylinder { diameter, length } => vec![
                ("diameter", diameter.mm(), CURVED_SIZE),
                ("length", length.mm(), CURVED_SIZE),
            ],
        };
        let pad = s
            .elastomer
            .as_ref()
            .map(|e| e.width.mm().min(e.length.mm()))
            .unwrap_or(f64::INFINITY);
        for (key, v, bound) in dims {
            if self.within(&ind.key(key), &format!("indenter {key}"), v, bound)
                && p.indenter.is_flat()
                && v > pad
            {
                self.error(
                    &ind.key(key),
                    format!(
                        "a flat punch {key} of {} mm is wider than the {} mm pad",
                        fmt_value(v),
                        fmt_value(pad)
                    ),
                    "use a punch smaller than the pad",
                );
            }
        }
    }

    /// `safety`: the force and torque limits and the monitor rate.
    fn safety_bounds(&mut self) {
        let p = self.p;
        let root = YamlPath::root();
        let safety = root.key("safety");
        self.within(
            &safety.key("max_fz"),
            "max_fz",
            p.safety.max_fz.n(),
            FORCE_LIMIT,
        );
        self.within(
            &safety.key("max_fxy"),
            "max_fxy",
            p.safety.max_fxy.n(),
            FORCE_LIMIT,
        );
        self.within(
            &safety.key("max_tz"),
            "max_tz",
            p.safety.max_tz.nmm(),
            TORQUE_LIMIT,
        );
        if let Some(r) = p.safety.monitor_rate {
            self.within(
                &safety.key("monitor_rate"),
                "monitor rate",
                r.hz(),
                MONITOR_RATE,
            );
        }
    }

    /// Every block's own values, and how deeply blocks nest.
    fn block_bounds(&mut self, blocks: &[Block], path: &YamlPath, depth: usize) {
        for (i, b) in blocks.iter().enumerate() {
            let at = path.index(i).key(b.keyword());
            match b {
                Block::Approach(a) => {
                    self.within(
                        &at.key("speed"),
                        "speed",
                        a.speed.value,
                        speed_bound(a.speed.unit),
                    );
                    self.within(
                        &at.key("reference_frames"),
                        "reference frames",
                        f64::from(a.reference_frames),
                        REFERENCE_FRAMES,
                    );
                }
                Block::Tare(t) => {
                    if let Some(d) = t.duration {
                        self.within(&at.key("duration"), "tare duration", d.s(), TARE);
                    }
                }
                Block::Stepped(s) => {
                    self.within(
                        &at.key("speed"),
                        "speed",
                        s.speed.value,
                        speed_bound(s.speed.unit),
                    );
                    self.settle_bounds(&s.settle, &at.key("settle"));
                    self.capture_bounds(
                        s.capture.force_window.s(),
                        s.capture.frames,
                        &at.key("capture"),
                    );
                    self.label_bound(s.label.as_deref(), &at);
                }
                Block::Hold(h) => {
                    self.within(&at.key("duration"), "hold", h.duration.s(), HOLD);
                    if let Some(c) = &h.capture {
                        self.capture_bounds(c.force_window.s(), c.frames, &at.key("capture"));
                    }
                    self.label_bound(h.label.as_deref(), &at);
                }
                Block::Move(m) => {
                    self.within(
                        &at.key("speed"),
                        "speed",
                        m.speed.value,
                        speed_bound(m.speed.unit),
                    );
                    if let Some(s) = &m.settle {
                        self.settle_bounds(s, &at.key("settle"));
                    }
                    if let Some(c) = &m.capture {
                        self.capture_bounds(c.force_window.s(), c.frames, &at.key("capture"));
                    }
                    self.label_bound(m.label.as_deref(), &at);
                }
                Block::Capture(c) => {
                    let window = c.force_window.map(|d| d.s()).unwrap_or(0.0);
                    self.capture_bounds(window, c.frames, &at);
                    self.label_bound(c.label.as_deref(), &at);
                }
                Block::Disturb(d) => {
                    if let Some(f) = d.force {
                        self.within(&at.key("force"), "disturbance force", f.n(), DISTURB_FORCE);
                    }
                    if let Some(t) = d.torque {
                        self.within(
                            &at.key("torque"),
                            "disturbance torque",
                            t.nmm(),
                            DISTURB_TORQUE,
                        );
                    }
                    self.within(
                        &at.key("frequency"),
                        "disturbance frequency",
                        d.frequency.hz(),
                        DISTURB_FREQUENCY,
                    );
                    self.within(
                        &at.key("duration"),
                        "disturbance duration",
                        d.duration.s(),
                        DISTURB_DURATION,
                    );
                    self.label_bound(d.label.as_deref(), &at);
                }
                Block::Record(r) => {
                    if self.nesting(depth, &at) {
                        self.block_bounds(&r.blocks, &at.key("blocks"), depth + 1);
                    }
                }
                Block::Repeat(r) => {
                    self.within(&at.key("times"), "times", f64::from(r.times), REPEAT);
                    if self.nesting(depth, &at) {
                        self.block_bounds(&r.blocks, &at.key("blocks"), depth + 1);
                    }
                }
                Block::Home(_) => {}
            }
        }
    }

    /// `false` (and an error) when a block at `depth` would nest too deeply.
    fn nesting(&mut self, depth: usize, at: &YamlPath) -> bool {
        if depth < NESTING {
            return true;
        }
        self.error(
            at,
            format!("`record` and `repeat` blocks nest more than {NESTING} deep here"),
            "flatten the sequence: a repeat of a repeat can be one repeat of the product",
        );
        false
    }

    fn settle_bounds(&mut self, s: &Settle, at: &YamlPath) {
        match s {
            Settle::Fixed(d) => {
                self.within(&at.key("fixed"), "settle", d.s(), SETTLE);
            }
            Settle::Rate(r) => {
                let at = at.key("rate");
                self.within(
                    &at.key("below"),
                    "drift threshold",
                    r.below.value(),
                    SETTLE_SLOPE,
                );
                self.within(
                    &at.key("window"),
                    "slope window",
                    r.window.s(),
                    SETTLE_WINDOW,
                );
                self.within(&at.key("min"), "min", r.min.s(), SETTLE);
                self.within(&at.key("max"), "max", r.max.s(), SETTLE);
            }
            Settle::Adaptive(a) => {
                let at = at.key("adaptive");
                self.within(&at.key("min"), "min", a.min.s(), SETTLE);
                self.within(&at.key("max"), "max", a.max.s(), SETTLE);
            }
        }
    }

    fn capture_bounds(&mut self, force_window_s: f64, frames: u32, at: &YamlPath) {
        self.within(
            &at.key("force_window"),
            "force window",
            force_window_s,
            FORCE_WINDOW,
        );
        self.within(&at.key("frames"), "frames", f64::from(frames), FRAMES);
    }

    fn label_bound(&mut self, label: Option<&str>, at: &YamlPath) {
        if let Some(l) = label
            && l.chars().count() > LABEL_CHARS
        {
            self.error(
                &at.key("label"),
                format!("the label has {} characters", l.chars().count()),
                format!("shorten it to at most {LABEL_CHARS}"),
            );
        }
    }
}
