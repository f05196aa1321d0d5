//! Frames are encoded and written on their own thread, so the plan task (which renders on
//! a dry run, tracks markers live and services the stages) and the encoder use both cores.
//!
//! Order and durability are the synchronous writer's: a frame's PNG is written under a
//! temporary name and renamed when complete, then its row goes to `frames.csv` (and its
//! true marker positions to `sim_markers.csv`), so a row never names a missing file. The
//! queue is short (a few frames), so a slow disk holds the plan back rather than filling
//! memory. The first failure stops the thread; the recorder reports it at the next frame or
//! when the run ends ([`FrameWriter::finish`]).

use std::path::PathBuf;
use std::sync::mpsc::{Receiver, SyncSender, sync_channel};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;

use image::ImageEncoder;
use image::codecs::png::{CompressionType, FilterType, PngEncoder};
use records::Frame;

use super::files::{CsvFile, write_new};
use super::rows::{FrameForce, FrameRow, MarkerTruthRow, SimFrameRow, round6};
use super::{RecordError, append_to};

/// Frames queued before the plan waits for the encoder.
const QUEUE: usize = 4;

enum Job {
    /// Boxed: the frame's metadata would make every queued message as large.
    Frame(Box<FrameJob>),
    /// Make everything written so far durable, then answer.
    Sync(SyncSender<()>),
}

struct FrameJob {
    n: u64,
    frame: Frame,
    step: u32,
    trial: u32,
    force: Option<FrameForce>,
}

/// The encoding thread and its queue.
pub(super) struct FrameWriter {
    tx: Option<SyncSender<Job>>,
    handle: Option<JoinHandle<()>>,
    error: Arc<Mutex<Option<RecordError>>>,
}

impl FrameWriter {
    /// Starts the thread writing into run directory `dir` (its `frames/` exists).
    pub(super) fn start(
        dir: PathBuf,
        mcap: Option<super::mcap_live::LiveMcap>,
    ) -> Result<Self, RecordError> {
        let (tx, rx) = sync_channel::<Job>(QUEUE);
        let error = Arc::new(Mutex::new(None));
        let slot = Arc::clone(&error);
        let frames = CsvFile::create(dir.join(crate::names::FRAMES))?;
        let handle = std::thread::Builder::new()
            .name("frame-writer".into())
            .spawn(move || run(dir, frames, rx, slot, mcap))
            .map_err(|e| RecordError::Io {
                path: PathBuf::from("frames"),
                source: e,
            })?;
        Ok(Self {
            tx: Some(tx),
            handle: Some(handle),
            error,
        })
    }

    /// Queues a frame; fails with the thread's first error, if it has stopped.
    pub(super) fn send(
        &mut self,
        n: u64,
        frame: &Frame,
        step: u32,
        trial: u32,
        force: Option<FrameForce>,
    ) -> Result<(), RecordError> {
        let job = Job::Frame(Box::new(FrameJob {
            n,
            frame: frame.clone(),
            step,
            trial,
            force,
        }));
        self.submit(job)
    }

    /// Waits until every frame queued so far is written and durable (a step's end).
    pub(super) fn sync(&mut self) -> Result<(), RecordError> {
        let (ack_tx, ack_rx) = sync_channel(1);
        self.submit(Job::Sync(ack_tx))?;
        match ack_rx.recv() {
            Ok(()) => Ok(()),
            Err(_) => Err(self.stopped()),
        }
    }

    fn submit(&mut self, job: Job) -> Result<(), RecordError> {
        if let Some(e) = self.take_error() {
            return Err(e);
        }
        let sent = self.tx.as_ref().map(|tx| tx.send(job));
        match sent {
            Some(Ok(())) => Ok(()),
            _ => Err(self.stopped()),
        }
    }

    /// The thread is gone: its error says why.
    fn stopped(&mut self) -> RecordError {
        self.finish().err().unwrap_or_else(|| RecordError::Frame {
            path: PathBuf::from("frames"),
            detail: "the frame writer stopped".into(),
        })
    }

    fn take_error(&self) -> Option<RecordError> {
        self.error
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .take()
    }

    /// Writes every queued frame and stops the thread; its first error, if any.
    pub(super) fn finish(&mut self) -> Result<(), RecordError> {
        self.tx = None;
        if let Some(h) = self.handle.take()
            && h.join().is_err()
        {
            return Err(RecordError::Frame {
                path: PathBuf::from("frames"),
                detail: "the frame writer panicked".into(),
            });
        }
        match self.take_error() {
            Some(e) => Err(e),
            None => Ok(()),
        }
    }
}

impl Drop for FrameWriter {
    fn drop(&mut self) {
        let _ = self.finish();
    }
}

fn run(
    dir: PathBuf,
    mut frames: CsvFile,
    rx: Receiver<Job>,
    error: Arc<Mutex<Option<RecordError>>>,
    mcap: Option<super::mcap_live::LiveMcap>,
) {
    let mut markers: Option<CsvFile> = None;
    let mut sim_frames: Option<CsvFile> = None;
    while let Ok(job) = rx.recv() {
        let done =
            match job {
                Job::Frame(f) => write(&dir, &mut frames, &mut markers, &f, mcap.as_ref())
                    .and_then(|()| match &f.frame.truth_surface {
                        Some(t) => write_maps(&dir, &mut sim_frames, f.n, t),
                        None => Ok(()),
                    }),
                Job::Sync(ack) => {
                    let synced = [Some(&mut frames), markers.as_mut(), sim_frames.as_mut()]
                        .into_iter()
                        .flatten()
                        .try_for_each(CsvFile::sync);
                    let _ = ack.send(());
                    synced
                }
            };
        if let Err(e) = done {
            *error.lock().unwrap_or_else(PoisonError::into_inner) = Some(e);
            return;
        }
    }
}

fn write(
    dir: &std::path::Path,
    frames: &mut CsvFile,
    markers: &mut Option<CsvFile>,
    job: &FrameJob,
    mcap: Option<&super::mcap_live::LiveMcap>,
) -> Result<(), RecordError> {
    let FrameJob {
        n,
        frame,
        step,
        trial,
        force,
    } = job;
    let file = crate::names::frame_png(*n);
    let path = dir.join(&file);
    let frame_err = |detail: String| RecordError::Frame {
        path: path.clone(),
        detail,
    };
    let expected = frame.width as usize * frame.height as usize * 3;
    if frame.rgb.len() != expected {
        return Err(frame_err(format!(
            "{} bytes do not make a {}×{} RGB image",
            frame.rgb.len(),
            frame.width,
            frame.height
        )));
    }
    // Fast deflate with the Sub filter: a camera frame's sensor noise leaves little to
    // compress; 1.0 ms a frame against 1.3 ms for the encoder's defaults and 85 ms for its
    // `Default` level, for 1–4 % more bytes (BENCHMARKS.md, "Grasp trials").
    let mut png = Vec::with_capacity(expected / 2);
    PngEncoder::new_with_quality(&mut png, CompressionType::Fast, FilterType::Sub)
        .write_image(
            &frame.rgb,
            frame.width,
            frame.height,
            image::ExtendedColorType::Rgb8,
        )
        .map_err(|e| frame_err(e.to_string()))?;
    write_new(&path, &png)?;
    if let Some(m) = mcap {
        m.with(|w, _| w.png(frame.t_ns, &png));
    }
    frames.row(&FrameRow {
        frame: *n,
        t_ns: frame.t_ns,
        step: *step,
        trial: *trial,
        file: &file,
        seq: frame.seq,
        fx_n: force.map(|f| round6(f.wrench.fx_n)),
        fy_n: force.map(|f| round6(f.wrench.fy_n)),
        fz_n: force.map(|f| round6(f.wrench.fz_n)),
        tx_nmm: force.map(|f| round6(f.wrench.tx_nmm)),
        ty_nmm: force.map(|f| round6(f.wrench.ty_nmm)),
        tz_nmm: force.map(|f| round6(f.wrench.tz_nmm)),
        fz_sd_n: force.and_then(|f| f.fz_sd_n).map(round6),
        force_samples: force.map(|f| f.samples),
        sim_t_ns: frame.truth_t_ns,
    })?;
    if let Some(truth) = &frame.truth_px {
        let path = dir.join(crate::names::SIM_MARKERS);
        for (id, [x, y]) in truth.iter().enumerate() {
            let row = MarkerTruthRow {
                frame: *n,
                id,
                x_px: round6(*x),
                y_px: round6(*y),
            };
            append_to(markers, path.clone(), &row)?;
        }
    }
    Ok(())
}

/// The simulator's traction maps of frame `n` (`sim_maps/NNNNNN.npy`, written whole then
/// renamed), then its row in `sim_frames.csv`: a row never names a missing file.
fn write_maps(
    dir: &std::path::Path,
    sim_frames: &mut Option<CsvFile>,
    n: u64,
    t: &records::SurfaceTruth,
) -> Result<(), RecordError> {
    let file = crate::names::sim_maps_npy(n);
    let path = dir.join(&file);
    let (w, h) = (t.width as usize, t.height as usize);
    let cells = w * h;
    let channels = [&t.pressure_kpa, &t.shear_x_kpa, &t.shear_y_kpa];
    if channels.iter().any(|c| c.len() != cells) || t.contact.len() != cells {
        return Err(RecordError::Frame {
            path,
            detail: format!("traction maps that are not {w}×{h}"),
        });
    }
    let maps_dir = dir.join(crate::names::SIM_MAPS_DIR);
    std::fs::create_dir_all(&maps_dir).map_err(|e| RecordError::Io {
        path: maps_dir.clone(),
        source: e,
    })?;
    let mut data = Vec::with_capacity(4 * cells);
    for c in channels {
        data.extend_from_slice(c);
    }
    data.extend(t.contact.iter().map(|&v| f32::from(v)));
    write_new(&path, &crate::npy::encode(&data, &[4, h, w]))?;
    // Loads from the maps: Σ traction × cell area (kPa·mm² = mN).
    let area = t.cell_mm * t.cell_mm;
    let load = |c: &[f32]| c.iter().map(|&v| f64::from(v)).sum::<f64>() * area / 1000.0;
    let contact = t.contact.iter().filter(|&&v| v != 0).count() as f64 * area;
    let row = SimFrameRow {
        frame: n,
        maps: &file,
        depth_mm: round6(t.depth_mm),
        shear_n: round6(t.shear_n),
        torque_nmm: round6(t.torque_nmm),
        centre_x_mm: round6(t.centre_mm.0),
        centre_y_mm: round6(t.centre_mm.1),
        rotation_rad: round6(t.rotation_rad),
        fz_n: round6(load(&t.pressure_kpa)),
        fx_n: round6(load(&t.shear_x_kpa)),
        fy_n: round6(load(&t.shear_y_kpa)),
        contact_area_mm2: round6(contact),
        cell_mm: t.cell_mm,
    };
    append_to(sim_frames, dir.join(crate::names::SIM_FRAMES), &row)
}
