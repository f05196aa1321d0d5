//! Writing files so that a failure leaves nothing half-written.
//!
//! A full disk, a read-only remount or a yanked USB drive must cost at most the row in
//! flight, never the file's shape: appends go out as one whole row and are cut back to the
//! last whole row if the write fails part-way ([`Appender`]); files that appear whole go
//! through a temporary name and a rename ([`write_atomic`], [`write_new`]); and a small
//! [`Reserve`] of disk space is held from the start so that, when the disk fills, freeing
//! it leaves room to write the run's final status.

use std::fs::{self, File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};

use super::RecordError;

pub(super) fn io(path: &Path) -> impl FnOnce(std::io::Error) -> RecordError + '_ {
    move |source| RecordError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// An append-only file written in whole records.
pub(super) struct Appender {
    path: PathBuf,
    file: File,
    /// Length up to the end of the last whole record.
    len: u64,
    /// Bytes of a torn last record cut when the file was opened.
    cut_bytes: u64,
}

impl Appender {
    /// Opens `path` for appending, creating it if missing. A file that exists belongs to a
    /// run being resumed: a torn last record (the process was killed part-way through a
    /// write) is cut back to the last whole one — it was never a record — and
    /// [`Self::cut_bytes`] says how much went.
    pub(super) fn create(path: PathBuf) -> Result<Self, RecordError> {
        use std::io::{Read, Seek, SeekFrom};
        let mut file = OpenOptions::new()
            .create(true)
            .truncate(false)
            .read(true)
            .write(true)
            .open(&path)
            .map_err(io(&path))?;
        let end = file.seek(SeekFrom::End(0)).map_err(io(&path))?;
        let mut len = end;
        if end > 0 {
            // Records end in a newline: find the last one in the tail.
            let tail = end.min(1 << 20);
            file.seek(SeekFrom::Start(end - tail)).map_err(io(&path))?;
            let mut buf = Vec::with_capacity(tail as usize);
            Read::by_ref(&mut file)
                .take(tail)
                .read_to_end(&mut buf)
                .map_err(io(&path))?;
            len = match buf.iter().rposition(|&b| b == b'\n') {
                Some(i) => end - tail + i as u64 + 1,
                None if tail == end => 0,
                None => end,
            };
            if len < end {
                file.set_len(len).map_err(io(&path))?;
            }
            file.seek(SeekFrom::Start(len)).map_err(io(&path))?;
        }
        Ok(Self {
            path,
            file,
            len,
            cut_bytes: end - len,
        })
    }

    /// Bytes of a torn last record cut when the file was opened.
    pub(super) fn cut_bytes(&self) -> u64 {
        self.cut_bytes
    }

    /// True if the file held records when it was opened (a resumed run's).
    pub(super) fn had_records(&self) -> bool {
        self.len > 0
    }

    /// The file.
    pub(super) fn path(&self) -> &Path {
        &self.path
    }

    /// Appends `bytes` as one record: on failure the file is cut back to its previous
    /// length, so a reader never sees a torn record.
    pub(super) fn append(&mut self, bytes: &[u8]) -> Result<(), RecordError> {
        use std::io::{Seek, SeekFrom};
        match self.file.write_all(bytes) {
            Ok(()) => {
                self.len += bytes.len() as u64;
                Ok(())
            }
            Err(e) => {
                // Best effort: the error that matters is the write's.
                let _ = self.file.set_len(self.len);
                let _ = self.file.seek(SeekFrom::Start(self.len));
                Err(io(&self.path)(e))
            }
        }
    }

    /// Makes everything appended so far durable.
    pub(super) fn sync(&mut self) -> Result<(), RecordError> {
        self.file.sync_data().map_err(io(&self.path))
    }
}

/// The memory a row is encoded into before it is appended: shared between the CSV
/// encoder, which owns one handle, and the file, which drains it after each row.
#[derive(Clone, Default)]
struct Staging(std::sync::Arc<std::sync::Mutex<Vec<u8>>>);

impl Write for Staging {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        records::lock(&self.0).extend_from_slice(buf);
        Ok(buf.len())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

/// A CSV file of rows of one type, each written whole.
pub(super) struct CsvFile {
    out: Appender,
    /// One encoder for the file's life (it writes the header before the first row).
    encoder: csv::Writer<Staging>,
    staged: Staging,
}

impl CsvFile {
    /// A new file, its header written with the first row; or a resumed run's file, whose
    /// rows continue under the header it has.
    pub(super) fn create(path: PathBuf) -> Result<Self, RecordError> {
        let staged = Staging::default();
        let out = Appender::create(path)?;
        let encoder = csv::WriterBuilder::new()
            .has_headers(!out.had_records())
            .from_writer(staged.clone());
        Ok(Self {
            out,
            encoder,
            staged,
        })
    }

    /// A file whose header, from `example`'s field names, is on disk at once (so even a
    /// run with no row has a readable file); a resumed run's file keeps its own.
    pub(super) fn with_header_of<T: serde::Serialize>(
        path: PathBuf,
        example: &T,
    ) -> Result<Self, RecordError> {
        let mut f = Self::create(path)?;
        if f.out.had_records() {
            return Ok(f);
        }
        let bytes = f.encode(example)?;
        let header_len = bytes
            .iter()
            .position(|&b| b == b'\n')
            .map(|i| i + 1)
            .unwrap_or(bytes.len());
        f.out.append(&bytes[..header_len])?;
        f.out.sync()?;
        Ok(f)
    }

    /// Bytes of a torn last row cut when the file was opened.
    pub(super) fn cut_bytes(&self) -> u64 {
        self.out.cut_bytes()
    }

    /// One row in memory, with the header before the first.
    fn encode<T: serde::Serialize>(&mut self, row: &T) -> Result<Vec<u8>, RecordError> {
        let path = self.out.path();
        self.encoder
            .serialize(row)
            .map_err(|source| RecordError::Csv {
                path: path.to_path_buf(),
                source,
            })?;
        self.encoder.flush().map_err(io(path))?;
        Ok(std::mem::take(&mut *records::lock(&self.staged.0)))
    }

    /// Writes one row through to the OS, whole or not at all.
    pub(super) fn row<T: serde::Serialize>(&mut self, row: &T) -> Result<(), RecordError> {
        let bytes = self.encode(row)?;
        self.out.append(&bytes)
    }

    /// Makes the rows durable.
    pub(super) fn sync(&mut self) -> Result<(), RecordError> {
        self.out.sync()
    }
}

/// The temporary name a file is written under before it is renamed into place.
fn temporary(path: &Path) -> PathBuf {
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(".tmp");
    path.with_file_name(name)
}

fn write_temp(tmp: &Path, contents: &[u8], sync: bool) -> Result<(), RecordError> {
    let r = (|| {
        let mut f = File::create(tmp)?;
        f.write_all(contents)?;
        if sync {
            f.sync_all()?;
        }
        Ok(())
    })();
    r.map_err(|e| {
        let _ = fs::remove_file(tmp);
        io(tmp)(e)
    })
}

/// Writes `contents` to `path` atomically: temp file, fsync, rename, fsync the directory.
/// On failure the temporary file is removed and `path` is untouched.
pub fn write_atomic(path: &Path, contents: &[u8]) -> Result<(), RecordError> {
    let tmp = temporary(path);
    write_temp(&tmp, contents, true)?;
    if let Err(e) = fs::rename(&tmp, path) {
        let _ = fs::remove_file(&tmp);
        return Err(io(path)(e));
    }
    if let Some(dir) = path.parent()
        && let Ok(d) = File::open(dir)
    {
        let _ = d.sync_all();
    }
    Ok(())
}

/// Writes a new file that appears whole or not at all (temp name, rename), without the
/// per-file fsync of [`write_atomic`]: frames are made durable with their step.
pub(super) fn write_new(path: &Path, contents: &[u8]) -> Result<(), RecordError> {
    let tmp = temporary(path);
    write_temp(&tmp, contents, false)?;
    fs::rename(&tmp, path).map_err(|e| {
        let _ = fs::remove_file(&tmp);
        io(path)(e)
    })
}

/// Disk space held back from the start of a run so the final status can still be written
/// when the disk fills: released on the first write failure, and at the end of the run.
pub(super) struct Reserve {
    path: Option<PathBuf>,
}

impl Reserve {
    /// Bytes held: `run.yaml` and the journal's last lines need a few kB; 128 KiB leaves
    /// room for a long error message and a filesystem's block granularity.
    const BYTES: usize = 128 * 1024;

    /// Writes the reserve file (fsynced, so its blocks are really allocated).
    pub(super) fn hold(path: PathBuf) -> Result<Self, RecordError> {
        write_temp(&path, &vec![0u8; Self::BYTES], true)?;
        Ok(Self { path: Some(path) })
    }

    /// Gives the space back.
    pub(super) fn release(&mut self) {
        if let Some(p) = self.path.take() {
            let _ = fs::remove_file(p);
        }
    }
}

impl Drop for Reserve {
    fn drop(&mut self) {
        self.release();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn failed_atomic_write_leaves_no_temporary() {
        let dir = tempfile::tempdir().expect("tempdir");
        // A directory where the file should go makes the rename fail.
        let target = dir.path().join("run.yaml");
        fs::create_dir(&target).expect("mkdir");
        assert!(write_atomic(&target, b"status: completed\n").is_err());
        let left: Vec<_> = fs::read_dir(dir.path())
            .expect("list")
            .map(|e| e.expect("entry").file_name())
            .collect();
        assert_eq!(left, vec![std::ffi::OsString::from("run.yaml")]);
    }

    #[derive(serde::Serialize)]
    struct Row {
        t_ns: u64,
        fz_n: f64,
    }

    #[test]
    fn csv_header_then_whole_rows() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("force.csv");
        let mut f =
            CsvFile::with_header_of(path.clone(), &Row { t_ns: 0, fz_n: 0.0 }).expect("create");
        assert_eq!(fs::read_to_string(&path).expect("read"), "t_ns,fz_n\n");
        f.row(&Row { t_ns: 5, fz_n: 1.5 }).expect("row");
        f.row(&Row { t_ns: 6, fz_n: 2.5 }).expect("row");
        assert_eq!(
            fs::read_to_string(&path).expect("read"),
            "t_ns,fz_n\n5,1.5\n6,2.5\n"
        );
    }

    #[test]
    fn a_resumed_file_loses_only_its_torn_row_and_keeps_one_header() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("force.csv");
        {
            let mut f = CsvFile::create(path.clone()).expect("create");
            f.row(&Row { t_ns: 5, fz_n: 1.5 }).expect("row");
        }
        // Killed part-way through the next row.
        let mut text = fs::read_to_string(&path).expect("read");
        text.push_str("6,2.");
        fs::write(&path, &text).expect("tear");
        let mut f = CsvFile::create(path.clone()).expect("reopen");
        assert_eq!(f.cut_bytes(), 4);
        f.row(&Row { t_ns: 7, fz_n: 3.5 }).expect("row");
        assert_eq!(
            fs::read_to_string(&path).expect("read"),
            "t_ns,fz_n\n5,1.5\n7,3.5\n"
        );
        // A file holding only a header keeps it, and gains no second one.
        let steps = dir.path().join("steps.csv");
        drop(CsvFile::with_header_of(steps.clone(), &Row { t_ns: 0, fz_n: 0.0 }).expect("new"));
        let mut f =
            CsvFile::with_header_of(steps.clone(), &Row { t_ns: 0, fz_n: 0.0 }).expect("reopen");
        assert_eq!(f.cut_bytes(), 0);
        f.row(&Row { t_ns: 1, fz_n: 0.5 }).expect("row");
        assert_eq!(
            fs::read_to_string(&steps).expect("read"),
            "t_ns,fz_n\n1,0.5\n"
        );
    }
}
