//! `gelrig track`.

use crate::cli::Exit;
use std::path::{Path, PathBuf};

use crate::track::Method;
use crate::track::recorded::{
    Input, Options, ShapeReading, Summary, TrackFailure, step_last_frames, track,
};

/// Track GelSight markers: positions, displacements and states per frame.
#[derive(clap::Args)]
pub(crate) struct Cmd {
    /// Frames to track (PNG), in order — or one run directory.
    #[arg(required = true, value_name = "FRAME.png… | RUN_DIR")]
    inputs: Vec<PathBuf>,
    /// Image of the untouched gel (frame 0). A run directory uses its first frame taken
    /// before contact unless this is given.
    #[arg(long, value_name = "REF.png")]
    reference: Option<PathBuf>,
    /// Where to write markers.csv [default: markers.csv; for a run: RUN_DIR/markers.csv].
    #[arg(long, value_name = "FILE")]
    out: Option<PathBuf>,
    /// Also write field pictures (colour-vector PNG, quiver PNG and SVG) and decomposition
    /// tables per frame into this folder.
    #[arg(long, value_name = "DIR")]
    field: Option<PathBuf>,
    /// Position estimate: centroid, lk (weighted Lucas–Kanade) or centroid+lk.
    #[arg(long, default_value = "centroid")]
    method: Method,
    /// Arrow length per pixel of displacement in quiver plots.
    #[arg(long, default_value_t = 3.0)]
    magnify: f64,
    /// No image of the untouched gel: fit the undeformed marker lattice to the periphery of
    /// the first frame (grid markers, centroid method) and track from there.
    #[arg(long, conflicts_with = "reference")]
    reference_free: bool,
    /// Only detect the markers of each frame on its own (no reference, no identities);
    /// writes detections.csv (frame,id,x_px,y_px,area_px,border).
    #[arg(long, conflicts_with_all = ["reference", "reference_free", "field"])]
    detect_only: bool,
    /// Do not find the contact region (no contact.csv).
    #[arg(long)]
    no_contact: bool,
    /// Image scale for contact.csv's mm columns [default: a run directory's own scale].
    #[arg(long, value_name = "MM", allow_negative_numbers = true)]
    mm_per_px: Option<f64>,
    /// Smallest colour change (relative intensity) that can be contact. The default suits
    /// a camera with fixed exposure; a GelSight Mini's automatic exposure drifts by up to
    /// 0.16 on an untouched gel, so pass 0.2 for it.
    #[arg(
        long,
        value_name = "CHANGE",
        default_value_t = 0.015,
        allow_negative_numbers = true
    )]
    contact_min_change: f64,
    /// Threads decoding frames ahead of the tracker, at most 16 [default: one per core].
    #[arg(long, value_name = "N", default_value_t = 0)]
    decoders: usize,
    /// A calibrated sensor file (`gelrig calibrate`): also read force and torque from the
    /// field of every frame into wrench.csv beside markers.csv.
    #[arg(long, value_name = "SENSOR.yaml", conflicts_with = "detect_only")]
    sensor: Option<PathBuf>,
    /// Write traction-map pictures (`traction_NNNNNN.svg`) and their integrals per frame
    /// (`traction.csv`) into this folder: calibrated with a `--sensor` of the traction
    /// method, else at a nominal modulus (needs --thickness-mm and an image scale).
    #[arg(long, value_name = "DIR", conflicts_with = "detect_only")]
    traction: Option<PathBuf>,
    /// A shape calibration (`gelrig shape calibrate`): also read each frame's height map and
    /// write the contact by depth (deepest point, area deeper than 0.03 mm, centroid,
    /// volume) to depth.csv beside markers.csv; on a run directory, also the height maps of
    /// each step's last frame to RUN_DIR/depth/, which the report shows.
    #[arg(long, value_name = "SHAPE.yaml", conflicts_with_all = ["detect_only", "reference_free"])]
    shape: Option<PathBuf>,
    /// The elastomer's thickness for uncalibrated traction maps, mm.
    #[arg(long, value_name = "MM", allow_negative_numbers = true)]
    thickness_mm: Option<f64>,
}

impl Cmd {
    pub(crate) fn run(self) -> anyhow::Result<Exit> {
        let run_dir = match self.inputs.as_slice() {
            [one] if one.is_dir() => Some(one.clone()),
            _ => None,
        };
        if (self.detect_only || self.reference_free) && run_dir.is_some() {
            err!(
                "error: --detect-only and --reference-free take image files; fix: pass the PNG \
                 frames (for a run: RUN_DIR/frames/*.png)"
            );
            return Ok(Exit::from(super::EXIT_INVALID));
        }
        if self.detect_only {
            return self.detect();
        }
        let Some((input, default_out)) = self.input(run_dir) else {
            return Ok(Exit::from(super::EXIT_INVALID));
        };
        let out = self.out.clone().unwrap_or(default_out);
        let sensor = match self.sensor.as_deref().map(crate::force::SensorFile::read) {
            Some(Ok(s)) => Some(s),
            Some(Err(e)) => {
                err!("error: {e}");
                return Ok(Exit::from(super::EXIT_INVALID));
            }
            None => None,
        };
        if !self.numbers_ok(sensor.is_some()) {
            return Ok(Exit::from(super::EXIT_INVALID));
        }
        let shape = match self.shape.as_deref().map(crate::shape::ShapeFile::read) {
            Some(Ok(f)) => Some(f),
            Some(Err(e)) => {
                err!("error: {e}");
                return Ok(Exit::from(super::EXIT_INVALID));
            }
            None => None,
        };
        let times = match &input {
            Input::RunDir { dir, .. } => crate::force::frame_times(dir),
            _ => Default::default(),
        };
        let opts = Options {
            method: self.method,
            field_dir: self.field.clone(),
            magnify: self.magnify,
            contact: !self.no_contact,
            mm_per_px: self.mm_per_px,
            decoders: self.decoders,
            contact_params: crate::track::ContactParams {
                min_change: self.contact_min_change,
                ..Default::default()
            },
            shape: shape
                .as_ref()
                .zip(self.shape.as_ref())
                .map(|(f, path)| ShapeReading {
                    model: f.model(None),
                    size_px: (f.width_px, f.height_px),
                    mm_per_px: f.mm_per_px,
                    path: path.clone(),
                }),
        };
        let summary = match track(&input, &out, &opts) {
            Ok(s) => s,
            Err(e @ TrackFailure::Write { .. }) => return Err(e.into()),
            Err(e) => {
                err!("error: {e}");
                return Ok(Exit::from(super::EXIT_INVALID));
            }
        };
        self.print_summary(&summary);
        if let (Some(file), Input::RunDir { dir, .. }) = (&shape, &input)
            && let Some(code) = depth_pictures(file, dir, &summary)?
        {
            return Ok(code);
        }
        if let Some(sensor) = &sensor
            && let Some(code) = read_force(sensor, &summary, &times)?
        {
            return Ok(code);
        }
        if let Some(dir) = &self.traction
            && let Some(code) = self.write_traction(dir, sensor.as_ref(), &summary, &times)?
        {
            return Ok(code);
        }
        if let Some(dir) = &self.field {
            out!(
                "wrote field pictures and decomposition tables to {}",
                dir.display()
            );
        }
        Ok(Exit::SUCCESS)
    }

    /// `--detect-only`: every marker of single frames, no identities.
    fn detect(&self) -> anyhow::Result<Exit> {
        let out = self
            .out
            .clone()
            .unwrap_or_else(|| PathBuf::from("detections.csv"));
        match crate::track::recorded::detect_only(&self.inputs, &out) {
            Ok(d) => {
                out!(
                    "detected {}–{} markers per frame in {} frames (median spacing {:.1} px)",
                    d.per_frame.0,
                    d.per_frame.1,
                    d.frames,
                    d.spacing_px
                );
                out!("wrote {}", d.csv.display());
                Ok(Exit::SUCCESS)
            }
            Err(e @ TrackFailure::Write { .. }) => Err(e.into()),
            Err(e) => {
                err!("error: {e}");
                Ok(Exit::from(super::EXIT_INVALID))
            }
        }
    }

    /// What to track and where `markers.csv` goes by default; `None` (said on stderr) when
    /// nothing says where the untouched gel is.
    fn input(&self, run_dir: Option<PathBuf>) -> Option<(Input, PathBuf)> {
        let reference = if self.reference_free {
            None
        } else {
            self.reference.clone()
        };
        Some(match (run_dir, reference) {
            (Some(dir), reference) => (
                Input::RunDir {
                    dir: dir.clone(),
                    reference,
                },
                dir.join(crate::runs::names::MARKERS),
            ),
            (None, Some(reference)) => (
                Input::Files {
                    reference,
                    frames: self.inputs.clone(),
                },
                PathBuf::from(crate::runs::names::MARKERS),
            ),
            (None, None) if self.reference_free => (
                Input::ReferenceFree {
                    frames: self.inputs.clone(),
                },
                PathBuf::from(crate::runs::names::MARKERS),
            ),
            (None, None) => {
                err!(
                    "error: no reference frame; fix: pass --reference REF.png (an image of the \
                     untouched gel) before the frames, --reference-free for a recording that \
                     starts in contact (grid markers), or give one run directory"
                );
                return None;
            }
        })
    }

    /// Whether the numbers given are numbers of their kind (said on stderr where not); an
    /// uncalibrated traction map needs the gel's thickness.
    fn numbers_ok(&self, has_sensor: bool) -> bool {
        if self.traction.is_some() && !has_sensor {
            match self.thickness_mm {
                Some(h) if h.is_finite() && h > 0.0 => {}
                _ => {
                    err!(
                        "error: --traction without a traction-map --sensor needs the gel's \
                         thickness; fix: pass --thickness-mm H (and --mm-per-px for image files)"
                    );
                    return false;
                }
            }
        }
        if !(self.contact_min_change.is_finite() && self.contact_min_change >= 0.0) {
            err!(
                "error: --contact-min-change {} is not a change; fix: pass a number ≥ 0 (0.015 \
                 for a fixed-exposure camera, 0.2 for a GelSight Mini)",
                self.contact_min_change
            );
            return false;
        }
        if let Some(s) = self.mm_per_px
            && !(s.is_finite() && s > 0.0)
        {
            err!(
                "error: --mm-per-px {s} is not a scale; fix: pass a positive number of mm per pixel"
            );
            return false;
        }
        true
    }

    /// What the tracking found, on stdout (warnings on stderr).
    fn print_summary(&self, summary: &Summary) {
        for w in &summary.warnings {
            err!("warning: {w}");
        }
        out!(
            "tracked {} frames, {} markers (spacing {:.1} px), method {}",
            summary.frames,
            summary.markers,
            summary.spacing_px,
            self.method.as_str()
        );
        let states: Vec<String> = summary
            .states
            .iter()
            .filter(|(_, n)| *n > 0)
            .map(|(s, n)| format!("{s} {n}"))
            .collect();
        if let Some(l) = &summary.lattice {
            out!(
                "reference-free start: lattice of spacing {:.2} px at {:.2}°, fitted to {} of {} \
                 markers (rms {:.3} px); frame 0's displacements are from it",
                l.spacing_px(),
                l.a_px[1].atan2(l.a_px[0]).to_degrees(),
                l.inliers,
                l.detections,
                l.rms_px
            );
        }
        out!("marker states after the reference: {}", states.join(", "));
        if summary.ambiguous_frames > 0 {
            out!(
                "{} frame(s) ambiguous: two placements of the markers explained them (and every \
                 frame since the last certain one) equally well, so their identities were \
                 withheld (`ambiguous`) until the frame told them apart",
                summary.ambiguous_frames
            );
        }
        out!(
            "median {:.3} ms per frame (detection + identity{})",
            summary.median_ms_per_frame,
            if self.method == Method::Centroid {
                ""
            } else {
                " + LK"
            }
        );
        if let Some((frame, disp)) = summary.largest {
            out!("largest deformation: frame {frame}, median displacement {disp:.2} px");
        }
        if let Some((rms, worst, n)) = summary.truth {
            out!(
                "against the simulator's exact centres: rms {rms:.4} px, worst {worst:.3} px \
                 ({n} tracked positions)"
            );
        }
        if let Some(path) = &summary.depth_csv {
            out!(
                "wrote {} (the contact read from depth, per frame)",
                path.display()
            );
        }
        if let Some(path) = &summary.contact_csv {
            match summary.largest_contact {
                Some((frame, r_px)) => out!(
                    "contact in {} frames; largest at frame {frame}: equivalent radius {r_px:.1} px{}",
                    summary.contact_frames,
                    summary
                        .mm_per_px
                        .map(|s| format!(" = {:.3} mm", r_px * s))
                        .unwrap_or_default()
                ),
                None => out!("no contact region in any frame"),
            }
            out!("wrote {}", path.display());
        }
        out!(
            "wall time {:.2} s ({:.2} ms per frame, decoding and writing included)",
            summary.wall_s,
            1e3 * summary.wall_s / summary.frames.max(1) as f64
        );
        out!("wrote {}", summary.markers_csv.display());
    }

    /// `--traction DIR`: the traction maps of the frames with contact; `Some` exit code where
    /// it cannot.
    fn write_traction(
        &self,
        dir: &Path,
        sensor: Option<&crate::force::SensorFile>,
        summary: &Summary,
        times: &std::collections::BTreeMap<u64, (u64, u32)>,
    ) -> anyhow::Result<Option<Exit>> {
        let frames = match crate::force::frames_of_markers(&summary.markers_csv, times) {
            Ok(f) => f,
            Err(e) => {
                err!("error: {e}");
                return Ok(Some(Exit::from(super::EXIT_INVALID)));
            }
        };
        let source = match (sensor, self.thickness_mm, summary.mm_per_px) {
            (Some(s), _, _) => crate::force::maps::MapSource::Sensor(s),
            (None, Some(h), Some(s)) => crate::force::maps::MapSource::Nominal {
                thickness_mm: h,
                mm_per_px: s,
            },
            (None, _, _) => {
                err!(
                    "error: --traction needs the image scale; fix: pass --mm-per-px S (a run \
                     directory has its own)"
                );
                return Ok(Some(Exit::from(super::EXIT_INVALID)));
            }
        };
        match crate::force::maps::write_maps(&source, &frames, dir) {
            Ok(rows) => {
                let unit = if rows.first().is_some_and(|r| r.calibrated) {
                    "N"
                } else {
                    "nominal units (modulus 1 MPa: shape and time course only)"
                };
                if let Some(peak) = rows.iter().max_by(|a, b| a.fz.abs().total_cmp(&b.fz.abs())) {
                    out!(
                        "traction maps of {} frames with contact; largest Fz {:.4} {unit} at frame {}",
                        rows.len(),
                        peak.fz,
                        peak.frame
                    );
                }
                out!("wrote {}", dir.join("traction.csv").display());
            }
            Err(e @ crate::force::SensorError::Write { .. }) => return Err(e.into()),
            Err(e) => {
                err!("error: {e}");
                return Ok(Some(Exit::from(super::EXIT_INVALID)));
            }
        }
        Ok(None)
    }
}

/// `--sensor`: the wrench of every frame into `wrench.csv` beside `markers.csv`, with how
/// many frames were outside the calibration; `Some` exit code where it cannot.
fn read_force(
    sensor: &crate::force::SensorFile,
    summary: &Summary,
    times: &std::collections::BTreeMap<u64, (u64, u32)>,
) -> anyhow::Result<Option<Exit>> {
    let rows = match crate::force::wrench_of_markers(sensor, &summary.markers_csv, times) {
        Ok(r) => r,
        Err(e @ crate::force::SensorError::Write { .. }) => return Err(e.into()),
        Err(e) => {
            err!("error: {e}");
            return Ok(Some(Exit::from(super::EXIT_INVALID)));
        }
    };
    let path = summary
        .markers_csv
        .with_file_name(crate::runs::names::WRENCH);
    crate::force::write_wrench_csv(&rows, &path)?;
    if let Some(peak) = rows
        .iter()
        .max_by(|a, b| a.fz_n.abs().total_cmp(&b.fz_n.abs()))
    {
        out!(
            "force from the field ({} frames): largest |Fz| {:.3} ± {:.3} N at frame {}",
            rows.len(),
            peak.fz_n,
            peak.fz_sd_n,
            peak.frame
        );
    }
    let outside: Vec<&crate::force::WrenchRow> = rows
        .iter()
        .filter(|r| !r.outside_calibration.is_empty())
        .collect();
    if !outside.is_empty() {
        let mut why: Vec<&str> = outside
            .iter()
            .flat_map(|r| r.outside_calibration.split(';'))
            .collect();
        why.sort_unstable();
        why.dedup();
        out!(
            "{} of {} frames outside the calibration ({}): their uncertainties are \
         widened by what the calibration measured on shapes it never saw \
         (`outside_calibration` in wrench.csv)",
            outside.len(),
            rows.len(),
            why.join(", ")
        );
    }
    out!("wrote {}", path.display());
    Ok(None)
}

/// `--shape` on a run directory: the height maps of each step's last frame in
/// `RUN_DIR/depth/` (with their `shape.csv`), for the report; `Some` exit code where it
/// cannot.
fn depth_pictures(
    file: &crate::shape::ShapeFile,
    dir: &Path,
    summary: &Summary,
) -> anyhow::Result<Option<Exit>> {
    let steps = match step_last_frames(dir) {
        Ok(s) => s,
        Err(e) => {
            err!("error: {e}");
            return Ok(Some(Exit::from(super::EXIT_INVALID)));
        }
    };
    let frames: Vec<PathBuf> = steps.into_iter().map(|(_, f)| f).collect();
    let out = dir.join(crate::runs::names::DEPTH_DIR);
    match crate::shape::write_height_maps(file, None, &summary.reference_png, &frames, &out, false)
    {
        Ok(rows) => {
            out!(
                "wrote the height maps of {} steps' last frames to {} (the report shows them)",
                rows.len(),
                out.display()
            );
            Ok(None)
        }
        Err(e @ crate::shape::ShapeFileError::Write { .. }) => Err(e.into()),
        Err(e) => {
            err!("error: {e}");
            Ok(Some(Exit::from(super::EXIT_INVALID)))
        }
    }
}
