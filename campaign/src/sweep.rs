//! The sweep file: a base protocol and the parameters to vary.
//!
//! ```yaml
//! sweep: punch-size-depth          # the campaign's name
//! protocol: box-normal-flat        # a shipped protocol, or a path relative to this file
//! rig: rigs/sim.yaml               # optional, as `gelrig run --rig`
//! set: {approach.speed: 2 mm/s}    # optional: applied to every point
//! grid:                            # every combination, in file order (the last varies fastest)
//!   indenter.diameter: [6 mm, 9.5 mm]
//!   seed: [1, 2, 3]
//! resources: {time_per_point: 10 min, memory: 2 GB}   # optional, for --slurm
//! ```
//!
//! In place of `grid:`, `list:` names the points one by one (`[{indenter.diameter: 6 mm,
//! seed: 1}, …]`), and `random:` / `latin_hypercube:` draw `n` points from ranges with a seed
//! of their own (`{n: 20, seed: 7, parameters: {indenter.diameter: {from: 5 mm, to: 10
//! mm}, seed: {from: 1, to: 1000}}}`). A key is any `gelrig run --set` key; `seed` is the
//! simulated devices' seed (`gelrig run --seed`).

use std::path::{Path, PathBuf};

use serde_yaml::Value;

use crate::CampaignError;
use crate::design::{Design, Range};

/// What the campaign needs of a point's run besides its parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct Sweep {
    /// The campaign's name (its folder's default name).
    pub name: String,
    /// The base protocol: a path resolved against the sweep file's folder, or a shipped
    /// protocol's name as written.
    pub protocol: PathBuf,
    /// The rig file, if given.
    pub rig: Option<PathBuf>,
    /// `--set` pairs applied to every point.
    pub fixed: Vec<(String, String)>,
    /// How the points are laid out.
    pub design: Design,
    /// Wall time one point may take on a cluster, s.
    pub time_per_point_s: f64,
    /// Memory one point's process may use, MB.
    pub memory_mb: u64,
}

/// A point's time on a cluster when the file does not say: 10 minutes.
pub const DEFAULT_TIME_PER_POINT_S: f64 = 600.0;
/// A point's memory when the file does not say: 2 GB.
pub const DEFAULT_MEMORY_MB: u64 = 2048;

const DESIGNS: [&str; 4] = ["grid", "list", "random", "latin_hypercube"];
const KEYS: [&str; 9] = [
    "sweep",
    "protocol",
    "rig",
    "set",
    "grid",
    "list",
    "random",
    "latin_hypercube",
    "resources",
];

impl Sweep {
    /// Reads and checks a sweep file.
    pub fn read(path: &Path) -> Result<Self, CampaignError> {
        let text = std::fs::read_to_string(path).map_err(|e| CampaignError::Read {
            path: path.to_path_buf(),
            detail: e.to_string(),
        })?;
        Self::parse(&text, path)
    }

    /// Parses a sweep file's text; `path` names it in messages and anchors relative paths.
    pub fn parse(text: &str, path: &Path) -> Result<Self, CampaignError> {
        let bad = |key: &str, detail: String| CampaignError::Sweep {
            path: path.to_path_buf(),
            key: key.to_string(),
            detail,
        };
        let doc: Value = serde_yaml::from_str(text).map_err(|e| bad("", e.to_string()))?;
        let Value::Mapping(map) = doc else {
            return Err(bad(
                "",
                "a sweep file is a mapping (sweep:, protocol:, and a design)".into(),
            ));
        };
        for k in map.keys() {
            let k = scalar(k).unwrap_or_default();
            if !KEYS.contains(&k.as_str()) {
                return Err(bad(
                    &k,
                    format!("unknown key; a sweep file has {}", KEYS.join(", ")),
                ));
            }
        }
        let get = |k: &str| map.get(Value::String(k.into()));
        let name = get("sweep")
            .and_then(scalar)
            .filter(|s| !s.trim().is_empty())
            .ok_or_else(|| bad("sweep", "name the campaign (sweep: my-campaign)".into()))?;
        let here = path.parent().unwrap_or(Path::new("."));
        let protocol = get("protocol").and_then(scalar).ok_or_else(|| {
            bad(
                "protocol",
                "name the base protocol (a shipped name or a path)".into(),
            )
        })?;
        let protocol = resolve(here, &protocol);
        let rig = get("rig").and_then(scalar).map(|r| here.join(r));
        let fixed = match get("set") {
            None => Vec::new(),
            Some(Value::Mapping(m)) => m
                .iter()
                .map(|(k, v)| {
                    let key = scalar(k).unwrap_or_default();
                    value_text(v)
                        .map(|v| (key.clone(), v))
                        .ok_or_else(|| bad(&format!("set.{key}"), "a value".into()))
                })
                .collect::<Result<_, _>>()?,
            Some(_) => return Err(bad("set", "a mapping of KEY: VALUE".into())),
        };
        let given: Vec<&str> = DESIGNS
            .iter()
            .copied()
            .filter(|d| get(d).is_some())
            .collect();
        let design = match given.as_slice() {
            [one] => Design::parse(one, get(one).unwrap_or(&Value::Null))
                .map_err(|(key, detail)| bad(&format!("{one}{key}"), detail))?,
            [] => {
                return Err(bad(
                    "",
                    format!("no design: give one of {}", DESIGNS.join(", ")),
                ));
            }
            many => {
                return Err(bad(
                    "",
                    format!(
                        "{} designs given ({}): give one",
                        many.len(),
                        many.join(", ")
                    ),
                ));
            }
        };
        let (time_per_point_s, memory_mb) =
            resources(get("resources")).map_err(|(k, d)| bad(&k, d))?;
        Ok(Self {
            name: name.trim().to_string(),
            protocol,
            rig,
            fixed,
            design,
            time_per_point_s,
            memory_mb,
        })
    }
}

/// A shipped protocol's bare name stays a name; anything that looks like a path is taken
/// relative to the sweep file's folder.
fn resolve(here: &Path, protocol: &str) -> PathBuf {
    let looks_like_path = protocol.contains('/') || protocol.ends_with(".yaml");
    if looks_like_path {
        here.join(protocol)
    } else {
        PathBuf::from(protocol)
    }
}

/// `resources: {time_per_point: 10 min, memory: 2 GB}`.
fn resources(v: Option<&Value>) -> Result<(f64, u64), (String, String)> {
    let mut out = (DEFAULT_TIME_PER_POINT_S, DEFAULT_MEMORY_MB);
    let Some(v) = v else {
        return Ok(out);
    };
    let Value::Mapping(m) = v else {
        return Err((
            "resources".into(),
            "a mapping: {time_per_point: 10 min, memory: 2 GB}".into(),
        ));
    };
    for (k, v) in m {
        let key = scalar(k).unwrap_or_default();
        let text = scalar(v).unwrap_or_default();
        let r = Range::quantity(&text);
        match (key.as_str(), r) {
            ("time_per_point", Some((n, unit))) if n > 0.0 => {
                let scale = match unit.as_str() {
                    "s" => 1.0,
                    "min" => 60.0,
                    "h" => 3600.0,
                    _ => {
                        return Err((
                            "resources.time_per_point".into(),
                            format!("{text:?}: give s, min or h"),
                        ));
                    }
                };
                out.0 = n * scale;
            }
            ("memory", Some((n, unit))) if n > 0.0 => {
                let scale = match unit.as_str() {
                    "MB" => 1.0,
                    "GB" => 1024.0,
                    _ => {
                        return Err((
                            "resources.memory".into(),
                            format!("{text:?}: give MB or GB"),
                        ));
                    }
                };
                out.1 = (n * scale).ceil() as u64;
            }
            _ => {
                return Err((
                    format!("resources.{key}"),
                    format!(
                        "{text:?}: resources are time_per_point (e.g. 10 min) and memory (e.g. 2 GB)"
                    ),
                ));
            }
        }
    }
    Ok(out)
}

/// A scalar's text (strings as written, numbers and booleans as YAML prints them).
pub(crate) fn scalar(v: &Value) -> Option<String> {
    match v {
        Value::String(s) => Some(s.clone()),
        Value::Number(n) => Some(n.to_string()),
        Value::Bool(b) => Some(b.to_string()),
        _ => None,
    }
}

/// A value as `--set` takes it: a scalar as written, a mapping or list as flow YAML (JSON),
/// e.g. `{force_window: 10 s, frames: 10}`. `None` for a null.
pub(crate) fn value_text(v: &Value) -> Option<String> {
    match v {
        Value::Mapping(_) | Value::Sequence(_) => serde_json::to_string(v).ok(),
        other => scalar(other),
    }
}
