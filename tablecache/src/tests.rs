//! The cache against its promises: the same model bit for bit from kept tables; damaged,
//! truncated and foreign entries never used; concurrent builders; the size bound.

use super::*;
use mechanics::Indenter;
use mechanics::contact::Contact;
use mechanics::geometry::presets;
use mechanics::response::{ContactModel, ModelSpec, Quality, State};
use std::sync::OnceLock;

/// The box gel (its shipped layer and material) under a 12.68 mm sphere, shear and a field view: a curved indenter pressed
/// with friction, so every kind of entry is solved (normal, pressed states, tangential
/// tables, pressing tractions, field pressures). At a coarse curved grid and loading path and
/// a 0.1 mm range: the cache's promises do not depend on resolution, and every test solves
/// this model at least once.
fn spec() -> ModelSpec {
    let contact = Contact::new(
        presets::BOX_LAYER,
        presets::box_material(),
        Indenter::Sphere { diameter_mm: 12.68 },
    )
    .expect("valid contact");
    ModelSpec {
        contact,
        max_depth_mm: 0.1,
        shear: true,
        twist: false,
        field_view_mm: Some((12.0, 9.0)),
        pressing_friction: true,
        quality: Quality {
            cells_curved: 8,
            field_cells: 32,
            path_steps: 4,
            ..Quality::default()
        },
    }
}

/// Everything a run reads from the model at two depths, as bits.
fn readings(store: Option<Arc<dyn TableStore>>) -> Vec<u64> {
    let mut m = ContactModel::build_stored(spec(), store).expect("builds");
    let mut out = Vec::new();
    // On a bucket (0.5 % of the 4.2 mm layer is 0.021 mm): one bucket of each table.
    {
        let d = 0.084;
        out.push(m.normal_force_n(d).to_bits());
        out.push(m.contact_radius_mm(d).to_bits());
        let (b, stick) = m.shear_curve(d).expect("shear built");
        out.extend(b.x.iter().chain(&b.f).chain(&stick).map(|v| v.to_bits()));
        let (ax, ay) = m.tilt_arms_mm(d);
        out.extend([ax.to_bits(), ay.to_bits()]);
        let f = m
            .field(State {
                depth_mm: d,
                shear_n: 0.05,
                torque_nmm: 0.0,
            })
            .expect("field built");
        out.extend(f.ux.iter().chain(&f.uy).chain(&f.uz).map(|v| v.to_bits()));
    }
    out
}

/// The readings of a model that keeps nothing, solved once for all the tests.
fn reference() -> Vec<u64> {
    static R: OnceLock<Vec<u64>> = OnceLock::new();
    R.get_or_init(|| readings(None)).clone()
}

fn disk(dir: &Path, max_bytes: u64) -> Arc<DiskTables> {
    Arc::new(DiskTables::new(dir, max_bytes))
}

fn entry_files(d: &DiskTables) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(d.entries_dir())
        .map(|rd| rd.flatten().map(|e| e.path()).collect())
        .unwrap_or_default();
    v.retain(|p| p.extension().is_some_and(|x| x == "bin"));
    v.sort();
    v
}

#[test]
fn kept_tables_give_the_same_model_bit_for_bit_and_are_read_not_solved() {
    let tmp = tempfile::tempdir().expect("temp dir");
    let reference = reference();
    let d = disk(tmp.path(), DEFAULT_MAX_BYTES);
    let cold = readings(Some(d.clone()));
    assert_eq!(
        cold, reference,
        "a model that fills the cache reads as one without"
    );
    let files = entry_files(&d);
    assert!(
        files.len() >= 6,
        "normal, pressed, tangential, pressing, field and tilt entries kept: {files:?}"
    );
    // An entry written again is renamed into place: a new inode. Read, it keeps its own.
    let inode = |f: &PathBuf| {
        use std::os::unix::fs::MetadataExt;
        std::fs::metadata(f).expect("entry").ino()
    };
    let stamp: Vec<_> = files.iter().map(inode).collect();
    let warm = readings(Some(d.clone()));
    assert_eq!(
        warm, reference,
        "a model read from the cache is the same bit for bit"
    );
    // Read, not solved again: no entry added or rewritten.
    assert_eq!(entry_files(&d), files);
    let again: Vec<_> = files.iter().map(inode).collect();
    assert_eq!(
        again, stamp,
        "every entry read in place, none solved and written again"
    );
    assert!(d.take_problems().is_empty());
}

#[test]
fn a_damaged_truncated_or_foreign_entry_is_never_used_and_is_solved_again() {
    let tmp = tempfile::tempdir().expect("temp dir");
    let reference = reference();
    let d = disk(tmp.path(), DEFAULT_MAX_BYTES);
    readings(Some(d.clone()));
    let files = entry_files(&d);
    assert!(files.len() >= 6);
    // Damage every kept entry a different way: a flipped payload bit, a truncation, an
    // empty file, another entry's bytes, a wrong magic.
    for (i, f) in files.iter().enumerate() {
        let mut b = std::fs::read(f).expect("entry");
        match i % 5 {
            0 => {
                let k = b.len() - 9;
                b[k] ^= 0x10;
            }
            1 => b.truncate(b.len() / 2),
            2 => b.clear(),
            3 => b = std::fs::read(&files[(i + 1) % files.len()]).expect("entry"),
            _ => b[0] = b'X',
        }
        std::fs::write(f, b).expect("damage");
    }
    let again = readings(Some(d.clone()));
    assert_eq!(again, reference, "damaged entries solved again, never used");
    // Each was replaced by a whole, valid entry.
    let third = readings(Some(d.clone()));
    assert_eq!(third, reference);
    for f in entry_files(&d) {
        let b = std::fs::read(&f).expect("entry");
        assert_eq!(&b[..8], b"GELRIGTB", "{f:?} rewritten whole");
    }
}

#[test]
fn concurrent_builders_share_one_folder_and_agree_and_solve_each_table_once() {
    let tmp = tempfile::tempdir().expect("temp dir");
    let reference = reference();
    let dir = tmp.path().to_path_buf();
    // Three builders of their own (as three runs would be), started together on an empty
    // folder: without build locks each would solve every table.
    let runs: Vec<_> = (0..3)
        .map(|_| {
            let dir = dir.clone();
            std::thread::spawn(move || {
                let d = disk(&dir, DEFAULT_MAX_BYTES);
                let r = readings(Some(d.clone()));
                (r, d.take_problems(), d.entries_written())
            })
        })
        .collect();
    let mut written = 0;
    for r in runs {
        let (r, problems, w) = r.join().expect("builder thread");
        assert_eq!(r, reference);
        assert!(problems.is_empty(), "{problems:?}");
        written += w;
    }
    let d = disk(&dir, DEFAULT_MAX_BYTES);
    let files = entry_files(&d).len() as u64;
    assert_eq!(
        written, files,
        "each of the {files} entries solved and written by one builder only"
    );
    assert_eq!(readings(Some(d.clone())), reference);
    assert_eq!(d.entries_written(), 0, "a later model reads every entry");
}

#[test]
fn past_its_limit_the_cache_drops_the_least_recently_used_entries() {
    let tmp = tempfile::tempdir().expect("temp dir");
    let d = disk(tmp.path(), DEFAULT_MAX_BYTES);
    readings(Some(d.clone()));
    let full = d.usage().expect("usage");
    assert!(full.entries >= 6 && full.bytes > 0);
    // A limit of half of it: a new entry trims to 90 % of the limit, oldest first.
    let files = entry_files(&d);
    let oldest = files[0].clone();
    let old = std::time::SystemTime::now() - std::time::Duration::from_secs(3600);
    std::fs::File::options()
        .write(true)
        .open(&oldest)
        .and_then(|f| f.set_modified(old))
        .expect("age an entry");
    let limit = full.bytes / 2;
    let small = disk(tmp.path(), limit);
    // Another spec's entry (another depth range) triggers the trim.
    let mut other = spec();
    other.max_depth_mm = 0.09;
    ContactModel::build_stored(other, Some(small.clone() as Arc<dyn TableStore>)).expect("builds");
    let after = small.usage().expect("usage");
    assert!(after.bytes <= limit, "{after:?} within {limit}");
    assert!(!oldest.exists(), "the least recently used entry went first");
    // Cleared: nothing left, and the count says what went.
    let gone = small.clear().expect("clear");
    assert_eq!(gone, after);
    assert_eq!(small.usage().expect("usage"), Usage::default());
    let left: Vec<_> = std::fs::read_dir(small.entries_dir())
        .expect("entries folder")
        .flatten()
        .map(|e| e.path())
        .collect();
    assert!(
        left.is_empty(),
        "nothing left behind, build locks included: {left:?}"
    );
}

#[test]
fn a_folder_that_cannot_be_written_is_reported_once_and_never_fails_the_model() {
    let tmp = tempfile::tempdir().expect("temp dir");
    // A file where the folder should be: every write fails.
    let blocked = tmp.path().join("not-a-folder");
    std::fs::write(&blocked, b"").expect("file");
    let d = disk(&blocked, DEFAULT_MAX_BYTES);
    assert_eq!(readings(Some(d.clone())), reference());
    let problems = d.take_problems();
    assert_eq!(problems.len(), 1, "{problems:?}");
    assert!(
        problems[0].contains("not-a-folder") && problems[0].contains("fix:"),
        "{}",
        problems[0]
    );
}

#[test]
fn the_folder_follows_the_environment_and_no_cache_turns_it_off() {
    // default_dir reads the environment; the test process's own is left alone (other
    // tests run beside it), so only what it already says is checked.
    match std::env::var_os("GELRIG_CACHE_DIR").filter(|v| !v.is_empty()) {
        Some(d) => assert_eq!(default_dir().expect("dir"), PathBuf::from(d)),
        None => {
            if let Ok(d) = default_dir() {
                assert!(d.ends_with("gelrig"), "{d:?}");
            }
        }
    }
    disable();
    assert!(shared().is_none() && store().is_none());
    DISABLED.store(false, Ordering::Relaxed);
}
