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
    let model = fit(&all, names, symmetric).map_err(|source| SensorError::Model {
        path: first.to_path_buf(),
        source,
    })?;
    let ranges = ranges(&all);
    let held_out =
        held_out(&per_run, &ranges, names, symmetric).map_err(|source| SensorError::Model {
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
        // The elongation term came with version 5; without it the file is a version 4 one.
        version: if names.contains(&analysis::force_sensor::ELONGATION_FEATURE) {
            VERSION
        } else {
            4
        },
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
            How::Traction(_, t, _) => Some(*t),
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

/// Each channel fitted on the features `names` it may see ([`masks`]).
pub(super) fn fit(
    samples: &[&Sample],
    names: &[&str],
    symmetric: bool,
) -> Result<LinearModel, analysis::force_sensor::SensorError> {
    let x: Vec<Vec<f64>> = samples.iter().map(|s| s.features.clone()).collect();
    let y: Vec<Vec<f64>> = samples.iter().map(|s| s.wrench.clone()).collect();
    let masks = masks(names, symmetric, samples);
    LinearModel::fit_masked(&x, &y, masks.as_deref())
}

/// Which of `names` each channel is fitted on: with `symmetric`, those that turn as it does
/// ([`analysis::force_sensor::channel_features`]); and the traction map's elongation term
/// only where the fit's own `samples` hold elongated contacts — a fit on round contacts
/// alone (an indenter left out of a calibration that has one strip) has nothing to fit it
/// on, and would extrapolate noise to the shape it never saw. `None`: every feature.
pub(super) fn masks(
    names: &[&str],
    symmetric: bool,
    samples: &[&Sample],
) -> Option<Vec<Vec<bool>>> {
    let mut masks = symmetric.then(|| analysis::force_sensor::channel_features(names));
    let term = names
        .iter()
        .position(|n| *n == analysis::force_sensor::ELONGATION_FEATURE);
    if let Some(j) = term
        && !super::gather::elongated_enough(samples.iter().map(|s| s.region.as_ref()))
    {
        let m = masks.get_or_insert_with(|| vec![vec![true; names.len()]; CHANNELS.len()]);
        for channel in m.iter_mut() {
            channel[j] = false;
        }
    }
    masks
}

/// Folds of the held-out error.
const FOLDS: usize = 5;

/// Held-out error per channel: [`FOLDS`] folds, each of every FOLDS-th frame of each run,
/// predicted by a model fitted on the others.
pub(super) fn held_out(
    runs: &[RunSamples],
    ranges: &BTreeMap<String, [f64; 2]>,
    names: &[&str],
    symmetric: bool,
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
        let model = fit(&train, names, symmetric)?;
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sensor::history::Region;
    use analysis::force_sensor::{TRACTION_FEATURES, TRACTION_FEATURES_ROUND};

    /// A frame whose contact has second moments `m` (px²), or none.
    fn frame(m: Option<[f64; 3]>) -> Sample {
        Sample {
            features: vec![0.0; 5],
            wrench: vec![0.0; 4],
            region: m.map(|m| Region {
                centroid_px: [0.0, 0.0],
                radius_px: 10.0,
                second_moments_px2: Some(m),
            }),
        }
    }

    #[test]
    fn the_elongation_term_is_fitted_only_on_elongated_contacts() {
        let disc = frame(Some([25.0, 25.0, 0.0]));
        let strip = frame(Some([400.0, 10.0, 0.0]));
        let none = frame(None);
        let round: Vec<&Sample> = vec![&disc; 40].into_iter().chain([&none; 10]).collect();
        // Round contacts only: the term is masked out of every channel, nothing else is.
        let m =
            masks(&TRACTION_FEATURES, false, &round).expect("round contacts: the term is masked");
        assert_eq!(m.len(), CHANNELS.len());
        for channel in &m {
            assert_eq!(channel, &[true, true, true, true, false]);
        }
        // Two strips in forty contacts (5 %): fitted, on every channel without symmetry...
        let some: Vec<&Sample> = vec![&disc; 38].into_iter().chain([&strip; 2]).collect();
        assert_eq!(masks(&TRACTION_FEATURES, false, &some), None);
        // ...and on Fz alone with it (a scalar), with the other features as before.
        let sym = masks(&TRACTION_FEATURES, true, &some).expect("symmetric: masks");
        assert_eq!(
            sym,
            analysis::force_sensor::channel_features(&TRACTION_FEATURES)
        );
        assert_eq!(
            sym.iter().map(|c| c[4]).collect::<Vec<_>>(),
            [false, false, true, false]
        );
        // One strip in forty is too few; a sensor without the term has nothing to mask.
        let one: Vec<&Sample> = vec![&disc; 39].into_iter().chain([&strip; 1]).collect();
        assert_eq!(
            masks(&TRACTION_FEATURES, true, &one).expect("one strip in forty: masked"),
            analysis::force_sensor::channel_features(&TRACTION_FEATURES)
                .into_iter()
                .map(|mut c| {
                    c[4] = false;
                    c
                })
                .collect::<Vec<_>>()
        );
        assert_eq!(masks(&TRACTION_FEATURES_ROUND, false, &round), None);
    }
}
