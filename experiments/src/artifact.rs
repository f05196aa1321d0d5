//! The files gelrig hands to users (sensor and material files): YAML, written to a
//! temporary name first and renamed, so a full disk or a kill leaves no half file under the
//! real name; and the one error such a file gives when it does not read or write.

use std::path::PathBuf;

/// Why a file gelrig hands to users (a sensor file, a material file) could not be read or
/// written.
#[derive(Debug, thiserror::Error)]
pub enum ArtifactError {
    /// Reading or parsing failed.
    #[error("{path}: {detail}; fix: {fix}")]
    Read {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        detail: String,
        /// What to do.
        fix: &'static str,
    },
    /// Writing failed.
    #[error("cannot write {path}: {detail}; fix: check the folder exists and is writable")]
    Write {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        detail: String,
    },
}

/// Writes `value` as YAML to `path` atomically; `Err` is the reason.
pub fn write_yaml<T: serde::Serialize>(path: &std::path::Path, value: &T) -> Result<(), String> {
    let text = serde_yaml::to_string(value).map_err(|e| e.to_string())?;
    let tmp = path.with_extension("yaml.partial");
    std::fs::write(&tmp, text).map_err(|e| e.to_string())?;
    std::fs::rename(&tmp, path).map_err(|e| e.to_string())
}
