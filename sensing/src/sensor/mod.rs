//! The GelSight as a force sensor: `gelrig calibrate` learns the map from the marker field
//! to the wrench on runs with frames and a force sensor and writes it as a sensor file
//! ([`file`]); `gelrig track --sensor` and `gelrig report --sensor` read the wrench from the
//! field of any run with it ([`wrench`]). The numbers are [`analysis::force_sensor`]'s.

pub mod calibrate;
mod choose;
pub mod envelope;
pub mod file;
mod fitting;
mod gather;
pub mod history;
pub mod live;
pub mod maps;
pub mod reader;
pub mod scale;
pub mod wrench;

use std::path::{Path, PathBuf};

use tracking::field::MarkerField;

use crate::run_data::{ForceRow, RunData};

pub use calibrate::calibrate;
pub use file::{SensorFile, SensorFileError};
pub use wrench::{WrenchRow, frames_of_markers, read_wrench, wrench_of_markers, write_wrench_csv};

/// Why the GelSight's force could not be calibrated or read.
#[derive(Debug, thiserror::Error)]
pub enum SensorError {
    /// A run could not be read.
    #[error(transparent)]
    Run(#[from] crate::run_data::RunDirError),
    /// A run lacks what calibration or reading needs.
    #[error("{path}: {detail}; fix: {fix}")]
    Unfit {
        /// The run directory.
        path: PathBuf,
        /// What it lacks.
        detail: String,
        /// What to do.
        fix: &'static str,
    },
    /// The marker layout or the model refused the data.
    #[error("{path}: {source}")]
    Model {
        /// The run (or sensor file) concerned.
        path: PathBuf,
        /// The analysis crate's reason.
        source: analysis::force_sensor::SensorError,
    },
    /// The sensor file.
    #[error(transparent)]
    File(#[from] SensorFileError),
    /// Writing an output failed.
    #[error("cannot write {path}: {detail}; fix: check the folder exists and is writable")]
    Write {
        /// The output.
        path: PathBuf,
        /// What went wrong.
        detail: String,
    },
}

/// One frame of a run: its number, time and field.
pub struct RunFrame {
    pub frame: u64,
    pub t_ns: u64,
    /// The step it was taken in (0 where unknown).
    pub step: u32,
    /// The image's contact region, if found.
    pub contact: Option<history::Region>,
    pub field: MarkerField,
}

/// The frames of a run directory with their fields and contact regions (tracked first if
/// it has no `markers.csv`).
pub fn load_frames(run_dir: &Path) -> Result<Vec<RunFrame>, SensorError> {
    Ok(run_frames(&crate::run_data::read_run(run_dir)?))
}

/// The frames of a run with their fields (frame 0, the reference, first).
pub fn run_frames(data: &RunData) -> Vec<RunFrame> {
    data.frames
        .iter()
        .filter_map(|f| {
            Some(RunFrame {
                frame: f.frame,
                t_ns: f.t_ns,
                step: f.step,
                contact: contact_of(&data.contact, f.frame),
                field: crate::run_data::frame_field(data, f.frame)?,
            })
        })
        .collect()
}

/// The contact region of `frame` in `contact.csv` rows.
pub fn contact_of(rows: &[crate::run_data::ContactRow], frame: u64) -> Option<history::Region> {
    rows.iter()
        .find(|r| r.frame == frame && r.radius_px > 0.0)
        .and_then(|r| {
            let centroid_px = [r.cx_px?, r.cy_px?];
            // A region that does not measure (an edited or damaged file) is no region: its
            // support would have no end.
            let finite = centroid_px.iter().all(|v| v.is_finite()) && r.radius_px.is_finite();
            finite.then_some(history::Region {
                centroid_px,
                radius_px: r.radius_px,
                second_moments_px2: match (r.sxx_px2, r.syy_px2, r.sxy_px2) {
                    (Some(a), Some(b), Some(c))
                        if a.is_finite()
                            && b.is_finite()
                            && c.is_finite()
                            && a >= 0.0
                            && b >= 0.0 =>
                    {
                        Some([a, b, c])
                    }
                    _ => None,
                },
            })
        })
}

/// The force sensor's wrench when a frame of `step` was taken at `t_ns`: for a frame
/// captured at the end of a settled step (within 0.1 s of its settle end), the step's
/// force-window mean (the quasistatic value the frame shows, with a tenth of a single
/// sample's noise over a 10 s window); else [`wrench_at`].
pub fn reference_at(data: &RunData, step: u32, t_ns: u64) -> Option<[f64; 4]> {
    reference_in(&data.force, &data.steps, step, t_ns)
}

/// [`reference_at`] over a force record and step table of one's own (the calibration's
/// elastic force).
pub fn reference_in(
    force: &[ForceRow],
    steps: &[crate::run_data::StepRow],
    step: u32,
    t_ns: u64,
) -> Option<[f64; 4]> {
    let captured = steps.iter().find(|s| {
        s.step == step
            && step > 0
            && s.force_window_s > 0.0
            && s.settle_end_ns.abs_diff(t_ns) <= 100_000_000
    });
    match captured {
        Some(s) => Some([s.fx_n, s.fy_n, s.fz_n, s.tz_nmm]),
        None => wrench_at(force, t_ns),
    }
}

/// The force sensor's wrench (Fx, Fy, Fz, Tz) at `t_ns`: the mean of the samples within
/// 60 ms (a frame's exposure against 20–1000 Hz force), else the nearest within 250 ms.
pub fn wrench_at(force: &[ForceRow], t_ns: u64) -> Option<[f64; 4]> {
    let i = force.partition_point(|r| r.t_ns < t_ns);
    let near = |r: &&ForceRow| r.t_ns.abs_diff(t_ns) <= 60_000_000;
    let lo = force[..i].iter().rev().take_while(near).count();
    let hi = force[i..].iter().take_while(near).count();
    let window = &force[i - lo..i + hi];
    if !window.is_empty() {
        let n = window.len() as f64;
        let mean = |f: fn(&ForceRow) -> f64| window.iter().map(f).sum::<f64>() / n;
        return Some([
            mean(|r| r.fx_n),
            mean(|r| r.fy_n),
            mean(|r| r.fz_n),
            mean(|r| r.tz_nmm),
        ]);
    }
    [i.checked_sub(1), Some(i)]
        .into_iter()
        .flatten()
        .filter_map(|k| force.get(k))
        .filter(|r| r.t_ns.abs_diff(t_ns) <= 250_000_000)
        .min_by_key(|r| r.t_ns.abs_diff(t_ns))
        .map(|r| [r.fx_n, r.fy_n, r.fz_n, r.tz_nmm])
}

/// Frame number → (time, step) of a run directory's frames (empty when it has none).
pub fn frame_times(run_dir: &Path) -> std::collections::BTreeMap<u64, (u64, u32)> {
    crate::run_data::read_csv::<crate::run_data::FrameRow>(&run_dir.join(rundir::names::FRAMES))
        .map(|rows| {
            rows.into_iter()
                .map(|r| (r.frame, (r.t_ns, r.step)))
                .collect()
        })
        .unwrap_or_default()
}

/// The image scale of a run (its sensor's view over its frames), mm/px.
pub fn run_mm_per_px(data: &RunData) -> Option<f64> {
    let (w, h) = data.frame_size?;
    crate::track::run_scale(&data.dir, w, h)
}

fn unfit(dir: &Path, detail: impl Into<String>, fix: &'static str) -> SensorError {
    SensorError::Unfit {
        path: dir.to_path_buf(),
        detail: detail.into(),
        fix,
    }
}

#[cfg(test)]
mod tests {
    use super::contact_of;

    /// A `contact.csv` written before the moment columns reads as discs; a damaged one (an
    /// infinite or negative moment, an infinite radius) does not give a region whose
    /// support has no end.
    #[test]
    fn contact_rows_old_and_damaged() {
        let dir = tempfile::tempdir().expect("a temporary directory");
        let old = dir.path().join("old.csv");
        std::fs::write(
            &old,
            "frame,area_px2,area_mm2,cx_px,cy_px,radius_mm,radius_px\n\
             0,0.0,0.0,,,0.0,0.0\n\
             1,5026.5,4.9,320.0,240.0,1.25,40.0\n",
        )
        .expect("written");
        let rows: Vec<crate::run_data::ContactRow> =
            crate::run_data::read_csv(&old).expect("an old contact.csv reads");
        assert_eq!(contact_of(&rows, 0), None, "no contact in frame 0");
        let r = contact_of(&rows, 1).expect("a region");
        assert_eq!((r.centroid_px, r.radius_px), ([320.0, 240.0], 40.0));
        assert_eq!(r.second_moments_px2, None, "an old file's region is a disc");
        let new = dir.path().join("new.csv");
        std::fs::write(
            &new,
            "frame,area_px2,area_mm2,cx_px,cy_px,radius_mm,radius_px,sxx_px2,syy_px2,sxy_px2\n\
             1,5026.5,4.9,320.0,240.0,1.25,40.0,900.0,300.0,10.0\n\
             2,5026.5,4.9,320.0,240.0,1.25,40.0,inf,300.0,10.0\n\
             3,5026.5,4.9,320.0,240.0,1.25,40.0,-5.0,300.0,10.0\n\
             4,5026.5,4.9,320.0,240.0,1.25,inf,400.0,400.0,0.0\n",
        )
        .expect("written");
        let rows: Vec<crate::run_data::ContactRow> =
            crate::run_data::read_csv(&new).expect("a new contact.csv reads");
        let m = |f: u64| contact_of(&rows, f).and_then(|r| r.second_moments_px2);
        assert_eq!(m(1), Some([900.0, 300.0, 10.0]));
        assert_eq!(m(2), None, "an infinite moment is dropped");
        assert_eq!(m(3), None, "a negative one too");
        assert_eq!(
            contact_of(&rows, 4),
            None,
            "an infinite radius is no region"
        );
    }
}
