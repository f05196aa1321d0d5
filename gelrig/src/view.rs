//! What the live view's server shows: the run under way (`gelrig run --live`), or finished
//! runs read from their directories (`gelrig view`). A finished run is read into the same
//! board the runner writes while it runs, so both are one page.

use std::collections::HashMap;
use std::path::{Component, Path, PathBuf};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::SystemTime;

use liveview::{Board, CurvePoint, Library, RunEntry, RunMeta, Tactile};

use sensing::run_data::{ForceRow, FrameRow, RunDirError, StepRow, TactileCsvRow, read_optional};

/// The board's meta of a run about to start on `clock`.
pub fn live_meta(
    loaded: &experiments::load::Loaded,
    plan: &experiments::plan::Plan,
    clock: rig::ClockMode,
) -> RunMeta {
    let s = &loaded.protocol.safety;
    RunMeta {
        dir: String::new(),
        protocol: loaded.protocol.name.clone(),
        rig: loaded.rig.name.clone(),
        steps_planned: loaded.compiled.steps,
        eta_s: plan.duration_s.max,
        time_scale: runner::time_scale(clock),
        max_fz_n: s.max_fz.n(),
        max_fxy_n: s.max_fxy.n(),
        max_tz_nmm: s.max_tz.nmm(),
        live: true,
    }
}

/// The run under way: one entry, `live` (in a queue, each run in turn).
pub struct LiveRun {
    board: Mutex<Arc<Board>>,
}

impl LiveRun {
    /// Shows `board`.
    pub fn new(board: Arc<Board>) -> Self {
        Self {
            board: Mutex::new(board),
        }
    }

    /// Shows `board` from now on (the queue's next run).
    pub fn set(&self, board: Arc<Board>) {
        *self.board.lock().unwrap_or_else(PoisonError::into_inner) = board;
    }

    fn current(&self) -> Arc<Board> {
        self.board
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .clone()
    }
}

impl Library for LiveRun {
    fn runs(&self) -> Vec<RunEntry> {
        let s = self.current().snapshot();
        vec![RunEntry {
            id: "live".into(),
            protocol: s.meta.protocol,
            status: s.status,
            started: String::new(),
            steps: format!("{}/{}", s.steps_done, s.meta.steps_planned),
            has_report: false,
        }]
    }

    fn only(&self) -> Option<String> {
        Some("live".into())
    }

    fn board(&self, id: &str) -> Result<Arc<Board>, String> {
        match id {
            "live" => Ok(self.current()),
            _ => Err(format!(
                "no run `{id}` here: this page shows the run under way"
            )),
        }
    }

    fn report(&self, _id: &str) -> Result<PathBuf, String> {
        Err(
            "the report is made once the run has ended: `gelrig report RUN_DIR`, or \
             `gelrig view RUN_DIR` to see it here"
                .into(),
        )
    }
}

/// Finished runs in a runs directory, or one run directory.
pub struct RunsOnDisk {
    root: PathBuf,
    /// `root` is itself a run directory.
    single: bool,
    boards: Mutex<HashMap<String, (SystemTime, Arc<Board>)>>,
}

impl RunsOnDisk {
    /// Runs under `path` (a runs directory), or `path` itself when it is a run directory.
    pub fn open(path: &Path) -> Result<Self, String> {
        if !path.is_dir() {
            return Err(format!(
                "{}: not a directory; fix: give a runs directory (e.g. `runs`) or one run directory",
                path.display()
            ));
        }
        let single = path.join(rundir::names::MANIFEST).is_file();
        if !single && rundir::listing::list(path)?.is_empty() {
            return Err(format!(
                "{}: no run directory in it (a run directory holds run.yaml); fix: give the \
                 folder `gelrig run --out` wrote to",
                path.display()
            ));
        }
        Ok(Self {
            root: path.to_path_buf(),
            single,
            boards: Mutex::new(HashMap::new()),
        })
    }

    /// The run directory of `id` (a plain name, one of the listed runs).
    fn dir_of(&self, id: &str) -> Result<PathBuf, String> {
        let name = self
            .root
            .file_name()
            .map(|n| n.to_string_lossy().to_string());
        if self.single {
            return match name {
                Some(n) if n == id => Ok(self.root.clone()),
                _ => Err(format!("no run `{id}` here")),
            };
        }
        let mut parts = Path::new(id).components();
        match (parts.next(), parts.next()) {
            (Some(Component::Normal(_)), None)
                if self.root.join(id).join(rundir::names::MANIFEST).is_file() =>
            {
                Ok(self.root.join(id))
            }
            _ => Err(format!("no run `{id}` in {}", self.root.display())),
        }
    }
}

impl Library for RunsOnDisk {
    fn runs(&self) -> Vec<RunEntry> {
        let listed = if self.single {
            self.root
                .parent()
                .map(|p| rundir::listing::list(p).unwrap_or_default())
                .unwrap_or_default()
                .into_iter()
                .filter(|r| r.dir.file_name() == self.root.file_name())
                .collect()
        } else {
            rundir::listing::list(&self.root).unwrap_or_default()
        };
        listed
            .into_iter()
            .map(|r| RunEntry {
                id: r
                    .dir
                    .file_name()
                    .map(|n| n.to_string_lossy().to_string())
                    .unwrap_or_default(),
                has_report: r.dir.join("report").join("report.html").is_file(),
                protocol: r.protocol,
                status: r.status,
                started: r.started.get(..19).unwrap_or(&r.started).replace('T', " "),
                steps: r.steps,
            })
            .collect()
    }

    fn only(&self) -> Option<String> {
        self.single
            .then(|| self.root.file_name())
            .flatten()
            .map(|n| n.to_string_lossy().to_string())
    }

    fn board(&self, id: &str) -> Result<Arc<Board>, String> {
        let dir = self.dir_of(id)?;
        let stamp = |f: &str| {
            std::fs::metadata(dir.join(f))
                .and_then(|m| m.modified())
                .unwrap_or(SystemTime::UNIX_EPOCH)
        };
        // A run still writing shows its newest rows: read again when its files changed.
        let changed = stamp(rundir::names::MANIFEST)
            .max(stamp(rundir::names::STEPS))
            .max(stamp(rundir::names::FORCE));
        let mut boards = self.boards.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some((at, b)) = boards.get(id)
            && *at == changed
        {
            return Ok(b.clone());
        }
        let board = read_board(&dir).map_err(|e| e.to_string())?;
        boards.insert(id.to_string(), (changed, board.clone()));
        Ok(board)
    }

    fn report(&self, id: &str) -> Result<PathBuf, String> {
        let dir = self.dir_of(id)?;
        let out = dir.join("report");
        if out.join("report.html").is_file() {
            return Ok(out);
        }
        if rundir::write::is_locked(&dir) {
            return Err(format!(
                "{id} is still running: its report is made once it has ended"
            ));
        }
        // As `gelrig report RUN_DIR` would: the report goes beside the run's data.
        report::report_with_sensor(&dir, None, None)
            .map(|w| w.dir)
            .map_err(|e| format!("making the report of {id}: {e}"))
    }
}

/// A finished (or interrupted) run read into a board: its force, steps, first and last
/// frames, and last tactile state.
pub fn read_board(dir: &Path) -> Result<Arc<Board>, RunDirError> {
    let manifest = rundir::write::read_manifest(dir).map_err(|detail| RunDirError::Missing {
        path: dir.join(rundir::names::MANIFEST),
        detail,
    })?;
    let protocol: Option<experiments::protocol::schema::Protocol> =
        std::fs::read_to_string(dir.join(rundir::names::PROTOCOL))
            .ok()
            .and_then(|t| serde_yaml::from_str(&t).ok());
    let limit = |f: fn(&experiments::protocol::schema::Safety) -> f64| {
        protocol.as_ref().map_or(f64::NAN, |p| f(&p.safety))
    };
    let board = Board::new(RunMeta {
        dir: dir.display().to_string(),
        protocol: manifest.protocol.clone(),
        rig: manifest.rig.clone(),
        steps_planned: manifest.steps_planned,
        eta_s: manifest.eta_s[1],
        time_scale: None,
        max_fz_n: limit(|s| s.max_fz.n()),
        max_fxy_n: limit(|s| s.max_fxy.n()),
        max_tz_nmm: limit(|s| s.max_tz.nmm()),
        live: false,
    });
    for f in read_optional::<ForceRow>(&dir.join(rundir::names::FORCE))?.unwrap_or_default() {
        board.force(f.t_ns, [f.fx_n, f.fy_n, f.fz_n, f.tz_nmm]);
    }
    let steps = sensing::run_data::read_csv::<StepRow>(&dir.join(rundir::names::STEPS))?;
    for s in &steps {
        let point = CurvePoint {
            step: s.step,
            label: s.label.clone(),
            axis: s.axis.clone(),
            position: s.position.unwrap_or(f64::NAN),
            unit: s.unit.clone(),
            wrench: [s.fx_n, s.fy_n, s.fz_n, s.tz_nmm],
        };
        board.step_done(
            point,
            s.trial,
            s.t_start_ns,
            s.t_end_ns.max(s.settle_end_ns),
        );
    }
    let frames = read_optional::<FrameRow>(&dir.join(rundir::names::FRAMES))?.unwrap_or_default();
    // The counter's usual step between recorded frames: a stream's stride (captures at the
    // steps' ends are far apart, and count as pauses).
    let stride = median_step(frames.iter().filter_map(|f| f.seq));
    for (k, f) in frames.iter().enumerate() {
        let image = (k == 0 || k + 1 == frames.len())
            .then(|| image::open(dir.join(rundir::names::frame_png(f.frame))).ok())
            .flatten()
            .map(|i| i.to_rgb8());
        let seq = (f.seq.unwrap_or(f.frame), stride);
        match image {
            Some(i) => board.frame(f.frame, f.t_ns, seq, i.dimensions(), i.as_raw()),
            None => board.frame_seen(f.t_ns, seq),
        }
    }
    if let Some(t) = read_optional::<TactileCsvRow>(&dir.join(rundir::names::TACTILE))?
        .unwrap_or_default()
        .last()
    {
        board.tactile(Tactile {
            state: t.state.clone(),
            gripping: t.gripping,
            stuck_fraction: t.stuck_fraction,
            t_s: t.t_ns as f64 * 1e-9,
            gelsight_fz_n: t.gelsight_fz_n,
        });
    }
    let status = rundir::listing::effective_status(dir, manifest.status);
    for w in &manifest.warnings {
        board.note(&format!("warning: {w}"));
    }
    board.note(&format!(
        "recorded run: {} of {} steps, {} frames",
        manifest.steps_completed,
        manifest.steps_planned,
        frames.len()
    ));
    board.finished(
        status,
        manifest.reason.as_deref().or(manifest.error.as_deref()),
    );
    Ok(board)
}

/// The usual step of a counter: the median difference between neighbours (`None` for
/// fewer than four values).
fn median_step(values: impl Iterator<Item = u64>) -> Option<u64> {
    let v: Vec<u64> = values.collect();
    let mut d: Vec<u64> = v.windows(2).map(|w| w[1].saturating_sub(w[0])).collect();
    if d.len() < 3 {
        return None;
    }
    d.sort_unstable();
    Some(d[d.len() / 2]).filter(|d| *d > 0)
}
