//! `run.yaml`: the run's status and provenance, and how other commands read it.

use std::collections::BTreeMap;
use std::fs::{self, OpenOptions};
use std::path::Path;

use serde::{Deserialize, Serialize};

/// Run status as written in `run.yaml`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    /// In progress (or killed, if the lock is free).
    Running,
    /// Finished every step.
    Completed,
    /// Stopped by the operator or a safety limit; motion stopped and retracted.
    Aborted,
    /// Stopped by an error (device, disk).
    Failed,
}

impl Manifest {
    /// What the run was, in a line per key (the MCAP file's `gelrig_run` metadata).
    pub fn headline(&self) -> std::collections::BTreeMap<String, String> {
        [
            ("protocol", self.protocol.clone()),
            ("status", self.status.name().to_string()),
            ("seed", self.seed.to_string()),
            ("rig", self.rig.clone()),
            ("started_utc", self.started_utc.clone()),
            ("gelrig_version", self.gelrig_version.clone()),
            ("clock", self.clock.clone()),
        ]
        .into_iter()
        .map(|(k, v)| (k.to_string(), v))
        .collect()
    }
}

impl Status {
    /// Lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            Status::Running => "running",
            Status::Completed => "completed",
            Status::Aborted => "aborted",
            Status::Failed => "failed",
        }
    }
}

/// A device as recorded in the manifest.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DeviceRecord {
    /// Role.
    pub role: String,
    /// Identity.
    pub identity: String,
}

/// `run.yaml`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    /// Run status.
    pub status: Status,
    /// Why the run was aborted.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
    /// The error that failed the run.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
    /// Protocol name.
    pub protocol: String,
    /// Protocol file as given.
    pub protocol_file: String,
    /// Rig name.
    pub rig: String,
    /// Rig file as given.
    pub rig_file: String,
    /// Start, RFC 3339 UTC.
    pub started_utc: String,
    /// End, RFC 3339 UTC.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ended_utc: Option<String>,
    /// gelrig version.
    pub gelrig_version: String,
    /// Seed of the simulated devices.
    pub seed: u64,
    /// `virtual`, `scaled ×k` or `monotonic`.
    pub clock: String,
    /// Process id of the run.
    pub pid: u32,
    /// Steps the plan has.
    pub steps_planned: u32,
    /// Steps completed and on disk.
    pub steps_completed: u32,
    /// Planned duration, [min, max] s.
    pub eta_s: [f64; 2],
    /// Devices opened.
    #[serde(default)]
    pub devices: Vec<DeviceRecord>,
    /// Tare offsets subtracted from every sample: fx, fy, fz (N), tx, ty, tz (N·mm).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tare: Option<[f64; 6]>,
    /// Axis origins (contact points), absolute, in the axis unit.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub origins: BTreeMap<String, f64>,
    /// Absolute axis positions at the end.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub final_positions: BTreeMap<String, f64>,
    /// Safety events (limit trips).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub safety_events: Vec<String>,
    /// Warnings from validation and the run.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
    /// The segments a resumed run continued in (`gelrig resume`), oldest first; empty for a
    /// run that went in one.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub resumed: Vec<Segment>,
    /// How each device's times were put on the run's timebase (`force`, `camera`), as of
    /// the end of the run.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub timing: BTreeMap<String, records::DeviceTiming>,
}

/// One continuation of a run by `gelrig resume`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Segment {
    /// When it started, RFC 3339 UTC.
    pub started_utc: String,
    /// Its start on the run's timebase, ns: rows stamped before it belong to earlier
    /// segments.
    pub t_start_ns: u64,
    /// The step it continued at.
    pub from_step: u32,
    /// Process id.
    pub pid: u32,
    /// How the previous segment ended (`interrupted` when it was killed).
    pub previous_status: String,
    /// Why it ended, when it said.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub previous_message: Option<String>,
    /// When the previous segment ended, RFC 3339 UTC (a killed one: when it last wrote a
    /// file), so a run's duration leaves out the time it was down.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub previous_ended_utc: Option<String>,
}

/// Reads a run directory's manifest.
pub fn read_manifest(dir: &Path) -> Result<Manifest, String> {
    let path = dir.join(crate::names::MANIFEST);
    let text =
        fs::read_to_string(&path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
    serde_yaml::from_str(&text).map_err(|e| format!("cannot parse {}: {e}", path.display()))
}

/// A file named inside a run directory (a `frames.csv` row), resolved and checked. A run
/// directory is data — copied from a colleague, edited, or crafted — so a name such as
/// `/etc/passwd` or `../../..` must never be opened: the name must be a relative path of
/// plain components, stay inside `dir` once symlinks are followed, and be a regular file.
pub fn run_file(dir: &Path, name: &str) -> Result<std::path::PathBuf, String> {
    use std::path::Component;
    let rel = Path::new(name);
    if name.is_empty() || !rel.components().all(|c| matches!(c, Component::Normal(_))) {
        return Err(format!(
            "`{}` is not a path inside the run directory",
            records::quote(name)
        ));
    }
    let inside = |p: &Path| {
        p.canonicalize()
            .map_err(|e| format!("`{}`: {e}", records::quote(name)))
    };
    let (root, file) = (inside(dir)?, inside(&dir.join(rel))?);
    if !file.starts_with(&root) {
        return Err(format!(
            "`{}` leads outside the run directory",
            records::quote(name)
        ));
    }
    if !file.is_file() {
        return Err(format!("`{}` is not a regular file", records::quote(name)));
    }
    Ok(file)
}

/// True if a process still holds the run's lock (the run is really in progress).
pub fn is_locked(dir: &Path) -> bool {
    match OpenOptions::new()
        .write(true)
        .open(dir.join(crate::names::LOCK))
    {
        Ok(f) => f.try_lock().is_err(),
        Err(_) => false,
    }
}
