//! The material file (`MATERIAL.yaml`): a gel fitted to a bench's runs, as a durable,
//! versioned artifact — the values a protocol uses (`material: {from: MATERIAL.yaml}`), their
//! uncertainties, what they were fitted on and how well the fit follows the records.

use std::path::Path;

use serde::{Deserialize, Serialize};

use super::schema::MaterialSpec;

/// What every material file says it is.
pub const FORMAT: &str = "gelrig-material";
/// The newest version this build writes and reads; version 1 files (without ν's
/// uncertainty) still read.
pub const VERSION: u32 = 2;

/// Why a material file could not be read or written.
pub type MaterialFileError = crate::artifact::ArtifactError;

/// A fitted gel.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialFile {
    /// Always [`FORMAT`].
    pub format: String,
    /// Format version ([`VERSION`]).
    pub version: u32,
    /// When it was fitted (RFC 3339, UTC).
    pub created: String,
    /// The values, as a protocol's `sensor.material` takes them.
    pub material: MaterialSpec,
    /// Standard uncertainties of the fitted values (Gauss–Newton; white force noise
    /// assumed, so a lower bound where the force sensor quantises).
    pub uncertainty: Uncertainty,
    /// Which values were fitted and which were held, and why.
    pub provenance: Vec<String>,
    /// The runs it was fitted on, with how well the fit follows each.
    pub fitted_on: Vec<FittedRun>,
}

/// Standard uncertainties.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Uncertainty {
    /// Of E∞, MPa.
    pub youngs_modulus_mpa: f64,
    /// Of each Prony term, in the material's order.
    pub prony: Vec<TermUncertainty>,
    /// Of the static friction coefficient, where it was fitted.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub friction: Option<f64>,
    /// Of Poisson's ratio, where the runs told it: the marker field around a flat punch, or
    /// two flat punch sizes' forces (version 2).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub poisson_ratio: Option<f64>,
}

/// One Prony term's uncertainties.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TermUncertainty {
    /// Of its weight.
    pub weight: f64,
    /// Of its time constant, s.
    pub tau_s: f64,
}

/// One run of the fit.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FittedRun {
    /// The run directory's name.
    pub run: String,
    /// Its protocol's name.
    pub protocol: String,
    /// What it told the fit: `pressing` (modulus, relaxation, contact offset) or
    /// `sliding` (friction).
    pub used_for: String,
    /// Where contact really began, from the recorded origin, mm (pressing runs).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub contact_offset_mm: Option<f64>,
    /// Its standard uncertainty, mm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub contact_offset_sd_mm: Option<f64>,
    /// The fitted force's residual rms against the record, N (pressing runs).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub residual_rms_n: Option<f64>,
    /// Force samples fitted (pressing runs).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub samples: Option<usize>,
}

impl MaterialFile {
    /// Reads and checks a material file.
    pub fn read(path: &Path) -> Result<Self, MaterialFileError> {
        let err = |detail: String, fix: &'static str| MaterialFileError::Read {
            path: path.to_path_buf(),
            detail,
            fix,
        };
        const FIX: &str = "give the MATERIAL.yaml that `gelrig fit-material --out` wrote";
        let text = std::fs::read_to_string(path).map_err(|e| err(e.to_string(), FIX))?;
        // The header first, so a newer file says so rather than failing on a field.
        #[derive(Deserialize)]
        struct Header {
            format: Option<String>,
            version: Option<u32>,
        }
        let h: Header = serde_yaml::from_str(&text)
            .map_err(|e| err(format!("not a material file: {e}"), FIX))?;
        if h.format.as_deref() != Some(FORMAT) {
            return Err(err(
                format!(
                    "not a material file (its format is {}, not {FORMAT})",
                    h.format.as_deref().unwrap_or("missing")
                ),
                FIX,
            ));
        }
        match h.version {
            Some(1 | VERSION) => {}
            Some(v) if v > VERSION => {
                return Err(err(
                    format!("written by a newer gelrig (version {v}; this one reads {VERSION})"),
                    "update gelrig, or fit the material again with this one",
                ));
            }
            v => {
                return Err(err(
                    format!(
                        "version {} is not one this gelrig reads (1 to {VERSION})",
                        v.map_or_else(|| "missing".to_string(), |v| v.to_string())
                    ),
                    FIX,
                ));
            }
        }
        let file: Self = serde_yaml::from_str(&text).map_err(|e| err(e.to_string(), FIX))?;
        file.check().map_err(|d| err(d, FIX))?;
        Ok(file)
    }

    /// Values no gel has: refused when read, so a hand-edited file cannot reach a bench.
    fn check(&self) -> Result<(), String> {
        let m = &self.material;
        if !(m.youngs_modulus.mpa() > 0.0 && m.youngs_modulus.mpa().is_finite()) {
            return Err("material.youngs_modulus must be positive".into());
        }
        if !(0.0..=0.5).contains(&m.poisson_ratio) {
            return Err("material.poisson_ratio must lie in [0, 0.5]".into());
        }
        if !(m.friction >= 0.0 && m.friction.is_finite()) {
            return Err("material.friction must be ≥ 0".into());
        }
        if m.prony
            .iter()
            .any(|t| !(t.weight >= 0.0 && t.weight.is_finite() && t.tau.s() > 0.0))
        {
            return Err("material.prony: each term needs weight ≥ 0 and tau > 0".into());
        }
        if self.uncertainty.prony.len() != m.prony.len() {
            return Err("uncertainty.prony must have one entry per Prony term".into());
        }
        Ok(())
    }

    /// Writes the file (to a temporary name first, so a failed write leaves no half file).
    pub fn write(&self, path: &Path) -> Result<(), MaterialFileError> {
        crate::artifact::write_yaml(path, self).map_err(|detail| MaterialFileError::Write {
            path: path.to_path_buf(),
            detail,
        })
    }
}

#[cfg(test)]
mod tests {
    use std::path::PathBuf;

    use super::*;

    fn shipped() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../protocols/materials/portable-fitted.yaml")
    }

    #[test]
    fn a_material_file_round_trips_and_a_newer_or_edited_one_is_refused() {
        let file = MaterialFile::read(&shipped()).expect("the shipped example reads");
        let dir = tempfile::tempdir().expect("tmp");
        let path = dir.path().join("m.yaml");
        file.write(&path).expect("writes");
        let again = MaterialFile::read(&path).expect("reads back");
        assert_eq!(
            serde_yaml::to_string(&again).ok(),
            serde_yaml::to_string(&file).ok()
        );
        let text = std::fs::read_to_string(&path).expect("text");
        for (edit, says) in [
            (
                text.replace(&format!("version: {}", file.version), "version: 9"),
                "newer gelrig",
            ),
            (
                text.replacen("youngs_modulus: 0.", "youngs_modulus: -0.", 1),
                "must be positive",
            ),
            (
                text.replace("gelrig-material", "gelrig-sensor"),
                "not a material file",
            ),
        ] {
            std::fs::write(&path, edit).expect("write");
            let e = MaterialFile::read(&path).expect_err("refused").to_string();
            assert!(e.contains(says) && e.contains("fix:"), "{e}");
        }
    }
}
