//! [`RunData`]: everything a report or a calibration reads from a run (its tables read by
//! the `rundir` crate), reading it — tracking its frames first when `markers.csv` is missing
//! — and the marker field of a frame. `report` and `sensor` both read runs through here;
//! neither reads the other's files.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

pub use rundir::read::{
    ContactRow, DepthRow, ForceRow, FrameRow, MarkerRow, RunDirError, SimRow, StepRow,
    TactileCsvRow, read_csv, read_optional, read_tactile,
};
use tracking::field::MarkerField;

/// Everything read from a run directory.
#[derive(Debug, Clone)]
pub struct RunData {
    pub dir: PathBuf,
    pub protocol_name: String,
    /// `run.yaml`: how the run went.
    pub manifest: rundir::write::Manifest,
    pub steps: Vec<StepRow>,
    pub force: Vec<ForceRow>,
    pub sim: Option<Vec<SimRow>>,
    pub frames: Vec<FrameRow>,
    /// Markers by frame number.
    pub markers: BTreeMap<u64, Vec<MarkerRow>>,
    /// Frame size, px, when frames exist.
    pub frame_size: Option<(usize, usize)>,
    /// The contact region per frame (`contact.csv`), when frames exist.
    pub contact: Vec<ContactRow>,
    /// The contact read from depth per frame (`depth.csv`, `gelrig track --shape`).
    pub depth: Vec<DepthRow>,
    /// The live tactile state per frame (`tactile.csv`), when the run tracked frames live.
    pub tactile: Vec<TactileCsvRow>,
}

impl RunData {
    /// The last frame of `step`: taken at the end of its settle, like its force window.
    pub fn last_frame_of(&self, step: u32) -> Option<u64> {
        self.frames
            .iter()
            .filter(|f| f.step == step)
            .map(|f| f.frame)
            .max()
    }
}

/// The run's protocol, loaded against its own rig file; `Err` says why it does not load.
pub fn run_protocol(dir: &Path) -> Result<experiments::load::Loaded, String> {
    experiments::load::load(
        &dir.join(rundir::names::PROTOCOL),
        Some(&dir.join(rundir::names::RIG)),
    )
    .map_err(|d| {
        format!(
            "its protocol.yaml does not load ({})",
            d.first().map(|d| d.to_string()).unwrap_or_default()
        )
    })
}

/// Reads the run, tracking its frames into `markers.csv` first if that is missing.
pub fn read_run(dir: &Path) -> Result<RunData, RunDirError> {
    read(dir, true)
}

/// Reads the run's tables without its markers — no tracking, for a reader of forces and
/// steps only (`fit-material`).
pub fn read_run_tables(dir: &Path) -> Result<RunData, RunDirError> {
    read(dir, false)
}

fn read(dir: &Path, with_markers: bool) -> Result<RunData, RunDirError> {
    if !dir.is_dir() {
        return Err(RunDirError::Missing {
            path: dir.to_path_buf(),
            detail: "not a directory".into(),
        });
    }
    let manifest = rundir::write::read_manifest(dir).map_err(|detail| RunDirError::Missing {
        path: dir.join(rundir::names::MANIFEST),
        detail,
    })?;
    // A resumed run is read as one: each step's rows from the segment that completed it.
    let segments = |steps: &[StepRow]| {
        rundir::resumed::Segments::new(
            &manifest,
            steps.iter().map(|r| (r.step, r.trial, r.t_end_ns)),
        )
    };
    let all_steps: Vec<StepRow> = read_csv(&dir.join(rundir::names::STEPS))?;
    // Segments are told from every step row, the abandoned attempts' included (a trial's
    // segment is that of its last row); the run's steps are the last row of each.
    let seg = segments(&all_steps);
    let steps = rundir::resumed::Segments::last_per_step(all_steps, |r| r.step);
    let mut force: Vec<ForceRow> =
        read_optional(&dir.join(rundir::names::FORCE))?.unwrap_or_default();
    let sim = read_optional::<SimRow>(&dir.join(rundir::names::SIM_STEPS))?
        .map(|rows| rundir::resumed::Segments::last_per_step(rows, |r| r.step));
    let mut frames: Vec<FrameRow> =
        read_optional(&dir.join(rundir::names::FRAMES))?.unwrap_or_default();
    let mut tactile = read_tactile(dir)?;
    if seg.resumed() {
        force.retain(|r| seg.keeps(r.step, r.trial, r.t_ns));
        frames.retain(|r| seg.keeps(r.step, r.trial, r.t_ns));
        tactile.retain(|r| seg.keeps(r.step, r.trial, r.t_ns));
    }
    let mut markers = BTreeMap::new();
    let mut frame_size = None;
    let mut contact = Vec::new();
    let mut depth = Vec::new();
    if with_markers && frames.len() > 1 {
        let path = dir.join(rundir::names::MARKERS);
        if !path.is_file() || !dir.join(rundir::names::CONTACT).is_file() {
            track_into_place(dir)?;
        }
        for m in read_csv::<MarkerRow>(&path)? {
            markers.entry(m.frame).or_insert_with(Vec::new).push(m);
        }
        frame_size = first_frame_size(dir);
        contact = read_optional(&dir.join(rundir::names::CONTACT))?.unwrap_or_default();
        depth = read_optional(&dir.join(rundir::names::DEPTH))?.unwrap_or_default();
    }
    Ok(RunData {
        dir: dir.to_path_buf(),
        protocol_name: manifest.protocol.clone(),
        manifest,
        steps,
        force,
        sim,
        frames,
        markers,
        frame_size,
        contact,
        depth,
        tactile,
    })
}

/// Tracks the run's frames into `markers.csv` and `contact.csv`: written in a folder of this
/// call's own and renamed into place when complete, so a second report or calibration
/// reading the same run meanwhile never sees a half-written table.
fn track_into_place(dir: &Path) -> Result<(), RunDirError> {
    let work = dir.join(work_folder_name());
    let err = |path: PathBuf, detail: String| RunDirError::Missing { path, detail };
    std::fs::create_dir_all(&work).map_err(|e| err(work.clone(), e.to_string()))?;
    let markers = work.join(rundir::names::MARKERS);
    let tracked = crate::track::track(
        &crate::track::Input::RunDir {
            dir: dir.to_path_buf(),
            reference: None,
        },
        &markers,
        &crate::track::Options::default(),
    )
    .map_err(|e| {
        err(
            dir.join(rundir::names::MARKERS),
            format!("tracking the run's frames failed: {e}"),
        )
    });
    let placed = tracked.and_then(|_| {
        for name in [rundir::names::CONTACT, rundir::names::MARKERS] {
            std::fs::rename(work.join(name), dir.join(name))
                .map_err(|e| err(dir.join(name), e.to_string()))?;
        }
        Ok(())
    });
    let _ = std::fs::remove_dir_all(&work);
    placed
}

/// A work folder's name no other call shares: the process and a count within it. The
/// process alone was not enough: two threads of one process (a Python user's pool, two tests)
/// tracking the same run at once wrote into one folder, and the first to finish removed the
/// other's half-written tables.
fn work_folder_name() -> String {
    static CALLS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let n = CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    format!(".tracking-{}-{n}", std::process::id())
}

fn first_frame_size(dir: &Path) -> Option<(usize, usize)> {
    let rows: Vec<BTreeMap<String, String>> = read_csv(&dir.join(rundir::names::FRAMES)).ok()?;
    let file = rows.first()?.get("file")?;
    let (w, h) = image::image_dimensions(rundir::write::run_file(dir, file).ok()?).ok()?;
    Some((w as usize, h as usize))
}

/// The interior marker field of a frame.
pub fn frame_field(data: &RunData, frame: u64) -> Option<MarkerField> {
    Some(field_of_rows(data.markers.get(&frame)?))
}

/// The marker field of one frame's rows of `markers.csv`, by marker identity.
pub fn field_of_rows(rows: &[MarkerRow]) -> MarkerField {
    let mut sorted: Vec<&MarkerRow> = rows.iter().collect();
    sorted.sort_by_key(|m| m.id);
    MarkerField {
        reference_px: sorted
            .iter()
            .map(|m| [m.x_px - m.dx_px, m.y_px - m.dy_px])
            .collect(),
        displacement_px: sorted.iter().map(|m| [m.dx_px, m.dy_px]).collect(),
        measured: sorted
            .iter()
            .map(|m| m.state == "tracked" || m.state == "merged")
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn two_calls_of_one_process_track_in_two_folders() {
        let names: Vec<String> = std::thread::scope(|s| {
            let a = s.spawn(super::work_folder_name);
            let b = s.spawn(super::work_folder_name);
            [a, b].map(|h| h.join().unwrap_or_default()).to_vec()
        });
        let pid = format!(".tracking-{}-", std::process::id());
        assert!(names.iter().all(|n| n.starts_with(&pid)), "{names:?}");
        assert_ne!(names[0], names[1]);
    }
}
