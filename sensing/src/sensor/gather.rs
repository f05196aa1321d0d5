//! What `gelrig calibrate` reads from its runs: the marker layout (the first run's reference;
//! the others matched to it by position, a run of another gel or view refused), every frame's
//! field against the force sensor (its mean over the step's force window for a frame
//! captured at a settled step's end, else over the frame's ±60 ms), the gel's relaxation from
//! the held pressing steps, and each frame's features read one way or another ([`How`]).

use std::path::{Path, PathBuf};

use analysis::force_sensor::scale::{SCALE_FEATURES, ScaleBasis};
use analysis::force_sensor::traction::TractionKernel;
use analysis::force_sensor::{FEATURES, Layout, TRACTION_FEATURES, TRACTION_FEATURES_ROUND};

use super::file::{RunRef, ScaleSettings, TractionSettings, View};
use super::{SensorError, reference_at, run_frames, run_mm_per_px, unfit};
use crate::run_data::{ForceRow, StepRow, read_run};
use analysis::force_sensor::memory::{self, HeldStep};

/// One calibration frame.
#[derive(Debug, Clone)]
pub(super) struct Sample {
    pub(super) features: Vec<f64>,
    pub(super) wrench: Vec<f64>,
    /// The image's contact region.
    pub(super) region: Option<super::history::Region>,
}

/// What calibration read from one run.
pub(super) struct RunSamples {
    pub(super) reference: RunRef,
    pub(super) samples: Vec<Sample>,
}

/// Frames of a run waiting for their features: the run's marker matching, and each frame
/// with the force sensor's reading beside it.
pub(super) struct Pending {
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

/// Reads `runs` (run directories; their frames are tracked first if they have no
/// `markers.csv`) into what calibration fits: the layout, each frame's field against the
/// force sensor, the gel's relaxation.
pub(super) fn gather(runs: &[PathBuf]) -> Result<(Gathered, &Path), SensorError> {
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
    let mut spec: Option<simbench::PlantSpec> = None;
    let mut pad_mm: Option<[f64; 2]> = None;
    let mut gripped = false;
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
            spec = experiments::protocol::plant_spec(&loaded.protocol, &loaded.compiled).ok();
            pad_mm = spec.as_ref().map(|s| {
                let pad = &s.contact.layer;
                [pad.width_mm, pad.length_mm]
            });
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
        gripped |= data.steps.iter().any(|s| s.axis == "grip");
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
        spec,
        pad_mm,
        gripped,
    };
    Ok((gathered, first.as_path()))
}

/// What calibration read from the runs, before features.
pub(super) struct Gathered {
    /// The gel's relaxation, where the runs' held pressing steps show it.
    pub(super) relaxation: Option<mechanics::Prony>,
    pub(super) layout: Layout,
    pub(super) view: View,
    pub(super) sensor: String,
    pub(super) refs: Vec<RunRef>,
    pub(super) pending: Vec<Pending>,
    /// The simulated bench the first run's protocol describes (elastomer, indenter).
    pub(super) spec: Option<simbench::PlantSpec>,
    /// The gel pad's extent, mm (width, height), centred on the view.
    pub(super) pad_mm: Option<[f64; 2]>,
    /// Whether some run grips an object (a grasp jig, whose force sensor may be turned
    /// against the camera) rather than indenting the gel.
    pub(super) gripped: bool,
}

/// What the features are.
pub(super) enum How<'a> {
    Moments,
    /// The traction map's integrals, with the elongation term where the calibration holds
    /// elongated contacts ([`Gathered::elongated`]).
    Traction(&'a TractionKernel, TractionSettings, bool),
    Scale(&'a ScaleBasis, &'a ScaleSettings),
}

impl How<'_> {
    /// The features' names.
    pub(super) fn names(&self) -> &'static [&'static str] {
        match self {
            How::Moments => &FEATURES[..],
            How::Traction(_, _, true) => &TRACTION_FEATURES[..],
            How::Traction(_, _, false) => &TRACTION_FEATURES_ROUND[..],
            How::Scale(..) => &SCALE_FEATURES[..],
        }
    }
}

impl Gathered {
    /// Whether the runs' contacts include elongated ones (a strip, a dowel, a can's side),
    /// enough for the traction map's elongation term to be fitted
    /// ([`elongated_enough`]). Round contacts only: the term is left out of the sensor.
    pub(super) fn elongated(&self) -> bool {
        elongated_enough(
            self.pending
                .iter()
                .flat_map(|p| p.frames.iter().map(|(f, _)| f.contact.as_ref())),
        )
    }
}

/// Whether at least [`ELONGATED_SHARE`] of the `regions` with a contact are [`ELONGATED`]
/// (regions without recorded moments count as round).
///
/// [`ELONGATED_SHARE`]: analysis::force_sensor::traction::ELONGATED_SHARE
/// [`ELONGATED`]: analysis::force_sensor::traction::ELONGATED
pub(super) fn elongated_enough<'r>(
    regions: impl Iterator<Item = Option<&'r super::history::Region>>,
) -> bool {
    use analysis::force_sensor::traction::{ELONGATED, ELONGATED_SHARE};
    let (mut contacts, mut long) = (0usize, 0usize);
    for r in regions.flatten() {
        contacts += 1;
        if elongation_of(Some(r)) >= ELONGATED {
            long += 1;
        }
    }
    contacts > 0 && long as f64 >= ELONGATED_SHARE * contacts as f64
}

/// A contact region's elongation ([`analysis::force_sensor::traction::elongation`]); 0 for
/// none, or for a region without recorded moments (a disc).
pub(super) fn elongation_of(region: Option<&super::history::Region>) -> f64 {
    region
        .and_then(|r| r.second_moments_px2)
        .map_or(0.0, analysis::force_sensor::traction::elongation)
}

/// Each run's frames read `how`: features against the force sensor's wrench, and each
/// frame's contact region.
pub(super) fn samples(g: &Gathered, how: &How<'_>) -> Vec<RunSamples> {
    samples_every(g, how, 1)
}

/// [`samples`] of every `stride`-th frame of each run.
pub(super) fn samples_every(g: &Gathered, how: &How<'_>, stride: usize) -> Vec<RunSamples> {
    let layout = &g.layout;
    g.pending
        .iter()
        .zip(g.refs.iter().cloned())
        .map(|(p, reference)| RunSamples {
            reference,
            samples: p
                .frames
                .iter()
                .step_by(stride.max(1))
                .map(|(f, w)| {
                    let (u, _) = layout.displacements_mm(&f.field, &p.map);
                    let features = match how {
                        How::Moments => layout.features(&u).to_vec(),
                        How::Scale(basis, _) => basis.features(&u),
                        How::Traction(kernel, t, elongated) => super::reader::traction_features(
                            super::reader::traction_map(
                                layout,
                                kernel,
                                t,
                                &u,
                                f.contact,
                                Some(t.lambda),
                            )
                            .as_ref(),
                            f.contact.as_ref(),
                            *elongated,
                        ),
                    };
                    Sample {
                        features,
                        wrench: w.to_vec(),
                        region: f.contact,
                    }
                })
                .collect(),
        })
        .collect()
}

/// `t` with λ the median of GCV's choices on every fourth frame with a contact region (every
/// n-th beyond four hundred of them; the kernel's cell is an eighth of the thickness, at most
/// half the map's cell).
pub(super) fn traction_settings(
    g: &Gathered,
    kernel: &TractionKernel,
    t: TractionSettings,
) -> TractionSettings {
    let mut t = t;
    // Every fourth frame with a contact region, at most about a hundred of them.
    let with_contact: usize = g
        .pending
        .iter()
        .map(|p| p.frames.iter().filter(|(f, _)| f.contact.is_some()).count())
        .sum();
    let stride = 4.max(with_contact.div_ceil(100));
    let mut lambdas: Vec<f64> = g
        .pending
        .iter()
        .flat_map(|p| {
            p.frames
                .iter()
                .filter(|(f, _)| f.contact.is_some())
                .step_by(stride)
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
