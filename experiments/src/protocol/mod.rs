//! Protocols: schema, parsing, checking and expansion.
//!
//! Loading follows dora's parse → resolve → check split: [`schema`] parses (serde, unknown
//! keys denied, units checked), [`crate::load`] resolves the rig file and the sensor
//! defaults, and [`compile`] checks everything that needs both and expands the sequence.

pub mod compile;
pub mod material;
pub mod material_file;
pub mod schema;
pub mod shipped;
pub mod source;

use std::path::Path;

use rig::config::RigConfig;
use simbench::{MarkerLayout, PlantSpec};

use crate::diag::{Diagnostic, Severity};
use compile::Compiled;
use schema::{IndenterSpec, Markers, Protocol};
use source::read;

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

/// Replaces `sensor.material: {from: FILE}` by the file's values (the run directory's
/// `protocol.yaml` then carries them, and reads back without the file).
pub(crate) fn read_material(
    path: &Path,
    text: &str,
    protocol: &mut Protocol,
) -> Result<(), Box<Diagnostic>> {
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
            "the protocol's `material: {from: …}` was not read (load the protocol with `experiments::load::load`)"
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
