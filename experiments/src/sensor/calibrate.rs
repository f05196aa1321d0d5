//! `gelrig calibrate RUN_DIR… --out SENSOR.yaml`: the field-to-wrench model fitted on runs
//! with frames and a force sensor, its error measured on data held out of the fit.
//!
//! Every frame of every run is a sample: its field moments against the force sensor's mean
//! over the step's force window for a frame captured at a settled step's end, else over the
//! frame's ±60 ms. The marker layout is the first run's reference; the other runs'
//! markers are matched to it by position (a run of another gel or view is refused). The
//! held-out error is five-fold: every fifth frame of each run left out in turn, so each
//! fold keeps every kind of load (a run of a new indenter is the test of generalising, and
//! `gelrig report --sensor` measures it).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use analysis::force_sensor::ridge::LinearModel;
use analysis::force_sensor::{CHANNELS, FEATURES, Layout};

use super::file::{ErrorStats, FORMAT, HeldOut, LayoutFile, METHOD, RunRef, VERSION, View};
use super::{SensorError, SensorFile, reference_at, run_frames, run_mm_per_px, unfit};
use crate::report::read_run;

/// One calibration frame.
#[derive(Debug, Clone)]
struct Sample {
    features: Vec<f64>,
    wrench: Vec<f64>,
}

/// What calibration read from one run.
struct RunSamples {
    reference: RunRef,
    samples: Vec<Sample>,
}

/// Fits a sensor on `runs` (run directories; their frames are tracked first if they have
/// no `markers.csv`).
pub fn calibrate(runs: &[PathBuf]) -> Result<SensorFile, SensorError> {
    let Some(first) = runs.first() else {
        return Err(unfit(
            Path::new("."),
            "no run directories given",
            "name the calibration runs: gelrig calibrate runs/A runs/B --out sensor.yaml",
        ));
    };
    let mut layout: Option<(Layout, View, String)> = None;
    let mut per_run = Vec::new();
    for dir in runs {
        let data = read_run(dir)?;
        let loaded = crate::protocol::load(&dir.join("protocol.yaml"), Some(&dir.join("rig.yaml")))
            .map_err(|d| {
                unfit(
                    dir,
                    format!(
                        "its protocol.yaml does not load ({})",
                        d.first().map(|d| d.to_string()).unwrap_or_default()
                    ),
                    "point calibrate at run directories made by `gelrig run`",
                )
            })?;
        let frames = run_frames(&data);
        if frames.len() < 2 {
            return Err(unfit(
                dir,
                "the run has no tracked frames",
                "calibrate on runs recorded with a camera (`capture: {frames: 1}` on steps)",
            ));
        }
        if data.force.is_empty() {
            return Err(unfit(
                dir,
                "the run has no force.csv",
                "calibrate on runs recorded with the force sensor (`record: {force: 20 Hz}`)",
            ));
        }
        let (Some(mm_per_px), Some((w, h))) = (run_mm_per_px(&data), data.frame_size) else {
            return Err(unfit(
                dir,
                "the image scale of its frames is unknown",
                "calibrate on runs made by `gelrig run` (their protocol gives the view)",
            ));
        };
        let sensor_kind = format!("{:?}", loaded.protocol.sensor.kind).to_lowercase();
        let reference_px = frames[0].field.reference_px.clone();
        let (lay, view, kind) = layout.get_or_insert_with(|| {
            (
                Layout::new(
                    reference_px.clone(),
                    mm_per_px,
                    [w as f64 / 2.0 - 0.5, h as f64 / 2.0 - 0.5],
                ),
                View {
                    mm_per_px,
                    width_px: w,
                    height_px: h,
                },
                sensor_kind.clone(),
            )
        });
        if *kind != sensor_kind || (view.width_px, view.height_px) != (w, h) {
            return Err(unfit(
                dir,
                format!(
                    "a {sensor_kind} sensor seen in {w}×{h} px frames, but {} was a {kind} sensor \
                     in {}×{} px frames",
                    first.display(),
                    view.width_px,
                    view.height_px
                ),
                "calibrate each sensor and view on its own runs",
            ));
        }
        let map = lay
            .match_markers(&reference_px)
            .map_err(|source| SensorError::Model {
                path: dir.clone(),
                source,
            })?;
        let mut samples = Vec::new();
        for f in &frames {
            let Some(wrench) = reference_at(&data, f.step, f.t_ns) else {
                continue;
            };
            let (u, _) = lay.displacements_mm(&f.field, &map);
            samples.push(Sample {
                features: lay.features(&u).to_vec(),
                wrench: wrench.to_vec(),
            });
        }
        per_run.push(RunSamples {
            reference: RunRef {
                run: dir
                    .file_name()
                    .map(|n| n.to_string_lossy().into_owned())
                    .unwrap_or_default(),
                protocol: data.protocol_name.clone(),
                indenter: serde_json::to_string(&loaded.protocol.indenter).unwrap_or_default(),
                frames: samples.len(),
            },
            samples,
        });
    }
    let Some((layout, view, sensor)) = layout else {
        return Err(unfit(first, "no runs read", "name run directories"));
    };
    let all: Vec<&Sample> = per_run.iter().flat_map(|r| &r.samples).collect();
    let model = fit(&all).map_err(|source| SensorError::Model {
        path: first.clone(),
        source,
    })?;
    let ranges = ranges(&all);
    let held_out = held_out(&per_run, &ranges).map_err(|source| SensorError::Model {
        path: first.clone(),
        source,
    })?;
    Ok(SensorFile {
        format: FORMAT.into(),
        version: VERSION,
        created: jiff::Timestamp::now().to_string(),
        sensor,
        view,
        layout: LayoutFile {
            centre_px: layout.centre_px,
            reference_px: layout.reference_px.clone(),
        },
        method: METHOD.into(),
        features: FEATURES.iter().map(|f| (*f).to_string()).collect(),
        model: SensorFile::model_file(&model),
        ranges,
        calibrated_on: per_run.into_iter().map(|r| r.reference).collect(),
        held_out,
    })
}

/// Per channel, the calibration's range of the force sensor's readings.
fn ranges(all: &[&Sample]) -> BTreeMap<String, [f64; 2]> {
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
pub(crate) fn span(ranges: &BTreeMap<String, [f64; 2]>, channel: &str) -> f64 {
    let r = |c: &str| ranges.get(c).map_or(0.0, |r| r[1] - r[0]);
    match channel {
        "fx_n" | "fy_n" => r("fx_n").max(r("fy_n")),
        c => r(c),
    }
}

fn fit(samples: &[&Sample]) -> Result<LinearModel, analysis::force_sensor::SensorError> {
    let x: Vec<Vec<f64>> = samples.iter().map(|s| s.features.clone()).collect();
    let y: Vec<Vec<f64>> = samples.iter().map(|s| s.wrench.clone()).collect();
    LinearModel::fit(&x, &y)
}

/// Folds of the held-out error.
const FOLDS: usize = 5;

/// Held-out error per channel: [`FOLDS`] folds, each of every FOLDS-th frame of each run,
/// predicted by a model fitted on the others.
fn held_out(
    runs: &[RunSamples],
    ranges: &BTreeMap<String, [f64; 2]>,
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
        let model = fit(&train)?;
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
pub(crate) fn stats(errors: &[f64], range: f64) -> ErrorStats {
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
