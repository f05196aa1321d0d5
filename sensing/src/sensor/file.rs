//! The sensor file (`SENSOR.yaml`): a calibrated GelSight as a durable, versioned artifact —
//! what it was calibrated on (marker layout, view scale, runs, ranges), the model, and its
//! own held-out error — so a force read from the field years later can say where it came
//! from and how far to trust it.

use std::collections::BTreeMap;
use std::path::Path;

use analysis::force_sensor::ridge::{ChannelFit, LinearModel};
use analysis::force_sensor::scale::SCALE_FEATURES;
use analysis::force_sensor::{
    CHANNELS, FEATURES, Layout, TRACTION_FEATURES, TRACTION_FEATURES_ROUND,
};
use serde::{Deserialize, Serialize};

pub use super::scale::ScaleSettings;

/// What every sensor file says it is.
pub const FORMAT: &str = "gelrig-sensor";
/// The newest version this build writes and reads (2 added `relaxation`; 3 `symmetric` and
/// the traction map's `ellipse`; 4 `chosen_by`, `unseen_shape` and `envelope`; 5 the traction
/// map's elongation term). A sensor without that term is written as version 4, so an
/// older gelrig still reads it.
pub const VERSION: u32 = 5;
/// Field moments, ridge per channel ([`analysis::force_sensor`]).
pub const METHOD: &str = "field-moments-ridge";
/// The inverse traction map's integrals, ridge per channel
/// ([`analysis::force_sensor::traction`]).
pub const METHOD_TRACTION: &str = "traction-map";
/// The thesis's scale fit of reference fields, superposed for combined loads, ridge per
/// channel ([`analysis::force_sensor::scale`]).
pub const METHOD_SCALE: &str = "scale-fit";

/// Why a sensor file could not be read or written.
pub type SensorFileError = experiments::artifact::ArtifactError;

/// A calibrated GelSight.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SensorFile {
    /// Always [`FORMAT`].
    pub format: String,
    /// Format version ([`VERSION`]).
    pub version: u32,
    /// When it was calibrated (RFC 3339, UTC).
    pub created: String,
    /// The sensor the calibration runs used (their protocol's `sensor.kind`).
    pub sensor: String,
    /// The camera's view of the gel.
    pub view: View,
    /// The untouched marker layout everything is measured from.
    pub layout: LayoutFile,
    /// How the field is turned into the wrench ([`METHOD`]).
    pub method: String,
    /// The field moments the model reads, in order.
    pub features: Vec<String>,
    /// The fitted model.
    pub model: ModelFile,
    /// Whether each channel was fitted only on the features that turn as it does
    /// (`gelrig calibrate --symmetric`; [`analysis::force_sensor::channel_features`]): the
    /// others then have no weight. Absent: every channel saw every feature.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub symmetric: bool,
    /// The traction map's settings (`traction-map` only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub traction: Option<TractionSettings>,
    /// The scale fit's reference fields (`scale-fit` only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scale: Option<ScaleSettings>,
    /// The gel's relaxation function g(t) = 1 + Σ wᵢ e^{−t/τᵢ}, fitted from the calibration
    /// runs' held pressing steps: the pressing field reads the elastic force, and Fz is its
    /// hereditary integral ([`analysis::force_sensor::memory`]). Absent: Fz is read as the
    /// field's force, with no memory.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub relaxation: Option<Vec<RelaxationTerm>>,
    /// Per channel, the range of the calibration's force sensor readings.
    pub ranges: BTreeMap<String, [f64; 2]>,
    /// The runs it was calibrated on.
    pub calibrated_on: Vec<RunRef>,
    /// Its own error on data it was not fitted to.
    pub held_out: HeldOut,
    /// How the method and its settings were chosen, with every candidate's score (absent
    /// before version 4, and where the method was given in full).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub chosen_by: Option<Choice>,
    /// Its error on indenters left out of the fit, each in turn: what it reads a shape it
    /// never saw with. Absent where every calibration run pressed the same indenter (then
    /// the unseen-shape error is unknown) and before version 4.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub unseen_shape: Option<UnseenShape>,
    /// What the calibration saw — contact sizes, shapes, places, loads and fields — against
    /// which a frame is judged inside or outside the calibration (absent before version 4).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub envelope: Option<Envelope>,
}

/// What the calibration saw ([`super::envelope`] judges frames against it).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Envelope {
    /// The contact regions of the calibration's frames (absent: none was found).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub contact: Option<ContactRange>,
    /// Per feature, its range over the calibration's frames.
    pub features: Vec<[f64; 2]>,
    /// The gel pad's extent, mm (width along the view's x, length along y), centred on the
    /// view: where a contact longer than the view is taken to end.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pad_mm: Option<[f64; 2]>,
}

/// The contact regions a calibration saw.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ContactRange {
    /// Equivalent radius (of the disc of the same area), mm: least and largest.
    pub radius_mm: [f64; 2],
    /// Elongation, the major over the minor axis of the moment ellipse: least and largest.
    pub elongation: [f64; 2],
    /// Largest distance of a region's centroid from the view's centre, mm.
    pub offset_mm: f64,
    /// Whether the calibration saw contacts across the view (running out of it at both ends
    /// of their length): then it has learnt what the view sees of them, and such a frame is
    /// neither corrected nor widened for the part beyond the view.
    #[serde(default)]
    pub across_view: bool,
}

/// How the calibration chose its method and settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Choice {
    /// The error that chose: `leave one indenter out` or `5 folds of frames` (one
    /// indenter).
    pub by: String,
    /// The channels the score sums (those the calibration loads above its force sensor's
    /// noise).
    pub scored: Vec<String>,
    /// Every candidate tried, best first.
    pub candidates: Vec<Candidate>,
}

/// One candidate of the choice.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Candidate {
    /// `moments`, `traction` or `scale`.
    pub method: String,
    /// Each channel on the features that turn as it does.
    pub symmetric: bool,
    /// The traction map's cell, mm (traction only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cell_mm: Option<f64>,
    /// The traction map's support (traction only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub support: Option<f64>,
    /// Per channel, the choosing error in % of the calibrated span.
    pub pct_range: BTreeMap<String, f64>,
    /// The score: the sum of the scored channels' %.
    pub score: f64,
}

/// The error on indenters left out of the fit.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct UnseenShape {
    /// How: each indenter left out in turn, read by a fit on the others.
    pub by: String,
    /// Per channel, pooled over the indenters left out.
    pub channels: BTreeMap<String, ErrorStats>,
    /// Per channel, the RMS of the error relative to the reading where the force sensor
    /// reads a tenth of the span or more: the share of a reading an unseen shape moves.
    pub relative: BTreeMap<String, f64>,
    /// Per indenter left out.
    pub shapes: Vec<ShapeError>,
}

/// The error on one indenter left out.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShapeError {
    /// The indenter, as its protocol gives it.
    pub indenter: String,
    /// Per channel.
    pub channels: BTreeMap<String, ErrorStats>,
}

/// The camera's view.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct View {
    /// Image scale on the gel, mm per pixel.
    pub mm_per_px: f64,
    /// Frame width, px.
    pub width_px: usize,
    /// Frame height, px.
    pub height_px: usize,
}

/// One term of the gel's relaxation function.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RelaxationTerm {
    /// Modulus of the term relative to the long-term modulus.
    pub weight: f64,
    /// Time constant, s.
    pub tau_s: f64,
}

/// How the traction map is solved.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TractionSettings {
    /// The elastomer's thickness (the layer's Green's tensor), mm.
    pub thickness_mm: f64,
    /// Cell of the Green's tensor's kernels, mm.
    pub kernel_dx_mm: f64,
    /// Cell of the traction map, mm.
    pub cell_mm: f64,
    /// The map's support: this many times the contact region's moment-equivalent ellipse
    /// (`ellipse`), or its equal-area disc.
    pub support: f64,
    /// Whether the support follows the region's moment-equivalent ellipse (calibrated since
    /// version 3); absent, as in older files, the equal-area disc their `support` was chosen
    /// for.
    #[serde(default)]
    pub ellipse: bool,
    /// Tikhonov regularisation (the median of GCV's choices over the calibration).
    pub lambda: f64,
}

/// The reference marker layout.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LayoutFile {
    /// Origin of the field moments, px.
    pub centre_px: [f64; 2],
    /// Reference marker centres, px.
    pub reference_px: Vec<[f64; 2]>,
}

/// The model: feature standardisation and one ridge fit per channel.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelFile {
    /// Feature means.
    pub mean: Vec<f64>,
    /// Feature standard deviations.
    pub scale: Vec<f64>,
    /// Calibration frames.
    pub samples: usize,
    /// Per channel (`fx_n`, `fy_n`, `fz_n`, `tz_nmm`).
    pub channels: BTreeMap<String, ChannelFile>,
}

/// One channel's ridge fit.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ChannelFile {
    /// Weights on the standardised features.
    pub weights: Vec<f64>,
    /// Intercept.
    pub bias: f64,
    /// Ridge parameter (GCV).
    pub lambda: f64,
    /// Residual scale, the channel's unit.
    pub sigma: f64,
    /// Effective degrees of freedom.
    pub dof: f64,
    /// (XᵀX + λI)⁻¹, row-major.
    pub inv_gram: Vec<f64>,
}

/// A calibration run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RunRef {
    /// Run directory name.
    pub run: String,
    /// Its protocol.
    pub protocol: String,
    /// Its indenter, as the protocol gives it.
    pub indenter: String,
    /// Frames used.
    pub frames: usize,
}

/// Held-out error.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HeldOut {
    /// How data was held out.
    pub by: String,
    /// Per channel.
    pub channels: BTreeMap<String, ErrorStats>,
}

/// Error of one channel against the force sensor.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ErrorStats {
    /// Root-mean-square error, the channel's unit.
    pub rmse: f64,
    /// RMSE in % of the calibrated range (Fx and Fy: of the shear force's, the larger of
    /// their two ranges).
    pub pct_range: f64,
    /// Mean error (GelSight − force sensor).
    pub bias: f64,
}

impl SensorFile {
    /// The layout the model reads fields with.
    pub fn layout(&self) -> Layout {
        Layout::new(
            self.layout.reference_px.clone(),
            self.view.mm_per_px,
            self.layout.centre_px,
        )
    }

    /// The gel's relaxation function, if the calibration fitted one.
    pub fn prony(&self) -> Option<mechanics::Prony> {
        let terms = self.relaxation.as_ref()?;
        mechanics::Prony::new(
            terms
                .iter()
                .map(|t| mechanics::PronyTerm {
                    weight: t.weight,
                    tau_s: t.tau_s,
                })
                .collect(),
        )
        .ok()
    }

    /// The model as the analysis crate uses it.
    pub fn model(&self) -> LinearModel {
        LinearModel {
            mean: self.model.mean.clone(),
            scale: self.model.scale.clone(),
            samples: self.model.samples,
            channels: CHANNELS
                .iter()
                .map(|c| {
                    let f = self.model.channels.get(*c);
                    ChannelFit {
                        weights: f.map(|f| f.weights.clone()).unwrap_or_default(),
                        bias: f.map_or(0.0, |f| f.bias),
                        lambda: f.map_or(0.0, |f| f.lambda),
                        sigma: f.map_or(0.0, |f| f.sigma),
                        inv_gram: f.map(|f| f.inv_gram.clone()).unwrap_or_default(),
                        dof: f.map_or(0.0, |f| f.dof),
                    }
                })
                .collect(),
        }
    }

    /// The model's part of a sensor file.
    pub fn model_file(m: &LinearModel) -> ModelFile {
        ModelFile {
            mean: m.mean.clone(),
            scale: m.scale.clone(),
            samples: m.samples,
            channels: CHANNELS
                .iter()
                .zip(&m.channels)
                .map(|(name, c)| {
                    (
                        (*name).to_string(),
                        ChannelFile {
                            weights: c.weights.clone(),
                            bias: c.bias,
                            lambda: c.lambda,
                            sigma: c.sigma,
                            dof: c.dof,
                            inv_gram: c.inv_gram.clone(),
                        },
                    )
                })
                .collect(),
        }
    }

    /// Reads and checks a sensor file.
    pub fn read(path: &Path) -> Result<Self, SensorFileError> {
        let err = |detail: String, fix: &'static str| SensorFileError::Read {
            path: path.to_path_buf(),
            detail,
            fix,
        };
        let text = std::fs::read_to_string(path).map_err(|e| {
            err(
                e.to_string(),
                "give the SENSOR.yaml that `gelrig calibrate --out` wrote",
            )
        })?;
        // The header first, so a newer file says so rather than failing on a field.
        #[derive(Deserialize)]
        struct Header {
            format: Option<String>,
            version: Option<u32>,
        }
        let h: Header = serde_yaml::from_str(&text).map_err(|e| {
            err(
                format!("not a sensor file: {e}"),
                "give the SENSOR.yaml that `gelrig calibrate --out` wrote",
            )
        })?;
        if h.format.as_deref() != Some(FORMAT) {
            return Err(err(
                format!("`format` is {:?}, not {FORMAT:?}", h.format),
                "give the SENSOR.yaml that `gelrig calibrate --out` wrote",
            ));
        }
        match h.version {
            Some(v) if v <= VERSION && v > 0 => {}
            v => {
                return Err(err(
                    format!("sensor file version {v:?}; this gelrig reads versions 1 to {VERSION}"),
                    "use the gelrig that wrote it, or calibrate again with this one",
                ));
            }
        }
        let s: Self = serde_yaml::from_str(&text).map_err(|e| {
            err(
                e.to_string(),
                "the file was edited or truncated: calibrate again, or restore it",
            )
        })?;
        s.check().map_err(|d| {
            err(
                d,
                "the file was edited or truncated: calibrate again, or restore it",
            )
        })?;
        Ok(s)
    }

    /// Internal consistency: dimensions agree, numbers are finite.
    fn check(&self) -> Result<(), String> {
        let (features, p): (&[&str], usize) = match self.method.as_str() {
            METHOD => (&FEATURES, FEATURES.len()),
            METHOD_TRACTION => (&TRACTION_FEATURES, TRACTION_FEATURES.len()),
            METHOD_SCALE => (&SCALE_FEATURES, SCALE_FEATURES.len()),
            m => {
                return Err(format!(
                    "method {m:?}: this gelrig knows {METHOD:?}, {METHOD_TRACTION:?} and \
                     {METHOD_SCALE:?}"
                ));
            }
        };
        // A traction sensor calibrated on round contacts only reads without the elongation
        // term (as every one did before it).
        let round = self.method == METHOD_TRACTION && self.features == TRACTION_FEATURES_ROUND;
        let p = if round {
            TRACTION_FEATURES_ROUND.len()
        } else {
            p
        };
        if self.method == METHOD_TRACTION && self.features == TRACTION_FEATURES && self.version < 5
        {
            return Err(format!(
                "version {} with the elongation term, which came with version 5",
                self.version
            ));
        }
        if self.features != features && !round {
            let or_round = if self.method == METHOD_TRACTION {
                format!(" (or, without the elongation term, {TRACTION_FEATURES_ROUND:?})")
            } else {
                String::new()
            };
            return Err(format!(
                "features {:?}, expected {features:?}{or_round}",
                self.features
            ));
        }
        match (&self.traction, self.method.as_str()) {
            (None, METHOD_TRACTION) => return Err("a traction-map sensor needs `traction`".into()),
            (Some(t), METHOD_TRACTION) => {
                let ok = [t.thickness_mm, t.kernel_dx_mm, t.cell_mm, t.support]
                    .iter()
                    .all(|v| v.is_finite() && *v > 0.0)
                    && t.lambda.is_finite()
                    && t.lambda >= 0.0;
                if !ok {
                    return Err("traction: settings must be positive numbers".into());
                }
            }
            (Some(_), _) => return Err("`traction` belongs to a traction-map sensor only".into()),
            (None, _) => {}
        }
        match (&self.scale, self.method.as_str()) {
            (None, METHOD_SCALE) => return Err("a scale-fit sensor needs `scale`".into()),
            (Some(sc), METHOD_SCALE) => {
                let n = self.layout.reference_px.len();
                if sc.fields.len() != 4
                    || sc.fields.iter().any(|f| f.len() != n)
                    || !(sc.contact_radius_mm.is_finite() && sc.contact_radius_mm > 0.0)
                    || super::scale::basis(sc, &self.layout()).is_none()
                {
                    return Err(format!(
                        "scale: needs 4 distinct fields of {n} markers each and a positive contact \
                         radius"
                    ));
                }
            }
            (Some(_), _) => return Err("`scale` belongs to a scale-fit sensor only".into()),
            (None, _) => {}
        }
        if let Some(terms) = &self.relaxation
            && !terms.iter().all(|t| {
                t.weight.is_finite() && t.weight >= 0.0 && t.tau_s.is_finite() && t.tau_s > 0.0
            })
        {
            return Err("relaxation: each term needs weight ≥ 0 and tau_s > 0".into());
        }
        if self.model.mean.len() != p || self.model.scale.len() != p {
            return Err(format!("model.mean and model.scale need {p} values"));
        }
        if !(self.view.mm_per_px.is_finite() && self.view.mm_per_px > 0.0) {
            return Err("view.mm_per_px must be a positive number".into());
        }
        if self.layout.reference_px.len() < 10 {
            return Err("layout.reference_px has fewer than 10 markers".into());
        }
        for c in CHANNELS {
            let f = self
                .model
                .channels
                .get(c)
                .ok_or_else(|| format!("model.channels lacks {c}"))?;
            if f.weights.len() != p || f.inv_gram.len() != p * p {
                return Err(format!(
                    "model.channels.{c}: weights need {p}, inv_gram {}",
                    p * p
                ));
            }
            let all = f
                .weights
                .iter()
                .chain(&f.inv_gram)
                .chain([&f.bias, &f.sigma]);
            if all.into_iter().any(|v| !v.is_finite()) {
                return Err(format!("model.channels.{c} has a non-finite number"));
            }
        }
        Ok(())
    }

    /// Writes the file (to a temporary beside it, then renamed: a failure leaves no half
    /// file under the name).
    pub fn write(&self, path: &Path) -> Result<(), SensorFileError> {
        experiments::artifact::write_yaml(path, self).map_err(|detail| SensorFileError::Write {
            path: path.to_path_buf(),
            detail,
        })
    }
}
