//! `gelrig track`: marker tracking over image files or a run directory's frames.
//!
//! The I/O around [`analysis::tracking`] and [`analysis::field`]: decode PNG frames, run
//! the pipeline, write `markers.csv` row by row (flushed after every frame, so an
//! interrupted or failing run keeps what it tracked), and optionally a field folder with
//! pictures and the field's decomposition per frame. On a simulated run the simulator's
//! exact marker centres (`sim_markers.csv`) are read back and the tracking error reported.

use std::collections::HashMap;
use std::fs::{self, File};
use std::path::{Path, PathBuf};
use std::time::Instant;

use analysis::field::decompose::{self, ProfileBin};
use analysis::field::picture::{self, Quiver};
use analysis::field::{DenseGrid, Interpolator, MarkerField};
use analysis::tracking::{MarkerState, Method, Pipeline, RgbView, TrackError, TrackParams};
use serde::{Deserialize, Serialize};

/// What to track.
#[derive(Debug, Clone, PartialEq)]
pub enum Input {
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
}

impl Default for Options {
    fn default() -> Self {
        Self {
            method: Method::Centroid,
            field_dir: None,
            magnify: 3.0,
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
}

/// Why tracking stopped. `markers.csv` keeps every frame tracked before the failure.
#[derive(Debug, thiserror::Error)]
pub enum TrackFailure {
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
    /// An output could not be written.
    #[error("cannot write {path}: {detail}; fix: check that the folder exists and is writable")]
    Write {
        /// The output file.
        path: PathBuf,
        /// What went wrong.
        detail: String,
    },
}

fn write_err(path: &Path) -> impl Fn(String) -> TrackFailure + '_ {
    move |detail| TrackFailure::Write {
        path: path.to_path_buf(),
        detail,
    }
}

/// Largest image file read, bytes: a 4K GelSight frame is a few MB as PNG.
const MAX_IMAGE_BYTES: u64 = 256 << 20;
/// Largest image side decoded, pixels.
const MAX_IMAGE_SIDE: u32 = 16_384;

/// Decodes an image file to RGB8. Only a regular file of at most [`MAX_IMAGE_BYTES`] is
/// read (`gelrig track /dev/zero` used to read until memory ran out), and the decoder is
/// bounded in size and memory.
pub fn load_rgb(path: &Path) -> Result<(usize, usize, Vec<u8>), TrackFailure> {
    let read_err = |detail: String| TrackFailure::Read {
        path: path.to_path_buf(),
        detail,
    };
    let meta = fs::metadata(path).map_err(|e| read_err(e.to_string()))?;
    if !meta.is_file() {
        return Err(read_err("not a regular file".into()));
    }
    if meta.len() > MAX_IMAGE_BYTES {
        return Err(read_err(format!(
            "{} bytes, over the {MAX_IMAGE_BYTES} bytes an image may have",
            meta.len()
        )));
    }
    let bytes = fs::read(path).map_err(|e| read_err(e.to_string()))?;
    let decode_err = |detail: String| TrackFailure::Decode {
        path: path.to_path_buf(),
        detail,
    };
    let mut reader = image::ImageReader::new(std::io::Cursor::new(&bytes))
        .with_guessed_format()
        .map_err(|e| decode_err(e.to_string()))?;
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(MAX_IMAGE_SIDE);
    limits.max_image_height = Some(MAX_IMAGE_SIDE);
    limits.max_alloc = Some(2 << 30);
    reader.limits(limits);
    let img = reader.decode().map_err(|e| decode_err(e.to_string()))?;
    let rgb = img.to_rgb8();
    Ok((rgb.width() as usize, rgb.height() as usize, rgb.into_raw()))
}

/// One row of `frames.csv`.
#[derive(Debug, Deserialize)]
struct FrameEntry {
    frame: u64,
    step: u32,
    file: String,
}

/// One row of `markers.csv`.
#[derive(Debug, Serialize)]
struct MarkerRow {
    frame: u64,
    id: usize,
    x_px: f64,
    y_px: f64,
    dx_px: f64,
    dy_px: f64,
    state: &'static str,
    /// Confidence in the identity, 0–1 (0 when not measured).
    confidence: f64,
}

/// One row of `decomposition.csv` (NaN where a representative does not exist).
#[derive(Debug, Serialize)]
struct DecompositionRow {
    frame: u64,
    measured: usize,
    median_disp_px: f64,
    max_disp_px: f64,
    mean_dx_px: f64,
    mean_dy_px: f64,
    radiating_x_px: f64,
    radiating_y_px: f64,
    shear_direction_deg: f64,
    rotation_deg: f64,
    rotation_x_px: f64,
    rotation_y_px: f64,
}

#[derive(Debug, Serialize)]
struct ProfileRow {
    frame: u64,
    at_px: f64,
    mean_px: f64,
    spread_px: f64,
    count: usize,
}

fn r4(v: f64) -> f64 {
    (v * 1e4).round() / 1e4
}

/// The reference file, its frame number (when it is one of the input's frames), and the
/// frames to track as (frame number, file).
type FrameList = (PathBuf, Option<u64>, Vec<(u64, PathBuf)>);

fn frame_list(input: &Input) -> Result<FrameList, TrackFailure> {
    match input {
        Input::Files { reference, frames } => Ok((
            reference.clone(),
            Some(0),
            frames
                .iter()
                .enumerate()
                .map(|(k, p)| (k as u64 + 1, p.clone()))
                .collect(),
        )),
        Input::RunDir { dir, reference } => {
            let list = dir.join("frames.csv");
            let mut rd = csv::Reader::from_path(&list).map_err(|e| TrackFailure::RunDir {
                dir: dir.clone(),
                detail: format!(
                    "cannot read frames.csv ({e}); fix: track a run that captured frames, or \
                     pass --reference REF.png FRAME.png…"
                ),
            })?;
            let mut entries = Vec::new();
            for (line, row) in rd.deserialize::<FrameEntry>().enumerate() {
                let row = row.map_err(|e| TrackFailure::RunDir {
                    dir: dir.clone(),
                    detail: format!(
                        "frames.csv line {}: {e}; fix: restore the file from the run's backup",
                        line + 2
                    ),
                })?;
                entries.push(row);
            }
            if entries.is_empty() {
                return Err(TrackFailure::RunDir {
                    dir: dir.clone(),
                    detail: "frames.csv lists no frames; fix: track a run whose protocol \
                             captures frames"
                        .into(),
                });
            }
            entries.sort_by_key(|e| e.frame);
            let mut files = std::collections::HashMap::new();
            for e in &entries {
                let path = crate::record::run_file(dir, &e.file).map_err(|d| TrackFailure::RunDir {
                    dir: dir.clone(),
                    detail: format!(
                        "frames.csv, frame {}: {d}; fix: frames.csv must name files under frames/",
                        e.frame
                    ),
                })?;
                files.insert(e.frame, path);
            }
            let file = |e: &FrameEntry| files.get(&e.frame).cloned().unwrap_or_default();
            let list = match reference {
                Some(r) => (
                    r.clone(),
                    None,
                    entries.iter().map(|e| (e.frame, file(e))).collect(),
                ),
                None => {
                    let Some(first) = entries.iter().find(|e| e.step == 0) else {
                        return Err(TrackFailure::RunDir {
                            dir: dir.clone(),
                            detail: "no frame was captured before contact (step 0); fix: add \
                                     `reference_frames: 1` to the protocol's approach, or pass \
                                     --reference with an image of the untouched gel"
                                .into(),
                        });
                    };
                    (
                        file(first),
                        Some(first.frame),
                        entries
                            .iter()
                            .filter(|e| e.frame != first.frame)
                            .map(|e| (e.frame, file(e)))
                            .collect(),
                    )
                }
            };
            Ok(list)
        }
    }
}

/// The simulator's exact centres per frame, if the run has them.
fn sim_truth(input: &Input) -> Option<HashMap<u64, Vec<[f64; 2]>>> {
    let Input::RunDir { dir, .. } = input else {
        return None;
    };
    #[derive(Deserialize)]
    struct Row {
        frame: u64,
        id: usize,
        x_px: f64,
        y_px: f64,
    }
    let mut rd = csv::Reader::from_path(dir.join("sim_markers.csv")).ok()?;
    let mut out: HashMap<u64, Vec<[f64; 2]>> = HashMap::new();
    for row in rd.deserialize::<Row>() {
        let r = row.ok()?;
        let v = out.entry(r.frame).or_default();
        if v.len() <= r.id {
            v.resize(r.id + 1, [f64::NAN; 2]);
        }
        v[r.id] = [r.x_px, r.y_px];
    }
    Some(out)
}

/// Field outputs of one tracking run.
struct FieldWriter {
    dir: PathBuf,
    interpolator: Interpolator,
    quiver: Quiver,
    full_scale_px: f64,
    width: usize,
    height: usize,
    decomposition: csv::Writer<File>,
    radial: csv::Writer<File>,
    central: csv::Writer<File>,
}

impl FieldWriter {
    fn new(dir: &Path, pipeline: &Pipeline, magnify: f64) -> Result<Self, TrackFailure> {
        fs::create_dir_all(dir).map_err(|e| write_err(dir)(e.to_string()))?;
        let r = pipeline.reference();
        let (w, h) = (r.width(), r.height());
        let csv_at = |name: &str| {
            let p = dir.join(name);
            csv::Writer::from_path(&p).map_err(|e| write_err(&p)(e.to_string()))
        };
        Ok(Self {
            dir: dir.to_path_buf(),
            interpolator: Interpolator::new(
                pipeline.tracker().reference_px(),
                DenseGrid::over_frame(w, h, 1.0),
            ),
            quiver: Quiver {
                frame_px: (w, h),
                zoom: 2.0,
                magnify,
                spacing_px: r.spacing_px(),
            },
            // Full brightness at half a spacing: the colours of one run compare across frames.
            full_scale_px: 0.5 * r.spacing_px(),
            width: w,
            height: h,
            decomposition: csv_at("decomposition.csv")?,
            radial: csv_at("radial_profile.csv")?,
            central: csv_at("central_line.csv")?,
        })
    }

    fn frame(&mut self, frame: u64, pipeline: &Pipeline) -> Result<(), TrackFailure> {
        let tracker = pipeline.tracker();
        let field = MarkerField::interior_from_tracker(tracker);
        let dense = self.interpolator.interpolate(&field);
        let colours = picture::colour_image(&dense, self.full_scale_px);
        let (g, w, h) = (dense.grid, self.width, self.height);
        debug_assert_eq!((g.nx, g.ny), (w, h));
        let png = self.dir.join(format!("field_{frame:06}.png"));
        image::save_buffer(&png, &colours, w as u32, h as u32, image::ColorType::Rgb8)
            .map_err(|e| write_err(&png)(e.to_string()))?;
        let zoom = self.quiver.zoom as usize;
        let background = picture::upscale(&colours, w, h, zoom);
        let (qw, qh, quiver) = picture::quiver_rgb(&field, &self.quiver, Some(&background))
            .map_err(|e| write_err(&self.dir)(e.to_string()))?;
        let qpng = self.dir.join(format!("quiver_{frame:06}.png"));
        image::save_buffer(&qpng, &quiver, qw, qh, image::ColorType::Rgb8)
            .map_err(|e| write_err(&qpng)(e.to_string()))?;
        let svg = picture::quiver_svg(&field, &self.quiver)
            .map_err(|e| write_err(&self.dir)(e.to_string()))?;
        let qsvg = self.dir.join(format!("quiver_{frame:06}.svg"));
        fs::write(&qsvg, svg).map_err(|e| write_err(&qsvg)(e.to_string()))?;

        let sp = pipeline.reference().spacing_px();
        let mags: Vec<f64> = field
            .measured_ids()
            .map(|i| field.displacement_px[i][0].hypot(field.displacement_px[i][1]))
            .collect();
        let centre = decompose::radiating_centre(&field);
        let shear = decompose::shear(&field, None, 0.5 * sp, 0.5 * sp);
        let rotation = decompose::rotation(&field, None, 0.0);
        let nan2 = [f64::NAN; 2];
        let row = DecompositionRow {
            frame,
            measured: mags.len(),
            median_disp_px: r4(decompose::median_magnitude(&field).unwrap_or(f64::NAN)),
            max_disp_px: r4(mags.iter().copied().fold(0.0, f64::max)),
            mean_dx_px: r4(shear.as_ref().map(|s| s.mean_px[0]).unwrap_or(0.0)),
            mean_dy_px: r4(shear.as_ref().map(|s| s.mean_px[1]).unwrap_or(0.0)),
            radiating_x_px: r4(centre.unwrap_or(nan2)[0]),
            radiating_y_px: r4(centre.unwrap_or(nan2)[1]),
            shear_direction_deg: r4(shear
                .as_ref()
                .map(|s| s.direction_rad.to_degrees())
                .unwrap_or(f64::NAN)),
            rotation_deg: r4(rotation
                .map(|r| r.angle_rad.to_degrees())
                .unwrap_or(f64::NAN)),
            rotation_x_px: r4(rotation.and_then(|r| r.centre_px).unwrap_or(nan2)[0]),
            rotation_y_px: r4(rotation.and_then(|r| r.centre_px).unwrap_or(nan2)[1]),
        };
        let path = self.dir.join("decomposition.csv");
        self.decomposition
            .serialize(&row)
            .map_err(|e| write_err(&path)(e.to_string()))?;
        let profile_rows = |bins: &[ProfileBin]| {
            bins.iter()
                .map(|b| ProfileRow {
                    frame,
                    at_px: r4(b.at_px),
                    mean_px: r4(b.mean_px),
                    spread_px: r4(b.spread_px),
                    count: b.count,
                })
                .collect::<Vec<_>>()
        };
        if let Some(c) = centre {
            let path = self.dir.join("radial_profile.csv");
            for r in profile_rows(&decompose::radial_profile(&field, c, 0.5 * sp)) {
                self.radial
                    .serialize(r)
                    .map_err(|e| write_err(&path)(e.to_string()))?;
            }
        }
        if let Some(s) = &shear {
            let path = self.dir.join("central_line.csv");
            for r in profile_rows(&s.central_line) {
                self.central
                    .serialize(r)
                    .map_err(|e| write_err(&path)(e.to_string()))?;
            }
        }
        for (w, name) in [
            (&mut self.decomposition, "decomposition.csv"),
            (&mut self.radial, "radial_profile.csv"),
            (&mut self.central, "central_line.csv"),
        ] {
            w.flush()
                .map_err(|e| write_err(&self.dir.join(name))(e.to_string()))?;
        }
        Ok(())
    }
}

/// Tracks the input and writes `markers.csv` to `out` (and the field folder if asked).
pub fn track(input: &Input, out: &Path, opts: &Options) -> Result<Summary, TrackFailure> {
    let (reference_path, reference_frame_no, frames) = frame_list(input)?;
    let (w, h, rgb) = load_rgb(&reference_path)?;
    let view = RgbView::new(w, h, &rgb).map_err(|source| TrackFailure::Reference {
        path: reference_path.clone(),
        source,
    })?;
    let mut pipeline =
        Pipeline::new(view, &TrackParams::default(), opts.method).map_err(|source| {
            TrackFailure::Reference {
                path: reference_path.clone(),
                source,
            }
        })?;
    if let Some(parent) = out.parent().filter(|p| !p.as_os_str().is_empty()) {
        fs::create_dir_all(parent).map_err(|e| write_err(parent)(e.to_string()))?;
    }
    let mut csv_out = csv::Writer::from_path(out).map_err(|e| write_err(out)(e.to_string()))?;
    let mut field = match &opts.field_dir {
        Some(d) => Some(FieldWriter::new(d, &pipeline, opts.magnify)?),
        None => None,
    };
    let truth = sim_truth(input);
    // Tracker id → simulator id, by the nearest centre on the reference frame.
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

    let mut counts: HashMap<&'static str, usize> = HashMap::new();
    let mut times = Vec::with_capacity(frames.len());
    let (mut largest, mut sq, mut worst, mut compared) = (None::<(u64, f64)>, 0.0, 0.0f64, 0);
    let mut write_frame = |frame: u64,
                           pipeline: &Pipeline,
                           counts: &mut HashMap<&'static str, usize>,
                           count: bool|
     -> Result<(), TrackFailure> {
        let t = pipeline.tracker();
        for id in 0..t.len() {
            let p = t.positions_px()[id];
            let d = t.displacement_px(id);
            let state = t.states()[id];
            if count {
                *counts.entry(state.as_str()).or_default() += 1;
            }
            csv_out
                .serialize(MarkerRow {
                    frame,
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
        csv_out.flush().map_err(|e| write_err(out)(e.to_string()))
    };
    if let Some(no) = reference_frame_no {
        write_frame(no, &pipeline, &mut counts, false)?;
        if let Some(f) = field.as_mut() {
            f.frame(no, &pipeline)?;
        }
    }
    for (frame, path) in &frames {
        let (fw, fh, rgb) = load_rgb(path)?;
        let view = RgbView::new(fw, fh, &rgb).map_err(|source| TrackFailure::Frame {
            path: path.clone(),
            source,
        })?;
        let t0 = Instant::now();
        pipeline.track(view).map_err(|source| TrackFailure::Frame {
            path: path.clone(),
            source,
        })?;
        times.push(t0.elapsed().as_secs_f64() * 1e3);
        write_frame(*frame, &pipeline, &mut counts, true)?;
        if let Some(f) = field.as_mut() {
            f.frame(*frame, &pipeline)?;
        }
        let tracker = pipeline.tracker();
        if let Some(m) = decompose::median_magnitude(&MarkerField::interior_from_tracker(tracker))
            && largest.is_none_or(|(_, best)| m > best)
        {
            largest = Some((*frame, m));
        }
        if let (Some(truth), Some(ids)) = (&truth, &truth_ids)
            && let Some(exact) = truth.get(frame)
        {
            for (k, &sim) in ids.iter().enumerate() {
                if tracker.states()[k] != MarkerState::Tracked {
                    continue;
                }
                if let Some(e) = exact.get(sim) {
                    let p = tracker.positions_px()[k];
                    let d = (p[0] - e[0]).hypot(p[1] - e[1]);
                    if d.is_finite() {
                        sq += d * d;
                        worst = worst.max(d);
                        compared += 1;
                    }
                }
            }
        }
    }
    times.sort_by(f64::total_cmp);
    let order = [
        "tracked",
        "border",
        "merged",
        "predicted",
        "out_of_view",
        "lost",
    ];
    Ok(Summary {
        frames: frames.len() + usize::from(reference_frame_no.is_some()),
        markers: pipeline.tracker().len(),
        spacing_px: pipeline.reference().spacing_px(),
        states: order
            .iter()
            .map(|s| (*s, counts.get(s).copied().unwrap_or(0)))
            .collect(),
        median_ms_per_frame: times.get(times.len() / 2).copied().unwrap_or(0.0),
        largest,
        truth: (compared > 0).then(|| ((sq / compared as f64).sqrt(), worst, compared)),
        markers_csv: out.to_path_buf(),
    })
}
