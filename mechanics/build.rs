//! Fingerprints this crate's source for the solved-table cache: a table kept on disk is
//! read back only by the very code that solved it. Any edit under `src/` (a solver's
//! tolerance, a path's increments, a grid rule) changes `MECHANICS_SOURCE_SHA256`, and with
//! it every table's key, so a stale table is never used — it is solved again.

use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};

fn sources(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let p = e.path();
        if p.is_dir() {
            sources(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

fn main() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let src = root.join("src");
    println!("cargo:rerun-if-changed=src");
    println!("cargo:rerun-if-changed=Cargo.toml");
    let mut files = Vec::new();
    sources(&src, &mut files);
    files.sort();
    let mut h = Sha256::new();
    for f in files
        .iter()
        .chain(std::iter::once(&root.join("Cargo.toml")))
    {
        let rel = f.strip_prefix(root).unwrap_or(f);
        h.update(rel.to_string_lossy().as_bytes());
        h.update([0]);
        // An unreadable file still changes the fingerprint (by its name alone).
        h.update(std::fs::read(f).unwrap_or_default());
        h.update([0]);
    }
    let hex: String = h.finalize().iter().map(|b| format!("{b:02x}")).collect();
    println!("cargo:rustc-env=MECHANICS_SOURCE_SHA256={hex}");
}
