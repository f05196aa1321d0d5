//! Reopening a run directory to continue it (`gelrig resume`): the same files, appended to.
//!
//! A run killed part-way leaves every row it recorded whole on disk except, at worst, the
//! one being written when it died ([`super::files`] cuts that torn tail when the file is
//! opened, and the journal says how many bytes went). Frames keep numbering after the
//! highest one on disk, so nothing recorded is ever overwritten.

use std::fs;
use std::path::Path;

use super::files::{Appender, CsvFile, Reserve, io};
use super::{Manifest, RecordError, Recorder, StepRow, read_manifest};

/// Why a run directory cannot be continued.
fn refused(dir: &Path, detail: String) -> RecordError {
    RecordError::Io {
        path: dir.to_path_buf(),
        source: std::io::Error::other(detail),
    }
}

impl Recorder {
    /// Opens the existing run directory `dir` to continue recording into it, taking its
    /// lock; `update` changes the manifest (status, the new segment) before anything else
    /// is written. Returns the recorder and the bytes of torn last rows cut, by file.
    pub fn reopen(
        dir: &Path,
        update: impl FnOnce(&mut Manifest),
    ) -> Result<(Self, Vec<(String, u64)>), RecordError> {
        let lock = super::take_lock(dir)?;
        let mut manifest = read_manifest(dir).map_err(|e| refused(dir, e))?;
        let reserve = Reserve::hold(dir.join(crate::names::RESERVE))?;
        let journal = Appender::create(dir.join(crate::names::JOURNAL))?;
        let steps = CsvFile::with_header_of(dir.join(crate::names::STEPS), &StepRow::example())?;
        let mut cut = Vec::new();
        let mut note = |name: &str, bytes: u64| {
            if bytes > 0 {
                cut.push((name.to_string(), bytes));
            }
        };
        note(crate::names::JOURNAL, journal.cut_bytes());
        note(crate::names::STEPS, steps.cut_bytes());
        let mut stream = |name: &str| -> Result<Option<CsvFile>, RecordError> {
            let path = dir.join(name);
            if !path.is_file() {
                return Ok(None);
            }
            let f = CsvFile::create(path)?;
            note(name, f.cut_bytes());
            Ok(Some(f))
        };
        let force = stream(crate::names::FORCE)?;
        let axes = stream(crate::names::AXES)?;
        let sim_steps = stream(crate::names::SIM_STEPS)?;
        let tactile = stream(crate::names::TACTILE)?;
        // frames.csv and sim_markers.csv are opened by the frame writer at the first frame;
        // their torn tails are cut then (and not reported).
        let frame_count = next_frame_number(dir)?;
        update(&mut manifest);
        let mut rec = Self {
            dir: dir.to_path_buf(),
            manifest,
            journal,
            steps,
            force,
            axes,
            frames: None,
            sim_steps,
            tactile,
            mcap: None,
            frame_count,
            reserve,
            broken: None,
            _lock: lock,
        };
        rec.write_manifest()?;
        Ok((rec, cut))
    }
}

/// One past the highest frame number on disk — in `frames.csv` or as a file in `frames/`
/// (a frame written whose row was not, or one left under its temporary name).
fn next_frame_number(dir: &Path) -> Result<u64, RecordError> {
    let frames = dir.join("frames");
    let mut next = 0u64;
    if frames.is_dir() {
        for entry in fs::read_dir(&frames).map_err(io(&frames))? {
            let entry = entry.map_err(io(&frames))?;
            let name = entry.file_name();
            let number = name
                .to_str()
                .and_then(|n| n.split('.').next())
                .and_then(|n| n.parse::<u64>().ok());
            if let Some(n) = number {
                next = next.max(n + 1);
            }
        }
    }
    let csv_path = dir.join(crate::names::FRAMES);
    if csv_path.is_file() {
        let mut r = csv::Reader::from_path(&csv_path).map_err(|e| RecordError::Csv {
            path: csv_path.clone(),
            source: e,
        })?;
        for row in r.records().flatten() {
            if let Some(n) = row.get(0).and_then(|v| v.parse::<u64>().ok()) {
                next = next.max(n + 1);
            }
        }
    }
    Ok(next)
}
