//! One entry's file: `MAGIC`, the format, the payload's length and SHA-256, then the
//! payload — postcard of (model key, name, table), which stores every `f64` as its
//! IEEE-754 bits, so a table read back is the table solved, NaN included.

use std::io::{Read, Write};
use std::path::Path;

use mechanics::response::TableEntry;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

/// The file format; bumped with any change to the layout below.
pub(crate) const FORMAT: u32 = 1;
const MAGIC: &[u8; 8] = b"GELRIGTB";
const HEADER: usize = 8 + 4 + 8 + 32;

#[derive(Serialize)]
struct Out<'a> {
    model: &'a str,
    name: &'a str,
    table: &'a TableEntry,
}

#[derive(Deserialize)]
struct In {
    model: String,
    name: String,
    table: TableEntry,
}

fn sha256_hex(parts: &[&[u8]]) -> String {
    let mut h = Sha256::new();
    for p in parts {
        h.update((p.len() as u64).to_le_bytes());
        h.update(p);
    }
    h.finalize().iter().map(|b| format!("{b:02x}")).collect()
}

/// The entry's address: SHA-256 of its model key, name and machine.
pub(crate) fn address(model: &str, name: &str, machine: &str) -> String {
    sha256_hex(&[model.as_bytes(), name.as_bytes(), machine.as_bytes()])
}

/// Writes the entry to a temporary file in `dir` and renames it to `path`.
pub(crate) fn write(
    dir: &Path,
    path: &Path,
    model: &str,
    name: &str,
    table: &TableEntry,
) -> std::io::Result<()> {
    let payload = postcard::to_stdvec(&Out { model, name, table })
        .map_err(|e| std::io::Error::other(format!("encoding the table {name}: {e}")))?;
    let digest = Sha256::digest(&payload);
    let mut tmp = tempfile::Builder::new()
        .prefix(".entry-")
        .suffix(".tmp")
        .tempfile_in(dir)?;
    {
        let f = tmp.as_file_mut();
        f.write_all(MAGIC)?;
        f.write_all(&FORMAT.to_le_bytes())?;
        f.write_all(&(payload.len() as u64).to_le_bytes())?;
        f.write_all(&digest)?;
        f.write_all(&payload)?;
        f.sync_data()?;
    }
    tmp.persist(path).map_err(|e| e.error)?;
    Ok(())
}

/// Reads the entry at `path` if it is whole, unaltered and for this model and name; a file
/// that is not is deleted (the table is solved again and written afresh). A read refreshes
/// the file's time, which eviction goes by.
pub(crate) fn read(path: &Path, model: &str, name: &str) -> Option<TableEntry> {
    let mut f = std::fs::File::open(path).ok()?;
    let mut bytes = Vec::new();
    if f.read_to_end(&mut bytes).is_err() {
        return None;
    }
    match decode(&bytes, model, name) {
        Some(t) => {
            let _ = f.set_modified(std::time::SystemTime::now());
            Some(t)
        }
        None => {
            // Damaged, truncated or another key's: never used. (A race with another run
            // writing the same entry renames a whole file over this one; deleting it
            // costs that run nothing but a solve next time.)
            let _ = std::fs::remove_file(path);
            None
        }
    }
}

fn decode(bytes: &[u8], model: &str, name: &str) -> Option<TableEntry> {
    if bytes.len() < HEADER || &bytes[..8] != MAGIC {
        return None;
    }
    let format = u32::from_le_bytes(bytes[8..12].try_into().ok()?);
    let len = u64::from_le_bytes(bytes[12..20].try_into().ok()?);
    let payload = &bytes[HEADER..];
    if format != FORMAT || payload.len() as u64 != len {
        return None;
    }
    if Sha256::digest(payload).as_slice() != &bytes[20..HEADER] {
        return None;
    }
    let e: In = postcard::from_bytes(payload).ok()?;
    (e.model == model && e.name == name).then_some(e.table)
}
