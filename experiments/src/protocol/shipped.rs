//! The protocols shipped with gelrig, found by name (`gelrig run box-normal-flat`) and
//! listed (`gelrig protocols`), so a newcomer needs no path into the source tree.
//!
//! Where they are: `$GELRIG_PROTOCOLS` if set; else the folder a package registered
//! ([`use_packaged`]: the Python wheel's `gelrig/protocols`); else `protocols/` beside a
//! source checkout's `target/<profile>/gelrig`; else `../share/gelrig/protocols` beside an
//! installed binary; else the checkout this binary was built from.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

static PACKAGED: OnceLock<PathBuf> = OnceLock::new();

/// Registers the shipped protocols a package carries (the Python wheel's copy), for this
/// process only: unlike setting `$GELRIG_PROTOCOLS`, nothing it starts inherits it. The
/// first registration wins; `false` if one was already made.
pub fn use_packaged(dir: PathBuf) -> bool {
    PACKAGED.set(dir).is_ok()
}

/// The folder of shipped protocols, if one is found.
pub fn dir() -> Option<PathBuf> {
    let mut candidates = Vec::new();
    if let Some(d) = std::env::var_os("GELRIG_PROTOCOLS") {
        candidates.push(PathBuf::from(d));
    }
    if let Some(d) = PACKAGED.get() {
        candidates.push(d.clone());
    }
    if let Ok(exe) = std::env::current_exe()
        && let Some(bin) = exe.parent()
    {
        candidates.push(bin.join("../../protocols"));
        candidates.push(bin.join("../share/gelrig/protocols"));
    }
    candidates.push(Path::new(env!("CARGO_MANIFEST_DIR")).join("../protocols"));
    candidates
        .into_iter()
        .find(|d| d.join("rigs/sim.yaml").is_file())
        .map(|d| d.canonicalize().unwrap_or(d))
}

/// `arg` as given when it is a file; else the shipped protocol of that name (`NAME` or
/// `NAME.yaml`), with `true`; else `arg` unchanged (its reading then fails, naming it).
pub fn resolve(arg: &Path) -> (PathBuf, bool) {
    if arg.is_file() || arg.components().count() != 1 {
        return (arg.to_path_buf(), false);
    }
    let Some(dir) = dir() else {
        return (arg.to_path_buf(), false);
    };
    let name = arg.to_string_lossy();
    let file = if name.ends_with(".yaml") {
        dir.join(&*name)
    } else {
        dir.join(format!("{name}.yaml"))
    };
    if file.is_file() {
        (file, true)
    } else {
        (arg.to_path_buf(), false)
    }
}

/// The shipped simulated rig, if the shipped protocols are found.
pub fn sim_rig() -> Option<PathBuf> {
    dir().map(|d| d.join("rigs/sim.yaml"))
}

/// A shipped protocol: its name, file and the first sentence of its description.
#[derive(Debug, Clone, PartialEq)]
pub struct Shipped {
    /// The protocol's file name without `.yaml`.
    pub name: String,
    /// Its file.
    pub path: PathBuf,
    /// The first sentence of its `description`.
    pub summary: String,
}

/// Every shipped protocol, by name.
pub fn list() -> Vec<Shipped> {
    let Some(dir) = dir() else {
        return Vec::new();
    };
    let Ok(entries) = std::fs::read_dir(&dir) else {
        return Vec::new();
    };
    let mut out: Vec<Shipped> = entries
        .filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|x| x == "yaml"))
        .filter(|p| {
            !p.file_name()
                .is_some_and(|n| n.to_string_lossy().starts_with('.'))
        })
        .map(|path| {
            let text = std::fs::read_to_string(&path).unwrap_or_default();
            let description = serde_yaml::from_str::<serde_yaml::Value>(&text)
                .ok()
                .and_then(|v| {
                    v.get("description")
                        .and_then(|d| d.as_str())
                        .map(str::to_string)
                })
                .unwrap_or_default();
            // Up to the first reference, colon or full stop: "Normal indentation of the box
            // sensor with a 9.5 mm flat circular punch".
            let cut = [" (", ": ", ". "]
                .iter()
                .filter_map(|m| description.find(m))
                .min()
                .unwrap_or(description.len());
            let summary = description[..cut].trim().to_string();
            Shipped {
                name: path
                    .file_stem()
                    .map(|s| s.to_string_lossy().into_owned())
                    .unwrap_or_default(),
                path,
                summary,
            }
        })
        .collect();
    out.sort_by(|a, b| a.name.cmp(&b.name));
    out
}
