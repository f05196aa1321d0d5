//! The run directory: everything a run measured, safe against crashes.
//!
//! Orchestration users' most common complaint is data lost when a run crashes or is
//! interrupted (orchestration spec, complaint 1). So every row is written through to the
//! OS as it is recorded, every step row and journal line is also fsynced, `run.yaml` is
//! replaced atomically (write, fsync, rename), and the directory holds `run.lock`, locked
//! for the life of the process: a run whose manifest says `running` but whose lock is free
//! was killed, and `gelrig runs` shows it as `interrupted`.
//!
//! A recording failure (a full disk, a read-only remount) must end the run promptly with
//! its status on disk and nothing torn: rows are appended whole and cut back on a failed
//! write, frames appear under their name only once complete, and a reserve of disk space
//! held since the start is released at the first failure so the final `run.yaml` still
//! fits ([`files`]). After a failure the recorder writes no more data, only the journal's
//! last lines and the final status, so the run's exit (stop, retract) is never held up
//! or flooded by retried writes.
//!
//! Layout (ARCHITECTURE.md): `protocol.yaml` (resolved, as run), `rig.yaml`, `run.yaml`,
//! `journal.jsonl`, `steps.csv`, and — only for streams the protocol records —
//! `force.csv`, `axes.csv`, `frames.csv` with `frames/*.png`; `run.reserve` while running.

mod files;
mod frame_writer;
mod mcap_live;
mod reopen;
pub mod rows;

use std::fs::{self, File, OpenOptions};
use std::path::{Path, PathBuf};

use records::{ForceSample, Frame, SimTruth, Wrench};

pub use crate::manifest::{
    DeviceRecord, Manifest, Segment, Status, is_locked, read_manifest, run_file,
};
pub use files::write_atomic;
use files::{Appender, CsvFile, Reserve, io};
use frame_writer::FrameWriter;
use rows::{AxesRow, ForceRow, SimStepRow, round6};
pub use rows::{FrameForce, StepRow, TactileRow};

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

/// Writes one run directory.
pub struct Recorder {
    dir: PathBuf,
    manifest: Manifest,
    journal: Appender,
    steps: CsvFile,
    force: Option<CsvFile>,
    axes: Option<CsvFile>,
    frames: Option<FrameWriter>,
    sim_steps: Option<CsvFile>,
    tactile: Option<CsvFile>,
    /// `run.mcap`, with `gelrig run --record mcap`.
    mcap: Option<mcap_live::LiveMcap>,
    frame_count: u64,
    reserve: Reserve,
    /// The first write failure; data is no longer written once set.
    broken: Option<String>,
    _lock: File,
}

/// Appends `row` to the stream file in `slot`, creating it at `path` on first use (a
/// stream's file exists only if the run recorded that stream).
fn append_to<T: serde::Serialize>(
    slot: &mut Option<CsvFile>,
    path: PathBuf,
    row: &T,
) -> Result<(), RecordError> {
    if slot.is_none() {
        *slot = Some(CsvFile::create(path)?);
    }
    match slot {
        Some(w) => w.row(row),
        None => Ok(()),
    }
}

/// Opens and locks the run's `run.lock` for the life of the recorder; fails if another
/// process holds it.
fn take_lock(dir: &Path) -> Result<File, RecordError> {
    let lock_path = dir.join(crate::names::LOCK);
    let lock = OpenOptions::new()
        .create(true)
        .truncate(false)
        .write(true)
        .open(&lock_path)
        .map_err(io(&lock_path))?;
    lock.try_lock().map_err(|e| RecordError::Io {
        path: lock_path.clone(),
        source: std::io::Error::other(format!(
            "{e}: another process is recording this run; fix: wait for it to end, or stop it"
        )),
    })?;
    Ok(lock)
}

/// `<UTC time>_<name>` made safe for a file name.
fn dir_name(name: &str) -> String {
    let stamp = jiff::Timestamp::now()
        .strftime("%Y%m%dT%H%M%SZ")
        .to_string();
    let safe: String = name
        .chars()
        .take(100)
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
        let lock = take_lock(&dir)?;
        // First, before anything else can fill the disk.
        let reserve = Reserve::hold(dir.join(crate::names::RESERVE))?;
        let p = dir.join(crate::names::PROTOCOL);
        fs::write(&p, protocol_yaml).map_err(io(&p))?;
        let p = dir.join(crate::names::RIG);
        fs::write(&p, rig_yaml).map_err(io(&p))?;
        let journal = Appender::create(dir.join(crate::names::JOURNAL))?;
        let steps = CsvFile::with_header_of(dir.join(crate::names::STEPS), &StepRow::example())?;
        let mut rec = Self {
            dir,
            manifest,
            journal,
            steps,
            force: None,
            axes: None,
            frames: None,
            sim_steps: None,
            tactile: None,
            mcap: None,
            frame_count: 0,
            reserve,
            broken: None,
            _lock: lock,
        };
        rec.write_manifest()?;
        Ok(rec)
    }

    /// Also writes the run as it goes to `run.mcap` (ROS 2 messages, as `gelrig export
    /// --format mcap` writes them); `rig_yaml` tells which axes are rotary. Before any data.
    pub fn record_mcap(&mut self, rig_yaml: &str) -> Result<(), RecordError> {
        let m = mcap_live::LiveMcap::create(&self.dir.join(crate::names::MCAP), rig_yaml)?;
        self.mcap = Some(m);
        Ok(())
    }

    /// As [`Self::record_mcap`] for a resumed run: `run.mcap` is written afresh, first with
    /// every record the directory holds from the earlier segments, then as the run goes.
    /// Before any new data.
    pub fn record_mcap_resumed(&mut self, rig_yaml: &str) -> Result<(), RecordError> {
        let m = mcap_live::LiveMcap::create(&self.dir.join(crate::names::MCAP), rig_yaml)?;
        m.write_earlier(&self.dir);
        self.mcap = Some(m);
        Ok(())
    }

    /// Why `run.mcap` stopped being written, once (the CSVs go on).
    pub fn mcap_failure(&self) -> Option<String> {
        self.mcap
            .as_ref()
            .and_then(mcap_live::LiveMcap::new_failure)
    }

    /// The run directory.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The manifest as it stands.
    pub fn manifest(&self) -> &Manifest {
        &self.manifest
    }

    /// The first write failure, once one happened.
    pub fn broken(&self) -> Option<&str> {
        self.broken.as_deref()
    }

    /// Records the first failure: releases the reserve so the final status fits, and stops
    /// writing data. Returns the error for the caller to end the run with.
    fn fail(&mut self, e: RecordError) -> RecordError {
        if self.broken.is_none() {
            self.reserve.release();
            self.broken = Some(e.to_string());
        }
        e
    }

    /// Runs a data write unless the recorder is broken; a failure breaks it.
    fn data<T>(
        &mut self,
        write: impl FnOnce(&mut Self) -> Result<T, RecordError>,
    ) -> Result<Option<T>, RecordError> {
        if self.broken.is_some() {
            return Ok(None);
        }
        match write(self) {
            Ok(v) => Ok(Some(v)),
            Err(e) => Err(self.fail(e)),
        }
    }

    /// Changes the manifest and rewrites `run.yaml` atomically. Tried even after a failure:
    /// the final status matters most.
    pub fn update_manifest(&mut self, f: impl FnOnce(&mut Manifest)) -> Result<(), RecordError> {
        f(&mut self.manifest);
        match self.write_manifest() {
            Ok(()) => Ok(()),
            Err(e) => Err(self.fail(e)),
        }
    }

    fn write_manifest(&mut self) -> Result<(), RecordError> {
        let path = self.dir.join(crate::names::MANIFEST);
        let text = serde_yaml::to_string(&self.manifest).map_err(|e| RecordError::Io {
            path: path.clone(),
            source: std::io::Error::other(e.to_string()),
        })?;
        write_atomic(&path, text.as_bytes())
    }

    /// Appends an event to `journal.jsonl` (one whole line); `durable` also fsyncs it. After
    /// a failure, events are still tried (they say how the run ended) but their own
    /// failures are not reported again.
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
        let mut bytes = line.to_string().into_bytes();
        bytes.push(b'\n');
        let r = self
            .journal
            .append(&bytes)
            .and_then(|()| if durable { self.journal.sync() } else { Ok(()) });
        match r {
            Err(e) if self.broken.is_none() => Err(self.fail(e)),
            _ => Ok(()),
        }
    }

    /// Appends a force sample (already tared) to `force.csv`.
    pub fn force(
        &mut self,
        s: &ForceSample,
        tared: &Wrench,
        step: u32,
        trial: u32,
    ) -> Result<(), RecordError> {
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
        if let Some(m) = &self.mcap
            && self.broken.is_none()
        {
            let v = [
                row.fx_n, row.fy_n, row.fz_n, row.tx_nmm, row.ty_nmm, row.tz_nmm,
            ];
            m.with(|w, _| w.wrench(row.t_ns, v));
        }
        self.data(|r| append_to(&mut r.force, r.dir.join(crate::names::FORCE), &row))
            .map(|_| ())
    }

    /// Appends an axis position to `axes.csv`.
    pub fn axis(
        &mut self,
        t_ns: u64,
        axis: &str,
        target: Option<f64>,
        position: f64,
    ) -> Result<(), RecordError> {
        let row = AxesRow {
            t_ns,
            axis,
            target: target.map(round6),
            position: round6(position),
        };
        if let Some(m) = &self.mcap
            && self.broken.is_none()
        {
            m.with(|w, rotary| {
                let rot = rotary.iter().any(|a| a == axis);
                w.joint(t_ns, axis, crate::ros2::si(row.position, rot))
            });
        }
        self.data(|r| append_to(&mut r.axes, r.dir.join(crate::names::AXES), &row))
            .map(|_| ())
    }

    /// Writes a frame to `frames/NNNNNN.png` (under a temporary name until complete) and a
    /// row to `frames.csv`; returns the frame number (`None` once the recorder is broken).
    pub fn frame(
        &mut self,
        frame: &Frame,
        step: u32,
        trial: u32,
        force: Option<FrameForce>,
    ) -> Result<Option<u64>, RecordError> {
        self.data(|r| r.write_frame(frame, step, trial, force))
    }

    fn write_frame(
        &mut self,
        frame: &Frame,
        step: u32,
        trial: u32,
        force: Option<FrameForce>,
    ) -> Result<u64, RecordError> {
        if self.frames.is_none() {
            let d = self.dir.join("frames");
            fs::create_dir_all(&d).map_err(io(&d))?;
            self.frames = Some(FrameWriter::start(self.dir.clone(), self.mcap.clone())?);
        }
        let n = self.frame_count;
        if let Some(w) = &mut self.frames {
            w.send(n, frame, step, trial, force)?;
        }
        self.frame_count += 1;
        Ok(n)
    }

    /// Appends the simulator's ground truth at the end of a step to `sim_steps.csv`.
    pub fn sim_truth(&mut self, step: u32, trial: u32, t: &SimTruth) -> Result<(), RecordError> {
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
        self.data(|r| {
            append_to(&mut r.sim_steps, r.dir.join(crate::names::SIM_STEPS), &row)?;
            r.sim_steps.as_mut().map_or(Ok(()), CsvFile::sync)
        })
        .map(|_| ())
    }

    /// Appends a frame's live tactile state to `tactile.csv`.
    pub fn tactile(&mut self, row: &TactileRow) -> Result<(), RecordError> {
        self.json_message(crate::ros2::Topic::Tactile, row.t_ns, row);
        self.data(|r| append_to(&mut r.tactile, r.dir.join(crate::names::TACTILE), row))
            .map(|_| ())
    }

    /// Appends a step row and makes it, and everything recorded before it, durable.
    pub fn step(&mut self, row: &StepRow) -> Result<(), RecordError> {
        self.json_message(crate::ros2::Topic::Steps, row.t_end_ns, row);
        self.data(|r| {
            r.steps.row(row)?;
            r.steps.sync()?;
            for w in [&mut r.force, &mut r.axes, &mut r.tactile]
                .into_iter()
                .flatten()
            {
                w.sync()?;
            }
            if let Some(f) = &mut r.frames {
                f.sync()?;
            }
            r.manifest.steps_completed = r.manifest.steps_completed.max(row.step);
            Ok(())
        })
        .map(|_| ())
    }

    /// A row as a JSON message of `run.mcap`, when the run writes one.
    fn json_message<T: serde::Serialize>(&self, topic: crate::ros2::Topic, t_ns: u64, row: &T) {
        if let (Some(m), None) = (&self.mcap, &self.broken) {
            let text = serde_json::to_string(row).unwrap_or_default();
            m.with(|w, _| w.json(topic, t_ns, &text));
        }
    }

    /// Frames written so far.
    pub fn frames_written(&self) -> u64 {
        self.frame_count
    }

    /// Waits until every frame handed over is written; the frame writer's first failure,
    /// if any (the recorder is then broken).
    pub fn flush_frames(&mut self) -> Result<(), RecordError> {
        match self.frames.as_mut().map(FrameWriter::finish) {
            Some(Err(e)) => Err(self.fail(e)),
            _ => Ok(()),
        }
    }

    /// Completes `run.mcap`, if the run writes one: the run's files, its manifest (as it
    /// stands: call it after the final status) and the summary. Then [`Self::mcap_failure`]
    /// says whether the file is whole.
    pub fn finish_mcap(&mut self) {
        if let Some(m) = &self.mcap {
            m.finish(&self.dir, &self.manifest);
        }
    }

    /// Ends the recording: the reserve is given back.
    pub fn close(&mut self) {
        self.reserve.release();
    }
}
