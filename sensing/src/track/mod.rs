//! `gelrig track`: marker tracking over image files or a run directory's frames.
//!
//! The I/O around [`tracking`] and [`tracking::field`]: decode PNG frames, run
//! the pipeline, write `markers.csv` row by row (flushed after every frame, so an
//! interrupted or failing run keeps what it tracked), and optionally a field folder with
//! pictures and the field's decomposition per frame. On a simulated run the simulator's
//! exact marker centres (`sim_markers.csv`) are read back and the tracking error reported.

use std::collections::HashMap;
use std::fs;
use std::path::{Path, PathBuf};
use std::time::Instant;

use rundir::write::rows::{ContactRow, MarkerRow};
use tracking::field::MarkerField;
use tracking::field::decompose;
use tracking::{FrameCheck, MarkerState, Method, Pipeline, RgbView, TrackError, TrackParams};

mod decode;
mod depth_out;
mod detect_only;
mod field_out;
mod input;

pub use detect_only::{Detections, detect_only};

use decode::DecodeAhead;
use depth_out::DepthOut;
pub use depth_out::ShapeReading;
use field_out::FieldWriter;
pub(crate) use input::run_scale;
use input::{frame_list, sim_truth};
pub use input::{load_rgb, step_last_frames};
use tracking::{ContactParams, ContactRegion};

/// What to track.
#[derive(Debug, Clone, PartialEq)]
pub enum Input {
    /// Frames with no image of the untouched gel (a recording that starts mid-contact):
    /// the undeformed lattice is fitted to the periphery of the first (frame 0).
    ReferenceFree {
        /// Frames 0, 1, …
        frames: Vec<PathBuf>,
    },
    /// A no-contact reference image and the frames to track, in order.
    Files {
        /// The reference (frame 0).
        reference: PathBuf,
        /// Frames 1, 2, …
        frames: Vec<PathBuf>,
    },
    /// A run directory: its `frames.csv` and `frames/`; the reference is its first frame
    /// of step 0 (taken before contact by the approach's `reference_frames`) unless given.
    RunDir {
        /// The run directory.
        dir: PathBuf,
        /// Another reference image, if the run has none.
        reference: Option<PathBuf>,
    },
}

/// How to track and what to write besides `markers.csv`.
#[derive(Debug, Clone, PartialEq)]
pub struct Options {
    /// Position estimate.
    pub method: Method,
    /// Folder for field pictures and decomposition tables, if wanted.
    pub field_dir: Option<PathBuf>,
    /// Arrow length per pixel of displacement in the quiver plots.
    pub magnify: f64,
    /// Find the contact region of every frame and write `contact.csv` beside `markers.csv`.
    pub contact: bool,
    /// Image scale, mm per pixel; a run directory's own scale (its sensor's view over the
    /// camera's frame) is used when this is not given.
    pub mm_per_px: Option<f64>,
    /// Threads decoding frames ahead of the tracker (0: one per core).
    pub decoders: usize,
    /// How the contact region is found.
    pub contact_params: ContactParams,
    /// Read each frame's height map too, and write `depth.csv` beside `markers.csv`.
    pub shape: Option<ShapeReading>,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            method: Method::Centroid,
            field_dir: None,
            magnify: 3.0,
            contact: true,
            mm_per_px: None,
            decoders: 0,
            contact_params: ContactParams::default(),
            shape: None,
        }
    }
}

/// What a tracking run did.
#[derive(Debug, Clone, PartialEq)]
pub struct Summary {
    /// Frames tracked, the reference included.
    pub frames: usize,
    /// Markers (identities) from the reference.
    pub markers: usize,
    /// Marker spacing measured on the reference, px.
    pub spacing_px: f64,
    /// Rows per state over all frames after the reference.
    pub states: Vec<(&'static str, usize)>,
    /// Median time per frame of detection, identity and LK (no decoding, no writing), ms.
    pub median_ms_per_frame: f64,
    /// The frame with the largest median displacement, and that displacement, px.
    pub largest: Option<(u64, f64)>,
    /// On simulated runs: rms and largest error of the tracked markers against the
    /// simulator's exact centres, px, and the number of positions compared.
    pub truth: Option<(f64, f64, usize)>,
    /// Where `markers.csv` went.
    pub markers_csv: PathBuf,
    /// Where `contact.csv` went, if asked for.
    pub contact_csv: Option<PathBuf>,
    /// Where `depth.csv` went, with `--shape`.
    pub depth_csv: Option<PathBuf>,
    /// The image of the untouched gel the frames were tracked against.
    pub reference_png: PathBuf,
    /// Frames with a contact region, and the largest one: (frame, equivalent radius px).
    pub contact_frames: usize,
    /// The largest contact region: frame and equivalent radius, px.
    pub largest_contact: Option<(u64, f64)>,
    /// The image scale used for mm columns, if known.
    pub mm_per_px: Option<f64>,
    /// Wall time of the whole command (decode, track, write), s.
    pub wall_s: f64,
    /// The lattice fitted on a reference-free start.
    pub lattice: Option<tracking::lattice::Lattice>,
    /// What the user should know about the input (the reference also among the frames,
    /// dark frames).
    pub warnings: Vec<String>,
    /// Frames whose identities were withheld because two placements of the markers
    /// explained them (and every frame since the last certain one) equally well.
    pub ambiguous_frames: usize,
}

/// Why tracking stopped. `markers.csv` keeps every frame tracked before the failure.
#[derive(Debug, thiserror::Error)]
pub enum TrackFailure {
    /// The options contradict each other.
    #[error("{detail}")]
    Usage {
        /// What, and the fix.
        detail: String,
    },
    /// An input file is missing or unreadable.
    #[error("cannot read {path}: {detail}; fix: check the path (frames are PNG files)")]
    Read {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        detail: String,
    },
    /// An input file is not a decodable image.
    #[error("{path} is not a readable PNG image ({detail}); fix: pass 8-bit RGB(A) PNG frames")]
    Decode {
        /// The file.
        path: PathBuf,
        /// Decoder message.
        detail: String,
    },
    /// The reference frame cannot be used.
    #[error("reference {path}: {source}")]
    Reference {
        /// The reference file.
        path: PathBuf,
        /// Why.
        source: TrackError,
    },
    /// A frame cannot be tracked.
    #[error("frame {path}: {source}")]
    Frame {
        /// The frame file.
        path: PathBuf,
        /// Why.
        source: TrackError,
    },
    /// The run directory lacks what tracking needs.
    #[error("run directory {dir}: {detail}")]
    RunDir {
        /// The run directory.
        dir: PathBuf,
        /// What is missing, and the fix.
        detail: String,
    },
    /// A frame shows another gel or camera than the reference ([`FrameCheck`]).
    #[error("frame {path} does not show the gel of the reference: {what}")]
    Mismatch {
        /// The frame file.
        path: PathBuf,
        /// What it shows instead, and the fix.
        what: String,
    },
    /// An output could not be written.
    #[error("cannot write {path}: {detail}; fix: check that the folder exists and is writable")]
    Write {
        /// The output file.
        path: PathBuf,
        /// What went wrong.
        detail: String,
    },
}

pub(super) fn write_err(path: &Path) -> impl Fn(String) -> TrackFailure + '_ {
    move |detail| TrackFailure::Write {
        path: path.to_path_buf(),
        detail,
    }
}

/// The row of `contact.csv` for a frame's contact region (empty centroid and mm columns
/// where unknown).
fn contact_row(frame: u64, c: Option<&ContactRegion>, mm_per_px: Option<f64>) -> ContactRow {
    let (area, radius) = c.map_or((0.0, 0.0), |c| (c.area_px2, c.radius_px));
    ContactRow {
        frame,
        area_px2: r4(area),
        area_mm2: mm_per_px.map(|s| r4(area * s * s)),
        cx_px: c.map(|c| r4(c.centroid_px[0])),
        cy_px: c.map(|c| r4(c.centroid_px[1])),
        radius_mm: mm_per_px.map(|s| r4(radius * s)),
        radius_px: r4(radius),
        sxx_px2: c.map(|c| r4(c.second_moments_px2[0])),
        syy_px2: c.map(|c| r4(c.second_moments_px2[1])),
        sxy_px2: c.map(|c| r4(c.second_moments_px2[2])),
    }
}

/// A frame the height map cannot be read from (its size is not the reference's).
fn frame_usage(path: &Path, e: shape::ShapeError) -> TrackFailure {
    TrackFailure::Usage {
        detail: format!("frame {}: {e}", path.display()),
    }
}

pub(super) fn r4(v: f64) -> f64 {
    (v * 1e4).round() / 1e4
}

/// Tracks the input and writes `markers.csv` to `out`, `contact.csv` beside it (unless
/// [`Options::contact`] is off) and the field folder if asked.
pub fn track(input: &Input, out: &Path, opts: &Options) -> Result<Summary, TrackFailure> {
    let started = Instant::now();
    let (reference_path, reference_frame_no, frames) = frame_list(input)?;
    let mut warnings = reference_among_frames(input, &reference_path, &frames);
    let (w, h, rgb) = load_rgb(&reference_path)?;
    let reference_err = |source| TrackFailure::Reference {
        path: reference_path.clone(),
        source,
    };
    let view = RgbView::new(w, h, &rgb).map_err(reference_err)?;
    let reference_free = matches!(input, Input::ReferenceFree { .. });
    let (mut pipeline, lattice) = if reference_free {
        let (p, l) = Pipeline::reference_free(view, &TrackParams::default(), opts.method)
            .map_err(reference_err)?;
        (p, Some(l))
    } else {
        let p = Pipeline::new(view, &TrackParams::default(), opts.method).map_err(reference_err)?;
        (p, None)
    };
    // The contact region is a change against the untouched gel, which a reference-free
    // start has not seen.
    let contact = opts.contact && !reference_free;
    if contact {
        pipeline
            .enable_contact(view, opts.contact_params.clone())
            .map_err(reference_err)?;
    }
    let mm_per_px = opts.mm_per_px.or_else(|| match input {
        Input::RunDir { dir, .. } => run_scale(dir, w, h),
        Input::Files { .. } | Input::ReferenceFree { .. } => None,
    });
    let mut writers = Writers::create(out, contact, mm_per_px)?;
    let mut depth = match &opts.shape {
        Some(reading) if !reference_free => Some(DepthOut::new(
            reading,
            shape::Rgb {
                width: w,
                height: h,
                pixels: &rgb,
            },
            out,
        )?),
        _ => None,
    };
    let mut field = match &opts.field_dir {
        Some(d) => Some(FieldWriter::new(d, &pipeline, opts.magnify)?),
        None => None,
    };
    let mut tally = Tally::new(sim_truth(input), reference_frame_no, &pipeline);
    let shown = |p: &Path| p.display().to_string();
    if let Some(no) = reference_frame_no {
        writers.frame(no, &shown(&reference_path), &pipeline, None)?;
        if let Some(f) = field.as_mut() {
            f.frame(no, &pipeline)?;
        }
        if let Some(d) = depth.as_mut() {
            d.frame(
                no,
                shape::Rgb::new(w, h, &rgb).map_err(|e| frame_usage(&reference_path, e))?,
            )?;
        }
    }
    // At most 16 decoders: each holds up to three frames in memory.
    let workers = match opts.decoders {
        0 => std::thread::available_parallelism().map_or(1, |n| n.get()),
        n => n,
    }
    .min(16);
    let frame_count = frames.len();
    let ahead = DecodeAhead::new(frames, workers);
    let pool = ahead.pool();
    for decoded in ahead {
        let (frame, path) = (decoded.frame, decoded.path);
        let (fw, fh, rgb) = decoded.image?;
        let frame_err = |source| TrackFailure::Frame {
            path: path.clone(),
            source,
        };
        let view = RgbView::new(fw, fh, &rgb).map_err(frame_err)?;
        let t0 = Instant::now();
        pipeline.track(view).map_err(frame_err)?;
        tally.times.push(t0.elapsed().as_secs_f64() * 1e3);
        // A frame of another gel or camera stops the command; a dark frame or one whose
        // identities the lattice leaves ambiguous does not (the frames after it are good).
        match pipeline.check_frame() {
            FrameCheck::SameGel => {}
            FrameCheck::FewBlobs { .. } => tally.few_blob_frames.push(frame),
            other => {
                return Err(TrackFailure::Mismatch {
                    path,
                    what: other.describe(),
                });
            }
        }
        writers.frame(frame, &shown(&path), &pipeline, Some(&mut tally.counts))?;
        if let Some(f) = field.as_mut() {
            f.frame(frame, &pipeline)?;
        }
        if let Some(d) = depth.as_mut() {
            d.frame(
                frame,
                shape::Rgb::new(fw, fh, &rgb).map_err(|e| frame_usage(&path, e))?,
            )?;
        }
        tally.frame(frame, &pipeline);
        pool.give(rgb);
    }
    if let (Some(first), Some(last)) = (tally.few_blob_frames.first(), tally.few_blob_frames.last())
    {
        warnings.push(format!(
            "{} frame(s) showed almost no markers (frames {first}–{last}): the camera was dark, \
             covered or out of focus there; their rows are predicted, lost or out of view",
            tally.few_blob_frames.len()
        ));
    }
    tally.times.sort_by(f64::total_cmp);
    Ok(Summary {
        ambiguous_frames: tally.ambiguous_frames,
        frames: frame_count + usize::from(reference_frame_no.is_some()),
        markers: pipeline.tracker().len(),
        spacing_px: pipeline.reference().spacing_px(),
        states: MarkerState::ALL
            .iter()
            .map(|s| {
                (
                    s.as_str(),
                    tally.counts.get(s.as_str()).copied().unwrap_or(0),
                )
            })
            .collect(),
        median_ms_per_frame: tally
            .times
            .get(tally.times.len() / 2)
            .copied()
            .unwrap_or(0.0),
        largest: tally.largest,
        truth: (tally.compared > 0).then(|| {
            (
                (tally.sq / tally.compared as f64).sqrt(),
                tally.worst,
                tally.compared,
            )
        }),
        markers_csv: out.to_path_buf(),
        contact_csv: writers.contact_path,
        depth_csv: depth.as_ref().map(|d| d.path().to_path_buf()),
        reference_png: reference_path.clone(),
        contact_frames: tally.contact_frames,
        largest_contact: tally.largest_contact,
        mm_per_px,
        wall_s: started.elapsed().as_secs_f64(),
        lattice,
        warnings,
    })
}

/// The reference given again among the frames tracks as no displacement at all, which
/// reads like a gel that never moved: a warning for each time it is.
fn reference_among_frames(
    input: &Input,
    reference_path: &Path,
    frames: &[(u64, PathBuf)],
) -> Vec<String> {
    if !matches!(input, Input::Files { .. }) {
        return Vec::new();
    }
    let canonical = |p: &Path| p.canonicalize().unwrap_or_else(|_| p.to_path_buf());
    let reference_canonical = canonical(reference_path);
    frames
        .iter()
        .filter(|(_, p)| canonical(p) == reference_canonical)
        .map(|(k, p)| {
            format!(
                "the reference {} is also frame {k}: it tracks as zero displacement (pass \
                 the frames after the reference)",
                p.display()
            )
        })
        .collect()
}

/// `markers.csv`, and `contact.csv` beside it, as the frames are tracked.
struct Writers {
    out: PathBuf,
    markers: csv::Writer<fs::File>,
    contact: Option<csv::Writer<fs::File>>,
    contact_path: Option<PathBuf>,
    mm_per_px: Option<f64>,
}

impl Writers {
    /// Creates `out` (its folder too) and, where `contact` is on, `contact.csv` beside it.
    fn create(out: &Path, contact: bool, mm_per_px: Option<f64>) -> Result<Self, TrackFailure> {
        if let Some(parent) = out.parent().filter(|p| !p.as_os_str().is_empty()) {
            fs::create_dir_all(parent).map_err(|e| write_err(parent)(e.to_string()))?;
        }
        let contact_path = contact.then(|| out.with_file_name(rundir::names::CONTACT));
        if contact_path.as_deref() == Some(out) {
            return Err(TrackFailure::Usage {
                detail: format!(
                    "--out {} would overwrite contact.csv, which is written beside it; fix: name \
                     the --out file otherwise (e.g. markers.csv), or pass --no-contact",
                    out.display()
                ),
            });
        }
        let markers = csv::Writer::from_path(out).map_err(|e| write_err(out)(e.to_string()))?;
        let contact = match &contact_path {
            Some(p) => Some(csv::Writer::from_path(p).map_err(|e| write_err(p)(e.to_string()))?),
            None => None,
        };
        Ok(Self {
            out: out.to_path_buf(),
            markers,
            contact,
            contact_path,
            mm_per_px,
        })
    }

    /// Writes a frame's rows (from `file`), counting its states into `counts` where given
    /// (the reference's are not counted).
    fn frame(
        &mut self,
        frame: u64,
        file: &str,
        pipeline: &Pipeline,
        mut counts: Option<&mut HashMap<&'static str, usize>>,
    ) -> Result<(), TrackFailure> {
        let out = &self.out;
        let t = pipeline.tracker();
        for id in 0..t.len() {
            let p = t.positions_px()[id];
            let d = t.displacement_px(id);
            let state = t.states()[id];
            if let Some(c) = counts.as_deref_mut() {
                *c.entry(state.as_str()).or_default() += 1;
            }
            self.markers
                .serialize(MarkerRow {
                    frame,
                    file,
                    id,
                    x_px: r4(p[0]),
                    y_px: r4(p[1]),
                    dx_px: r4(d[0]),
                    dy_px: r4(d[1]),
                    state: state.as_str(),
                    confidence: r4(t.confidences()[id]),
                })
                .map_err(|e| write_err(out)(e.to_string()))?;
        }
        self.markers
            .flush()
            .map_err(|e| write_err(out)(e.to_string()))?;
        if let (Some(w), Some(path)) = (self.contact.as_mut(), &self.contact_path) {
            w.serialize(contact_row(frame, pipeline.contact(), self.mm_per_px))
                .map_err(|e| write_err(path)(e.to_string()))?;
            w.flush().map_err(|e| write_err(path)(e.to_string()))?;
        }
        Ok(())
    }
}

/// The simulator's exact marker centres by frame, on a simulated run.
type Truth = HashMap<u64, Vec<[f64; 2]>>;

/// What the command says of the frames it tracked: states, times, the largest deformation
/// and contact, frames dark or ambiguous, and on simulated runs the error against the
/// simulator's exact centres.
struct Tally {
    counts: HashMap<&'static str, usize>,
    times: Vec<f64>,
    few_blob_frames: Vec<u64>,
    ambiguous_frames: usize,
    largest: Option<(u64, f64)>,
    contact_frames: usize,
    largest_contact: Option<(u64, f64)>,
    truth: Option<Truth>,
    /// Tracker id → simulator id, by the nearest centre on the reference frame.
    truth_ids: Option<Vec<usize>>,
    sq: f64,
    worst: f64,
    compared: usize,
}

impl Tally {
    fn new(truth: Option<Truth>, reference_frame_no: Option<u64>, pipeline: &Pipeline) -> Self {
        let truth_ids: Option<Vec<usize>> = truth.as_ref().and_then(|t| {
            let refs = t.get(&reference_frame_no?)?;
            Some(
                pipeline
                    .tracker()
                    .reference_px()
                    .iter()
                    .map(|p| {
                        (0..refs.len())
                            .min_by(|&a, &b| {
                                let da = (refs[a][0] - p[0]).hypot(refs[a][1] - p[1]);
                                let db = (refs[b][0] - p[0]).hypot(refs[b][1] - p[1]);
                                da.total_cmp(&db)
                            })
                            .unwrap_or(0)
                    })
                    .collect(),
            )
        });
        Self {
            counts: HashMap::new(),
            times: Vec::new(),
            few_blob_frames: Vec::new(),
            ambiguous_frames: 0,
            largest: None,
            contact_frames: 0,
            largest_contact: None,
            truth,
            truth_ids,
            sq: 0.0,
            worst: 0.0,
            compared: 0,
        }
    }

    /// Takes in a tracked frame.
    fn frame(&mut self, frame: u64, pipeline: &Pipeline) {
        if !pipeline.tracker().aliases_px().is_empty() {
            self.ambiguous_frames += 1;
        }
        if let Some(c) = pipeline.contact() {
            self.contact_frames += 1;
            if self.largest_contact.is_none_or(|(_, r)| c.radius_px > r) {
                self.largest_contact = Some((frame, c.radius_px));
            }
        }
        let tracker = pipeline.tracker();
        if let Some(m) = decompose::median_magnitude(&MarkerField::interior_from_tracker(tracker))
            && self.largest.is_none_or(|(_, best)| m > best)
        {
            self.largest = Some((frame, m));
        }
        let (Some(truth), Some(ids)) = (&self.truth, &self.truth_ids) else {
            return;
        };
        let Some(exact) = truth.get(&frame) else {
            return;
        };
        for (k, &sim) in ids.iter().enumerate() {
            if tracker.states()[k] != MarkerState::Tracked {
                continue;
            }
            if let Some(e) = exact.get(sim) {
                let p = tracker.positions_px()[k];
                let d = (p[0] - e[0]).hypot(p[1] - e[1]);
                if d.is_finite() {
                    self.sq += d * d;
                    self.worst = self.worst.max(d);
                    self.compared += 1;
                }
            }
        }
    }
}
