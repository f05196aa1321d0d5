//! Fitting a sensor on gathered samples: the per-channel ridge (on the features each
//! channel may use), its error on frames held out (five folds of every fifth frame of each
//! run, so each fold keeps every kind of load), and the sensor file with what the calibration
//! saw ([`super::envelope`]).

use std::collections::BTreeMap;
use std::path::Path;

use analysis::force_sensor::CHANNELS;
use analysis::force_sensor::ridge::LinearModel;

use super::file::{
    ErrorStats, FORMAT, HeldOut, LayoutFile, METHOD, METHOD_SCALE, METHOD_TRACTION, RelaxationTerm,
    VERSION,
};
use super::gather::{Gathered, How, RunSamples, Sample};
use super::{SensorError, SensorFile};

/// The sensor file of `g` read `how`, fitted on `per_run` (its [`samples`]).
pub(super) fn finish(
    g: &Gathered,
    how: &How<'_>,
    per_run: Vec<RunSamples>,
    first: &Path,
    symmetric: bool,
) -> Result<SensorFile, SensorError> {
    let view = &g.view;
    let layout = &g.layout;
    let all: Vec<&Sample> = per_run.iter().flat_map(|r| &r.samples).collect();
    let names = how.names();
    let masks = symmetric.then(|| analysis::force_sensor::channel_features(names));
    let model = fit(&all, masks.as_deref()).map_err(|source| SensorError::Model {
        path: first.to_path_buf(),
        source,
    })?;
    let ranges = ranges(&all);
    let held_out =
        held_out(&per_run, &ranges, masks.as_deref()).map_err(|source| SensorError::Model {
            path: first.to_path_buf(),
            source,
        })?;
    let envelope = super::file::Envelope::of(
        all.iter()
            .map(|s| (s.features.as_slice(), s.region.as_ref())),
        view,
        g.pad_mm,
    );
    Ok(SensorFile {
        format: FORMAT.into(),
        version: VERSION,
        created: jiff::Timestamp::now().to_string(),
        sensor: g.sensor.clone(),
        view: view.clone(),
        layout: LayoutFile {
            centre_px: layout.centre_px,
            reference_px: layout.reference_px.clone(),
        },
        method: match how {
            How::Moments => METHOD,
            How::Traction(..) => METHOD_TRACTION,
            How::Scale(..) => METHOD_SCALE,
        }
        .into(),
        features: names.iter().map(|f| (*f).to_string()).collect(),
        model: SensorFile::model_file(&model),
        symmetric,
        traction: match how {
            How::Traction(_, t) => Some(*t),
            _ => None,
        },
        scale: match how {
            How::Scale(_, s) => Some((*s).clone()),
            _ => None,
        },
        relaxation: g.relaxation.as_ref().map(|p| {
            p.terms()
                .iter()
                .map(|t| RelaxationTerm {
                    weight: t.weight,
                    tau_s: t.tau_s,
                })
                .collect()
        }),
        ranges,
        calibrated_on: per_run.into_iter().map(|r| r.reference).collect(),
        held_out,
        chosen_by: None,
        unseen_shape: None,
        envelope: Some(envelope),
    })
}

/// Per channel, the calibration's range of the force sensor's readings.
pub(super) fn ranges(all: &[&Sample]) -> BTreeMap<String, [f64; 2]> {
    CHANNELS
        .iter()
        .enumerate()
        .map(|(c, name)| {
            let (lo, hi) = all
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), s| {
                    (l.min(s.wrench[c]), h.max(s.wrench[c]))
                });
            ((*name).to_string(), [lo, hi])
        })
        .collect()
}

/// The span a channel's error is quoted against: its calibrated range, except that Fx and
/// Fy share the shear force's (the larger of the two), so a direction the calibration
/// hardly loaded is not judged against its noise.
pub fn span(ranges: &BTreeMap<String, [f64; 2]>, channel: &str) -> f64 {
    let r = |c: &str| ranges.get(c).map_or(0.0, |r| r[1] - r[0]);
    match channel {
        "fx_n" | "fy_n" => r("fx_n").max(r("fy_n")),
        c => r(c),
    }
}

/// Each channel fitted on the features `masks` marks for it (every feature without).
pub(super) fn fit(
    samples: &[&Sample],
    masks: Option<&[Vec<bool>]>,
) -> Result<LinearModel, analysis::force_sensor::SensorError> {
    let x: Vec<Vec<f64>> = samples.iter().map(|s| s.features.clone()).collect();
    let y: Vec<Vec<f64>> = samples.iter().map(|s| s.wrench.clone()).collect();
    LinearModel::fit_masked(&x, &y, masks)
}

/// Folds of the held-out error.
const FOLDS: usize = 5;

/// Held-out error per channel: [`FOLDS`] folds, each of every FOLDS-th frame of each run,
/// predicted by a model fitted on the others.
pub(super) fn held_out(
    runs: &[RunSamples],
    ranges: &BTreeMap<String, [f64; 2]>,
    masks: Option<&[Vec<bool>]>,
) -> Result<HeldOut, analysis::force_sensor::SensorError> {
    // Every fifth frame of each run in a fold: each fold holds every run's loads.
    let all: Vec<(usize, &Sample)> = runs
        .iter()
        .flat_map(|r| r.samples.iter().enumerate())
        .collect();
    let folds = FOLDS;
    let mut errors: Vec<Vec<f64>> = vec![Vec::new(); CHANNELS.len()];
    for k in 0..folds {
        let train: Vec<&Sample> = all
            .iter()
            .filter(|(i, _)| i % folds != k)
            .map(|(_, s)| *s)
            .collect();
        let model = fit(&train, masks)?;
        for (i, s) in &all {
            if i % folds == k {
                let (v, _) = model.predict(&s.features);
                for c in 0..CHANNELS.len() {
                    errors[c].push(v[c] - s.wrench[c]);
                }
            }
        }
    }
    Ok(HeldOut {
        by: format!("{FOLDS} folds of every {FOLDS}th frame of each run"),
        channels: CHANNELS
            .iter()
            .zip(&errors)
            .map(|(name, e)| ((*name).to_string(), stats(e, span(ranges, name))))
            .collect(),
    })
}

/// RMSE, its share of `range` in % (see [`span`]), and the mean of `errors`.
pub fn stats(errors: &[f64], range: f64) -> ErrorStats {
    let n = errors.len().max(1) as f64;
    let rmse = (errors.iter().map(|e| e * e).sum::<f64>() / n).sqrt();
    ErrorStats {
        rmse,
        pct_range: if range > 0.0 {
            100.0 * rmse / range
        } else {
            0.0
        },
        bias: errors.iter().sum::<f64>() / n,
    }
}
