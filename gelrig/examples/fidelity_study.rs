//! Error against run time of the simulated bench's fidelity levels (docs/benchmarks/
//! simulator.md, "Fidelity levels"): every shipped protocol dry-run at `fast`, `default` and
//! `reference`, each from a cold table cache and again warm, and each level's step forces
//! against the reference level's.
//!
//! ```text
//! cargo run --release -p gelrig --example fidelity_study -- [--seed N] [PROTOCOL ...]
//! ```
//!
//! The error of a run is its worst channel (Fx, Fy, Fz, Tz; those the reference moves by
//! more than 1 N or N·mm): the largest difference of a step's recorded force from the
//! reference run's same step, in % of the reference's range over the run's steps (and, beside
//! it, the root-mean-square of those differences, worst channel). The same
//! seed gives every level the same sensor noise, so what differs is the model. Cold: the
//! table cache emptied first (`gelrig cache clear`); warm: the same run again. A warm run's
//! steps must equal its cold run's, byte for byte (the cache changes nothing).

use std::path::{Path, PathBuf};
use std::time::Instant;

use experiments::load::{Overrides, load_with_overrides};
use gelrig::sim::Fidelity;
use runner::run_virtual_blocking;

type Row = std::collections::BTreeMap<String, String>;

/// Channels compared, and the least range of the reference's steps that makes one count: a
/// grasp's step means of Tz (a 2 Hz twist averages out) span little more than 0.5 N·mm, and
/// on seed 2 of `lifting-can` one step's difference there read as 44 % of that range while
/// the forces agreed: a channel the run hardly moves says nothing about the model.
const CHANNELS: [&str; 4] = ["fx_n", "fy_n", "fz_n", "tz_nmm"];
const MIN_RANGE: f64 = 1.0;

fn rows(path: &Path) -> Vec<Row> {
    let mut r = csv::Reader::from_path(path).expect("steps.csv");
    r.deserialize().map(|x| x.expect("row")).collect()
}

/// One dry run: its steps.csv text and wall seconds.
fn dry_run(protocol: &Path, level: Fidelity, out: &Path, seed: u64) -> (String, f64) {
    let overrides = Overrides {
        fidelity: Some(level),
        ..Default::default()
    };
    let loaded = load_with_overrides(protocol, None, &Default::default(), &overrides)
        .unwrap_or_else(|d| panic!("{}: {d:?}", protocol.display()));
    std::fs::create_dir_all(out).expect("out");
    let started = Instant::now();
    let o = run_virtual_blocking(&loaded, out, seed).expect("run");
    let wall = started.elapsed().as_secs_f64();
    assert_eq!(
        o.status,
        rundir::write::Status::Completed,
        "{}: {:?}",
        protocol.display(),
        o.message
    );
    let steps = std::fs::read_to_string(o.dir.join("steps.csv")).expect("steps");
    std::fs::remove_dir_all(&o.dir).expect("remove the run");
    (steps, wall)
}

/// The worst channel's largest step difference from `reference`, % of its range, and which;
/// and the largest channel's root-mean-square step difference, % of its range. A grasp's slip
/// or regrip that lands a step earlier moves the first figure a lot and the second little.
fn error_pct(steps: &str, reference: &str, tmp: &Path) -> (f64, &'static str, f64) {
    let (a, b) = (tmp.join("a.csv"), tmp.join("b.csv"));
    std::fs::write(&a, steps).expect("write");
    std::fs::write(&b, reference).expect("write");
    let (got, want) = (rows(&a), rows(&b));
    assert_eq!(got.len(), want.len(), "the same steps at every level");
    let value = |r: &Row, c: &str| r.get(c).and_then(|v| v.parse::<f64>().ok());
    let mut worst = (0.0, "none");
    let mut worst_rms: f64 = 0.0;
    for c in CHANNELS {
        let v: Vec<f64> = want.iter().filter_map(|r| value(r, c)).collect();
        let range = v.iter().copied().fold(f64::NEG_INFINITY, f64::max)
            - v.iter().copied().fold(f64::INFINITY, f64::min);
        if range.is_nan() || range <= MIN_RANGE {
            continue;
        }
        let diffs: Vec<f64> = got
            .iter()
            .zip(&want)
            .filter_map(|(g, w)| Some((value(g, c)? - value(w, c)?).abs()))
            .collect();
        let diff = diffs.iter().copied().fold(0.0, f64::max);
        let rms = (diffs.iter().map(|d| d * d).sum::<f64>() / diffs.len().max(1) as f64).sqrt();
        worst_rms = worst_rms.max(100.0 * rms / range);
        let pct = 100.0 * diff / range;
        if pct > worst.0 {
            worst = (pct, c);
        }
    }
    (worst.0, worst.1, worst_rms)
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut seed = 1;
    let mut names = Vec::new();
    let mut it = args.iter();
    while let Some(a) = it.next() {
        if a == "--seed" {
            seed = it.next().and_then(|s| s.parse().ok()).expect("--seed N");
        } else {
            names.push(a.clone());
        }
    }
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut protocols: Vec<PathBuf> = std::fs::read_dir(root.join("protocols"))
        .expect("protocols")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "yaml"))
        .filter(|p| {
            names.is_empty()
                || names
                    .iter()
                    .any(|n| p.file_stem().is_some_and(|s| s == n.as_str()))
        })
        .collect();
    protocols.sort();
    let tmp = tempfile::tempdir().expect("tmp");
    let cache = tablecache::shared()
        .expect("the table cache is off (GELRIG_NO_CACHE): the study measures cold and warm runs");
    eprintln!(
        "table cache {} (emptied before each cold run)",
        cache.dir().display()
    );
    println!(
        "| protocol | fast: error, cold, warm | default: error, cold, warm | reference: cold, warm | fast / default, cold |"
    );
    println!("|---|---|---|---|---|");
    // (protocol, fast's error %, default's error %, default cold / fast cold).
    let mut summary: Vec<(String, f64, f64, f64)> = Vec::new();
    for p in &protocols {
        let name = p.file_stem().and_then(|s| s.to_str()).unwrap_or("?");
        let mut cells = Vec::new();
        let mut reference = String::new();
        let mut cold_s = Vec::new();
        let mut errors = Vec::new();
        for level in [Fidelity::Reference, Fidelity::Default, Fidelity::Fast] {
            cache.clear().expect("clear the cache");
            let out = tmp.path().join(level.as_str());
            let (steps, cold) = dry_run(p, level, &out, seed);
            let (warm_steps, warm) = dry_run(p, level, &out, seed);
            assert_eq!(
                steps,
                warm_steps,
                "{name} at {}: warm != cold",
                level.as_str()
            );
            cold_s.push(cold);
            if level == Fidelity::Reference {
                cells.push(format!("{cold:.2} s, {warm:.2} s"));
                reference = steps;
            } else {
                let (pct, channel, rms) = error_pct(&steps, &reference, tmp.path());
                errors.push(pct);
                cells.push(format!(
                    "{pct:.2} % ({channel}; rms {rms:.2} %), {cold:.2} s, {warm:.2} s"
                ));
            }
            eprintln!(
                "{name} {}: {cold:.2} s cold, {warm:.2} s warm",
                level.as_str()
            );
        }
        println!(
            "| {name} | {} | {} | {} | {:.1}× |",
            cells[2],
            cells[1],
            cells[0],
            cold_s[1] / cold_s[2]
        );
        summary.push((
            name.to_string(),
            errors[1],
            errors[0],
            cold_s[1] / cold_s[2],
        ));
    }
    let worst = |pick: fn(&(String, f64, f64, f64)) -> f64| {
        summary
            .iter()
            .max_by(|a, b| pick(a).total_cmp(&pick(b)))
            .map(|s| (pick(s), s.0.clone()))
            .unwrap_or_default()
    };
    let (fast, fast_at) = worst(|s| s.1);
    let (default, default_at) = worst(|s| s.2);
    let mut speed: Vec<f64> = summary.iter().map(|s| s.3).collect();
    speed.sort_by(f64::total_cmp);
    println!();
    println!("worst fast error: {fast:.2} % ({fast_at})");
    println!("worst default error: {default:.2} % ({default_at})");
    if let (Some(lo), Some(hi)) = (speed.first(), speed.last()) {
        println!(
            "fast against default, cold: {lo:.1}× to {hi:.1}×, median {:.1}×",
            speed[speed.len() / 2]
        );
    }
}
