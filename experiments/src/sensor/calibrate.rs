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
use analysis::force_sensor::traction::TractionKernel;
use analysis::force_sensor::{CHANNELS, FEATURES, Layout, TRACTION_FEATURES};

use super::file::{
    ErrorStats, FORMAT, HeldOut, LayoutFile, METHOD, METHOD_TRACTION, RunRef, TractionSettings,
    VERSION, View,
};
use super::{SensorError, SensorFile, reference_at, run_frames, run_mm_per_px, unfit};
use crate::rundir::read_run;

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

/// How to calibrate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CalibrateOptions {
    /// Field moments (`false`) or the traction map's integrals (`true`).
    pub traction: bool,
    /// The traction map's cell, mm.
    pub cell_mm: f64,
    /// The traction map's support, in contact radii; `None`: the one of [`SUPPORTS`] with
    /// the smallest held-out error.
    pub support: Option<f64>,
}

/// Supports tried when none is given, in contact radii: the image's contact region is the
/// traction's support, a little wider for a region found short of the contact's edge.
pub const SUPPORTS: [f64; 4] = [1.1, 1.2, 1.3, 1.5];

impl Default for CalibrateOptions {
    fn default() -> Self {
        Self {
            traction: false,
            cell_mm: 1.0,
            support: None,
        }
    }
}

/// Frames of a run waiting for their features: the run's marker matching, and each frame
/// with the force sensor's reading beside it.
struct Pending {
    map: Vec<Option<usize>>,
    frames: Vec<(super::RunFrame, [f64; 4])>,
}

/// Fits a sensor on `runs` (run directories; their frames are tracked first if they have
/// no `markers.csv`).
pub fn calibrate(runs: &[PathBuf], opts: &CalibrateOptions) -> Result<SensorFile, SensorError> {
    let Some(first) = runs.first() else {
        return Err(unfit(
            Path::new("."),
            "no run directories given",
            "name the calibration runs: gelrig calibrate runs/A runs/B --out sensor.yaml",
        ));
    };
    let mut layout: Option<(Layout, View, String)> = None;
    let mut refs = Vec::new();
    let mut pending = Vec::new();
    let mut thickness_mm = None;
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
        if thickness_mm.is_none() {
            thickness_mm = crate::protocol::plant_spec(&loaded.protocol, &loaded.compiled)
                .ok()
                .map(|s| s.contact.layer.thickness_mm);
        }
        let frames: Vec<(super::RunFrame, [f64; 4])> = frames
            .into_iter()
            .filter_map(|f| {
                let w = reference_at(&data, f.step, f.t_ns)?;
                Some((f, w))
            })
            .collect();
        refs.push(RunRef {
            run: dir
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default(),
            protocol: data.protocol_name.clone(),
            indenter: serde_json::to_string(&loaded.protocol.indenter).unwrap_or_default(),
            frames: frames.len(),
        });
        pending.push(Pending { map, frames });
    }
    let Some((layout, view, sensor)) = layout else {
        return Err(unfit(first, "no runs read", "name run directories"));
    };
    let gathered = Gathered {
        layout,
        view,
        sensor,
        refs,
        pending,
    };
    if !opts.traction {
        return finish(&gathered, None, first);
    }
    let Some(h) = thickness_mm else {
        return Err(unfit(
            first,
            "the elastomer's thickness is unknown",
            "calibrate on runs made by `gelrig run` (their protocol gives the sensor)",
        ));
    };
    let supports: Vec<f64> = match opts.support {
        Some(s) => vec![s],
        None => SUPPORTS.to_vec(),
    };
    // The layer's kernels depend on the thickness, the cell and the view, not the support:
    // built once for every support tried.
    let base = TractionSettings {
        thickness_mm: h,
        kernel_dx_mm: (h / 8.0).min(opts.cell_mm / 2.0),
        cell_mm: opts.cell_mm,
        support: 1.0,
        lambda: 0.0,
    };
    let kernel = super::reader::kernel_from_view(&gathered.view, &base);
    let mut best: Option<(f64, SensorFile)> = None;
    for support in supports {
        let t = traction_settings(&gathered, &kernel, TractionSettings { support, ..base });
        let file = finish(&gathered, Some((&kernel, t)), first)?;
        let score: f64 = file.held_out.channels.values().map(|s| s.pct_range).sum();
        if best.as_ref().is_none_or(|(b, _)| score < *b) {
            best = Some((score, file));
        }
    }
    best.map(|(_, f)| f)
        .ok_or_else(|| unfit(first, "no support to try", "give --support"))
}

/// What calibration read from the runs, before features.
struct Gathered {
    layout: Layout,
    view: View,
    sensor: String,
    refs: Vec<RunRef>,
    pending: Vec<Pending>,
}

/// Features, fit and held-out error of `g`, with the traction map's settings `traction`
/// (field moments without).
fn finish(
    g: &Gathered,
    traction: Option<(&TractionKernel, TractionSettings)>,
    first: &Path,
) -> Result<SensorFile, SensorError> {
    let (layout, view) = (&g.layout, &g.view);
    let reader_kernel = traction;
    let per_run: Vec<RunSamples> = g
        .pending
        .iter()
        .zip(g.refs.iter().cloned())
        .map(|(p, reference)| RunSamples {
            reference,
            samples: p
                .frames
                .iter()
                .map(|(f, w)| {
                    let (u, _) = layout.displacements_mm(&f.field, &p.map);
                    let features = match &reader_kernel {
                        None => layout.features(&u).to_vec(),
                        Some((kernel, t)) => super::reader::traction_map(
                            layout,
                            kernel,
                            t,
                            &u,
                            f.contact,
                            Some(t.lambda),
                        )
                        .map_or(vec![0.0; 4], |m| m.wrench.to_vec()),
                    };
                    Sample {
                        features,
                        wrench: w.to_vec(),
                    }
                })
                .collect(),
        })
        .collect();
    let all: Vec<&Sample> = per_run.iter().flat_map(|r| &r.samples).collect();
    let model = fit(&all).map_err(|source| SensorError::Model {
        path: first.to_path_buf(),
        source,
    })?;
    let ranges = ranges(&all);
    let held_out = held_out(&per_run, &ranges).map_err(|source| SensorError::Model {
        path: first.to_path_buf(),
        source,
    })?;
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
        method: if traction.is_some() {
            METHOD_TRACTION
        } else {
            METHOD
        }
        .into(),
        features: if traction.is_some() {
            TRACTION_FEATURES.iter().map(|f| (*f).to_string()).collect()
        } else {
            FEATURES.iter().map(|f| (*f).to_string()).collect()
        },
        model: SensorFile::model_file(&model),
        traction: traction.map(|(_, t)| t),
        ranges,
        calibrated_on: per_run.into_iter().map(|r| r.reference).collect(),
        held_out,
    })
}

/// `t` with λ the median of GCV's choices on every fourth frame with a contact region (the
/// kernel's cell is an eighth of the thickness, at most half the map's cell).
fn traction_settings(
    g: &Gathered,
    kernel: &TractionKernel,
    t: TractionSettings,
) -> TractionSettings {
    let mut t = t;
    let mut lambdas: Vec<f64> = g
        .pending
        .iter()
        .flat_map(|p| {
            p.frames
                .iter()
                .filter(|(f, _)| f.contact.is_some())
                .step_by(4)
                .map(move |(f, _)| (f, &p.map))
        })
        .filter_map(|(f, map)| {
            let (u, _) = g.layout.displacements_mm(&f.field, map);
            super::reader::traction_map(&g.layout, kernel, &t, &u, f.contact, None)
                .map(|m| m.lambda)
        })
        .collect();
    lambdas.sort_by(f64::total_cmp);
    t.lambda = lambdas.get(lambdas.len() / 2).copied().unwrap_or(0.0);
    t
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
