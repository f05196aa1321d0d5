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
use analysis::force_sensor::scale::{SCALE_FEATURES, ScaleBasis};
use analysis::force_sensor::traction::TractionKernel;
use analysis::force_sensor::{CHANNELS, FEATURES, Layout, TRACTION_FEATURES};

use super::file::{
    ErrorStats, FORMAT, HeldOut, LayoutFile, METHOD, METHOD_SCALE, METHOD_TRACTION, RelaxationTerm,
    RunRef, ScaleSettings, TractionSettings, VERSION, View,
};
use super::{SensorError, SensorFile, reference_at, run_frames, run_mm_per_px, unfit};
use crate::run_data::{ForceRow, StepRow, read_run};
use analysis::force_sensor::memory::{self, HeldStep};

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

/// What a sensor reads the field by.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// Field moments ([`analysis::force_sensor`]).
    Moments,
    /// The inverse traction map's integrals ([`analysis::force_sensor::traction`]).
    Traction,
    /// The thesis's scale fit of reference fields ([`analysis::force_sensor::scale`]).
    Scale,
}

/// How to calibrate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CalibrateOptions {
    /// What the field is read by.
    pub method: Method,
    /// The traction map's cell, mm; `None`: the one of [`CELLS`] (with its support) with the
    /// smallest held-out error.
    pub cell_mm: Option<f64>,
    /// The traction map's support, in multiples of the contact region's moment ellipse;
    /// `None`: the one of [`SUPPORTS`] with the smallest held-out error.
    pub support: Option<f64>,
    /// Fit each channel only on the features that turn as it does
    /// ([`analysis::force_sensor::channel_features`]), for a force sensor whose axes are the
    /// view's; otherwise every channel sees every feature.
    pub symmetric: bool,
}

/// Supports tried when none is given, in multiples of the contact region's moment ellipse:
/// the image's contact region is the traction's support, a little wider for a region found
/// short of the contact's edge.
pub const SUPPORTS: [f64; 4] = [1.1, 1.2, 1.3, 1.5];

/// Cells tried when none is given, mm. Which one reads best depends on the layer: on the
/// 2 mm portable pad a 1.5 mm cell's held-out Fz is a half to a quarter of a 1 mm cell's, on the
/// 4.2 mm box pad they are close (BENCHMARKS.md, "Force from the GelSight"), so the
/// calibration's own held-out error chooses, as it chooses the support: the sum of the four
/// channels' held-out % (a channel the calibration runs hardly load — Tz without a twisting
/// run — adds its noise to every candidate alike, and can tip a close choice). A 0.75 mm cell
/// is not tried: it triples the calibration's time (57 s against 20 s on the box's five runs)
/// and the reading's, for a held-out Fz no better than 1 mm's (the unseen ellipse and
/// rectangle half a point closer).
pub const CELLS: [f64; 3] = [1.0, 1.5, 2.0];

impl Default for CalibrateOptions {
    fn default() -> Self {
        Self {
            method: Method::Moments,
            cell_mm: None,
            support: None,
            symmetric: false,
        }
    }
}

/// Frames of a run waiting for their features: the run's marker matching, and each frame
/// with the force sensor's reading beside it.
struct Pending {
    map: Vec<Option<usize>>,
    frames: Vec<(super::RunFrame, [f64; 4])>,
    /// The run's force record and steps, for the elastic force's targets.
    force: Vec<ForceRow>,
    steps: Vec<StepRow>,
}

/// Axes that press the gel: their held steps show its relaxation.
const PRESSING_AXES: [&str; 2] = ["normal", "grip"];

/// The held steps of the pressing axis in `data`, with the force while each held.
fn held_steps(data: &crate::run_data::RunData) -> Vec<HeldStep> {
    data.steps
        .iter()
        .filter(|s| PRESSING_AXES.contains(&s.axis.as_str()) && s.settle_s >= 10.0)
        .filter_map(|s| {
            let settle_ns = (s.settle_s * 1e9) as u64;
            let move_end = s.settle_end_ns.checked_sub(settle_ns)?;
            let change_ns = s.t_start_ns + move_end.saturating_sub(s.t_start_ns) / 2;
            let (t_s, f): (Vec<f64>, Vec<f64>) = data
                .force
                .iter()
                .filter(|r| r.t_ns >= move_end && r.t_ns <= s.settle_end_ns)
                .map(|r| (r.t_ns as f64 * 1e-9, r.fz_n))
                .unzip();
            Some(HeldStep {
                change_s: change_ns as f64 * 1e-9,
                t_s,
                f,
            })
        })
        .collect()
}

/// The elastic force behind each run's Fz ([`memory::elastic_of`]), and the frames' targets
/// with it in place of the force sensor's Fz.
fn to_elastic(pending: &mut [Pending], prony: &mechanics::Prony) {
    for p in pending {
        let t: Vec<u64> = p.force.iter().map(|r| r.t_ns).collect();
        let fz: Vec<f64> = p.force.iter().map(|r| r.fz_n).collect();
        let fe = memory::elastic_of(prony, &t, &fz);
        let force: Vec<ForceRow> = p
            .force
            .iter()
            .zip(&fe)
            .map(|(r, &fz_n)| ForceRow { fz_n, ..*r })
            .collect();
        let steps: Vec<StepRow> = p
            .steps
            .iter()
            .map(|s| {
                let from = s
                    .settle_end_ns
                    .saturating_sub((s.force_window_s * 1e9) as u64);
                let window: Vec<f64> = force
                    .iter()
                    .filter(|r| r.t_ns >= from && r.t_ns <= s.settle_end_ns)
                    .map(|r| r.fz_n)
                    .collect();
                let fz_n = if window.is_empty() {
                    s.fz_n
                } else {
                    window.iter().sum::<f64>() / window.len() as f64
                };
                StepRow { fz_n, ..s.clone() }
            })
            .collect();
        for (f, w) in &mut p.frames {
            if let Some(e) = super::reference_in(&force, &steps, f.step, f.t_ns) {
                w[2] = e[2];
            }
        }
    }
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
    let mut spec: Option<rig::sim::PlantSpec> = None;
    let mut held = Vec::new();
    for dir in runs {
        let data = read_run(dir)?;
        let loaded = crate::run_data::run_protocol(dir).map_err(|e| {
            unfit(
                dir,
                e,
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
        if spec.is_none() {
            spec = crate::protocol::plant_spec(&loaded.protocol, &loaded.compiled).ok();
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
        held.push(held_steps(&data));
        pending.push(Pending {
            map,
            frames,
            force: data.force,
            steps: data.steps,
        });
    }
    let Some((layout, view, sensor)) = layout else {
        return Err(unfit(first, "no runs read", "name run directories"));
    };
    let relaxation = memory::fit_relaxation_runs(&held);
    if let Some(prony) = &relaxation {
        to_elastic(&mut pending, prony);
    }
    let gathered = Gathered {
        relaxation,
        layout,
        view,
        sensor,
        refs,
        pending,
    };
    let how_unknown = || {
        unfit(
            first,
            "the elastomer and indenter are unknown",
            "calibrate on runs made by `gelrig run` (their protocol gives the sensor)",
        )
    };
    match opts.method {
        Method::Moments => return finish(&gathered, &How::Moments, first, opts.symmetric),
        Method::Scale => {
            let spec = spec.as_ref().ok_or_else(how_unknown)?;
            let settings = super::scale::reference_fields(spec, &gathered.layout)
                .map_err(|e| unfit(first, e, "calibrate with --method moments"))?;
            let basis = super::scale::basis(&settings, &gathered.layout).ok_or_else(|| {
                unfit(
                    first,
                    "the reference fields cannot be told apart at these markers",
                    "calibrate with --method moments",
                )
            })?;
            return finish(
                &gathered,
                &How::Scale(&basis, &settings),
                first,
                opts.symmetric,
            );
        }
        Method::Traction => {}
    }
    let Some(h) = spec.as_ref().map(|s| s.contact.layer.thickness_mm) else {
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
    let cells: Vec<f64> = match opts.cell_mm {
        Some(c) => vec![c],
        None => CELLS.to_vec(),
    };
    let mut best: Option<(f64, SensorFile)> = None;
    for cell_mm in cells {
        // The layer's kernels depend on the thickness, the cell and the view, not the
        // support: built once per cell for every support tried.
        let base = TractionSettings {
            thickness_mm: h,
            kernel_dx_mm: (h / 8.0).min(cell_mm / 2.0),
            cell_mm,
            support: 1.0,
            ellipse: true,
            lambda: 0.0,
        };
        let kernel = super::reader::kernel_from_view(&gathered.view, &base);
        for &support in &supports {
            let t = traction_settings(&gathered, &kernel, TractionSettings { support, ..base });
            let file = finish(&gathered, &How::Traction(&kernel, t), first, opts.symmetric)?;
            let score: f64 = file.held_out.channels.values().map(|s| s.pct_range).sum();
            // A candidate whose held-out error is not a number is no candidate.
            if score.is_finite() && best.as_ref().is_none_or(|(b, _)| score < *b) {
                best = Some((score, file));
            }
        }
    }
    best.map(|(_, f)| f).ok_or_else(|| {
        unfit(
            first,
            "no cell and support gave a finite held-out error",
            "calibrate on runs whose force record and frames overlap, or give --cell-mm and \
             --support",
        )
    })
}

/// What calibration read from the runs, before features.
struct Gathered {
    /// The gel's relaxation, where the runs' held pressing steps show it.
    relaxation: Option<mechanics::Prony>,
    layout: Layout,
    view: View,
    sensor: String,
    refs: Vec<RunRef>,
    pending: Vec<Pending>,
}

/// What the features are.
enum How<'a> {
    Moments,
    Traction(&'a TractionKernel, TractionSettings),
    Scale(&'a ScaleBasis, &'a ScaleSettings),
}

/// Features, fit and held-out error of `g` read `how`.
fn finish(
    g: &Gathered,
    how: &How<'_>,
    first: &Path,
    symmetric: bool,
) -> Result<SensorFile, SensorError> {
    let (layout, view) = (&g.layout, &g.view);
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
                    let features = match how {
                        How::Moments => layout.features(&u).to_vec(),
                        How::Scale(basis, _) => basis.features(&u),
                        How::Traction(kernel, t) => super::reader::traction_map(
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
    let names: &[&str] = match how {
        How::Moments => &FEATURES[..],
        How::Traction(..) => &TRACTION_FEATURES[..],
        How::Scale(..) => &SCALE_FEATURES[..],
    };
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

/// Each channel fitted on the features `masks` marks for it (every feature without).
fn fit(
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
fn held_out(
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
