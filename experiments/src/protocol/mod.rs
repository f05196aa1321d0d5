//! Protocols: schema, loading, checking and expansion.
//!
//! Loading follows dora's parse → resolve → check split: [`schema`] parses (serde, unknown
//! keys denied, units checked), [`load`] resolves the rig file and the sensor defaults,
//! and [`compile`] checks everything that needs both and expands the sequence.

pub mod compile;
pub mod material;
pub mod material_file;
mod overrides;
pub mod schema;
pub mod shipped;
pub mod source;

use std::path::{Path, PathBuf};

use rig::config::RigConfig;
use simbench::{MarkerLayout, PlantSpec};

use crate::diag::{Diagnostic, Severity};
use compile::{Budget, Compiled};
use schema::{IndenterSpec, Markers, Protocol};
use source::read;

/// A protocol with its rig, checked and expanded.
#[derive(Debug, Clone)]
pub struct Loaded {
    /// The protocol file.
    pub path: PathBuf,
    /// Its text, exactly as read.
    pub text: String,
    /// Parsed, with sensor defaults filled in.
    pub protocol: Protocol,
    /// The rig file used.
    pub rig_path: PathBuf,
    /// The rig's text.
    pub rig_text: String,
    /// The parsed rig.
    pub rig: RigConfig,
    /// The expanded run.
    pub compiled: Compiled,
    /// Its plan — steps, durations, data — computed once as the protocol is checked (its
    /// data budget is part of the check) and carried to the runner and the commands.
    pub plan: crate::plan::Plan,
    /// Warnings (errors prevent a `Loaded`).
    pub warnings: Vec<Diagnostic>,
}

impl Loaded {
    /// The real (not simulated in-process) devices this protocol opens, by role. Any one of
    /// them puts the run on the monotonic clock: a real stage or sensor cannot be driven in
    /// virtual time.
    pub fn real_devices(&self) -> Vec<String> {
        use rig::config::{AxisDriver, CameraDriver, DisturberDriver, ForceDriver};
        let needs = &self.compiled.needs;
        let mut real = Vec::new();
        for role in &needs.axes {
            if self
                .rig
                .axes
                .get(role)
                .is_some_and(|a| !matches!(a.driver, AxisDriver::Sim))
            {
                real.push(role.to_string());
            }
        }
        let force = self.rig.force.as_ref();
        if needs.force && force.is_some_and(|f| !matches!(f.driver, ForceDriver::Sim)) {
            real.push("force".into());
        }
        let camera = self.rig.camera.as_ref();
        if needs.camera && camera.is_some_and(|c| !matches!(c.driver, CameraDriver::Sim)) {
            real.push("camera".into());
        }
        let disturber = self.rig.disturber.as_ref();
        if needs.disturber && disturber.is_some_and(|d| !matches!(d.driver, DisturberDriver::Sim)) {
            real.push("disturber".into());
        }
        real
    }
}

/// Top-level keys of a protocol file.
const PROTOCOL_KEYS: &[&str] = &[
    "name",
    "description",
    "rig",
    "sensor",
    "indenter",
    "object",
    "safety",
    "record",
    "sequence",
];
/// Top-level keys of a rig file.
const RIG_KEYS: &[&str] = &[
    "name",
    "description",
    "axes",
    "force",
    "camera",
    "disturber",
    "sim",
    "contact",
    "twins",
];

/// Reads and checks a rig file on its own (for `gelrig probe` and `gelrig sim serve`).
pub fn load_rig(path: &Path) -> Result<(RigConfig, String), Vec<Diagnostic>> {
    let text = read(path, "the rig file")?;
    source::mapping(path, &text, "a rig file", RIG_KEYS)?;
    let rig = RigConfig::from_yaml_str(&text)
        .map_err(|e| vec![Diagnostic::from_yaml_error(path, &text, &e)])?;
    let diags: Vec<Diagnostic> = rig
        .check()
        .into_iter()
        .map(|i| Diagnostic::at_path(path, &text, &i.path, Severity::Error, i.message, i.fix))
        .collect();
    if diags.is_empty() {
        Ok((rig, text))
    } else {
        Err(diags)
    }
}

/// Parses protocol text; the error is located in `file`. Duplicate keys are errors, and a
/// document that is not a mapping is reported without its content.
pub fn parse(file: &Path, text: &str) -> Result<Protocol, Box<Diagnostic>> {
    source::mapping(file, text, "a protocol", PROTOCOL_KEYS)
        .map_err(|mut d| Box::new(d.remove(0)))?;
    serde_yaml::from_str::<Protocol>(text).map_err(|e| {
        let mut d = Diagnostic::from_yaml_error(file, text, &e);
        // Errors inside internally tagged maps (`indenter:`, `markers:`) come without a
        // place — at the document's first line, which follows any leading comments (a
        // protocol that opens with a comment block had them pointed at its `name:`): find
        // the value serde was reading, and the offending token in it.
        let start = text
            .lines()
            .position(|l| {
                let l = l.trim();
                !(l.is_empty() || l.starts_with('#') || l == "---")
            })
            .map_or(1, |i| i + 1);
        if e.location()
            .is_none_or(|l| l.line() <= start && l.column() <= 1)
            && let Some(path) = failing_path(text)
        {
            d = relocate(d, file, text, &path);
        }
        Box::new(d)
    })
}

/// The path of the value whose deserialisation failed, as far as serde can follow it.
fn failing_path(text: &str) -> Option<rig::config::YamlPath> {
    let de = serde_yaml::Deserializer::from_str(text);
    let err = serde_path_to_error::deserialize::<_, Protocol>(de).err()?;
    let mut path = rig::config::YamlPath::root();
    for seg in err.path().iter() {
        path = match seg {
            serde_path_to_error::Segment::Map { key } => path.key(key),
            serde_path_to_error::Segment::Seq { index } => path.index(*index),
            _ => return None,
        };
    }
    (!path.0.is_empty()).then_some(path)
}

/// `d` moved to `path` in `text` — and, when its message quotes the offending value
/// (`` `12.5` has no unit``) or names a missing field, to that value or the mapping's start.
fn relocate(d: Diagnostic, file: &Path, text: &str, path: &rig::config::YamlPath) -> Diagnostic {
    let mut at = Diagnostic::at_path(
        file,
        text,
        path,
        d.severity,
        d.message.clone(),
        d.fix.clone(),
    );
    if let Some(token) = d
        .message
        .strip_prefix('`')
        .and_then(|r| r.split('`').next())
        .filter(|t| !t.is_empty())
    {
        // The quoted value on the value's line (or the lines of its block below).
        for (k, line) in text
            .lines()
            .enumerate()
            .skip(at.line.saturating_sub(1))
            .take(12)
        {
            let from = if k + 1 == at.line {
                at.column.saturating_sub(1)
            } else {
                0
            };
            if let Some(c) = line.get(from..).and_then(|rest| rest.find(token)) {
                at.line = k + 1;
                at.column = from + c + 1;
                at.source_line = Some(line.to_string());
                break;
            }
        }
    }
    at
}

/// Reads, parses, resolves and checks `protocol_path` against its rig (or `rig_override`),
/// within the default [`Budget`]. Returns every error found, located, or the loaded
/// protocol and its warnings.
pub fn load(protocol_path: &Path, rig_override: Option<&Path>) -> Result<Loaded, Vec<Diagnostic>> {
    load_with(protocol_path, rig_override, &Budget::default())
}

/// [`load`] within `budget`: a protocol that would expand into more steps, or write more
/// bytes by its plan's estimate, is refused with the numbers.
pub fn load_with(
    protocol_path: &Path,
    rig_override: Option<&Path>,
    budget: &Budget,
) -> Result<Loaded, Vec<Diagnostic>> {
    let text = read(protocol_path, "the protocol")?;
    load_text(protocol_path, text, rig_override, budget)
}

/// Values given on the command line in place of the protocol's own.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Overrides {
    /// `KEY=VALUE` pairs: a dotted path into the protocol (`indenter.diameter`,
    /// `sequence.3.stepped.step`) and a YAML value (`10 mm`, `{fixed: 60 s}`).
    pub set: Vec<String>,
    /// The run's name in place of the protocol's.
    pub name: Option<String>,
}

/// [`load_with`] with `overrides` applied to the protocol's text first. An edited protocol is
/// recorded as run (its `protocol.yaml`) and gets a name of its own: `--name`, or the
/// protocol's name with a hash of the overrides (`box-normal-flat-3f9a1c`), so its runs are
/// told apart from the unedited protocol's. Diagnostics then refer to the edited text.
pub fn load_with_overrides(
    protocol_path: &Path,
    rig_override: Option<&Path>,
    budget: &Budget,
    overrides: &Overrides,
) -> Result<Loaded, Vec<Diagnostic>> {
    if overrides == &Overrides::default() {
        return load_with(protocol_path, rig_override, budget);
    }
    let text = read(protocol_path, "the protocol")?;
    let edited = overrides::apply(&text, overrides).map_err(|(message, fix)| {
        vec![Diagnostic::at_path(
            protocol_path,
            &text,
            &rig::config::YamlPath::root(),
            Severity::Error,
            message,
            fix,
        )]
    })?;
    load_text(protocol_path, edited, rig_override, budget)
}

/// Parses, resolves and checks protocol `text` read from `protocol_path` (relative paths in
/// it resolve against that file's folder).
fn load_text(
    protocol_path: &Path,
    text: String,
    rig_override: Option<&Path>,
    budget: &Budget,
) -> Result<Loaded, Vec<Diagnostic>> {
    let mut protocol = parse(protocol_path, &text).map_err(|d| vec![*d])?;
    read_material(protocol_path, &text, &mut protocol).map_err(|d| vec![*d])?;
    protocol.sensor.resolve_defaults();
    let rig_path = match (rig_override, &protocol.rig) {
        (Some(r), _) => r.to_path_buf(),
        (None, Some(r)) => protocol_path.parent().unwrap_or(Path::new(".")).join(r),
        (None, None) => {
            return Err(vec![Diagnostic::at_path(
                protocol_path,
                &text,
                &rig::config::YamlPath::root().key("name"),
                Severity::Error,
                "this protocol names no rig",
                "add `rig: rigs/sim.yaml` (relative to the protocol) or pass `--rig FILE`",
            )]);
        }
    };
    if rig_override.is_none() && !rig_path.exists() {
        // A protocol copied away from its `rigs/` folder: say where `rig:` led, at the line.
        let suggest = shipped::sim_rig()
            .map(|p| {
                let shown = std::env::current_dir()
                    .ok()
                    .and_then(|cwd| p.strip_prefix(&cwd).ok().map(Path::to_path_buf))
                    .unwrap_or(p);
                format!("pass `--rig {}` (the simulated rig), or ", shown.display())
            })
            .unwrap_or_default();
        return Err(vec![Diagnostic::at_path(
            protocol_path,
            &text,
            &rig::config::YamlPath::root().key("rig"),
            Severity::Error,
            format!(
                "`rig: {}` resolves to {}, which does not exist (a rig path is relative to the \
                 protocol's folder)",
                protocol.rig.as_deref().unwrap_or_default(),
                std::path::absolute(&rig_path)
                    .unwrap_or_else(|_| rig_path.clone())
                    .display()
            ),
            format!("{suggest}correct `rig:` to point at a rig file"),
        )]);
    }
    let rig_text = read(&rig_path, "the rig file")?;
    source::mapping(&rig_path, &rig_text, "a rig file", RIG_KEYS)?;
    let rig = RigConfig::from_yaml_str(&rig_text)
        .map_err(|e| vec![Diagnostic::from_yaml_error(&rig_path, &rig_text, &e)])?;
    let mut diags: Vec<Diagnostic> = rig
        .check()
        .into_iter()
        .map(|i| {
            Diagnostic::at_path(
                &rig_path,
                &rig_text,
                &i.path,
                Severity::Error,
                i.message,
                i.fix,
            )
        })
        .collect();
    // A protocol cannot be checked against a rig that is itself wrong (reversed travel,
    // absurd speeds): report the rig first.
    if !diags.is_empty() {
        return Err(diags);
    }
    let compiled = compile::compile_with(&protocol, &rig, budget);
    if let Some(rel) = &protocol.record.gelsight_force {
        let at = rig::config::YamlPath::root()
            .key("record")
            .key("gelsight_force");
        let file = protocol_path.parent().unwrap_or(Path::new(".")).join(rel);
        let frames = compiled.actions.iter().any(
            |a| matches!(&a.kind, compile::ActionKind::StreamsBegin(r) if r.frames_hz.is_some()),
        );
        if !file.is_file() {
            diags.push(Diagnostic::at_path(
                protocol_path,
                &text,
                &at,
                Severity::Error,
                format!("the sensor file {} does not exist", file.display()),
                "give the SENSOR.yaml written by `gelrig calibrate --out`, relative to this protocol",
            ));
        } else if !frames {
            diags.push(Diagnostic::at_path(
                protocol_path,
                &text,
                &at,
                Severity::Error,
                "the GelSight's force is read from tracked frames, and this protocol records none",
                "record continuous frames (`record: {frames: 25 Hz, blocks: …}`) where the force \
                 is wanted",
            ));
        }
    }
    for i in &compiled.issues {
        let (file, src) = if i.in_rig {
            (&rig_path, &rig_text)
        } else {
            (&protocol_path.to_path_buf(), &text)
        };
        diags.push(Diagnostic::at_path(
            file,
            src,
            &i.path,
            i.severity,
            i.message.clone(),
            i.fix.clone(),
        ));
    }
    if diags.iter().any(Diagnostic::is_error) {
        return Err(diags);
    }
    if let Some(d) = too_fine_to_simulate(protocol_path, &text, &protocol, &compiled, &rig) {
        diags.push(d);
        return Err(diags);
    }
    let planned = crate::plan::plan(&protocol, &compiled, &rig);
    if planned.bytes.max > budget.max_bytes as f64 {
        diags.push(Diagnostic::at_path(
            protocol_path,
            &text,
            &rig::config::YamlPath::root().key("sequence"),
            Severity::Error,
            format!(
                "the run would write up to {} ({} frames, {} force rows over {}), over the data budget of {}",
                crate::plan::human_bytes(planned.bytes.max),
                rig::units::fmt_value(planned.frames.max.round()),
                rig::units::fmt_value(planned.force_rows.max.round()),
                crate::plan::human_duration(planned.duration_s.max),
                crate::plan::human_bytes(budget.max_bytes as f64)
            ),
            "check settle times, frame counts and stream rates; if the run really is that big, pass `--max-data SIZE` (e.g. `--max-data 500GB`)",
        ));
        return Err(diags);
    }
    Ok(Loaded {
        path: protocol_path.to_path_buf(),
        text,
        protocol,
        rig_path,
        rig_text,
        rig,
        compiled,
        plan: planned,
        warnings: diags,
    })
}

/// On a rig that simulates the elastomer, an indenter whose contact model would need a grid
/// finer than the simulator solves on (a 0.03 mm sphere on a 4.2 mm layer) is refused here,
/// before a run spends minutes building it or runs out of memory.
fn too_fine_to_simulate(
    path: &Path,
    text: &str,
    protocol: &Protocol,
    compiled: &Compiled,
    rig: &RigConfig,
) -> Option<Diagnostic> {
    use mechanics::response::{ContactModel, MAX_GRID_SIDE};
    if !rig.uses_sim() {
        return None;
    }
    let spec = plant_spec(protocol, compiled).ok()?;
    let side = ContactModel::grid_side(&spec.contact, &spec.quality, compiled.needs.camera);
    (side > MAX_GRID_SIDE).then(|| {
        Diagnostic::at_path(
            path,
            text,
            &rig::config::YamlPath::root().key("indenter"),
            Severity::Error,
            format!(
                "the simulated bench would solve this contact on a grid {side} cells wide (at most {MAX_GRID_SIDE}): the indenter is too small for the {} mm layer",
                rig::units::fmt_value(spec.contact.layer.thickness_mm)
            ),
            "use a larger indenter, or run on a real rig",
        )
    })
}

/// Replaces `sensor.material: {from: FILE}` by the file's values (the run directory's
/// `protocol.yaml` then carries them, and reads back without the file).
fn read_material(path: &Path, text: &str, protocol: &mut Protocol) -> Result<(), Box<Diagnostic>> {
    let Some(schema::MaterialEntry::From(from)) = &protocol.sensor.material else {
        return Ok(());
    };
    let file = path.parent().unwrap_or(Path::new(".")).join(&from.from);
    let at = rig::config::YamlPath::root()
        .key("sensor")
        .key("material")
        .key("from");
    let m = material_file::MaterialFile::read(&file).map_err(|e| {
        let detail = match &e {
            material_file::MaterialFileError::Read { path, detail, .. } => {
                format!("the material file {}: {detail}", path.display())
            }
            other => other.to_string(),
        };
        Box::new(Diagnostic::at_path(
            path,
            text,
            &at,
            Severity::Error,
            detail,
            "give the MATERIAL.yaml that `gelrig fit-material --out` wrote, relative to this protocol",
        ))
    })?;
    protocol.sensor.material = Some(schema::MaterialEntry::Inline(m.material));
    Ok(())
}

/// The simulated bench's description of this protocol's sensor, indenter and object;
/// `compiled` bounds the depths the contact model must cover.
pub fn plant_spec(p: &Protocol, compiled: &Compiled) -> Result<PlantSpec, String> {
    let sensor = &p.sensor;
    let kind = sensor.kind;
    let e = sensor
        .elastomer
        .clone()
        .unwrap_or_else(|| schema::defaults::elastomer(kind));
    let m = match &sensor.material {
        None => schema::defaults::material(kind),
        Some(entry) => entry.values().cloned().ok_or_else(|| {
            "the protocol's `material: {from: …}` was not read (load the protocol with              `protocol::load`)"
                .to_string()
        })?,
    };
    let v = sensor
        .view
        .clone()
        .unwrap_or_else(|| schema::defaults::view(kind));
    let markers = match sensor
        .markers
        .clone()
        .unwrap_or_else(|| schema::defaults::markers(kind))
    {
        Markers::Grid {
            columns,
            rows,
            spacing,
            diameter,
        } => MarkerLayout::Grid {
            columns,
            rows,
            spacing_mm: spacing.mm(),
            diameter_mm: diameter.mm(),
        },
        Markers::Random { spacing, size } => MarkerLayout::Random {
            spacing_mm: spacing.mm(),
            size_mm: size.mm(),
        },
    };
    let indenter = match &p.indenter {
        IndenterSpec::FlatCircle { diameter } => mechanics::Indenter::FlatCircle {
            diameter_mm: diameter.mm(),
        },
        IndenterSpec::FlatEllipse { major, minor } => mechanics::Indenter::FlatEllipse {
            major_mm: major.mm(),
            minor_mm: minor.mm(),
        },
        IndenterSpec::FlatRectangle { width, length } => mechanics::Indenter::FlatRectangle {
            width_mm: width.mm(),
            length_mm: length.mm(),
        },
        IndenterSpec::FlatTriangle { side } => {
            mechanics::Indenter::FlatTriangle { side_mm: side.mm() }
        }
        IndenterSpec::Sphere { diameter } => mechanics::Indenter::Sphere {
            diameter_mm: diameter.mm(),
        },
        IndenterSpec::Cylinder { diameter, length } => mechanics::Indenter::Cylinder {
            diameter_mm: diameter.mm(),
            length_mm: length.mm(),
        },
    };
    let contact = mechanics::contact::Contact::new(
        mechanics::Layer {
            width_mm: e.width.mm(),
            length_mm: e.length.mm(),
            thickness_mm: e.thickness.mm(),
        },
        mechanics::Material {
            youngs_modulus_mpa: m.youngs_modulus.mpa(),
            poisson_ratio: m.poisson_ratio,
            prony: m
                .prony
                .iter()
                .map(|t| mechanics::PronyTerm {
                    weight: t.weight,
                    tau_s: t.tau.s(),
                })
                .collect(),
            friction: m.friction,
        },
        indenter,
    )
    .map_err(|e| e.to_string())?;
    let h = e.thickness.mm();
    Ok(PlantSpec {
        contact,
        markers,
        view_width_mm: v.width.mm(),
        view_height_mm: v.height.mm(),
        object_mass_g: p.object.as_ref().map(|o| o.mass.g()),
        max_depth_mm: compiled.max_depth_mm(0.5 * h).clamp(0.05 * h, 0.95 * h),
        kinetic_friction: m.kinetic_friction.unwrap_or(0.9 * m.friction),
        quality: simbench::Quality::default(),
    })
}
