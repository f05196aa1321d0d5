//! The run directory: everything a run measured, safe against crashes.
//!
//! Orchestration users' most common complaint is data lost when a run crashes or is
//! interrupted (orchestration spec, complaint 1). So every row is written through to the
//! OS as it is recorded, every step row and journal line is also fsynced, `run.yaml` is
//! replaced atomically (write, fsync, rename), and the directory holds `run.lock`, locked
//! for the life of the process: a run whose manifest says `running` but whose lock is free
//! was killed, and `gelrig runs` shows it as `interrupted`.
//!
//! Layout (ARCHITECTURE.md): `protocol.yaml` (resolved, as run), `rig.yaml`, `run.yaml`,
//! `journal.jsonl`, `steps.csv`, and — only for streams the protocol records —
//! `force.csv`, `axes.csv`, `frames.csv` with `frames/*.png`.

use std::collections::BTreeMap;
use std::fs::{self, File, OpenOptions};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use rig::{ForceSample, Frame, SimTruth, Wrench};
use serde::{Deserialize, Serialize};

/// Failure to record.
#[derive(Debug, thiserror::Error)]
pub enum RecordError {
    /// A file could not be written.
    #[error("cannot write {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// A CSV row could not be written.
    #[error("cannot write {path}: {source}")]
    Csv {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: csv::Error,
    },
    /// A frame could not be encoded.
    #[error("cannot write frame {path}: {detail}")]
    Frame {
        /// The file.
        path: PathBuf,
        /// Why.
        detail: String,
    },
}

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> RecordError + '_ {
    move |source| RecordError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// Run status as written in `run.yaml`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    /// In progress (or killed, if the lock is free).
    Running,
    /// Finished every step.
    Completed,
    /// Stopped by the operator or a safety limit; motion stopped and retracted.
    Aborted,
    /// Stopped by an error (device, disk).
    Failed,
}

impl Status {
    /// Lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            Status::Running => "running",
            Status::Completed => "completed",
            Status::Aborted => "aborted",
            Status::Failed => "failed",
        }
    }
}

/// A device as recorded in the manifest.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DeviceRecord {
    /// Role.
    pub role: String,
    /// Identity.
    pub identity: String,
}

/// `run.yaml`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    /// Run status.
    pub status: Status,
    /// Why the run was aborted.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
    /// The error that failed the run.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
    /// Protocol name.
    pub protocol: String,
    /// Protocol file as given.
    pub protocol_file: String,
    /// Rig name.
    pub rig: String,
    /// Rig file as given.
    pub rig_file: String,
    /// Start, RFC 3339 UTC.
    pub started_utc: String,
    /// End, RFC 3339 UTC.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ended_utc: Option<String>,
    /// gelrig version.
    pub gelrig_version: String,
    /// Seed of the simulated devices.
    pub seed: u64,
    /// `virtual`, `scaled ×k` or `monotonic`.
    pub clock: String,
    /// Process id of the run.
    pub pid: u32,
    /// Steps the plan has.
    pub steps_planned: u32,
    /// Steps completed and on disk.
    pub steps_completed: u32,
    /// Planned duration, [min, max] s.
    pub eta_s: [f64; 2],
    /// Devices opened.
    #[serde(default)]
    pub devices: Vec<DeviceRecord>,
    /// Tare offsets subtracted from every sample: fx, fy, fz (N), tx, ty, tz (N·mm).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tare: Option<[f64; 6]>,
    /// Axis origins (contact points), absolute, in the axis unit.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub origins: BTreeMap<String, f64>,
    /// Absolute axis positions at the end.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub final_positions: BTreeMap<String, f64>,
    /// Safety events (limit trips).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub safety_events: Vec<String>,
    /// Warnings from validation and the run.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
}

/// One row of `steps.csv`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StepRow {
    /// Step number.
    pub step: u32,
    /// Trial.
    pub trial: u32,
    /// Label.
    pub label: String,
    /// load, unload, move, hold, capture, disturb.
    pub phase: String,
    /// Axis moved, or empty.
    pub axis: String,
    /// Target relative to the axis origin, axis unit (empty without a move).
    pub target: Option<f64>,
    /// Position relative to the axis origin at the end of the step.
    pub position: Option<f64>,
    /// mm or deg.
    pub unit: String,
    /// Quasistatic (window-mean) force and torque.
    pub fx_n: Option<f64>,
    /// See `fx_n`.
    pub fy_n: Option<f64>,
    /// See `fx_n`.
    pub fz_n: Option<f64>,
    /// See `fx_n`.
    pub tx_nmm: Option<f64>,
    /// See `fx_n`.
    pub ty_nmm: Option<f64>,
    /// See `fx_n`.
    pub tz_nmm: Option<f64>,
    /// Time waited after the move, s.
    pub settle_s: f64,
    /// fixed, converged, timeout or none.
    pub settle_verdict: String,
    /// Averaging window, s.
    pub force_window_s: f64,
    /// Samples in the window.
    pub window_samples: u32,
    /// Standard deviation of the signal along the axis over the window.
    pub window_std: Option<f64>,
    /// Whether any sample in the step was saturated.
    pub saturated: bool,
    /// Frames captured.
    pub frames: u32,
    /// Absolute position at the end.
    pub position_abs: Option<f64>,
    /// Step start, ns.
    pub t_start_ns: u64,
    /// End of the settle, which is the end of the force window, ns.
    pub settle_end_ns: u64,
    /// Step end (after any frames), ns.
    pub t_end_ns: u64,
}

impl StepRow {
    fn example() -> Self {
        Self {
            step: 0,
            trial: 0,
            label: String::new(),
            phase: String::new(),
            axis: String::new(),
            target: None,
            position: None,
            unit: String::new(),
            fx_n: None,
            fy_n: None,
            fz_n: None,
            tx_nmm: None,
            ty_nmm: None,
            tz_nmm: None,
            settle_s: 0.0,
            settle_verdict: String::new(),
            force_window_s: 0.0,
            window_samples: 0,
            window_std: None,
            saturated: false,
            frames: 0,
            position_abs: None,
            t_start_ns: 0,
            settle_end_ns: 0,
            t_end_ns: 0,
        }
    }
}

fn round6(v: f64) -> f64 {
    (v * 1e6).round() / 1e6
}

#[derive(Serialize)]
struct ForceRow {
    t_ns: u64,
    step: u32,
    trial: u32,
    fx_n: f64,
    fy_n: f64,
    fz_n: f64,
    tx_nmm: f64,
    ty_nmm: f64,
    tz_nmm: f64,
    ft_seq: u64,
    status: u32,
}

#[derive(Serialize)]
struct AxesRow<'a> {
    t_ns: u64,
    axis: &'a str,
    target: Option<f64>,
    position: f64,
}

#[derive(Serialize)]
struct MarkerTruthRow {
    frame: u64,
    id: usize,
    x_px: f64,
    y_px: f64,
}

#[derive(Serialize)]
struct SimStepRow {
    step: u32,
    trial: u32,
    depth_mm: f64,
    fx_n: f64,
    fy_n: f64,
    fz_n: f64,
    tz_nmm: f64,
    fx_eq_n: f64,
    fz_eq_n: f64,
    tz_eq_nmm: f64,
    contact_radius_mm: f64,
    shear_stick_fraction: Option<f64>,
    twist_stick_fraction: Option<f64>,
    shear_slips: u32,
    twist_slips: u32,
    object_slips: u32,
}

#[derive(Serialize)]
struct FrameRow<'a> {
    frame: u64,
    t_ns: u64,
    step: u32,
    trial: u32,
    file: &'a str,
    seq: u64,
}

struct Csv {
    path: PathBuf,
    w: csv::Writer<File>,
}

impl Csv {
    fn create(path: PathBuf) -> Result<Self, RecordError> {
        let f = File::create(&path).map_err(io(&path))?;
        Ok(Self {
            w: csv::Writer::from_writer(f),
            path,
        })
    }

    /// A writer whose header comes from `example`'s field names and is on disk at once.
    fn with_header_of<T: Serialize>(path: PathBuf, example: &T) -> Result<Self, RecordError> {
        let mut probe = csv::Writer::from_writer(Vec::new());
        let csv_err = |source| RecordError::Csv {
            path: path.clone(),
            source,
        };
        probe.serialize(example).map_err(csv_err)?;
        let bytes = probe.into_inner().map_err(|e| RecordError::Io {
            path: path.clone(),
            source: std::io::Error::other(e.to_string()),
        })?;
        let header_len = bytes
            .iter()
            .position(|&b| b == b'\n')
            .map(|i| i + 1)
            .unwrap_or(bytes.len());
        let mut f = File::create(&path).map_err(io(&path))?;
        f.write_all(&bytes[..header_len]).map_err(io(&path))?;
        f.sync_data().map_err(io(&path))?;
        Ok(Self {
            w: csv::WriterBuilder::new().has_headers(false).from_writer(f),
            path,
        })
    }

    /// Writes one row through to the OS.
    fn row<T: Serialize>(&mut self, row: &T) -> Result<(), RecordError> {
        self.w.serialize(row).map_err(|source| RecordError::Csv {
            path: self.path.clone(),
            source,
        })?;
        self.w.flush().map_err(io(&self.path))
    }

    fn sync(&mut self) -> Result<(), RecordError> {
        self.w.flush().map_err(io(&self.path))?;
        self.w.get_ref().sync_data().map_err(io(&self.path))
    }
}

/// Writes one run directory.
pub struct Recorder {
    dir: PathBuf,
    manifest: Manifest,
    journal: BufWriter<File>,
    journal_path: PathBuf,
    steps: Csv,
    force: Option<Csv>,
    axes: Option<Csv>,
    frames: Option<Csv>,
    sim_steps: Option<Csv>,
    sim_markers: Option<Csv>,
    frame_count: u64,
    _lock: File,
}

/// `<UTC time>_<name>` made safe for a file name.
fn dir_name(name: &str) -> String {
    let stamp = jiff::Timestamp::now()
        .strftime("%Y%m%dT%H%M%SZ")
        .to_string();
    let safe: String = name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '-'
            }
        })
        .collect();
    format!("{stamp}_{safe}")
}

/// Writes `contents` to `path` atomically: temp file, fsync, rename, fsync the directory.
pub fn write_atomic(path: &Path, contents: &[u8]) -> Result<(), RecordError> {
    let tmp = path.with_extension("tmp");
    {
        let mut f = File::create(&tmp).map_err(io(&tmp))?;
        f.write_all(contents).map_err(io(&tmp))?;
        f.sync_all().map_err(io(&tmp))?;
    }
    fs::rename(&tmp, path).map_err(io(path))?;
    if let Some(dir) = path.parent()
        && let Ok(d) = File::open(dir)
    {
        let _ = d.sync_all();
    }
    Ok(())
}

impl Recorder {
    /// Creates a new run directory under `out` and writes its first files.
    pub fn create(
        out: &Path,
        manifest: Manifest,
        protocol_yaml: &str,
        rig_yaml: &str,
    ) -> Result<Self, RecordError> {
        fs::create_dir_all(out).map_err(io(out))?;
        let base = dir_name(&manifest.protocol);
        let mut dir = out.join(&base);
        let mut n = 1;
        loop {
            match fs::create_dir(&dir) {
                Ok(()) => break,
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
                    n += 1;
                    dir = out.join(format!("{base}-{n}"));
                }
                Err(e) => return Err(io(&dir)(e)),
            }
        }
        let lock_path = dir.join("run.lock");
        let lock = OpenOptions::new()
            .create(true)
            .truncate(false)
            .write(true)
            .open(&lock_path)
            .map_err(io(&lock_path))?;
        lock.try_lock().map_err(|e| RecordError::Io {
            path: lock_path.clone(),
            source: std::io::Error::other(e.to_string()),
        })?;
        let p = dir.join("protocol.yaml");
        fs::write(&p, protocol_yaml).map_err(io(&p))?;
        let p = dir.join("rig.yaml");
        fs::write(&p, rig_yaml).map_err(io(&p))?;
        let journal_path = dir.join("journal.jsonl");
        let journal = BufWriter::new(File::create(&journal_path).map_err(io(&journal_path))?);
        // The header is written up front, so even a run with no step has a readable file.
        let steps = Csv::with_header_of(dir.join("steps.csv"), &StepRow::example())?;
        let mut rec = Self {
            dir,
            manifest,
            journal,
            journal_path,
            steps,
            force: None,
            axes: None,
            frames: None,
            sim_steps: None,
            sim_markers: None,
            frame_count: 0,
            _lock: lock,
        };
        rec.write_manifest()?;
        Ok(rec)
    }

    /// The run directory.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The manifest as it stands.
    pub fn manifest(&self) -> &Manifest {
        &self.manifest
    }

    /// Changes the manifest and rewrites `run.yaml` atomically.
    pub fn update_manifest(&mut self, f: impl FnOnce(&mut Manifest)) -> Result<(), RecordError> {
        f(&mut self.manifest);
        self.write_manifest()
    }

    fn write_manifest(&mut self) -> Result<(), RecordError> {
        let path = self.dir.join("run.yaml");
        let text = serde_yaml::to_string(&self.manifest).map_err(|e| RecordError::Io {
            path: path.clone(),
            source: std::io::Error::other(e.to_string()),
        })?;
        write_atomic(&path, text.as_bytes())
    }

    /// Appends an event to `journal.jsonl`; `durable` also fsyncs it.
    pub fn journal(
        &mut self,
        t_ns: u64,
        event: &str,
        fields: serde_json::Value,
        durable: bool,
    ) -> Result<(), RecordError> {
        let mut line = serde_json::json!({ "t_ns": t_ns, "event": event });
        if let (Some(obj), serde_json::Value::Object(extra)) = (line.as_object_mut(), fields) {
            obj.extend(extra);
        }
        let p = self.journal_path.clone();
        writeln!(self.journal, "{line}").map_err(io(&p))?;
        self.journal.flush().map_err(io(&p))?;
        if durable {
            self.journal.get_ref().sync_data().map_err(io(&p))?;
        }
        Ok(())
    }

    /// Appends a force sample (already tared) to `force.csv`.
    pub fn force(
        &mut self,
        s: &ForceSample,
        tared: &Wrench,
        step: u32,
        trial: u32,
    ) -> Result<(), RecordError> {
        if self.force.is_none() {
            self.force = Some(Csv::create(self.dir.join("force.csv"))?);
        }
        let row = ForceRow {
            t_ns: s.t_ns,
            step,
            trial,
            fx_n: round6(tared.fx_n),
            fy_n: round6(tared.fy_n),
            fz_n: round6(tared.fz_n),
            tx_nmm: round6(tared.tx_nmm),
            ty_nmm: round6(tared.ty_nmm),
            tz_nmm: round6(tared.tz_nmm),
            ft_seq: s.ft_seq,
            status: s.status,
        };
        match &mut self.force {
            Some(w) => w.row(&row),
            None => Ok(()),
        }
    }

    /// Appends an axis position to `axes.csv`.
    pub fn axis(
        &mut self,
        t_ns: u64,
        axis: &str,
        target: Option<f64>,
        position: f64,
    ) -> Result<(), RecordError> {
        if self.axes.is_none() {
            self.axes = Some(Csv::create(self.dir.join("axes.csv"))?);
        }
        let row = AxesRow {
            t_ns,
            axis,
            target: target.map(round6),
            position: round6(position),
        };
        match &mut self.axes {
            Some(w) => w.row(&row),
            None => Ok(()),
        }
    }

    /// Writes a frame to `frames/NNNNNN.png` and a row to `frames.csv`; returns the frame
    /// number.
    pub fn frame(&mut self, frame: &Frame, step: u32, trial: u32) -> Result<u64, RecordError> {
        if self.frames.is_none() {
            let d = self.dir.join("frames");
            fs::create_dir_all(&d).map_err(io(&d))?;
            self.frames = Some(Csv::create(self.dir.join("frames.csv"))?);
        }
        let n = self.frame_count;
        let file = format!("frames/{n:06}.png");
        let path = self.dir.join(&file);
        let img = image::RgbImage::from_raw(frame.width, frame.height, frame.rgb.clone())
            .ok_or_else(|| RecordError::Frame {
                path: path.clone(),
                detail: format!(
                    "{} bytes do not make a {}×{} RGB image",
                    frame.rgb.len(),
                    frame.width,
                    frame.height
                ),
            })?;
        img.save_with_format(&path, image::ImageFormat::Png)
            .map_err(|e| RecordError::Frame {
                path: path.clone(),
                detail: e.to_string(),
            })?;
        let row = FrameRow {
            frame: n,
            t_ns: frame.t_ns,
            step,
            trial,
            file: &file,
            seq: frame.seq,
        };
        if let Some(w) = &mut self.frames {
            w.row(&row)?;
        }
        if let Some(truth) = &frame.truth_px {
            if self.sim_markers.is_none() {
                self.sim_markers = Some(Csv::create(self.dir.join("sim_markers.csv"))?);
            }
            if let Some(w) = &mut self.sim_markers {
                for (id, [x, y]) in truth.iter().enumerate() {
                    w.row(&MarkerTruthRow {
                        frame: n,
                        id,
                        x_px: round6(*x),
                        y_px: round6(*y),
                    })?;
                }
            }
        }
        self.frame_count += 1;
        Ok(n)
    }

    /// Appends the simulator's ground truth at the end of a step to `sim_steps.csv`.
    pub fn sim_truth(&mut self, step: u32, trial: u32, t: &SimTruth) -> Result<(), RecordError> {
        if self.sim_steps.is_none() {
            self.sim_steps = Some(Csv::create(self.dir.join("sim_steps.csv"))?);
        }
        let row = SimStepRow {
            step,
            trial,
            depth_mm: round6(t.depth_mm),
            fx_n: round6(t.wrench.fx_n),
            fy_n: round6(t.wrench.fy_n),
            fz_n: round6(t.wrench.fz_n),
            tz_nmm: round6(t.wrench.tz_nmm),
            fx_eq_n: round6(t.equilibrium.fx_n),
            fz_eq_n: round6(t.equilibrium.fz_n),
            tz_eq_nmm: round6(t.equilibrium.tz_nmm),
            contact_radius_mm: round6(t.contact_radius_mm),
            shear_stick_fraction: t.shear_stick_fraction.map(round6),
            twist_stick_fraction: t.twist_stick_fraction.map(round6),
            shear_slips: t.shear_slips,
            twist_slips: t.twist_slips,
            object_slips: t.object_slips,
        };
        match &mut self.sim_steps {
            Some(w) => {
                w.row(&row)?;
                w.sync()
            }
            None => Ok(()),
        }
    }

    /// Appends a step row and makes it, and everything recorded before it, durable.
    pub fn step(&mut self, row: &StepRow) -> Result<(), RecordError> {
        self.steps.row(row)?;
        self.steps.sync()?;
        for w in [&mut self.force, &mut self.axes, &mut self.frames]
            .into_iter()
            .flatten()
        {
            w.sync()?;
        }
        self.manifest.steps_completed = self.manifest.steps_completed.max(row.step);
        Ok(())
    }

    /// Frames written so far.
    pub fn frames_written(&self) -> u64 {
        self.frame_count
    }
}

/// Reads a run directory's manifest.
pub fn read_manifest(dir: &Path) -> Result<Manifest, String> {
    let path = dir.join("run.yaml");
    let text =
        fs::read_to_string(&path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
    serde_yaml::from_str(&text).map_err(|e| format!("cannot parse {}: {e}", path.display()))
}

/// True if a process still holds the run's lock (the run is really in progress).
pub fn is_locked(dir: &Path) -> bool {
    match OpenOptions::new().write(true).open(dir.join("run.lock")) {
        Ok(f) => f.try_lock().is_err(),
        Err(_) => false,
    }
}
