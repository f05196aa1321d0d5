//! A protocol's elastomer material: its values, or `{from: MATERIAL.yaml}` — a gel fitted to
//! a bench's runs (`gelrig fit-material`), which loading replaces by the file's values.

use rig::units::{Duration, Pressure};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// A protocol's material: given, or fitted to a bench's runs and read from a file.
#[derive(Debug, Clone, Serialize, JsonSchema)]
#[serde(untagged)]
pub enum MaterialEntry {
    /// `{from: MATERIAL.yaml}`.
    From(MaterialFrom),
    /// The values.
    Inline(MaterialSpec),
}

/// Where a fitted material is read from.
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct MaterialFrom {
    /// The file `gelrig fit-material --out` wrote, relative to the protocol.
    pub from: String,
}

impl MaterialEntry {
    /// The values, once given or read.
    pub fn values(&self) -> Option<&MaterialSpec> {
        match self {
            Self::Inline(m) => Some(m),
            Self::From(_) => None,
        }
    }
}

/// By hand rather than `untagged`: serde's untagged enums report any mistake inside the
/// values as "did not match any variant"; this keeps the values' own message (an unknown
/// field, a missing one, a bad unit).
impl<'de> Deserialize<'de> for MaterialEntry {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        use serde::de::Error;
        let v = serde_yaml::Value::deserialize(d)?;
        if v.as_mapping().is_some_and(|m| m.contains_key("from")) {
            return serde_yaml::from_value(v).map(Self::From).map_err(|e| {
                D::Error::custom(format!(
                    "material: {e} (with from: the values come from the file, nothing else \
                         goes beside it)"
                ))
            });
        }
        serde_yaml::from_value(v)
            .map(Self::Inline)
            .map_err(|e| D::Error::custom(format!("material: {e}")))
    }
}

/// Elastomer material (linear viscoelastic, isotropic).
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct MaterialSpec {
    /// Long-term (relaxed) Young's modulus.
    pub youngs_modulus: Pressure,
    /// Poisson ratio, 0 to 0.5 (silicone: 0.49–0.5).
    pub poisson_ratio: f64,
    /// Static Coulomb friction coefficient against the indenter.
    pub friction: f64,
    /// Sliding (kinetic) friction coefficient, at most `friction` (default 0.9 × it): the
    /// force drop after full slip (thesis Fig. 4-16).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub kinetic_friction: Option<f64>,
    /// Prony terms: modulus `weight × E` relaxing with time constant `tau`.
    #[serde(default)]
    pub prony: Vec<PronySpec>,
}

/// One Prony (Maxwell) term.
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PronySpec {
    /// Modulus of the term relative to the long-term modulus.
    pub weight: f64,
    /// Relaxation time.
    pub tau: Duration,
}
