//! Seeded mutation fuzzing of protocols and rig files (cargo-fuzz needs a nightly toolchain;
//! this runs on the stable one, in CI, with a fixed budget).
//!
//! Every shipped protocol and rig file is mutated — numbers replaced by extremes (10³⁰⁸,
//! 10⁻³²⁰, NaN, ±∞, 2³², 2⁶⁴), units swapped or dropped, lines deleted, duplicated or
//! re-indented, keys repeated, blocks nested in repeats, bytes flipped, a byte-order mark
//! — and each case must load and plan without a panic and within a time bound. Cases that
//! validate with a small plan on the simulated rig are also dry-run in virtual time: the run
//! must end (any status) within a wall-time bound, with its directory no larger than the
//! plan's data estimate allows.
//!
//! `GELRIG_FUZZ_CASES` (default 1500), `GELRIG_FUZZ_RUNS` (dry runs, default 10) and
//! `GELRIG_FUZZ_SEED` (default 1) run it longer or elsewhere:
//!
//! ```text
//! GELRIG_FUZZ_CASES=200000 GELRIG_FUZZ_RUNS=300 GELRIG_FUZZ_SEED=7 \
//!     cargo test --release -p gelrig-tests --test e2e fuzz -- --nocapture
//! ```
//!
//! A failing case is written to `target/fuzz-failures/` with its seed and printed.

use std::panic::AssertUnwindSafe;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use crate::support::{protocol, root, run_virtual, shipped};

/// A small deterministic generator (SplitMix64): the cases depend on the seed alone.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
    fn pick<'a, T>(&mut self, xs: &'a [T]) -> &'a T {
        &xs[self.below(xs.len())]
    }
}

const EXTREMES: &[&str] = &[
    "1e308",
    "-1e308",
    "1e-320",
    "0",
    "-0",
    "NaN",
    ".nan",
    ".inf",
    "-.inf",
    "4294967296",
    "18446744073709551616",
    "-1",
    "1e18",
    "0.0000001",
    "999999999999",
    "1e9",
    "3.5e-7",
];
const UNITS: &[&str] = &[
    "mm", "deg", "s", "ms", "Hz", "N", "mN", "N·mm", "%", "mm/s", "deg/s", "g", "MPa", "N/s", "",
    "parsecs",
];
const KEYS: &[&str] = &[
    "times",
    "frames",
    "to",
    "from",
    "step",
    "speed",
    "duration",
    "fixed",
    "max_fz",
    "force",
    "normal",
    "axis",
    "diameter",
    "fps",
    "width",
    "travel",
    "resolution",
    "max_speed",
    "name",
];

/// Positions of number tokens in `line` as (start, end) byte offsets.
fn numbers(line: &str) -> Vec<(usize, usize)> {
    let b = line.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        let starts = b[i].is_ascii_digit()
            && (i == 0 || !(b[i - 1].is_ascii_alphanumeric() || b[i - 1] == b'_'));
        if starts {
            let s = if i > 0 && b[i - 1] == b'-' { i - 1 } else { i };
            let mut e = i;
            while e < b.len() && (b[e].is_ascii_digit() || b[e] == b'.' || b[e] == b'e') {
                e += 1;
            }
            out.push((s, e));
            i = e;
        } else {
            i += 1;
        }
    }
    out
}

/// One mutation of `text`.
fn mutate(text: &str, rng: &mut Rng) -> String {
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    if lines.is_empty() {
        return text.to_string();
    }
    let k = rng.below(lines.len());
    match rng.below(12) {
        0..=3 => {
            // A number becomes an extreme (the commonest mutation: values are the risk).
            let with: Vec<usize> = (0..lines.len())
                .filter(|i| !numbers(&lines[*i]).is_empty())
                .collect();
            if let Some(&i) = with.get(rng.below(with.len())) {
                let spans = numbers(&lines[i]);
                let (s, e) = *rng.pick(&spans);
                let x = *rng.pick(EXTREMES);
                lines[i].replace_range(s..e, x);
            }
        }
        4 => {
            // A unit swapped or dropped.
            let u = *rng.pick(&UNITS[..UNITS.len() - 2]);
            if let Some(p) = lines[k].find(&format!(" {u}")) {
                let to = *rng.pick(UNITS);
                lines[k].replace_range(p + 1..p + 1 + u.len(), to);
            }
        }
        5 => {
            lines.remove(k);
        }
        6 => {
            let l = lines[k].clone();
            lines.insert(k, l);
        }
        7 => {
            if rng.below(2) == 0 {
                lines[k].insert_str(0, "  ");
            } else if lines[k].starts_with("  ") {
                lines[k].drain(..2);
            }
        }
        8 => {
            // A key repeated inside a flow mapping, or a key renamed.
            if let Some(p) = lines[k].find('}') {
                let key = *rng.pick(KEYS);
                lines[k].insert_str(p, &format!(", {key}: 1 mm"));
            } else if let Some(p) = lines[k].find(':') {
                let key = *rng.pick(KEYS);
                let start = lines[k][..p].rfind([' ', '{', '-']).map_or(0, |s| s + 1);
                lines[k].replace_range(start..p, key);
            }
        }
        9 => {
            // The sequence nested in repeats.
            if let Some(i) = lines.iter().position(|l| l.starts_with("sequence:")) {
                let times = *rng.pick(&["1", "1000", "4294967295", "0", "-1"]);
                let depth = 1 + rng.below(3);
                let mut nested = Vec::new();
                for d in 0..depth {
                    let pad = "  ".repeat(1 + 3 * d);
                    nested.push(format!("{pad}- repeat:"));
                    nested.push(format!("{pad}    times: {times}"));
                    nested.push(format!("{pad}    blocks:"));
                }
                let pad = "  ".repeat(3 * depth);
                let body: Vec<String> =
                    lines[i + 1..].iter().map(|l| format!("{pad}{l}")).collect();
                lines.truncate(i + 1);
                lines.extend(nested);
                lines.extend(body);
            }
        }
        10 => {
            // A byte flipped to something odd.
            let odd = *rng.pick(&[
                "\u{0}", "\u{7f}", "é", "\u{feff}", "{", "]", ":", "&", "*", "!", "'", "\"",
            ]);
            let chars: Vec<char> = lines[k].chars().collect();
            if !chars.is_empty() {
                let at = rng.below(chars.len());
                let mut s: String = chars[..at].iter().collect();
                s.push_str(odd);
                s.extend(chars[at + 1..].iter());
                lines[k] = s;
            }
        }
        _ => {
            // Very long values.
            if let Some(p) = lines[k].find(": ") {
                let long = "9".repeat(1 + rng.below(400));
                lines[k].insert_str(p + 2, &long);
            }
        }
    }
    let mut out = lines.join("\n");
    out.push('\n');
    if rng.below(50) == 0 {
        out.insert(0, '\u{feff}');
    }
    out
}

fn env_or(name: &str, default: u64) -> u64 {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// Runs `f` on a thread and waits up to `limit`; `Err` says whether it panicked or hung.
fn bounded<T: Send + 'static>(
    limit: Duration,
    f: impl FnOnce() -> T + Send + 'static,
) -> Result<T, &'static str> {
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let r = std::panic::catch_unwind(AssertUnwindSafe(f));
        let _ = tx.send(r);
    });
    match rx.recv_timeout(limit) {
        Ok(Ok(v)) => Ok(v),
        Ok(Err(_)) => Err("panicked"),
        Err(_) => Err("hung"),
    }
}

fn save_failure(seed: u64, case: u64, what: &str, kind: &str, text: &str) -> PathBuf {
    let dir = root().join("target/fuzz-failures");
    let _ = std::fs::create_dir_all(&dir);
    let p = dir.join(format!("seed{seed}-case{case}-{kind}.yaml"));
    let _ = std::fs::write(&p, text);
    println!(
        "FUZZ FAILURE ({what} {kind}), seed {seed}, case {case}: saved to {}",
        p.display()
    );
    println!("{text}");
    p
}

/// Bytes in the files under `dir`.
fn size(dir: &Path) -> u64 {
    std::fs::read_dir(dir)
        .map(|d| {
            d.flatten()
                .map(|e| {
                    let p = e.path();
                    if p.is_dir() {
                        size(&p)
                    } else {
                        e.metadata().map(|m| m.len()).unwrap_or(0)
                    }
                })
                .sum()
        })
        .unwrap_or(0)
}

#[test]
fn mutated_protocols_and_rigs_never_panic_hang_or_run_away() {
    let seed = env_or("GELRIG_FUZZ_SEED", 1);
    let cases = env_or("GELRIG_FUZZ_CASES", 1500);
    let runs_wanted = env_or("GELRIG_FUZZ_RUNS", 10);
    let mut rng = Rng(seed);
    let tmp = tempfile::tempdir().unwrap();
    let sim = root().join("protocols/rigs/sim.yaml");
    let rigs: Vec<PathBuf> = ["sim", "sim-wire"]
        .iter()
        .map(|r| root().join(format!("protocols/rigs/{r}.yaml")))
        .collect();
    let sources: Vec<(String, String)> = shipped()
        .into_iter()
        .map(|n| {
            let text = std::fs::read_to_string(protocol(&n))
                .unwrap()
                .replace("rig: rigs/sim.yaml", &format!("rig: {}", sim.display()));
            (n, text)
        })
        .collect();
    let (mut validated, mut runs, mut failures) = (0u64, 0u64, Vec::new());
    let t0 = Instant::now();
    for case in 0..cases {
        // One case in four mutates a rig file under an unmutated protocol.
        let on_rig = rng.below(4) == 0;
        let (name, base) = rng.pick(&sources).clone();
        let (p_text, rig_path) = if on_rig {
            let r = rng.pick(&rigs).clone();
            let mut t = std::fs::read_to_string(&r).unwrap();
            for _ in 0..1 + rng.below(3) {
                t = mutate(&t, &mut rng);
            }
            let rp = tmp.path().join(format!("case{case}.rig.yaml"));
            std::fs::write(&rp, &t).unwrap();
            (base.clone(), rp)
        } else {
            let mut t = base.clone();
            for _ in 0..1 + rng.below(3) {
                t = mutate(&t, &mut rng);
            }
            (t, sim.clone())
        };
        let p = tmp.path().join(format!("case{case}.yaml"));
        std::fs::write(&p, &p_text).unwrap();
        let shown = || {
            if on_rig {
                std::fs::read_to_string(&rig_path).unwrap_or_default()
            } else {
                p_text.clone()
            }
        };
        let (p2, r2) = (p.clone(), rig_path.clone());
        let loaded = bounded(Duration::from_secs(5), move || {
            let l = experiments::load::load(&p2, Some(&r2)).ok()?;
            let plan = l.plan.clone();
            Some((l, plan))
        });
        let (loaded, plan) = match loaded {
            Ok(Some(x)) => x,
            Ok(None) => continue,
            Err(kind) => {
                failures.push(save_failure(seed, case, &name, kind, &shown()));
                continue;
            }
        };
        validated += 1;
        let small = plan.bytes.max <= 20e6 && plan.steps.len() <= 200;
        if runs < runs_wanted && small && loaded.real_devices().is_empty() {
            runs += 1;
            let out = tmp.path().join(format!("run{case}"));
            let (o2, budget) = (out.clone(), plan.bytes.max);
            let r = bounded(Duration::from_secs(120), move || {
                run_virtual(&loaded, &o2, case, None).0
            });
            match r {
                Ok(outcome) => {
                    let bytes = size(&outcome.dir) as f64;
                    // Frames compress, and the journal and manifest come on top.
                    if bytes > 2.0 * budget + 1e6 {
                        failures.push(save_failure(seed, case, &name, "ran-away", &shown()));
                    }
                }
                Err(kind) => failures.push(save_failure(seed, case, &name, kind, &shown())),
            }
            let _ = std::fs::remove_dir_all(&out);
        }
        let _ = std::fs::remove_file(&p);
    }
    println!(
        "fuzz: seed {seed}, {cases} cases ({validated} validated, {runs} dry-run) in {:.1} s",
        t0.elapsed().as_secs_f64()
    );
    assert!(failures.is_empty(), "fuzz failures: {failures:?}");
    assert!(
        validated > 0 && runs > 0,
        "the mutations never produced a valid protocol"
    );
}
