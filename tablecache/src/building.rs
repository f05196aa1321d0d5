//! One builder per entry: a run that misses an entry takes that entry's lock (an advisory
//! `flock` on `<address>.building` beside it) before solving it, and a second run (or
//! thread) missing the same entry waits for the lock and then reads what the first one
//! wrote, instead of solving the same table beside it. On a fresh machine, where every test
//! and run starts with an empty cache, two solves of one table were the common case.
//!
//! Deadlock cannot arise: a thread only ever waits while it holds no build lock. A table
//! solved inside another one's solve (a curved indenter's pressed states inside its normal
//! table) is solved without a lock of its own. A lock is let go when its entry is saved; one
//! whose solve failed is let go when the process ends (the kernel drops `flock`s of a closed
//! file), and a waiter gives up after [`WAIT`] and solves the table itself, so a run never
//! hangs on another.

use std::collections::HashMap;
use std::fs::File;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::thread::ThreadId;
use std::time::{Duration, Instant};

/// Longest wait for another builder of the same entry: far above any one table's solve
/// (about 0.7 s for a curved indenter's depth bucket here, a few seconds on a slow machine).
const WAIT: Duration = Duration::from_secs(300);
const POLL: Duration = Duration::from_millis(20);

/// The build locks this process holds, by entry file.
#[derive(Debug, Default)]
pub(crate) struct Building {
    held: Mutex<HashMap<PathBuf, (ThreadId, File)>>,
}

fn lock_path(entry: &Path) -> PathBuf {
    entry.with_extension("building")
}

impl Building {
    /// Whether the calling thread holds a build lock now.
    fn holds_any(&self) -> bool {
        let me = std::thread::current().id();
        self.held
            .lock()
            .map(|h| h.values().any(|(t, _)| *t == me))
            .unwrap_or(true)
    }

    /// Takes the build lock of the entry at `entry` for the calling thread, waiting for
    /// another builder at most [`WAIT`]. `false` when no lock was taken (the thread holds
    /// another one, the folder cannot be written, or the wait ran out): the caller solves
    /// the table without one, as with no cache.
    pub(crate) fn acquire(&self, entry: &Path) -> bool {
        if self.holds_any() {
            return false;
        }
        let Some(dir) = entry.parent() else {
            return false;
        };
        if std::fs::create_dir_all(dir).is_err() {
            return false;
        }
        let Ok(file) = crate::evict::open_lock(&lock_path(entry)) else {
            return false;
        };
        let start = Instant::now();
        loop {
            match file.try_lock() {
                Ok(()) => break,
                Err(std::fs::TryLockError::WouldBlock) if start.elapsed() < WAIT => {
                    std::thread::sleep(POLL)
                }
                Err(_) => return false,
            }
        }
        match self.held.lock() {
            Ok(mut h) => {
                h.insert(entry.to_path_buf(), (std::thread::current().id(), file));
                true
            }
            Err(_) => false,
        }
    }

    /// Lets go of the build lock of the entry at `entry`, if this process holds it.
    pub(crate) fn release(&self, entry: &Path) {
        if let Ok(mut h) = self.held.lock() {
            h.remove(entry);
        }
    }
}
