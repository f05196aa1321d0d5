//! How `gelrig calibrate` chooses its method and settings: by what a sensor is for — reading
//! contacts it was not calibrated on.
//!
//! Frames held out of the runs a model was fitted on share their indenter with the fit, so
//! their error rewards a model that learns the calibration's shapes (the box sensor's
//! moments, fitted on every feature, read held-out frames within 0.7 % and an unseen ellipse
//! 5–7 % of span off). Leaving each *indenter* out in turn and reading its runs with a fit
//! on the others measures what the issue asks of a sensor: the error on a shape it never
//! saw. Every method (moments, traction map, scale fit), and each traction cell and support,
//! is scored so — fitted by symmetry on an indentation rig, on every feature in a grasp jig
//! (see [`choose`]) — and the smallest sum over the channels the calibration loads wins, and the winner's error on shapes left out goes into the
//! sensor file (`unseen_shape`) and the command's output. With a single indenter nothing can
//! be left out: the frames held out choose, and the file says the unseen-shape error is
//! unknown.

use std::collections::BTreeMap;
use std::path::Path;

use analysis::force_sensor::CHANNELS;
use analysis::force_sensor::traction::TractionKernel;

use super::file::{Candidate, Choice, ErrorStats, ShapeError, TractionSettings, UnseenShape};
use super::fitting::{finish, fit, held_out, ranges, span, stats};
use super::gather::{Gathered, How, RunSamples, Sample, samples, samples_every, traction_settings};
use super::{SensorError, SensorFile, unfit};

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

impl Method {
    /// Every method, in the order candidates are listed.
    pub const ALL: [Self; 3] = [Self::Moments, Self::Traction, Self::Scale];

    /// The name on the command line.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Moments => "moments",
            Self::Traction => "traction",
            Self::Scale => "scale",
        }
    }
}

/// How to calibrate. What is `None` is chosen by the error on indenters left out of the fit
/// (each indenter in turn), or, where every run pressed the same indenter, by the error on
/// frames held out of the runs.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CalibrateOptions {
    /// What the field is read by; `None`: chosen.
    pub method: Option<Method>,
    /// The traction map's cell, mm; `None`: chosen from [`CELLS`].
    pub cell_mm: Option<f64>,
    /// The traction map's support, in multiples of the contact region's moment ellipse;
    /// `None`: chosen from [`SUPPORTS`].
    pub support: Option<f64>,
    /// Fit each channel only on the features that turn as it does
    /// ([`analysis::force_sensor::channel_features`]), for a force sensor whose axes are the
    /// view's; `Some(false)`: every channel sees every feature; `None`: chosen.
    pub symmetric: Option<bool>,
}

/// Supports tried when none is given, in multiples of the contact region's moment ellipse:
/// the image's contact region is the traction's support, a little wider for a region found
/// short of the contact's edge.
pub const SUPPORTS: [f64; 4] = [1.1, 1.2, 1.3, 1.5];

/// Cells tried when none is given, mm. Which one reads best depends on the layer: on the
/// 2 mm portable pad a 1.5 mm cell's held-out Fz is a half to a quarter of a 1 mm cell's, on the
/// 4.2 mm box pad they are close (BENCHMARKS.md, "Force from the GelSight"), so the
/// calibration's own error chooses, as it chooses the support. A 0.75 mm cell is not tried:
/// it triples the calibration's time and the reading's, for a held-out Fz no better than
/// 1 mm's.
pub const CELLS: [f64; 3] = [1.0, 1.5, 2.0];

/// A candidate's settings, enough to rebuild how it reads.
#[derive(Debug, Clone, Copy)]
struct Spec {
    method: Method,
    /// The features it reads.
    names: &'static [&'static str],
    symmetric: bool,
    /// The traction map's settings, λ chosen (traction only).
    traction: Option<TractionSettings>,
}

/// A candidate scored.
struct Scored {
    spec: Spec,
    row: Candidate,
}

/// The candidates scored so far, and the best.
struct Board<'a> {
    groups: &'a [usize],
    n_groups: usize,
    scored: &'a [String],
    noise: &'a BTreeMap<String, f64>,
    best: Option<Scored>,
    rows: Vec<Candidate>,
}

impl Board<'_> {
    /// Scores a candidate on its samples and keeps it if it is the best so far.
    fn consider(&mut self, spec: Spec, per_run: Vec<RunSamples>) {
        let row = score(
            &spec,
            &per_run,
            self.groups,
            self.n_groups,
            self.scored,
            self.noise,
        );
        let better =
            row.score.is_finite() && self.best.as_ref().is_none_or(|b| row.score < b.row.score);
        self.rows.push(row.clone());
        if better {
            self.best = Some(Scored { spec, row });
        }
    }
}

/// Every traction map cell and support (those `opts` leaves open), each with and without
/// the symmetric fit as `symmetric` allows, on a layer `thickness_mm` thick.
fn consider_traction(
    board: &mut Board<'_>,
    g: &Gathered,
    opts: &CalibrateOptions,
    thickness_mm: f64,
    symmetric: &[bool],
    every: usize,
) {
    let cells: Vec<f64> = opts.cell_mm.map_or(CELLS.to_vec(), |c| vec![c]);
    let supports: Vec<f64> = opts.support.map_or(SUPPORTS.to_vec(), |s| vec![s]);
    for cell_mm in cells {
        let base = TractionSettings {
            thickness_mm,
            kernel_dx_mm: (thickness_mm / 8.0).min(cell_mm / 2.0),
            cell_mm,
            support: 1.0,
            ellipse: true,
            lambda: 0.0,
        };
        // The kernels depend on the thickness, the cell and the view, not the support:
        // built once per cell.
        let kernel = super::reader::kernel_from_view(&g.view, &base);
        for &support in &supports {
            let t = traction_settings(g, &kernel, TractionSettings { support, ..base });
            let how = How::Traction(&kernel, t, g.elongated());
            let per_run = samples_every(g, &how, every);
            for &sym in symmetric {
                let spec = Spec {
                    method: Method::Traction,
                    names: how.names(),
                    symmetric: sym,
                    traction: Some(t),
                };
                board.consider(spec, clone_runs(&per_run));
            }
        }
    }
}

/// Most frames a candidate is scored on (evenly strided over each run): a jig calibration of
/// thousands of frames would otherwise solve every traction map of every cell and support.
const MAX_SCORED_FRAMES: usize = 300;

/// Calibrates `g` as `opts` says, choosing what it leaves open.
pub(super) fn choose(
    g: &Gathered,
    opts: &CalibrateOptions,
    first: &Path,
) -> Result<SensorFile, SensorError> {
    let groups = indenter_groups(g);
    let n_groups = groups.iter().copied().max().map_or(0, |m| m + 1);
    let methods: Vec<Method> = opts.method.map_or(Method::ALL.to_vec(), |m| vec![m]);
    // On an indentation rig the force sensor's axes are the view's, and the isotropic layer
    // allows only the symmetric reading: a fit on every feature may also lean on what every
    // calibration indenter happens to share (all round, as a flat punch and a sphere are),
    // which leaving one out cannot see, and an elongated or twisted contact then leaks into
    // the squeeze (fitted on every feature, the portable's moments read the can 2.2× its
    // force while reading the left-out indenter within 0.4 % of span). A grasp jig's force
    // sensor may be turned against the camera: there only the fit on every feature can map it.
    let symmetric: Vec<bool> = opts.symmetric.map_or_else(|| vec![!g.gripped], |s| vec![s]);
    let explicit = opts.method.is_some();
    let every = stride(g);
    let scored_channels = loaded_channels(g);
    let noise = channel_noise(g);
    // Leaving an indenter out tells something only where another indenter holds the left-out
    // one's kind of load; otherwise (one indenter, or each the only one of its kind) the
    // frames held out choose, and the unseen-shape error is unknown.
    let n_groups = if n_groups >= 2 && {
        let per_run = samples(g, &How::Moments);
        let all: Vec<&Sample> = per_run.iter().flat_map(|r| &r.samples).collect();
        left_out(
            &per_run,
            &groups,
            n_groups,
            &ranges(&all),
            (How::Moments.names(), false),
            &noise,
        )
        .is_some()
    } {
        n_groups
    } else {
        1
    };
    let mut board = Board {
        groups: &groups,
        n_groups,
        scored: &scored_channels,
        noise: &noise,
        best: None,
        rows: Vec::new(),
    };
    for method in methods {
        match method {
            Method::Moments => {
                for &sym in &symmetric {
                    let spec = Spec {
                        method,
                        names: How::Moments.names(),
                        symmetric: sym,
                        traction: None,
                    };
                    board.consider(spec, samples_every(g, &How::Moments, every));
                }
            }
            Method::Scale => {
                let Some((settings, basis)) = scale_of(g) else {
                    if explicit {
                        return Err(unfit(
                            first,
                            "the calibration contact's reference fields cannot be made (the \
                             runs' elastomer and indenter are unknown, or their fields cannot \
                             be told apart at these markers)",
                            "calibrate with --method moments",
                        ));
                    }
                    continue;
                };
                let how = How::Scale(&basis, &settings);
                for &sym in &symmetric {
                    let spec = Spec {
                        method,
                        names: how.names(),
                        symmetric: sym,
                        traction: None,
                    };
                    board.consider(spec, samples_every(g, &how, every));
                }
            }
            Method::Traction => {
                let Some(h) = g.spec.as_ref().map(|s| s.contact.layer.thickness_mm) else {
                    if explicit {
                        return Err(unfit(
                            first,
                            "the elastomer's thickness is unknown",
                            "calibrate on runs made by `gelrig run` (their protocol gives the \
                             sensor)",
                        ));
                    }
                    continue;
                };
                consider_traction(&mut board, g, opts, h, &symmetric, every);
            }
        }
    }
    let (best, mut rows) = (board.best, board.rows);
    let Some(best) = best else {
        return Err(unfit(
            first,
            "no method gave a finite error on the calibration's data",
            "calibrate on runs whose force record and frames overlap, with --method moments",
        ));
    };
    // The winner, fitted on every frame.
    let spec = best.spec;
    let scale = (spec.method == Method::Scale)
        .then(|| scale_of(g))
        .flatten();
    let kernel: Option<TractionKernel> = spec
        .traction
        .map(|t| super::reader::kernel_from_view(&g.view, &t));
    let how = match (spec.method, &scale, &kernel, spec.traction) {
        (Method::Scale, Some((settings, basis)), _, _) => How::Scale(basis, settings),
        (Method::Traction, _, Some(k), Some(t)) => How::Traction(k, t, g.elongated()),
        _ => How::Moments,
    };
    let per_run = samples(g, &how);
    let unseen = unseen_shape(
        g,
        &per_run,
        &groups,
        n_groups,
        spec.symmetric,
        how.names(),
        &noise,
    );
    let mut file = finish(g, &how, per_run, first, spec.symmetric)?;
    file.unseen_shape = unseen;
    rows.sort_by(|a, b| a.score.total_cmp(&b.score));
    if rows.len() > 1 {
        file.chosen_by = Some(Choice {
            by: if n_groups >= 2 {
                "leave one indenter out".into()
            } else {
                "5 folds of frames (no indenter could be left out with its kind of load held by \
                 another: the unseen-shape error is unknown)"
                    .into()
            },
            scored: scored_channels.clone(),
            candidates: rows,
        });
    }
    Ok(file)
}

/// The scale fit's reference fields and basis, if the runs describe their contact.
fn scale_of(
    g: &Gathered,
) -> Option<(
    super::file::ScaleSettings,
    analysis::force_sensor::scale::ScaleBasis,
)> {
    let spec = g.spec.as_ref()?;
    let settings = super::scale::reference_fields(spec, &g.layout).ok()?;
    let basis = super::scale::basis(&settings, &g.layout)?;
    Some((settings, basis))
}

/// Each run's indenter group: runs whose protocols give the same indenter share one.
fn indenter_groups(g: &Gathered) -> Vec<usize> {
    let mut seen: Vec<&str> = Vec::new();
    g.refs
        .iter()
        .map(|r| match seen.iter().position(|s| *s == r.indenter) {
            Some(k) => k,
            None => {
                seen.push(&r.indenter);
                seen.len() - 1
            }
        })
        .collect()
}

/// The stride that leaves at most [`MAX_SCORED_FRAMES`] frames over all runs.
fn stride(g: &Gathered) -> usize {
    let total: usize = samples_count(g);
    total.div_ceil(MAX_SCORED_FRAMES).max(1)
}

fn samples_count(g: &Gathered) -> usize {
    g.refs.iter().map(|r| r.frames).sum()
}

fn clone_runs(runs: &[RunSamples]) -> Vec<RunSamples> {
    runs.iter()
        .map(|r| RunSamples {
            reference: r.reference.clone(),
            samples: r.samples.clone(),
        })
        .collect()
}

/// A candidate's row: its error per channel (on indenters left out when there are two or
/// more, else on frames held out) and the score, with the channels scored.
fn score(
    spec: &Spec,
    per_run: &[RunSamples],
    groups: &[usize],
    n_groups: usize,
    loaded: &[String],
    noise: &BTreeMap<String, f64>,
) -> Candidate {
    let reads = (spec.names, spec.symmetric);
    let all: Vec<&Sample> = per_run.iter().flat_map(|r| &r.samples).collect();
    let ranges = ranges(&all);
    let per_channel: BTreeMap<String, ErrorStats> = if n_groups >= 2 {
        match left_out(per_run, groups, n_groups, &ranges, reads, noise) {
            Some((pooled, _, _)) => pooled,
            None => return unscored(spec),
        }
    } else {
        match held_out(per_run, &ranges, spec.names, spec.symmetric) {
            Ok(h) => h.channels,
            Err(_) => return unscored(spec),
        }
    };
    let total: f64 = loaded
        .iter()
        .filter_map(|c| per_channel.get(c.as_str()))
        .map(|s| s.pct_range)
        .sum();
    Candidate {
        method: spec.method.as_str().into(),
        symmetric: spec.symmetric,
        cell_mm: spec.traction.map(|t| t.cell_mm),
        support: spec.traction.map(|t| t.support),
        pct_range: per_channel
            .iter()
            .map(|(c, s)| (c.clone(), s.pct_range))
            .collect(),
        score: if total.is_finite() {
            total
        } else {
            f64::INFINITY
        },
    }
}

fn unscored(spec: &Spec) -> Candidate {
    Candidate {
        method: spec.method.as_str().into(),
        symmetric: spec.symmetric,
        cell_mm: spec.traction.map(|t| t.cell_mm),
        support: spec.traction.map(|t| t.support),
        pct_range: BTreeMap::new(),
        score: f64::INFINITY,
    }
}

/// The channels the calibration loads: those the field moments read, on frames held out
/// of their own fit, within a tenth of their span. A channel nobody loaded — Tz without a
/// twisting run — is its force sensor's noise (the box's four indentation runs: 23 % of its
/// span), and would choose by chance.
fn loaded_channels(g: &Gathered) -> Vec<String> {
    let per_run = samples(g, &How::Moments);
    let all: Vec<&Sample> = per_run.iter().flat_map(|r| &r.samples).collect();
    let ranges = ranges(&all);
    match held_out(&per_run, &ranges, How::Moments.names(), false) {
        Ok(h) => h
            .channels
            .into_iter()
            .filter(|(_, s)| s.pct_range <= 10.0)
            .map(|(c, _)| c)
            .collect(),
        Err(_) => CHANNELS.iter().map(|c| (*c).to_string()).collect(),
    }
}

/// Each channel's noise, which decides what a run loads: the RMSE of the field moments fitted
/// on every feature, on frames held out. One yardstick for every candidate: judged by each
/// candidate's own noise, a noisier reading saw fewer runs as loading a channel, was scored on
/// other frames than the rest, or on none (the portable's four runs: 11 of 12 traction maps
/// scored nothing, and the twelfth won against readings scored on every fold).
fn channel_noise(g: &Gathered) -> BTreeMap<String, f64> {
    let per_run = samples(g, &How::Moments);
    let all: Vec<&Sample> = per_run.iter().flat_map(|r| &r.samples).collect();
    held_out(&per_run, &ranges(&all), How::Moments.names(), false)
        .map(|h| h.channels.into_iter().map(|(c, s)| (c, s.rmse)).collect())
        .unwrap_or_default()
}

/// Pooled and per-group error on each indenter group read by a fit on the others, with the
/// pooled relative error; `None` when a fit fails. `noise` is [`channel_noise`].
#[allow(clippy::type_complexity)]
fn left_out(
    per_run: &[RunSamples],
    groups: &[usize],
    n_groups: usize,
    ranges: &BTreeMap<String, [f64; 2]>,
    (names, symmetric): (&[&str], bool),
    noise: &BTreeMap<String, f64>,
) -> Option<(
    BTreeMap<String, ErrorStats>,
    Vec<BTreeMap<String, ErrorStats>>,
    BTreeMap<String, f64>,
)> {
    let mut pooled: Vec<Vec<f64>> = vec![Vec::new(); CHANNELS.len()];
    let mut relative: Vec<Vec<f64>> = vec![Vec::new(); CHANNELS.len()];
    let mut per_group = Vec::new();
    // Which channels each run loads — a run is a kind of load, a press, a shear, a twist:
    // those it moves by at least a quarter as much, against the calibration's span, as the
    // channel it moves most (a sphere pressed to 3 N still presses).
    let loads: Vec<[bool; 4]> = per_run
        .iter()
        .map(|r| {
            let own = super::fitting::ranges(&r.samples.iter().collect::<Vec<_>>());
            let share: Vec<f64> = CHANNELS
                .iter()
                .map(|name| span(&own, name) / span(ranges, name).max(1e-12))
                .collect();
            let most = share.iter().copied().fold(0.0, f64::max);
            let mut l = [false; 4];
            for (c, name) in CHANNELS.iter().enumerate() {
                // Above the channel's noise too: ten times what a fit on every frame misses.
                let floor = noise.get(*name).copied().unwrap_or(0.0);
                l[c] = most > 0.0 && share[c] >= 0.25 * most && span(&own, name) >= 10.0 * floor;
            }
            l
        })
        .collect();
    for k in 0..n_groups {
        let train: Vec<&Sample> = per_run
            .iter()
            .zip(groups)
            .filter(|(_, g)| **g != k)
            .flat_map(|(r, _)| &r.samples)
            .collect();
        let model = fit(&train, names, symmetric).ok()?;
        let train_ranges = super::fitting::ranges(&train);
        let train_loads: Vec<[bool; 4]> = groups
            .iter()
            .enumerate()
            .filter(|(_, g)| **g != k)
            .map(|(i, _)| loads[i])
            .collect();
        let mut errors: Vec<Vec<f64>> = vec![Vec::new(); CHANNELS.len()];
        for (i, r) in per_run.iter().enumerate().filter(|(i, _)| groups[*i] == k) {
            // A run is judged only where the others hold its kind of load: a shear run left
            // out with the only shearing indenter tests the shear's absence, not the shape.
            let kind = loads[i];
            let held = train_loads.iter().any(|t| (0..4).all(|c| !kind[c] || t[c]));
            if !held {
                continue;
            }
            for s in &r.samples {
                // Within the loads the others were fitted on: a shape, not an extrapolation
                // in load (which a reading flags as `load` on its own).
                let within = (0..CHANNELS.len()).filter(|&c| kind[c]).all(|c| {
                    let t = train_ranges
                        .get(CHANNELS[c])
                        .copied()
                        .unwrap_or([f64::NEG_INFINITY, f64::INFINITY]);
                    let room = 0.1 * (t[1] - t[0]);
                    s.wrench[c] >= t[0] - room && s.wrench[c] <= t[1] + room
                });
                if !within {
                    continue;
                }
                let (v, _) = model.predict(&s.features);
                for c in (0..CHANNELS.len()).filter(|&c| kind[c]) {
                    let e = v[c] - s.wrench[c];
                    errors[c].push(e);
                    pooled[c].push(e);
                    if s.wrench[c].abs() >= 0.1 * span(ranges, CHANNELS[c]) {
                        relative[c].push(e / s.wrench[c]);
                    }
                }
            }
        }
        per_group.push(
            CHANNELS
                .iter()
                .zip(&errors)
                .filter(|(_, e)| !e.is_empty())
                .map(|(n, e)| ((*n).to_string(), stats(e, span(ranges, n))))
                .collect(),
        );
    }
    if pooled.iter().all(Vec::is_empty) {
        return None;
    }
    let pooled = CHANNELS
        .iter()
        .zip(&pooled)
        .filter(|(_, e)| !e.is_empty())
        .map(|(n, e)| ((*n).to_string(), stats(e, span(ranges, n))))
        .collect();
    let relative = CHANNELS
        .iter()
        .zip(&relative)
        .filter(|(_, r)| !r.is_empty())
        .map(|(n, r)| {
            let rms = (r.iter().map(|v| v * v).sum::<f64>() / r.len().max(1) as f64).sqrt();
            ((*n).to_string(), rms)
        })
        .collect();
    Some((pooled, per_group, relative))
}

/// The chosen reading's error on each indenter left out, on every frame.
fn unseen_shape(
    g: &Gathered,
    per_run: &[RunSamples],
    groups: &[usize],
    n_groups: usize,
    symmetric: bool,
    names: &[&str],
    noise: &BTreeMap<String, f64>,
) -> Option<UnseenShape> {
    if n_groups < 2 {
        return None;
    }
    let all: Vec<&Sample> = per_run.iter().flat_map(|r| &r.samples).collect();
    let ranges = ranges(&all);
    let (pooled, per_group, relative) = left_out(
        per_run,
        groups,
        n_groups,
        &ranges,
        (names, symmetric),
        noise,
    )?;
    let indenter_of = |k: usize| {
        groups
            .iter()
            .position(|&x| x == k)
            .map(|i| g.refs[i].indenter.clone())
            .unwrap_or_default()
    };
    Some(UnseenShape {
        by: format!("each of {n_groups} indenters left out in turn, read by a fit on the others"),
        channels: pooled,
        relative,
        shapes: per_group
            .into_iter()
            .enumerate()
            .map(|(k, channels)| ShapeError {
                indenter: indenter_of(k),
                channels,
            })
            .collect(),
    })
}
