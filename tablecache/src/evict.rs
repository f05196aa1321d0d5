//! Size: what the cache holds, keeping it under its limit (least recently used out), and
//! clearing it.

use std::path::{Path, PathBuf};
use std::time::SystemTime;

use crate::CacheError;

/// What the cache holds.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Usage {
    /// Entry files.
    pub entries: u64,
    /// Their bytes.
    pub bytes: u64,
}

struct Kept {
    path: PathBuf,
    bytes: u64,
    used: SystemTime,
}

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> CacheError + '_ {
    move |source| CacheError::Io {
        path: path.to_path_buf(),
        source,
    }
}

fn list(entries: &Path) -> Result<Vec<Kept>, CacheError> {
    let rd = match std::fs::read_dir(entries) {
        Ok(rd) => rd,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Vec::new()),
        Err(e) => return Err(io(entries)(e)),
    };
    let mut out = Vec::new();
    for e in rd.flatten() {
        let path = e.path();
        if path.extension().is_none_or(|x| x != "bin") {
            continue;
        }
        // A file another run deletes meanwhile is simply not counted.
        if let Ok(m) = e.metadata() {
            out.push(Kept {
                path,
                bytes: m.len(),
                used: m.modified().unwrap_or(SystemTime::UNIX_EPOCH),
            });
        }
    }
    Ok(out)
}

pub(crate) fn usage(entries: &Path) -> Result<Usage, CacheError> {
    let kept = list(entries)?;
    Ok(Usage {
        entries: kept.len() as u64,
        bytes: kept.iter().map(|k| k.bytes).sum(),
    })
}

/// Opens (creating) the folder's lock file.
fn lock_file(dir: &Path) -> Result<std::fs::File, CacheError> {
    let p = dir.join(".lock");
    open_lock(&p).map_err(io(&p))
}

/// Opens (creating, never truncating) a file to hold an advisory lock on: the folder's
/// `.lock`, or an entry's build lock ([`crate::building`]).
pub(crate) fn open_lock(path: &Path) -> std::io::Result<std::fs::File> {
    std::fs::OpenOptions::new()
        .create(true)
        .truncate(false)
        .write(true)
        .open(path)
}

/// Deletes the least recently used entries until the cache is at most 90 % of
/// `max_bytes`, when it is over `max_bytes`. Another run already trimming (the lock
/// taken) is left to it.
pub(crate) fn trim(dir: &Path, entries: &Path, max_bytes: u64) -> Result<(), CacheError> {
    let mut kept = list(entries)?;
    let total: u64 = kept.iter().map(|k| k.bytes).sum();
    if total <= max_bytes {
        return Ok(());
    }
    let lock = lock_file(dir)?;
    if lock.try_lock().is_err() {
        return Ok(());
    }
    kept.sort_by_key(|k| k.used);
    let mut total = total;
    let goal = max_bytes / 10 * 9;
    for k in kept {
        if total <= goal {
            break;
        }
        match std::fs::remove_file(&k.path) {
            Ok(()) => total = total.saturating_sub(k.bytes),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                total = total.saturating_sub(k.bytes)
            }
            Err(e) => return Err(io(&k.path)(e)),
        }
    }
    Ok(())
}

/// Deletes every entry (under the lock, waiting for a trim in progress).
pub(crate) fn clear(dir: &Path, entries: &Path) -> Result<Usage, CacheError> {
    if !dir.exists() {
        return Ok(Usage::default());
    }
    let lock = lock_file(dir)?;
    lock.lock().map_err(io(dir))?;
    let mut gone = Usage::default();
    for k in list(entries)? {
        match std::fs::remove_file(&k.path) {
            Ok(()) => {
                gone.entries += 1;
                gone.bytes += k.bytes;
            }
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => return Err(io(&k.path)(e)),
        }
    }
    // And the entries' empty build-lock files (`building`): one a run holds now only costs
    // a second builder of its table.
    if let Ok(rd) = std::fs::read_dir(entries) {
        for e in rd.flatten() {
            if e.path().extension().is_some_and(|x| x == "building") {
                let _ = std::fs::remove_file(e.path());
            }
        }
    }
    Ok(gone)
}
