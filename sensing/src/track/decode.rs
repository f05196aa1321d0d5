//! Frames decoded ahead of the tracker, on every core.
//!
//! PNG decoding is most of the CPU time of `gelrig track` (the tracker needs ~1 ms for a
//! 640×480 frame, the decoder ~2–3 ms), so frames are decoded by worker threads while the
//! tracker works on the frame before. Worker `k` of `n` decodes frames `k, k + n, …` into its
//! own bounded channel; the consumer reads the channels in turn, so frames arrive in order
//! with at most [`AHEAD`] frames per worker in memory.

use std::path::PathBuf;
use std::sync::mpsc::{Receiver, sync_channel};
use std::sync::{Arc, Mutex};

use super::TrackFailure;
use super::input::load_rgb_into;

/// Pixel buffers the tracker is done with, for the decoders to fill again.
#[derive(Clone, Default)]
pub(super) struct Pool(Arc<Mutex<Vec<Vec<u8>>>>);

impl Pool {
    /// A buffer to decode into: one given back, or a new one.
    fn take(&self) -> Vec<u8> {
        self.0
            .lock()
            .ok()
            .and_then(|mut p| p.pop())
            .unwrap_or_default()
    }

    /// Gives a tracked frame's pixels back (a few are kept: about one per frame in flight).
    pub(super) fn give(&self, buf: Vec<u8>) {
        if let Ok(mut p) = self.0.lock()
            && p.len() < 64
        {
            p.push(buf);
        }
    }
}

/// Frames each worker may hold decoded before the tracker takes them.
const AHEAD: usize = 2;

/// One decoded frame (or why it could not be decoded).
pub(super) struct Decoded {
    pub(super) frame: u64,
    pub(super) path: PathBuf,
    pub(super) image: Result<(usize, usize, Vec<u8>), TrackFailure>,
}

/// The frames, in order, decoded by `workers` threads.
pub(super) struct DecodeAhead {
    channels: Vec<Receiver<Decoded>>,
    frames: Vec<(u64, PathBuf)>,
    next: usize,
    pool: Pool,
}

impl DecodeAhead {
    pub(super) fn new(frames: Vec<(u64, PathBuf)>, workers: usize) -> Self {
        let workers = workers.clamp(1, frames.len().max(1));
        let pool = Pool::default();
        let channels = (0..workers)
            .map(|k| {
                let (tx, rx) = sync_channel(AHEAD);
                let mine: Vec<(u64, PathBuf)> =
                    frames.iter().skip(k).step_by(workers).cloned().collect();
                let pool = pool.clone();
                std::thread::spawn(move || {
                    let mut bytes = Vec::new();
                    for (frame, path) in mine {
                        let mut pixels = pool.take();
                        let image = load_rgb_into(&path, &mut bytes, &mut pixels)
                            .map(|(w, h)| (w, h, pixels));
                        // The tracker stopped (an error, or it is done): so do we.
                        if tx.send(Decoded { frame, path, image }).is_err() {
                            return;
                        }
                    }
                });
                rx
            })
            .collect();
        Self {
            channels,
            frames,
            next: 0,
            pool,
        }
    }

    /// Where the tracker gives back the pixels of frames it is done with.
    pub(super) fn pool(&self) -> Pool {
        self.pool.clone()
    }
}

impl Iterator for DecodeAhead {
    type Item = Decoded;

    fn next(&mut self) -> Option<Decoded> {
        let (frame, path) = self.frames.get(self.next)?.clone();
        let channel = &self.channels[self.next % self.channels.len()];
        self.next += 1;
        // A worker that vanished without sending its frame must not shorten the run silently.
        Some(channel.recv().unwrap_or_else(|_| Decoded {
            frame,
            path: path.clone(),
            image: Err(TrackFailure::Read {
                path,
                detail: "the decoding thread stopped before this frame".into(),
            }),
        }))
    }
}
