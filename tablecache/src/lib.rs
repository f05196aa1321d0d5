//! The solved-table cache: contact tables ([`mechanics::response::TableStore`]) kept on
//! disk between runs, so that a second dry run of a protocol reads the tables the first
//! one solved instead of solving them again (a curved indenter's loading path is about
//! 0.66 s per depth bucket).
//!
//! - **Content-addressed**: an entry's file is named by the SHA-256 of its model key (the
//!   whole contact spec and the solver's source fingerprint, [`mechanics::response::model_key`]),
//!   its name (`pressed/40`) and this machine's FFT code path; the file repeats the key and
//!   name, and carries the SHA-256 of its payload. A file that is truncated, damaged, of
//!   another format or for another key is deleted and the table solved again — never used.
//! - **Concurrent runs**: each entry is written to a temporary file in the same folder and
//!   renamed into place (atomic on POSIX), so a reader sees a whole entry or none. A run
//!   that misses an entry takes its build lock first, so a second run missing it meanwhile
//!   waits and reads it rather than solving it too ([`building`]); where two runs do solve
//!   one entry, they write the same bytes. Eviction holds an exclusive lock (`.lock`), and
//!   a reader that loses a file to it solves the table again.
//! - **Bounded**: past the size limit (2 GiB unless `GELRIG_CACHE_MAX_MB` says otherwise)
//!   the least recently used entries are deleted (a read refreshes an entry's time).
//! - **Where**: `$GELRIG_CACHE_DIR`, else `$XDG_CACHE_HOME/gelrig`, else
//!   `~/.cache/gelrig`; `GELRIG_NO_CACHE=1` or [`disable`] (`--no-cache`) bypasses it.
//!
//! A cache that cannot be written (a full disk, a read-only folder) never fails a run: the
//! first failure stops further writes and is kept for the run to report ([`problems`]).

mod building;
mod entry;
mod evict;

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, OnceLock};

use mechanics::response::{TableEntry, TableStore};

pub use evict::Usage;

/// What can go wrong with the cache folder itself (entries that fail are solved again).
#[derive(Debug, thiserror::Error)]
pub enum CacheError {
    /// The folder could not be created, listed or cleaned.
    #[error(
        "table cache {path}: {source}; fix: check the folder's permissions and free space, set GELRIG_CACHE_DIR to another folder, or run with --no-cache"
    )]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// No folder: neither `GELRIG_CACHE_DIR`, `XDG_CACHE_HOME` nor `HOME` is set.
    #[error("no folder for the table cache: set GELRIG_CACHE_DIR (or HOME)")]
    NoFolder,
}

/// Default size limit, bytes.
pub const DEFAULT_MAX_BYTES: u64 = 2 << 30;

/// The cache in one folder.
#[derive(Debug)]
pub struct DiskTables {
    dir: PathBuf,
    max_bytes: u64,
    machine: String,
    /// Cleared at the first write that fails: the folder is not written again.
    writable: AtomicBool,
    problems: Mutex<Vec<String>>,
    /// The entries this process is solving ([`building`]).
    building: building::Building,
    /// Entries written by this instance.
    written: AtomicU64,
}

impl DiskTables {
    /// The cache in `dir` (created on first write), bounded by `max_bytes`.
    pub fn new(dir: impl Into<PathBuf>, max_bytes: u64) -> Self {
        Self {
            dir: dir.into(),
            max_bytes,
            machine: machine(),
            writable: AtomicBool::new(true),
            problems: Mutex::new(Vec::new()),
            building: building::Building::default(),
            written: AtomicU64::new(0),
        }
    }

    /// The cache the environment names (see the module's doc), `None` when it is turned
    /// off or no folder is known.
    pub fn from_env() -> Option<Self> {
        if std::env::var("GELRIG_NO_CACHE").is_ok_and(|v| !v.is_empty() && v != "0") {
            return None;
        }
        let dir = default_dir().ok()?;
        let max_bytes = std::env::var("GELRIG_CACHE_MAX_MB")
            .ok()
            .and_then(|v| v.trim().parse::<u64>().ok())
            .map_or(DEFAULT_MAX_BYTES, |mb| mb.saturating_mul(1 << 20));
        Some(Self::new(dir, max_bytes))
    }

    /// Its folder.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Its size limit, bytes.
    pub fn max_bytes(&self) -> u64 {
        self.max_bytes
    }

    /// Entries and bytes kept now.
    pub fn usage(&self) -> Result<Usage, CacheError> {
        evict::usage(&self.entries_dir())
    }

    /// Deletes every entry; returns what was deleted.
    pub fn clear(&self) -> Result<Usage, CacheError> {
        evict::clear(&self.dir, &self.entries_dir())
    }

    /// Entries this instance has written (each one a table it solved).
    pub fn entries_written(&self) -> u64 {
        self.written.load(Ordering::Relaxed)
    }

    /// Failures to write since the last call (each once), for the run to report.
    pub fn take_problems(&self) -> Vec<String> {
        self.problems
            .lock()
            .map(|mut p| std::mem::take(&mut *p))
            .unwrap_or_default()
    }

    fn entries_dir(&self) -> PathBuf {
        self.dir.join(format!("tables-v{}", entry::FORMAT))
    }

    fn path_of(&self, model: &str, name: &str) -> PathBuf {
        let id = entry::address(model, name, &self.machine);
        self.entries_dir().join(format!("{id}.bin"))
    }

    fn note(&self, what: String) {
        self.writable.store(false, Ordering::Relaxed);
        if let Ok(mut p) = self.problems.lock() {
            p.push(what);
        }
    }
}

impl TableStore for DiskTables {
    fn load(&self, model: &str, name: &str) -> Option<TableEntry> {
        let path = self.path_of(model, name);
        if let Some(t) = entry::read(&path, model, name) {
            return Some(t);
        }
        // Missed: become its builder, or wait for the one building it and read theirs.
        if !self.writable.load(Ordering::Relaxed) || !self.building.acquire(&path) {
            return None;
        }
        let t = entry::read(&path, model, name);
        if t.is_some() {
            self.building.release(&path);
        }
        t
    }

    fn save(&self, model: &str, name: &str, table: &TableEntry) {
        let path = self.path_of(model, name);
        let written = self.write(model, name, &path, table);
        // Written or not, waiters may go on (to read it, or to solve it themselves).
        self.building.release(&path);
        if written {
            self.written.fetch_add(1, Ordering::Relaxed);
        }
    }
}

impl DiskTables {
    /// Writes one entry and keeps the cache within its bound; whether it was written.
    fn write(&self, model: &str, name: &str, path: &Path, table: &TableEntry) -> bool {
        if !self.writable.load(Ordering::Relaxed) {
            return false;
        }
        let dir = self.entries_dir();
        let written = std::fs::create_dir_all(&dir)
            .and_then(|()| entry::write(&dir, path, model, name, table));
        match written {
            Ok(()) => {
                if let Err(e) = evict::trim(&self.dir, &dir, self.max_bytes) {
                    self.note(e.to_string());
                }
                true
            }
            Err(e) => {
                self.note(
                    CacheError::Io {
                        path: dir,
                        source: e,
                    }
                    .to_string(),
                );
                false
            }
        }
    }
}

/// The folder the environment names: `$GELRIG_CACHE_DIR`, `$XDG_CACHE_HOME/gelrig`,
/// `~/.cache/gelrig`.
pub fn default_dir() -> Result<PathBuf, CacheError> {
    let var = |k: &str| {
        std::env::var_os(k)
            .filter(|v| !v.is_empty())
            .map(PathBuf::from)
    };
    if let Some(d) = var("GELRIG_CACHE_DIR") {
        return Ok(d);
    }
    if let Some(d) = var("XDG_CACHE_HOME") {
        return Ok(d.join("gelrig"));
    }
    var("HOME")
        .map(|h| h.join(".cache").join("gelrig"))
        .ok_or(CacheError::NoFolder)
}

/// The FFT code path this machine takes (rustfft picks AVX, SSE or NEON at run time, and
/// their last bits may differ): part of every address, so a cache folder shared between
/// machines never hands one machine's tables to another.
fn machine() -> String {
    #[cfg(target_arch = "x86_64")]
    {
        format!(
            "x86_64 avx={} fma={} sse4.1={}",
            std::arch::is_x86_feature_detected!("avx"),
            std::arch::is_x86_feature_detected!("fma"),
            std::arch::is_x86_feature_detected!("sse4.1"),
        )
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        std::env::consts::ARCH.to_string()
    }
}

static DISABLED: AtomicBool = AtomicBool::new(false);
static SHARED: OnceLock<Option<Arc<DiskTables>>> = OnceLock::new();

/// Turns the process's cache off (`--no-cache`): models built after this solve every table.
pub fn disable() {
    DISABLED.store(true, Ordering::Relaxed);
}

/// The process's cache ([`DiskTables::from_env`]), shared by every model it builds; `None`
/// when turned off.
pub fn shared() -> Option<Arc<DiskTables>> {
    if DISABLED.load(Ordering::Relaxed) {
        return None;
    }
    SHARED
        .get_or_init(|| DiskTables::from_env().map(Arc::new))
        .clone()
}

/// [`shared`] as the store a contact model takes.
pub fn store() -> Option<Arc<dyn TableStore>> {
    shared().map(|s| s as Arc<dyn TableStore>)
}

/// Write failures of the process's cache since the last call.
pub fn problems() -> Vec<String> {
    SHARED
        .get()
        .and_then(|s| s.as_ref())
        .map(|s| s.take_problems())
        .unwrap_or_default()
}

#[cfg(test)]
mod tests;
