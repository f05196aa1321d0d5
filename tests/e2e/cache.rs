//! The solved-table cache seen from the command line: a run that reads kept tables records
//! what a run that solves them records, byte for byte, seed for seed; `gelrig cache` shows
//! and clears it; `--no-cache` bypasses it; a damaged cache is solved again, never used.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

use crate::support::{gelrig, protocol};

/// Every recorded file of the run in `out` (CSV tables and frames) by its path inside the
/// run: what a run measured, not when the wall clock says it ran (the journal and the
/// manifest carry wall times).
fn recorded(out: &Path) -> BTreeMap<String, Vec<u8>> {
    let run = std::fs::read_dir(out)
        .expect("runs dir")
        .flatten()
        .map(|e| e.path())
        .find(|p| p.is_dir())
        .expect("a run directory");
    let mut files = BTreeMap::new();
    let mut stack = vec![run.clone()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).expect("dir").flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|x| x == "csv" || x == "png") {
                let rel = p.strip_prefix(&run).expect("inside").display().to_string();
                files.insert(rel, std::fs::read(&p).expect("file"));
            }
        }
    }
    files
}

fn dry_run(cache: &Path, out: &Path, extra: &[&str]) -> BTreeMap<String, Vec<u8>> {
    let r = Command::new(gelrig())
        .env("GELRIG_CACHE_DIR", cache)
        .env_remove("GELRIG_NO_CACHE")
        .arg("run")
        .arg(protocol("box-shear-sphere"))
        .args(["--seed", "4", "--quiet", "--out"])
        .arg(out)
        .args(extra)
        .output()
        .expect("gelrig runs");
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert!(
        !String::from_utf8_lossy(&r.stderr).contains("table cache"),
        "{}",
        String::from_utf8_lossy(&r.stderr)
    );
    recorded(out)
}

fn cache_cmd(cache: &Path, args: &[&str]) -> String {
    let r = Command::new(gelrig())
        .env("GELRIG_CACHE_DIR", cache)
        .env_remove("GELRIG_NO_CACHE")
        .arg("cache")
        .args(args)
        .output()
        .expect("gelrig cache");
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    String::from_utf8_lossy(&r.stdout).into_owned()
}

fn entries(cache: &Path) -> Vec<PathBuf> {
    let mut v = Vec::new();
    for d in std::fs::read_dir(cache).into_iter().flatten().flatten() {
        if d.path().is_dir() {
            v.extend(
                std::fs::read_dir(d.path())
                    .into_iter()
                    .flatten()
                    .flatten()
                    .map(|e| e.path())
                    .filter(|p| p.extension().is_some_and(|x| x == "bin")),
            );
        }
    }
    v
}

#[test]
fn a_run_on_kept_tables_records_what_a_run_that_solves_them_records() {
    let tmp = tempfile::tempdir().expect("temp dir");
    let cache = tmp.path().join("cache");
    let solved = dry_run(&cache, &tmp.path().join("cold"), &[]);
    assert!(
        solved.keys().any(|k| k.ends_with("force.csv")) && solved.len() >= 3,
        "{:?}",
        solved.keys()
    );
    let kept = entries(&cache);
    assert!(kept.len() >= 4, "the run kept its tables: {kept:?}");
    let shown = cache_cmd(&cache, &[]);
    assert!(
        shown.contains(&format!("{} tables", kept.len()))
            && shown.contains(&cache.display().to_string()),
        "{shown}"
    );

    // An entry solved again is renamed into place (a new inode); one read keeps its own.
    let inodes = |files: &[PathBuf]| -> Vec<u64> {
        use std::os::unix::fs::MetadataExt;
        files
            .iter()
            .map(|f| std::fs::metadata(f).expect("entry").ino())
            .collect()
    };
    let before = inodes(&kept);
    let warm = dry_run(&cache, &tmp.path().join("warm"), &[]);
    assert_eq!(
        solved.keys().collect::<Vec<_>>(),
        warm.keys().collect::<Vec<_>>()
    );
    for (k, v) in &solved {
        assert!(
            warm[k] == *v,
            "{k} differs between the cold and the warm run"
        );
    }
    assert_eq!(entries(&cache).len(), kept.len(), "nothing new solved");
    assert_eq!(inodes(&kept), before, "every table read, none solved again");

    let bypassed = dry_run(&cache, &tmp.path().join("nocache"), &["--no-cache"]);
    for (k, v) in &solved {
        assert!(bypassed[k] == *v, "{k} differs with --no-cache");
    }

    // Damaged: every entry cut short. Solved again, the same records, whole entries back.
    for e in &kept {
        let b = std::fs::read(e).expect("entry");
        std::fs::write(e, &b[..b.len() / 3]).expect("truncate");
    }
    let repaired = dry_run(&cache, &tmp.path().join("repaired"), &[]);
    for (k, v) in &solved {
        assert!(repaired[k] == *v, "{k} differs after the cache was damaged");
    }
    for e in entries(&cache) {
        assert_eq!(&std::fs::read(&e).expect("entry")[..8], b"GELRIGTB");
    }

    let cleared = cache_cmd(&cache, &["clear"]);
    assert!(
        cleared.contains(&format!("{} tables", kept.len())),
        "{cleared}"
    );
    assert!(entries(&cache).is_empty());
}
