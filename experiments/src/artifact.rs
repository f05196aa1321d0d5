//! Writing the files gelrig hands to users (sensor and material files): YAML, written to a
//! temporary name first and renamed, so a full disk or a kill leaves no half file under the
//! real name.

use std::path::Path;

/// Writes `value` as YAML to `path` atomically; `Err` is the reason.
pub fn write_yaml<T: serde::Serialize>(path: &Path, value: &T) -> Result<(), String> {
    let text = serde_yaml::to_string(value).map_err(|e| e.to_string())?;
    let tmp = path.with_extension("yaml.partial");
    std::fs::write(&tmp, text).map_err(|e| e.to_string())?;
    std::fs::rename(&tmp, path).map_err(|e| e.to_string())
}
