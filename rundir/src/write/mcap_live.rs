//! `gelrig run --record mcap`: `run.mcap` written as the run goes, beside the CSVs, with the
//! messages `gelrig export --format mcap` writes from a finished run (force, frames, stage
//! positions, steps, the grasp's tactile state). The frame writer's thread adds each PNG as
//! it encodes it, so a frame is compressed once for both files.
//!
//! The CSVs stay the record: a failure writing the MCAP file (a full disk) stops only the
//! MCAP file, and the run says so (a warning naming `gelrig export`, which rebuilds the file
//! from the CSVs). A run killed before its end leaves a file without its summary section;
//! MCAP readers read such a file's complete chunks in streaming mode, and the export rebuilds
//! a whole one. A resumed run that records it starts the file afresh with every record its
//! directory already holds (an MCAP file cannot be appended to past its summary, and a
//! killed run's has none), then goes on live.

use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, PoisonError};

use super::RecordError;
use crate::ros2::{Ros2Mcap, rotary_axes};

type Writer = Ros2Mcap<BufWriter<File>>;

struct State {
    w: Option<Writer>,
    rotary: Vec<String>,
    failed: Option<String>,
    reported: bool,
}

/// The MCAP file being written, shared by the recorder and its frame writer.
#[derive(Clone)]
pub(super) struct LiveMcap {
    path: PathBuf,
    state: Arc<Mutex<State>>,
}

impl LiveMcap {
    /// Creates `path`; `rig_yaml` tells which axes are rotary.
    pub(super) fn create(path: &Path, rig_yaml: &str) -> Result<Self, RecordError> {
        let io = |e: std::io::Error| RecordError::Io {
            path: path.to_path_buf(),
            source: e,
        };
        let file = File::create(path).map_err(io)?;
        let w = Ros2Mcap::create(BufWriter::new(file))
            .map_err(|e| io(std::io::Error::other(e.to_string())))?;
        Ok(Self {
            path: path.to_path_buf(),
            state: Arc::new(Mutex::new(State {
                w: Some(w),
                rotary: rotary_axes(rig_yaml),
                failed: None,
                reported: false,
            })),
        })
    }

    /// Writes with `f` unless an earlier write failed; a failure ends the file's writing.
    pub(super) fn with(
        &self,
        f: impl FnOnce(&mut Writer, &[String]) -> Result<(), mcap::McapError>,
    ) {
        let mut s = self.state.lock().unwrap_or_else(PoisonError::into_inner);
        let State {
            w, rotary, failed, ..
        } = &mut *s;
        if let Some(writer) = w.as_mut()
            && let Err(e) = f(writer, rotary)
        {
            *failed = Some(e.to_string());
            *w = None;
        }
    }

    /// Writes what `dir` already holds (a resumed run's earlier segments, read back from
    /// the CSVs and frames) before anything new: the file a resumed run writes as it goes is
    /// then the whole run, as `gelrig export` would write it.
    pub(super) fn write_earlier(&self, dir: &Path) {
        let mut s = self.state.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some(writer) = s.w.as_mut()
            && let Err(e) = crate::export::write_records(dir, writer)
        {
            s.failed = Some(match e {
                crate::export::RecordsError::Read(e) => format!("the earlier segments: {e}"),
                crate::export::RecordsError::Mcap(e) => e.to_string(),
            });
            s.w = None;
        }
    }

    /// Why the file stopped being written, the first time it is asked after it did.
    pub(super) fn new_failure(&self) -> Option<String> {
        let mut s = self.state.lock().unwrap_or_else(PoisonError::into_inner);
        if s.reported {
            return None;
        }
        let why = s.failed.clone()?;
        s.reported = true;
        Some(format!(
            "{} is incomplete from here: {why}; the CSVs are complete — \
             `gelrig export RUN_DIR --format mcap` rebuilds it from them",
            self.path.display()
        ))
    }

    /// Attaches the run's files and its manifest, writes the summary and closes the file.
    pub(super) fn finish(&self, dir: &Path, manifest: &super::Manifest) {
        self.with(|w, _| {
            for name in [
                crate::names::PROTOCOL,
                crate::names::RIG,
                crate::names::MANIFEST,
            ] {
                if let Ok(bytes) = std::fs::read(dir.join(name)) {
                    w.attach(name, bytes)?;
                }
            }
            w.run_metadata(manifest.headline())
        });
        let mut s = self.state.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some(w) = s.w.take()
            && let Err(e) = w.finish()
        {
            s.failed = Some(e.to_string());
        }
    }
}
