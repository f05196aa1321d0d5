//! The two slope models behind one type, and each prepared for a frame size.

use serde::{Deserialize, Serialize};

use crate::local_linear::{LocalLinear, Prepared};
use crate::lut::Lut;

/// Which model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ModelKind {
    /// [`LocalLinear`]: the response varies over the frame.
    LocalLinear,
    /// [`Lut`]: colour alone.
    Lut,
}

impl ModelKind {
    /// The name in files and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            ModelKind::LocalLinear => "local-linear",
            ModelKind::Lut => "lut",
        }
    }
}

/// A fitted map from colour change to slope.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", tag = "kind")]
pub enum SlopeModel {
    /// See [`LocalLinear`].
    LocalLinear(LocalLinear),
    /// See [`Lut`].
    Lut(Lut),
}

impl SlopeModel {
    /// Which model this is.
    pub fn kind(&self) -> ModelKind {
        match self {
            SlopeModel::LocalLinear(_) => ModelKind::LocalLinear,
            SlopeModel::Lut(_) => ModelKind::Lut,
        }
    }

    /// The model prepared for `width × height` frames; `None` when it holds too little (fewer
    /// than 3 presses, or an empty table).
    pub fn prepare(&self, width: usize, height: usize) -> Option<SlopeMap> {
        let inner = match self {
            SlopeModel::LocalLinear(m) => Inner::LocalLinear(m.prepare(width, height)?),
            SlopeModel::Lut(t) => Inner::Lut(t.filled()?),
        };
        Some(SlopeMap {
            width,
            height,
            inner,
        })
    }
}

/// A model ready to read frames of one size.
#[derive(Debug, Clone)]
pub struct SlopeMap {
    pub(crate) width: usize,
    pub(crate) height: usize,
    inner: Inner,
}

#[derive(Debug, Clone)]
enum Inner {
    LocalLinear(Prepared),
    Lut(Vec<[f32; 2]>),
}

impl SlopeMap {
    /// Lights the model by the session's `background`: a model fitted on the flat-fielded
    /// colour change is turned back into grey levels for this background
    /// ([`Prepared::light`]); a model of the raw change is left as it is.
    pub(crate) fn light(&mut self, background: &crate::frame::Rgb<'_>) {
        if let Inner::LocalLinear(p) = &mut self.inner {
            p.light(background);
        }
    }

    /// Slopes of the colour change (3 per pixel) where `touched`, zero elsewhere.
    pub(crate) fn slopes(&self, change: &[f32], touched: &[bool], gx: &mut [f32], gy: &mut [f32]) {
        match &self.inner {
            Inner::LocalLinear(p) => p.slopes(change, touched, gx, gy),
            Inner::Lut(t) => crate::lut::slopes(t, change, touched, gx, gy),
        }
    }
}
