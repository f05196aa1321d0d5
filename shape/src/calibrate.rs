//! Calibration on ball presses: both slope models fitted, each scored on presses left out of
//! its fit (leave one press out: each press read by a model fitted on all the others), and
//! the one that reads the held-out cap heights best kept as the choice.

use serde::{Deserialize, Serialize};

use crate::ShapeError;
use crate::ball::{self, BallScore, Circle};
use crate::depth::Depth;
use crate::frame::Rgb;
use crate::local_linear::{self, LocalLinear};
use crate::lut::{self, Lut};
use crate::model::{ModelKind, SlopeModel};

/// A ball press: its frame and its contact circle.
#[derive(Debug, Clone)]
pub struct Press<'a> {
    /// A name for reports (the file's).
    pub name: String,
    /// The frame.
    pub frame: Rgb<'a>,
    /// The contact circle.
    pub circle: Circle,
}

/// One press read by a model fitted without it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PressScore {
    /// The press's name.
    pub press: String,
    /// How the depth map read the ball.
    #[serde(flatten)]
    pub score: BallScore,
}

/// A model's figures on presses left out of its fit.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HeldOut {
    /// The model.
    pub model: ModelKind,
    /// Median |cap height error|, %.
    pub height_median_pct: f64,
    /// Largest |cap height error|, %, and its press.
    pub height_worst_pct: f64,
    /// The press of `height_worst_pct`.
    pub height_worst_press: String,
    /// Median |fitted sphere radius error|, %.
    pub radius_median_pct: f64,
    /// Largest |fitted sphere radius error|, %.
    pub radius_worst_pct: f64,
    /// Median over presses of the rms slope error, degrees.
    pub slope_rms_median_deg: f64,
    /// Largest spurious height beyond the contact, share of the cap height.
    pub spurious_worst: f64,
    /// Presses read with the depth sign wrong (the centre above its edge).
    pub sign_errors: usize,
    /// Each press.
    pub presses: Vec<PressScore>,
}

/// Both fitted models and their held-out figures; `chosen` reads the held-out cap heights
/// with the smallest root-mean-square error.
#[derive(Debug, Clone)]
pub struct Calibration {
    /// The local-linear model, fitted on every press.
    pub local_linear: LocalLinear,
    /// The lookup table, fitted on every press.
    pub lut: Lut,
    /// Held-out figures, local-linear first.
    pub held_out: Vec<HeldOut>,
    /// The model to use.
    pub chosen: ModelKind,
}

/// What each press contributes to either model, computed once: its local-linear response
/// and its pixels' sums per lookup-table bin (sparse). A fold's models are then built from
/// the other presses' parts without reading a frame again.
struct Parts {
    responses: Vec<Option<local_linear::Response>>,
    sums: Vec<Vec<(usize, [f64; 3])>>,
}

impl Parts {
    fn new(presses: &[Press<'_>], background: &Rgb<'_>, ball_px: f64) -> Self {
        let n = lut::BINS * lut::BINS * lut::BINS;
        let mut dense = vec![[0.0f64; 3]; n];
        let mut sums = Vec::with_capacity(presses.len());
        for p in presses {
            dense.fill([0.0; 3]);
            lut::accumulate(&p.frame, background, &p.circle, ball_px, &mut dense);
            sums.push(
                dense
                    .iter()
                    .enumerate()
                    .filter(|(_, s)| s[2] > 0.0)
                    .map(|(k, s)| (k, *s))
                    .collect(),
            );
        }
        let flat = crate::frame::flat_field(background);
        let inks = crate::markers::press_inks(background, presses.iter().map(|p| &p.frame));
        Self {
            responses: presses
                .iter()
                .zip(&inks)
                .map(|(p, ink)| {
                    local_linear::fit_response(
                        &p.frame,
                        background,
                        Some(&flat),
                        ink.as_deref(),
                        &p.circle,
                        ball_px,
                    )
                })
                .collect(),
            sums,
        }
    }

    /// The model of `kind` fitted on every press but `without` (on all with `None`).
    fn fit(&self, kind: ModelKind, without: Option<usize>) -> SlopeModel {
        let keep = |i: &usize| Some(*i) != without;
        match kind {
            ModelKind::LocalLinear => SlopeModel::LocalLinear(LocalLinear {
                responses: (0..self.responses.len())
                    .filter(keep)
                    .filter_map(|i| self.responses[i].clone())
                    .collect(),
                flat_field: true,
            }),
            ModelKind::Lut => {
                let mut dense = vec![[0.0f64; 3]; lut::BINS * lut::BINS * lut::BINS];
                for i in (0..self.sums.len()).filter(keep) {
                    for (k, s) in &self.sums[i] {
                        for c in 0..3 {
                            dense[*k][c] += s[c];
                        }
                    }
                }
                SlopeModel::Lut(Lut::from_sums(&dense))
            }
        }
    }
}

/// Fits both models on `presses` (against `background`, a ball of radius `ball_px` pixels)
/// and scores each by leaving one press out at a time. Needs at least 4 presses of the
/// background's size.
pub fn calibrate(
    background: Rgb<'_>,
    presses: &[Press<'_>],
    ball_px: f64,
    mm_per_px: f64,
) -> Result<Calibration, ShapeError> {
    if presses.len() < 4 {
        return Err(ShapeError::Calibration(format!(
            "{} ball presses: calibrating needs at least 4 (and 20 or more spread over the \
             whole frame to read every part of it; docs/how-to/calibrate-shape.md)",
            presses.len()
        )));
    }
    for p in presses {
        p.frame
            .same_size(background.width, background.height, "background is")
            .map_err(|e| ShapeError::Calibration(format!("{}: {e}", p.name)))?;
    }
    let (w, h) = (background.width, background.height);
    let parts = Parts::new(presses, &background, ball_px);
    let mut held_out = Vec::new();
    for kind in [ModelKind::LocalLinear, ModelKind::Lut] {
        let mut scores = Vec::new();
        for (i, p) in presses.iter().enumerate() {
            let Some(map) = parts.fit(kind, Some(i)).prepare(w, h) else {
                continue;
            };
            let mut depth = Depth::new(map, background, mm_per_px)?;
            depth.height(p.frame)?;
            let (d, gx, gy) = depth.last_depth_px();
            scores.push(PressScore {
                press: p.name.clone(),
                score: ball::score(d, (gx, gy), (w, h), &p.circle, ball_px),
            });
        }
        held_out.push(summarise(kind, scores)?);
    }
    let rms = |ho: &HeldOut| {
        (ho.presses
            .iter()
            .map(|p| p.score.height_error_pct.powi(2))
            .sum::<f64>()
            / ho.presses.len().max(1) as f64)
            .sqrt()
    };
    let chosen = held_out
        .iter()
        .min_by(|a, b| rms(a).total_cmp(&rms(b)))
        .map_or(ModelKind::LocalLinear, |h| h.model);
    let (SlopeModel::LocalLinear(local_linear), SlopeModel::Lut(lut)) = (
        parts.fit(ModelKind::LocalLinear, None),
        parts.fit(ModelKind::Lut, None),
    ) else {
        return Err(ShapeError::Calibration(
            "internal: a fit of another kind".into(),
        ));
    };
    Ok(Calibration {
        local_linear,
        lut,
        held_out,
        chosen,
    })
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    if v.is_empty() {
        return f64::NAN;
    }
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

fn summarise(model: ModelKind, presses: Vec<PressScore>) -> Result<HeldOut, ShapeError> {
    if presses.is_empty() {
        return Err(ShapeError::Calibration(format!(
            "the {} model could not be fitted without any one press: the presses are too few \
             or too alike",
            model.name()
        )));
    }
    let abs = |f: fn(&BallScore) -> f64| {
        presses
            .iter()
            .map(|p| f(&p.score).abs())
            .collect::<Vec<_>>()
    };
    let heights = abs(|s| s.height_error_pct);
    let radii = abs(|s| s.radius_error_pct);
    let (worst_i, height_worst_pct) = heights
        .iter()
        .copied()
        .enumerate()
        .fold((0, 0.0), |a, (i, v)| if v > a.1 { (i, v) } else { a });
    Ok(HeldOut {
        model,
        height_median_pct: median(heights.clone()),
        height_worst_pct,
        height_worst_press: presses[worst_i].press.clone(),
        radius_median_pct: median(radii.clone()),
        radius_worst_pct: radii.iter().copied().fold(0.0, f64::max),
        slope_rms_median_deg: median(abs(|s| s.slope_rms_deg)),
        spurious_worst: presses.iter().map(|p| p.score.spurious).fold(0.0, f64::max),
        sign_errors: presses
            .iter()
            .filter(|p| p.score.height_error_pct <= -100.0)
            .count(),
        presses,
    })
}
