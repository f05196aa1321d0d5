//! What a report's analyses found: the run's blocks and steps, and each analysis's results
//! (linearity, hysteresis, relaxation, slip, force from field), as the writers read them.

use analysis::field_force;
use analysis::hysteresis::Hysteresis;
use analysis::linearity::{LineFit, LinearRange, PowerLaw};
use analysis::relaxation::{SharedFit, StepRelaxation};
use analysis::slip::SlipReport;
use simbench::PlantSpec;

/// What the axis of a block loads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// Normal indentation: fz against depth.
    Normal,
    /// Shear: tangential force against shear offset.
    Shear,
    /// Torsion: torque against angle.
    Rotation,
}

impl Kind {
    pub(crate) fn name(self) -> &'static str {
        match self {
            Self::Normal => "normal",
            Self::Shear => "shear",
            Self::Rotation => "rotation",
        }
    }

    pub(crate) fn force_label(self) -> &'static str {
        match self {
            Self::Normal => "normal force Fz (N)",
            Self::Shear => "shear force (N)",
            Self::Rotation => "torque Tz (N·mm)",
        }
    }

    /// What the block's axis sets, in the lab's words: depth, shear offset, angle.
    pub(crate) fn load_name(self) -> &'static str {
        match self {
            Self::Normal => "depth",
            Self::Shear => "shear offset",
            Self::Rotation => "angle",
        }
    }

    pub(crate) fn force_unit(self) -> &'static str {
        if self == Self::Rotation { "N·mm" } else { "N" }
    }
}

/// One step of a block.
#[derive(Debug, Clone)]
pub struct BlockStep {
    /// Index into the run's steps.
    pub row: usize,
    /// Step number.
    pub step: u32,
    /// Load (depth, offset or angle) in the axis unit.
    pub load: f64,
    /// Quasistatic force (the thesis's last-window mean) along the block's channel.
    pub force: f64,
    /// Normal force, N.
    pub normal_n: f64,
    /// Whether this step unloads.
    pub unloading: bool,
}

/// Consecutive quasistatic steps of one axis.
#[derive(Debug, Clone)]
pub struct Block {
    /// What it loads.
    pub kind: Kind,
    /// Axis unit.
    pub unit: String,
    /// Steps in order.
    pub steps: Vec<BlockStep>,
    /// Shear direction of the measured force, rad (shear blocks).
    pub force_direction_rad: f64,
    /// Sign applied to the channel so loading is positive.
    pub sign: f64,
    /// The step before the block (the preload of a shear or torsion block), row index.
    pub before: Option<usize>,
    /// Linearity of the loading steps.
    pub linearity: Option<Linearity>,
    /// Loading against unloading.
    pub hysteresis: Option<Hysteresis>,
    /// Marker displacement against force, loading against unloading.
    pub displacement_hysteresis: Option<Hysteresis>,
    /// Slip (shear and rotation).
    pub slip: Option<Slip>,
    /// Force from the field.
    pub field_force: Option<FieldForce>,
    /// Marker displacement per step (mean, max) in px, when frames exist.
    pub displacement_px: Vec<Option<(f64, f64)>>,
    /// Profiles per step (radial or central line), px.
    pub profiles: Vec<(u32, Vec<(f64, f64)>)>,
}

/// Linearity results of a block.
#[derive(Debug, Clone)]
pub struct Linearity {
    /// Fit with intercept, over the linear range.
    pub with_intercept: LineFit,
    /// Fit through the origin, over the linear range.
    pub through_origin: LineFit,
    /// Fit with intercept over every loading step.
    pub all: LineFit,
    /// Linear range (5 % tolerance).
    pub range: Option<LinearRange>,
    /// Power law (curved indenters, normal load).
    pub power_law: Option<PowerLaw>,
    /// Mean marker displacement against force: slope px per force unit, R².
    pub displacement_vs_force: Option<LineFit>,
}

/// Slip results of a block.
#[derive(Debug, Clone)]
pub struct Slip {
    /// The classification.
    pub report: SlipReport,
    /// Friction coefficient estimate.
    pub mu: Option<f64>,
    /// Why μ is absent.
    pub mu_note: Option<String>,
    /// The simulator's onset (first full slip, or under 10 % of the contact still
    /// sticking), step number.
    pub sim_onset_step: Option<u32>,
}

/// Force-from-field results of a block.
#[derive(Debug, Clone)]
pub struct FieldForce {
    /// Fitted scale per step (NaN where no fit).
    pub scales: Vec<f64>,
    /// Calibration and prediction.
    pub prediction: field_force::Prediction,
}

/// Relaxation of one step.
#[derive(Debug, Clone)]
pub struct StepRelax {
    /// Step number.
    pub step: u32,
    /// Its block's kind.
    pub kind: Kind,
    /// Analysis.
    pub fit: StepRelaxation,
    /// Samples (t from the end of the move, s; force).
    pub t_s: Vec<f64>,
    /// Force samples.
    pub f: Vec<f64>,
    /// The simulator's equilibrium value, if known.
    pub truth: Option<f64>,
    /// The move's end, s on the run's clock.
    pub start_s: f64,
}

/// Everything the report shows.
#[derive(Debug, Clone)]
pub struct Report {
    /// Blocks in run order.
    pub blocks: Vec<Block>,
    /// Per relaxing step.
    pub relaxation: Vec<StepRelax>,
    /// Time constants shared by the run's steps.
    pub shared: Option<SharedFit>,
    /// Settle error curve.
    pub settle: Option<super::settle_study::SettleCurve>,
    /// Whether a reference contact model was available for field fits.
    pub model_note: Option<String>,
    /// The simulator's equilibrium stiffness of the main block, force per unit.
    pub sim_slope: Option<f64>,
}

/// The reference contact model of the run's own protocol (its sensor, material and
/// indenter), for force from field; `Err` says why there is none.
pub(crate) struct RefModel {
    pub spec: PlantSpec,
}
