//! Checks of the protocol as a whole: streams against the devices, the sensor's and
//! indenter's physics, the safety limits, and retract positions.

use rig::config::{AxisRole, YamlPath};
use rig::units::{AxisQuantity, fmt_value};

use super::bounds::{AXES_RATE, FORCE_RATE, FRAME_RATE};
use super::{Compiler, EPS, StreamRates};
use crate::protocol::schema::{IndenterSpec, Markers};

impl Compiler<'_> {
    pub(super) fn check_streams(&mut self, r: &StreamRates, at: &YamlPath) {
        if let Some(hz) = r.force_hz {
            self.need_force(&at.key("force"), "a force stream");
            self.within(&at.key("force"), "force rate", hz, FORCE_RATE);
            let max = self
                .rig
                .force
                .as_ref()
                .map(|f| f.max_rate.map(|r| r.hz()).unwrap_or(1000.0))
                .unwrap_or(f64::INFINITY);
            if hz <= 0.0 || hz > max {
                self.error(
                    &at.key("force"),
                    format!(
                        "force rate {} Hz is outside (0, {}] Hz, what the sensor delivers",
                        fmt_value(hz),
                        fmt_value(max)
                    ),
                    format!("write a rate up to {} Hz", fmt_value(max)),
                );
            }
        }
        if let Some(hz) = r.frames_hz {
            self.need_camera(&at.key("frames"), "a frame stream");
            self.within(&at.key("frames"), "frame rate", hz, FRAME_RATE);
            let fps = self
                .rig
                .camera
                .as_ref()
                .map(|c| c.fps.hz())
                .unwrap_or(f64::INFINITY);
            if hz <= 0.0 || hz > fps + EPS {
                self.error(
                    &at.key("frames"),
                    format!(
                        "frame rate {} Hz is outside (0, {}] Hz, the camera's frame rate",
                        fmt_value(hz),
                        fmt_value(fps)
                    ),
                    format!("write a rate up to {} Hz", fmt_value(fps)),
                );
            }
        }
        if let Some(hz) = r.axes_hz {
            self.within(&at.key("axes"), "axes rate", hz, AXES_RATE);
        }
    }

    pub(super) fn check_physics(&mut self) {
        let s = &self.p.sensor;
        let at = YamlPath::root().key("sensor");
        if let Some(e) = &s.elastomer {
            for (k, v) in [
                ("width", e.width.mm()),
                ("length", e.length.mm()),
                ("thickness", e.thickness.mm()),
            ] {
                if v <= 0.0 {
                    self.error(
                        &at.key("elastomer").key(k),
                        format!("elastomer {k} must be positive"),
                        "write e.g. `4.2 mm`",
                    );
                }
            }
        }
        if let Some(Markers::Grid {
            columns,
            rows,
            spacing,
            diameter,
        }) = &s.markers
        {
            if *columns == 0 || *rows == 0 {
                self.error(
                    &at.key("markers"),
                    "a marker grid needs at least one row and column",
                    "write e.g. `columns: 18, rows: 16`",
                );
            }
            if diameter.mm() <= 0.0 || diameter.mm() >= spacing.mm() {
                self.error(
                    &at.key("markers").key("diameter"),
                    "markers must be smaller than their spacing",
                    "write a diameter below the spacing, e.g. 1.4 mm at 2.52 mm",
                );
            }
        }
        if let Some(Markers::Random { spacing, size }) = &s.markers
            && (size.mm() <= 0.0 || size.mm() >= spacing.mm())
        {
            self.error(
                &at.key("markers").key("size"),
                "markers must be smaller than their spacing",
                "write a size below the spacing, e.g. 0.7 mm at 2 mm",
            );
        }
        if let Some(v) = &s.view
            && (v.width.mm() <= 0.0 || v.height.mm() <= 0.0)
        {
            self.error(
                &at.key("view"),
                "the view must have a positive size",
                "write e.g. `{width: 45 mm, height: 40 mm}`",
            );
        }
        if let Some(m) = s.material.as_ref().and_then(|m| m.values()) {
            let mat = at.key("material");
            if m.youngs_modulus.mpa() <= 0.0 {
                self.error(
                    &mat.key("youngs_modulus"),
                    "the modulus must be positive",
                    "write e.g. `0.25 MPa`",
                );
            }
            if !(0.0..=0.5).contains(&m.poisson_ratio) {
                self.error(
                    &mat.key("poisson_ratio"),
                    format!("Poisson ratio {} is outside [0, 0.5]", m.poisson_ratio),
                    "silicone elastomers are nearly incompressible: write 0.49 or 0.5",
                );
            }
            if m.friction < 0.0 {
                self.error(
                    &mat.key("friction"),
                    "friction cannot be negative",
                    "write e.g. `0.6`",
                );
            }
            for (i, t) in m.prony.iter().enumerate() {
                if t.weight < 0.0 {
                    self.error(
                        &mat.key("prony").index(i).key("weight"),
                        "a Prony weight cannot be negative",
                        "write a weight ≥ 0",
                    );
                }
                if t.tau.s() <= 0.0 {
                    self.error(
                        &mat.key("prony").index(i).key("tau"),
                        "a relaxation time must be positive",
                        "write e.g. `20 s`",
                    );
                }
            }
        }
        let dims: Vec<(&str, f64)> = match &self.p.indenter {
            IndenterSpec::FlatCircle { diameter } | IndenterSpec::Sphere { diameter } => {
                vec![("diameter", diameter.mm())]
            }
            IndenterSpec::FlatEllipse { major, minor } => {
                if minor.mm() > major.mm() {
                    self.error(
                        &YamlPath::root().key("indenter").key("minor"),
                        "the minor axis is longer than the major axis",
                        "swap `major` and `minor`",
                    );
                }
                vec![("major", major.mm()), ("minor", minor.mm())]
            }
            IndenterSpec::FlatRectangle { width, length } => {
                vec![("width", width.mm()), ("length", length.mm())]
            }
            IndenterSpec::FlatTriangle { side } => vec![("side", side.mm())],
            IndenterSpec::Cylinder { diameter, length } => {
                vec![("diameter", diameter.mm()), ("length", length.mm())]
            }
        };
        for (k, v) in dims {
            if v <= 0.0 {
                self.error(
                    &YamlPath::root().key("indenter").key(k),
                    format!("indenter {k} must be positive"),
                    "write e.g. `9.5 mm`",
                );
            }
        }
        if let Some(o) = &self.p.object
            && o.mass.g() <= 0.0
        {
            self.error(
                &YamlPath::root().key("object").key("mass"),
                "the object's mass must be positive",
                "write e.g. `100 g`",
            );
        }
    }

    pub(super) fn check_safety(&mut self) {
        let s = &self.p.safety;
        let at = YamlPath::root().key("safety");
        let range = self
            .rig
            .force
            .as_ref()
            .map(|f| (f.model.name(), f.model.range()));
        let checks = [
            (
                "max_fz",
                s.max_fz.n(),
                range.map(|r| r.1.fz_n),
                "axial",
                "N",
            ),
            (
                "max_fxy",
                s.max_fxy.n(),
                range.map(|r| r.1.fxy_n),
                "tangential",
                "N",
            ),
            (
                "max_tz",
                s.max_tz.nmm(),
                range.map(|r| r.1.torque_nmm),
                "torque",
                "N·mm",
            ),
        ];
        for (key, v, limit, what, unit) in checks {
            if v <= 0.0 {
                self.error(
                    &at.key(key),
                    format!("{key} must be positive"),
                    format!("write the largest load the run may reach, in {unit}"),
                );
            }
            if let (Some(limit), Some((model, _))) = (limit, range)
                && v > limit + EPS
            {
                self.error(
                    &at.key(key),
                    format!(
                        "{key} {} {unit} is above the {model}'s {what} range {} {unit}: the sensor saturates before this limit can trip",
                        fmt_value(v),
                        fmt_value(limit)
                    ),
                    format!("set {key} to at most {} {unit}", fmt_value(limit)),
                );
            }
        }
        if let Some(r) = s.monitor_rate
            && r.hz() <= 0.0
        {
            self.error(
                &at.key("monitor_rate"),
                "the monitor rate must be positive",
                "write e.g. `50 Hz`",
            );
        }
        for (role, [lo, hi]) in &s.travel {
            let path = at.key("travel").key(role.name());
            match self.rig.axes.get(role) {
                None => self.warn(
                    &path,
                    format!(
                        "rig `{}` has no `{role}` axis; this limit does nothing",
                        self.rig.name
                    ),
                    "remove it, or add the axis to the rig",
                ),
                Some(cfg) => {
                    if lo.natural_unit() != cfg.unit()
                        || hi.natural_unit() != cfg.unit()
                        || matches!(lo, AxisQuantity::Percent(_))
                        || matches!(hi, AxisQuantity::Percent(_))
                    {
                        self.error(
                            &path,
                            format!(
                                "travel limits must be in {}, the {role} axis unit",
                                cfg.unit().symbol()
                            ),
                            format!("write them in {}", cfg.unit().symbol()),
                        );
                    } else if lo.raw() >= hi.raw() {
                        self.error(
                            &path,
                            "the travel limits are empty",
                            "write [min, max] with min < max",
                        );
                    }
                }
            }
        }
    }

    pub(super) fn check_retract(&mut self) {
        let at = YamlPath::root().key("safety").key("retract");
        let used: Vec<AxisRole> = self.out.needs.axes.iter().copied().collect();
        for role in used {
            let Some(cfg) = self.rig.axes.get(&role) else {
                continue;
            };
            match self.p.safety.retract.get(&role) {
                None if role.presses() => self.error(
                    &YamlPath::root().key("safety"),
                    format!("the {role} axis presses into the elastomer but has no retract position"),
                    format!("add `retract: {{{role}: 0 mm}}` (absolute stage position clear of the sensor) to `safety`"),
                ),
                None => {}
                Some(q) => {
                    let (min, max) = cfg.travel();
                    match q.in_axis_unit(cfg.unit(), self.thickness_mm) {
                        Some(v) if matches!(q, AxisQuantity::Percent(_)) => {
                            let _ = v;
                            self.error(
                                &at.key(role.name()),
                                "a retract position is absolute and cannot be a percentage",
                                format!("write it in {}", cfg.unit().symbol()),
                            );
                        }
                        Some(v) if v < min - EPS || v > max + EPS => self.error(
                            &at.key(role.name()),
                            format!("retract position {q} is outside the {role} travel [{}, {}]", fmt_value(min), fmt_value(max)),
                            "choose a position inside the travel, clear of the sensor",
                        ),
                        Some(_) => {}
                        None => self.error(
                            &at.key(role.name()),
                            format!("`{q}` does not fit the {role} axis, which moves in {}", cfg.unit().symbol()),
                            format!("write it in {}", cfg.unit().symbol()),
                        ),
                    }
                }
            }
        }
    }
}
