//! Frames decoded ahead of the tracker, on every core.
//!
//! PNG decoding is most of the CPU time of `gelrig track` (the tracker needs ~1 ms for a
//! 640×480 frame, the decoder ~2–3 ms), so frames are decoded by worker threads while the
//! tracker works on the frame before. Worker `k` of `n` decodes frames `k, k + n, …` into its
//! own bounded channel; the consumer reads the channels in turn, so frames arrive in order
//! with at most [`AHEAD`] frames per worker in memory.

use std::path::PathBuf;
use std::sync::mpsc::{Receiver, sync_channel};

use super::TrackFailure;
use super::input::load_rgb;

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
}

impl DecodeAhead {
    pub(super) fn new(frames: Vec<(u64, PathBuf)>, workers: usize) -> Self {
        let workers = workers.clamp(1, frames.len().max(1));
        let channels = (0..workers)
            .map(|k| {
                let (tx, rx) = sync_channel(AHEAD);
                let mine: Vec<(u64, PathBuf)> =
                    frames.iter().skip(k).step_by(workers).cloned().collect();
                std::thread::spawn(move || {
                    for (frame, path) in mine {
                        let image = load_rgb(&path);
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
        }
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
