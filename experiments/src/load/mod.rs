//! Loading a protocol: read it, apply command-line overrides, read its rig and material,
//! compile it, check it and plan it once — the [`Loaded`] protocol every command and the
//! runner start from. It sits above both the protocol language and the planner, so neither
//! needs the other.

use std::path::{Path, PathBuf};

use rig::config::RigConfig;

use crate::diag::{Diagnostic, Severity};
use crate::protocol::compile::{self, Budget, Compiled};
use crate::protocol::schema::Protocol;
use crate::protocol::source::read;
use crate::protocol::{load_rig, parse, plant_spec, read_material, shipped};

mod overrides;

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
    load_text(protocol_path, text, rig_override, budget, None)
}

/// Values given on the command line in place of the protocol's own.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Overrides {
    /// `KEY=VALUE` pairs: a dotted path into the protocol (`indenter.diameter`,
    /// `sequence.3.stepped.step`) and a YAML value (`10 mm`, `{fixed: 60 s}`).
    pub set: Vec<String>,
    /// The run's name in place of the protocol's.
    pub name: Option<String>,
    /// The simulated bench's fidelity in place of the rig file's `sim: {fidelity}`; the
    /// edited rig is what the run records (its `rig.yaml`).
    pub fidelity: Option<rig::config::Fidelity>,
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
    let text = read(protocol_path, "the protocol")?;
    let protocol_edits = Overrides {
        fidelity: None,
        ..overrides.clone()
    };
    let edited = if protocol_edits == Overrides::default() {
        text
    } else {
        overrides::apply(&text, overrides).map_err(|(message, fix)| {
            vec![Diagnostic::at_path(
                protocol_path,
                &text,
                &rig::config::YamlPath::root(),
                Severity::Error,
                message,
                fix,
            )]
        })?
    };
    load_text(
        protocol_path,
        edited,
        rig_override,
        budget,
        overrides.fidelity,
    )
}

/// The rig with its simulated bench's fidelity set to `level` (`sim: {fidelity}`), in the
/// parsed rig and in the text the run records. A rig without a simulated bench is refused:
/// it has nothing to resolve.
fn with_fidelity(
    rig_path: &Path,
    (mut rig, text): (RigConfig, String),
    level: rig::config::Fidelity,
) -> Result<(RigConfig, String), Vec<Diagnostic>> {
    let refuse = |message: String| {
        vec![Diagnostic::at_path(
            rig_path,
            &text,
            &rig::config::YamlPath::root(),
            Severity::Error,
            message,
            "drop --fidelity: it sets how finely a simulated bench solves its contact",
        )]
    };
    let Some(sim) = rig.sim.as_mut() else {
        return Err(refuse(format!(
            "--fidelity {}: rig `{}` has no simulated bench (`sim:`)",
            level.as_str(),
            rig.name
        )));
    };
    sim.fidelity = Some(level);
    let mut doc: serde_yaml::Value = serde_yaml::from_str(&text)
        .map_err(|e| refuse(format!("the rig file does not re-read: {e}")))?;
    let set = doc
        .get_mut("sim")
        .and_then(serde_yaml::Value::as_mapping_mut)
        .map(|m| m.insert("fidelity".into(), level.as_str().into()));
    if set.is_none() {
        return Err(refuse("the rig file's `sim:` is not a mapping".into()));
    }
    let body = serde_yaml::to_string(&doc)
        .map_err(|e| refuse(format!("the edited rig does not write: {e}")))?;
    let edited = format!(
        "# {} with `sim: {{fidelity: {}}}` set by --fidelity\n{body}",
        rig_path.display(),
        level.as_str()
    );
    Ok((rig, edited))
}

/// Parses, resolves and checks protocol `text` read from `protocol_path` (relative paths in
/// it resolve against that file's folder).
fn load_text(
    protocol_path: &Path,
    text: String,
    rig_override: Option<&Path>,
    budget: &Budget,
    fidelity: Option<rig::config::Fidelity>,
) -> Result<Loaded, Vec<Diagnostic>> {
    let mut protocol = parse(protocol_path, &text).map_err(|d| vec![*d])?;
    read_material(protocol_path, &text, &mut protocol).map_err(|d| vec![*d])?;
    protocol.sensor.resolve_defaults();
    let rig_path = rig_path_of(protocol_path, &text, &protocol, rig_override)?;
    let (rig, rig_text) = match fidelity {
        Some(level) => with_fidelity(&rig_path, load_rig(&rig_path)?, level)?,
        None => load_rig(&rig_path)?,
    };
    let mut diags = Vec::new();
    let compiled = compile::compile_with(&protocol, &rig, budget);
    diags.extend(gelsight_force_issue(
        protocol_path,
        &text,
        &protocol,
        &compiled,
    ));
    diags.extend(traction_maps_issue(protocol_path, &text, &protocol, &rig));
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
    if let Some(d) = over_budget(protocol_path, &text, &planned, budget) {
        diags.push(d);
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

/// The rig file a protocol runs on: `--rig`, or its `rig:` relative to the protocol's folder.
fn rig_path_of(
    protocol_path: &Path,
    text: &str,
    protocol: &Protocol,
    rig_override: Option<&Path>,
) -> Result<PathBuf, Vec<Diagnostic>> {
    let rig_path = match (rig_override, &protocol.rig) {
        (Some(r), _) => r.to_path_buf(),
        (None, Some(r)) => protocol_path.parent().unwrap_or(Path::new(".")).join(r),
        (None, None) => {
            return Err(vec![Diagnostic::at_path(
                protocol_path,
                text,
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
            text,
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
    Ok(rig_path)
}

/// `record: {gelsight_force: SENSOR.yaml}` needs the file and frames to read it from.
fn gelsight_force_issue(
    protocol_path: &Path,
    text: &str,
    protocol: &Protocol,
    compiled: &Compiled,
) -> Option<Diagnostic> {
    let rel = protocol.record.gelsight_force.as_ref()?;
    let at = rig::config::YamlPath::root()
        .key("record")
        .key("gelsight_force");
    let file = protocol_path.parent().unwrap_or(Path::new(".")).join(rel);
    let frames = compiled
        .actions
        .iter()
        .any(|a| matches!(&a.kind, compile::ActionKind::StreamsBegin(r) if r.frames_hz.is_some()));
    if !file.is_file() {
        Some(Diagnostic::at_path(
            protocol_path,
            text,
            &at,
            Severity::Error,
            format!("the sensor file {} does not exist", file.display()),
            "give the SENSOR.yaml written by `gelrig calibrate --out`, relative to this protocol",
        ))
    } else if !frames {
        Some(Diagnostic::at_path(
            protocol_path,
            text,
            &at,
            Severity::Error,
            "the GelSight's force is read from tracked frames, and this protocol records none",
            "record continuous frames (`record: {frames: 25 Hz, blocks: …}`) where the force \
             is wanted",
        ))
    } else {
        None
    }
}

/// Frame pixels per traction-map cell `record: {traction_maps: N}` accepts.
pub const TRACTION_MAP_PX: std::ops::RangeInclusive<u32> = 1..=32;

/// `record: {traction_maps: N}` needs a simulated camera (the maps are the simulator's) and a
/// cell size within [`TRACTION_MAP_PX`].
fn traction_maps_issue(
    protocol_path: &Path,
    text: &str,
    protocol: &Protocol,
    rig: &rig::config::RigConfig,
) -> Option<Diagnostic> {
    let px = protocol.record.traction_maps?;
    let at = rig::config::YamlPath::root()
        .key("record")
        .key("traction_maps");
    let sim_camera = rig
        .camera
        .as_ref()
        .is_some_and(|c| matches!(c.driver, rig::config::CameraDriver::Sim));
    let (message, fix) = if !TRACTION_MAP_PX.contains(&px) {
        (
            format!(
                "traction maps of {px} px cells: the cell size is {} to {} frame pixels",
                TRACTION_MAP_PX.start(),
                TRACTION_MAP_PX.end()
            ),
            "write `traction_maps: 4` (160 × 120 maps of a 640 × 480 frame)".to_string(),
        )
    } else if !sim_camera {
        (
            format!(
                "traction maps are the simulator's, and rig `{}` has no simulated camera",
                rig.name
            ),
            "remove `traction_maps:`, or run on a rig with `camera: {driver: sim}` \
             (`--rig protocols/rigs/sim.yaml`)"
                .to_string(),
        )
    } else {
        return None;
    };
    Some(Diagnostic::at_path(
        protocol_path,
        text,
        &at,
        Severity::Error,
        message,
        fix,
    ))
}

/// A run that would write more than the data budget, named with its frames, rows and time.
fn over_budget(
    protocol_path: &Path,
    text: &str,
    planned: &crate::plan::Plan,
    budget: &Budget,
) -> Option<Diagnostic> {
    if planned.bytes.max <= budget.max_bytes as f64 {
        return None;
    }
    Some(Diagnostic::at_path(
        protocol_path,
        text,
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
    ))
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
    let quality = simbench::quality_for(rig.fidelity());
    let side = ContactModel::grid_side(&spec.contact, &quality, compiled.needs.camera);
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
            if rig.fidelity() == rig::config::Fidelity::Default {
                "use a larger indenter, or run on a real rig".to_string()
            } else {
                format!(
                    "the rig's fidelity `{}` asks for the finer grid: use `--fidelity default` (or a \
                     larger indenter)",
                    rig.fidelity().as_str()
                )
            },
        )
    })
}
