//! Paths, the `gelrig` binary, in-process runs and run-directory readers.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

use experiments::load::{Loaded, load};
use experiments::plan::Plan;
use runner::{Cancel, Launch, RunOutcome, run};

/// The workspace root.
pub(crate) fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap()
        .to_path_buf()
}

/// A shipped protocol by name.
pub(crate) fn protocol(name: &str) -> PathBuf {
    root().join("protocols").join(format!("{name}.yaml"))
}

/// The simulated rig file.
pub(crate) fn sim_rig() -> PathBuf {
    root().join("protocols/rigs/sim.yaml")
}

/// Every shipped protocol's name: every `*.yaml` directly in `protocols/` (the rigs and
/// materials live in subfolders), read from the folder so that a protocol added there is in
/// every all-protocols test without anyone remembering to list it.
pub(crate) fn shipped() -> Vec<String> {
    let dir = root().join("protocols");
    let mut names: Vec<String> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .filter_map(|entry| {
            let path = entry.ok()?.path();
            let name = path.file_name()?.to_str()?;
            name.strip_suffix(".yaml").map(str::to_string)
        })
        .collect();
    names.sort();
    assert!(
        names.len() >= 15,
        "{}: {} protocols found",
        dir.display(),
        names.len()
    );
    names
}

/// Path of the `gelrig` binary of this build profile, built (or brought up to date) once
/// per test process so the tests never run a stale binary. `GELRIG_BIN` names another
/// binary instead (an installed one, or an older build to show a test fails there).
///
/// Built as `cargo build --workspace --bins`, not `-p gelrig`: the workspace's features
/// unified the way `cargo test --workspace` unifies them, so the binary that command already
/// linked is reused. With `-p gelrig` the dependencies resolve to other features and a fresh
/// clone compiled a second copy of them inside the test run.
pub(crate) fn gelrig() -> PathBuf {
    static BIN: OnceLock<PathBuf> = OnceLock::new();
    BIN.get_or_init(|| {
        if let Some(bin) = std::env::var_os("GELRIG_BIN") {
            return PathBuf::from(bin);
        }
        let exe = std::env::current_exe().unwrap();
        // target/<profile>/deps/e2e-… → target/<profile>
        let profile_dir = exe.parent().unwrap().parent().unwrap().to_path_buf();
        let release = profile_dir.file_name().is_some_and(|n| n == "release");
        let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
        let mut cmd = Command::new(cargo);
        cmd.current_dir(root())
            .args(["build", "-q", "--workspace", "--bins"]);
        if release {
            cmd.arg("--release");
        }
        let status = cmd.status().expect("cargo runs");
        assert!(status.success(), "building gelrig failed");
        profile_dir.join("gelrig")
    })
    .clone()
}

/// `gelrig runs DIR`'s stdout.
pub(crate) fn runs_listing(dir: &Path) -> String {
    gelrig_ok([std::ffi::OsStr::new("runs"), dir.as_os_str()])
}

/// `gelrig ARGS`'s standard output, asserting it succeeded (its standard error if not).
pub(crate) fn gelrig_ok<I, S>(args: I) -> String
where
    I: IntoIterator<Item = S>,
    S: AsRef<std::ffi::OsStr>,
{
    let out = Command::new(gelrig()).args(args).output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// Loads a protocol file against the simulated rig, panicking with the diagnostics.
pub(crate) fn load_ok(path: &Path) -> Loaded {
    match load(path, Some(&sim_rig())) {
        Ok(l) => l,
        Err(diags) => panic!(
            "{} does not load:\n{}",
            path.display(),
            diags
                .iter()
                .map(|d| d.to_string())
                .collect::<Vec<_>>()
                .join("\n")
        ),
    }
}

/// Writes `text` as a protocol file in `dir` and loads it against the simulated rig.
pub(crate) fn load_text(dir: &Path, text: &str) -> Result<Loaded, Vec<experiments::Diagnostic>> {
    let p = dir.join("protocol.yaml");
    std::fs::write(&p, text).unwrap();
    load(&p, Some(&sim_rig()))
}

/// A shipped protocol's text.
pub(crate) fn shipped_text(name: &str) -> String {
    std::fs::read_to_string(protocol(name)).unwrap()
}

/// Runs a loaded protocol in-process on virtual time, with `cancel_after_s` of run time
/// before an interrupt (if given).
pub(crate) fn run_virtual(
    loaded: &Loaded,
    out: &Path,
    seed: u64,
    cancel_after_s: Option<f64>,
) -> (RunOutcome, Plan) {
    let plan = loaded.plan.clone();
    let Some(cancel_after_s) = cancel_after_s else {
        let outcome = runner::run_virtual_blocking(loaded, out, seed).unwrap();
        return (outcome, plan);
    };
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .start_paused(true)
        .build()
        .unwrap();
    let cancel = Cancel::new();
    let outcome = rt.block_on(async {
        let c = cancel.clone();
        tokio::spawn(async move {
            tokio::time::sleep(std::time::Duration::from_secs_f64(cancel_after_s)).await;
            c.interrupt();
        });
        run(Launch::new(loaded).out(out).seed(seed), cancel)
            .await
            .unwrap()
    });
    (outcome, plan)
}

/// Where this test process keeps its shared dry runs: a directory of its own under the
/// target's test scratch space. A static is never dropped, so a temporary directory there
/// would outlive the process (1.4 GB of runs each time); instead the directories of
/// processes that have ended are removed when the next one starts.
fn process_root() -> &'static Path {
    static ROOT: OnceLock<PathBuf> = OnceLock::new();
    ROOT.get_or_init(shared_runs_root)
}

fn shared_runs_root() -> PathBuf {
    let base = Path::new(env!("CARGO_TARGET_TMPDIR")).join("shared-dry-runs");
    if let Ok(entries) = std::fs::read_dir(&base) {
        for e in entries.flatten() {
            let ended = e
                .file_name()
                .to_str()
                .and_then(|n| n.parse::<u32>().ok())
                .is_none_or(|pid| !Path::new(&format!("/proc/{pid}")).exists());
            if ended {
                let _ = std::fs::remove_dir_all(e.path());
            }
        }
    }
    let root = base.join(std::process::id().to_string());
    std::fs::create_dir_all(&root).unwrap();
    root
}

/// The run directory of a shipped protocol dry-run once per test process (seed 1),
/// shared by every test that only reads it (`every_shipped_protocol_dry_runs_to_completion`
/// runs all of them through here, so the others find theirs done). Each protocol has its own
/// lock: two tests wanting two protocols run them side by side; two wanting one wait for
/// one run.
pub(crate) fn shared_dry_run(name: &str) -> PathBuf {
    type Cell = std::sync::Arc<OnceLock<PathBuf>>;
    static RUNS: OnceLock<std::sync::Mutex<std::collections::BTreeMap<String, Cell>>> =
        OnceLock::new();
    let cell = RUNS
        .get_or_init(Default::default)
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
        .entry(name.to_string())
        .or_default()
        .clone();
    cell.get_or_init(|| {
        let loaded = load_ok(&protocol(name));
        let out = process_root().join(name);
        let (outcome, _) = run_virtual(&loaded, &out, 1, None);
        assert_eq!(
            outcome.status,
            rundir::write::Status::Completed,
            "{name}: {:?}",
            outcome.message
        );
        outcome.dir
    })
    .clone()
}

/// A one-trial `lifting-can` run of `seed`, once per test process, shared by the tests that
/// only read it (or track it in place), as [`shared_dry_run`] is.
pub(crate) fn shared_one_trial_can(seed: u64) -> PathBuf {
    shared_can(1, seed)
}

/// A `lifting-can` run of `trials` trials on `seed`, once per test process, shared as
/// [`shared_one_trial_can`] is.
pub(crate) fn shared_can(trials: u32, seed: u64) -> PathBuf {
    type Cell = std::sync::Arc<OnceLock<PathBuf>>;
    static RUNS: OnceLock<std::sync::Mutex<std::collections::BTreeMap<(u32, u64), Cell>>> =
        OnceLock::new();
    let cell = RUNS
        .get_or_init(Default::default)
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
        .entry((trials, seed))
        .or_default()
        .clone();
    cell.get_or_init(|| {
        let text = shipped_text("lifting-can").replace("times: 10", &format!("times: {trials}"));
        let name = match trials {
            1 => format!("one-trial-can-seed-{seed}"),
            n => format!("{n}-trial-can-seed-{seed}"),
        };
        dry_text(&process_root().join(name), &text, seed)
    })
    .clone()
}

/// A protocol's text dry-run into `dir` (made if missing) on `seed`, to completion.
pub(crate) fn dry_text(dir: &Path, text: &str, seed: u64) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let loaded = load_text(dir, text).unwrap_or_else(|d| panic!("{}", d[0]));
    let (o, _) = run_virtual(&loaded, dir, seed, None);
    assert_eq!(
        o.status,
        rundir::write::Status::Completed,
        "{:?}",
        o.message
    );
    o.dir
}

/// Rows of a CSV file as maps from column to text.
pub(crate) fn csv_rows(path: &Path) -> Vec<std::collections::BTreeMap<String, String>> {
    let mut r = csv::Reader::from_path(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let headers = r.headers().unwrap().clone();
    r.records()
        .map(|rec| {
            let rec = rec.unwrap();
            headers
                .iter()
                .map(str::to_string)
                .zip(rec.iter().map(str::to_string))
                .collect()
        })
        .collect()
}

/// A numeric column of CSV rows.
pub(crate) fn col(rows: &[std::collections::BTreeMap<String, String>], name: &str) -> Vec<f64> {
    rows.iter()
        .map(|r| {
            r[name]
                .parse::<f64>()
                .unwrap_or_else(|e| panic!("{name} = {:?}: {e}", r[name]))
        })
        .collect()
}

/// The run manifest.
pub(crate) fn manifest(dir: &Path) -> rundir::write::Manifest {
    rundir::write::read_manifest(dir).unwrap()
}

/// Width and height of a PNG file.
pub(crate) fn image_size(path: &Path) -> (u32, u32) {
    // PNG IHDR: width and height are big-endian u32 at bytes 16..24.
    let bytes = std::fs::read(path).unwrap();
    assert_eq!(&bytes[1..4], b"PNG", "{}", path.display());
    (
        u32::from_be_bytes(bytes[16..20].try_into().unwrap()),
        u32::from_be_bytes(bytes[20..24].try_into().unwrap()),
    )
}

/// Waits (up to 30 s) for the run directory under `out` to journal `event`.
pub(crate) fn wait_for_event(out: &Path, event: &str) -> bool {
    wait_for_event_within(out, event, std::time::Duration::from_secs(30))
}

/// Waits up to `limit` for the run directory under `out` to journal `event`.
pub(crate) fn wait_for_event_within(out: &Path, event: &str, limit: std::time::Duration) -> bool {
    let deadline = std::time::Instant::now() + limit;
    let needle = format!("\"event\":\"{event}\"");
    while std::time::Instant::now() < deadline {
        let seen = std::fs::read_dir(out)
            .ok()
            .and_then(|mut d| d.next())
            .is_some_and(|e| {
                std::fs::read_to_string(e.unwrap().path().join("journal.jsonl"))
                    .is_ok_and(|j| j.contains(&needle))
            });
        if seen {
            return true;
        }
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
    false
}

/// Runs protocol `p` on rig file `rig` in-process on the monotonic clock (as `gelrig run`
/// does for a real bench), with `meanwhile` running on a thread given the runs folder.
pub(crate) fn run_on_real_rig(
    rig: &Path,
    p: &Path,
    meanwhile: impl FnOnce(std::path::PathBuf) + Send + 'static,
) -> runner::RunOutcome {
    let loaded = experiments::load::load(p, Some(rig)).unwrap_or_else(|d| {
        panic!(
            "{}",
            d.iter()
                .map(|d| d.to_string())
                .collect::<Vec<_>>()
                .join("\n")
        )
    });
    let out = p.parent().unwrap().join("runs");
    let out2 = out.clone();
    let side = std::thread::spawn(move || meanwhile(out2));
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap();
    let outcome = rt
        .block_on(runner::run(
            runner::Launch::new(&loaded)
                .out(out)
                .clock(rig::ClockMode::Monotonic),
            runner::Cancel::new(),
        ))
        .unwrap();
    side.join().unwrap();
    outcome
}

/// `sim-wire.yaml`'s rotation axis (the AZ-true Modbus map), with `edit` applied to its
/// `modbus:` mapping.
pub(crate) fn sim_wire_rotation(edit: impl FnOnce(&mut serde_yaml::Mapping)) -> serde_yaml::Value {
    let text = std::fs::read_to_string(root().join("protocols/rigs/sim-wire.yaml")).unwrap();
    let doc: serde_yaml::Value = serde_yaml::from_str(&text).unwrap();
    let mut axis = doc["axes"]["rotation"].clone();
    if let Some(m) = axis["modbus"].as_mapping_mut() {
        edit(m);
    }
    axis
}

/// Turns an AZ-true (long form) map into the short form whose lone trigger write
/// `0x0066 := 1` an AZ ignores.
pub(crate) fn to_short_form(m: &mut serde_yaml::Mapping) {
    for k in ["move", "acceleration", "deceleration", "current"] {
        m.remove(k);
    }
    m.insert("target".into(), 0x005C.into());
    m.insert("speed".into(), 0x005E.into());
    let mut trigger = serde_yaml::Mapping::new();
    trigger.insert("addr".into(), 0x0066.into());
    trigger.insert("value".into(), 1.into());
    m.insert("trigger".into(), trigger.into());
}

/// The real GelSight Mini sequence in ../shared/data, or `None` after a logged skip of
/// `what` (a failure under `GELRIG_REQUIRE_DATA=1`, as in CI; a fresh clone lacks it).
pub(crate) fn mini_press_dir(what: &str) -> Option<PathBuf> {
    testkit::shared_data(env!("CARGO_MANIFEST_DIR"), "gelsight-mini-press", what)
}

/// Whether `python3` can `import_line` (e.g. `import numpy, scipy`) for an independent peer
/// needing `what`; where it cannot, a logged skip — or a failure under
/// `GELRIG_REQUIRE_PEERS=1` (set by CI), where a missing peer must not pass silently.
pub(crate) fn python_peer(import_line: &str, what: &str, install: &str) -> bool {
    let available = Command::new("python3")
        .args(["-c", import_line])
        .stderr(std::process::Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if !available {
        testkit::skip(
            testkit::Need::Peers,
            "a comparison with an independent peer",
            &format!("it needs {what}; {install}"),
        );
    }
    available
}

/// Runs the peer script `script` (under the repository) with `args`, asking it to write its
/// JSON to a temporary file with `out_flag`, and returns that JSON; panics with the
/// script's stderr when it fails.
pub(crate) fn peer_json(script: &str, args: &[&str], out_flag: &str) -> serde_json::Value {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("peer.json");
    let run = Command::new("python3")
        .arg(root().join(script))
        .args(args)
        .arg(out_flag)
        .arg(&out)
        .output()
        .expect("python3");
    assert!(
        run.status.success(),
        "{script} failed: {}",
        String::from_utf8_lossy(&run.stderr)
    );
    let text = std::fs::read_to_string(&out).expect("the peer's JSON");
    serde_json::from_str(&text).expect("JSON")
}

/// A copy of run directory `src` at `dst`, without a `report/` a report wrote into it.
pub(crate) fn copy_run_dir(src: &Path, dst: &Path) {
    std::fs::create_dir_all(dst).unwrap();
    for e in std::fs::read_dir(src).unwrap() {
        let p = e.unwrap().path();
        let to = dst.join(p.file_name().unwrap());
        if p.is_dir() {
            if p.file_name().is_some_and(|n| n == "report") {
                continue;
            }
            copy_run_dir(&p, &to);
        } else {
            std::fs::copy(&p, &to).unwrap();
        }
    }
}
