//! A run that can never be left blind, stuck or running (issue "Safety first"): a disk that
//! fills, interrupts during setup, rigs that mix real and simulated devices, and the
//! watchdog stopping the bench while the plan task waits on a slow device.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use nix::sys::signal::{Signal, kill};
use nix::unistd::Pid;
use rundir::write::Status;

use crate::support::{
    csv_rows, gelrig, manifest, protocol, run_on_real_rig, wait_for_event, wait_for_event_within,
};

/// Runs `script` (sh) in a private mount namespace where a tmpfs of `size` is mounted on
/// `$FS`; `None` (a logged skip; a failure under `GELRIG_REQUIRE_MOUNT=1`, as in CI) where
/// this machine allows no mount namespace.
fn in_small_fs(size: &str, script: &str, keep: &Path) -> Option<std::process::Output> {
    let body = format!(
        "set -e; FS=$(mktemp -d); mount -t tmpfs -o size={size} tmpfs \"$FS\"; export FS; \
         set +e; {script}; rc=$?; cp -a \"$FS\"/. '{}'/ ; exit $rc",
        keep.display()
    );
    for args in [&["-r", "-m"][..], &["-m"][..]] {
        let probe = Command::new("unshare")
            .args(args)
            .args(["sh", "-c", "mount -t tmpfs -o size=64k tmpfs /mnt"])
            .stderr(Stdio::null())
            .status();
        if probe.is_ok_and(|s| s.success()) {
            return Some(
                Command::new("unshare")
                    .args(args)
                    .args(["sh", "-c", &body])
                    .output()
                    .unwrap(),
            );
        }
    }
    testkit::skip(
        testkit::Need::Mount,
        "a full disk during a run",
        "this machine allows no mount namespace for a small filesystem (unshare -rm / -m)",
    );
    None
}

/// Every file under `dir`, recursively.
fn files(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            out.extend(files(&p));
        } else {
            out.push(p);
        }
    }
    out
}

/// A full disk during a run, on the virtual and on a scaled clock, at a size where the
/// first frame cannot be written and at one where force.csv fills mid-run: the run ends
/// promptly as failed (exit 1) naming the disk error, run.yaml carries the final status,
/// and nothing is torn — no temporary file, no half-written PNG, every CSV row whole,
/// every journal line JSON — and the space reserve is gone.
#[test]
fn a_full_disk_ends_the_run_promptly_failed_with_nothing_torn() {
    for (clock, size) in [("virtual", "300k"), ("virtual", "2m"), ("400", "2m")] {
        let keep = tempfile::tempdir().unwrap();
        let script = format!(
            "'{}' run '{}' --plain --time-scale {clock} --out \"$FS/runs\"",
            gelrig().display(),
            protocol("box-normal-flat").display()
        );
        let t0 = Instant::now();
        let Some(out) = in_small_fs(size, &script, keep.path()) else {
            return;
        };
        let elapsed = t0.elapsed();
        let stderr = String::from_utf8_lossy(&out.stderr);
        let what = format!("clock {clock}, disk {size}: {stderr}");
        assert_eq!(out.status.code(), Some(1), "{what}");
        assert!(
            elapsed < Duration::from_secs(60),
            "took {elapsed:?}: {what}"
        );
        let runs: Vec<PathBuf> = std::fs::read_dir(keep.path().join("runs"))
            .unwrap()
            .map(|e| e.unwrap().path())
            .collect();
        assert_eq!(runs.len(), 1, "{what}");
        let dir = &runs[0];
        let m = manifest(dir);
        assert_eq!(m.status, Status::Failed, "{what}");
        let error = m.error.clone().unwrap_or_default();
        assert!(error.contains("No space left on device"), "{error}");
        assert!(m.ended_utc.is_some(), "{what}");
        for f in files(dir) {
            let name = f.file_name().unwrap().to_string_lossy().to_string();
            assert!(
                !name.ends_with(".tmp") && name != "run.reserve",
                "{} left behind: {what}",
                f.display()
            );
            if name.ends_with(".png") {
                image::open(&f).unwrap_or_else(|e| panic!("{}: {e}", f.display()));
            }
            if name.ends_with(".csv") {
                let mut r = csv::Reader::from_path(&f).unwrap();
                for rec in r.records() {
                    rec.unwrap_or_else(|e| panic!("{} has a torn row: {e}", f.display()));
                }
            }
        }
        let journal = std::fs::read_to_string(dir.join("journal.jsonl")).unwrap();
        for line in journal.lines() {
            serde_json::from_str::<serde_json::Value>(line)
                .unwrap_or_else(|e| panic!("torn journal line {line:?}: {e}"));
        }
        assert!(journal.contains("\"run_end\""), "{what}");
        // frames.csv names only frames that exist.
        if dir.join("frames.csv").exists() {
            for row in csv_rows(&dir.join("frames.csv")) {
                assert!(dir.join(&row["file"]).is_file(), "{}: {what}", row["file"]);
            }
        }
    }
}

/// Ctrl-C at any moment of setup — while the protocol is read, while the contact model of
/// `box-shear-flat` is built (about half a second), while devices open — stops the run:
/// exit 130, and a run directory, if one was made, says `aborted` with the reason and has
/// no completed step. The model is built afresh (`--no-cache`): read from a warm table
/// cache it is ready within a few milliseconds, and the run had completed a step 120 ms
/// after its start (3 Dec), so the interrupts would no longer fall in setup.
#[test]
fn an_interrupt_during_setup_always_stops_the_run() {
    for delay_ms in [40u64, 120, 250, 400] {
        let out = tempfile::tempdir().unwrap();
        let mut child = Command::new(gelrig())
            .args(["--no-cache", "run"])
            .arg(protocol("box-shear-flat"))
            .args(["--plain", "--out"])
            .arg(out.path())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        std::thread::sleep(Duration::from_millis(delay_ms));
        kill(Pid::from_raw(child.id() as i32), Signal::SIGINT).unwrap();
        let deadline = Instant::now() + Duration::from_secs(30);
        let status = loop {
            if let Some(s) = child.try_wait().unwrap() {
                break s;
            }
            assert!(Instant::now() < deadline, "still running 30 s after Ctrl-C");
            std::thread::sleep(Duration::from_millis(20));
        };
        let stderr = {
            use std::io::Read;
            let mut s = String::new();
            child.stderr.take().unwrap().read_to_string(&mut s).unwrap();
            s
        };
        assert_eq!(status.code(), Some(130), "after {delay_ms} ms: {stderr}");
        for dir in std::fs::read_dir(out.path()).unwrap() {
            let dir = dir.unwrap().path();
            let m = manifest(&dir);
            assert_eq!(m.status, Status::Aborted, "after {delay_ms} ms: {stderr}");
            let reason = m.reason.unwrap_or_default();
            assert!(reason.contains("interrupted by the operator"), "{reason}");
            if delay_ms <= 120 {
                assert_eq!(m.steps_completed, 0, "after {delay_ms} ms: {reason}");
            }
        }
    }
}

/// Serves twins of `sim-wire.yaml` at real time and returns the rig file they are bound
/// in, with its `twins:` marker removed: to gelrig these are real devices.
struct RealTwins {
    child: std::process::Child,
    rig: PathBuf,
}

impl Drop for RealTwins {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn real_twins(dir: &Path) -> RealTwins {
    let bound = dir.join("bound.yaml");
    let child = Command::new(gelrig())
        .args(["sim", "serve", "--time-scale", "1", "--rig"])
        .arg(crate::support::root().join("protocols/rigs/sim-wire.yaml"))
        .arg("--protocol")
        .arg(protocol("box-normal-flat"))
        .arg("--write")
        .arg(&bound)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let deadline = Instant::now() + Duration::from_secs(60);
    while !bound.exists() {
        assert!(Instant::now() < deadline, "sim serve wrote no rig");
        std::thread::sleep(Duration::from_millis(50));
    }
    let mut doc: serde_yaml::Value =
        serde_yaml::from_str(&std::fs::read_to_string(&bound).unwrap()).unwrap();
    doc.as_mapping_mut().unwrap().remove("twins").unwrap();
    let rig = dir.join("real.yaml");
    std::fs::write(&rig, serde_yaml::to_string(&doc).unwrap()).unwrap();
    RealTwins { child, rig }
}

/// A rig with real stages and a real sensor beside a rendered camera runs on the monotonic
/// clock (a run in virtual time would fail at once waiting for the real sensor), and
/// `--time-scale` on it is refused naming the real devices.
#[test]
fn a_mixed_rig_runs_in_real_time() {
    let tmp = tempfile::tempdir().unwrap();
    let twins = real_twins(tmp.path());
    let p = tmp.path().join("mixed.yaml");
    std::fs::write(
        &p,
        "name: mixed-rig\n\
         sensor: {kind: box}\n\
         indenter: {shape: flat_circle, diameter: 9.5 mm}\n\
         safety: {max_fz: 40 N, max_fxy: 10 N, max_tz: 100 N·mm, retract: {normal: 0 mm}}\n\
         sequence:\n\
         \x20 - home: {axes: [normal]}\n\
         \x20 - tare: {duration: 0.5 s}\n\
         \x20 - move: {axis: normal, to: 2 mm, speed: 2 mm/s, settle: {fixed: 0.5 s}, capture: {force_window: 0.2 s, frames: 1}}\n",
    )
    .unwrap();
    let run = |extra: &[&str]| {
        Command::new(gelrig())
            .arg("run")
            .arg(&p)
            .arg("--rig")
            .arg(&twins.rig)
            .args(["--quiet", "--out"])
            .arg(tmp.path().join("runs"))
            .args(extra)
            .output()
            .unwrap()
    };
    let o = run(&["--time-scale", "60"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("real devices (normal, force)"),
        "{err}"
    );
    let o = run(&[]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    let dir = PathBuf::from(String::from_utf8_lossy(&o.stdout).trim());
    let m = manifest(&dir);
    assert_eq!(m.clock, "monotonic");
    assert_eq!(m.status, Status::Completed);
    assert_eq!(csv_rows(&dir.join("frames.csv")).len(), 1);
}

/// The watchdog does not wait for the plan task. The plan polls the Zaber stage
/// continuously (`record: {axes: 50 Hz}`); the stage then starts answering 200 ms late, so
/// the plan is almost always inside a driver call, and the Nano17 (a Net F/T twin) jumps
/// to 55 N against `max_fz: 40 N`. The watchdog trips and sends the stop on the port's
/// second handle (message id 99) within a fraction of one of those calls, well before the
/// plan sees the trip, and the run aborts naming the limit.
#[test]
fn the_watchdog_stops_the_stage_while_the_plan_waits_on_it() {
    use rig::drivers::netft_rdt::CalInfo;
    use rig::twins::netft::{NetFtTwin, TwinParams as FtParams};
    use rig::twins::zaber::{TwinParams as ZParams, ZaberTwin};
    use rig::{ForceRange, Wrench, lock};

    const MICROSTEP_MM: f64 = 0.047625e-3;
    let zaber = ZaberTwin::spawn(ZParams {
        device: 1,
        limits: (0, (25.0 / MICROSTEP_MM) as i64),
        require_checksum: true,
        time_scale: 1.0,
    })
    .unwrap();
    let ft = NetFtTwin::spawn(FtParams {
        rate_hz: 1000.0,
        cal: CalInfo {
            force_unit: 2,
            torque_unit: 4,
            counts_per_force: 1_000_000,
            counts_per_torque: 1_000,
        },
        range: ForceRange::NANO17,
        first_seq: (1, 1),
    })
    .unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let rig = tmp.path().join("rig.yaml");
    std::fs::write(
        &rig,
        format!(
            "name: slow-stage\n\
             axes:\n\
             \x20 normal: {{driver: zaber, port: {}, device: 1, axis_number: 1, microstep: {MICROSTEP_MM}, checksum: true, travel: [0 mm, 25 mm], max_speed: 2 mm/s, resolution: 0.002 mm}}\n\
             force: {{driver: net_ft, model: nano17, address: '{}', calibration_port: {}}}\n",
            zaber.path(),
            ft.rdt_addr(),
            ft.calibration_addr().port()
        ),
    )
    .unwrap();
    let p = tmp.path().join("p.yaml");
    std::fs::write(
        &p,
        "name: watchdog-while-busy\n\
         sensor: {kind: box}\n\
         indenter: {shape: flat_circle, diameter: 9.5 mm}\n\
         safety: {max_fz: 40 N, max_fxy: 10 N, max_tz: 100 N·mm, retract: {normal: 0 mm}}\n\
         sequence:\n\
         \x20 - home: {axes: [normal]}\n\
         \x20 - tare: {duration: 0.3 s}\n\
         \x20 - record:\n\
         \x20     axes: 50 Hz\n\
         \x20     blocks:\n\
         \x20       - hold: {duration: 8 s}\n",
    )
    .unwrap();
    let zfaults = zaber.faults().clone();
    let probe = zaber.transcript_probe();
    let load = ft.load.clone();
    let outcome = run_on_real_rig(&rig, &p, move |out: PathBuf| {
        // Once the axes stream (and so the polling) has begun: slow replies, and the load.
        if !wait_for_event(&out, "streams_begin") {
            return;
        }
        std::thread::sleep(Duration::from_millis(300));
        lock(&zfaults).delay = Duration::from_millis(200);
        std::thread::sleep(Duration::from_millis(300));
        *lock(&load) = Wrench {
            fz_n: 55.0,
            ..Wrench::default()
        };
        // Once the stop is in, the stage answers promptly again for the retract.
        let deadline = Instant::now() + Duration::from_secs(10);
        while Instant::now() < deadline && !probe().iter().any(|l| l.contains(" 99 stop")) {
            std::thread::sleep(Duration::from_millis(5));
        }
        lock(&zfaults).delay = Duration::ZERO;
    });
    assert_eq!(outcome.status, Status::Aborted, "{:?}", outcome.message);
    let msg = outcome.message.unwrap_or_default();
    assert!(msg.contains("exceeds max_fz 40 N"), "{msg}");
    let journal = std::fs::read_to_string(outcome.dir.join("journal.jsonl")).unwrap();
    let trip: serde_json::Value = journal
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap())
        .find(|v| v["event"] == "safety_trip")
        .expect("a safety_trip event");
    let ms = |a: &str, b: u64| (trip[a].as_u64().unwrap() as f64 - b as f64) * 1e-6;
    let latency_ms = ms("t_stop_sent_ns", trip["t_sample_ns"].as_u64().unwrap());
    assert!(
        latency_ms < 100.0,
        "sample to stop sent took {latency_ms} ms, longer than half a driver call"
    );
    let noticed: u64 = journal
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap())
        .find(|v| v["event"] == "stop")
        .and_then(|v| v["t_ns"].as_u64())
        .expect("a stop event");
    let ahead_ms = -ms("t_stop_sent_ns", noticed);
    assert!(
        ahead_ms > 50.0,
        "the stop went out only {ahead_ms} ms before the plan noticed: it waited for the plan"
    );
    let transcript = zaber.transcript();
    assert!(
        transcript
            .iter()
            .any(|l| l.starts_with("> ") && l.contains(" 99 stop")),
        "no stop with the watchdog's id: {transcript:?}"
    );
}

/// A Net F/T twin with Nano17 ranges, counts per unit not 1e6.
fn netft_twin() -> rig::twins::netft::NetFtTwin {
    rig::twins::netft::NetFtTwin::spawn(rig::twins::netft::TwinParams {
        rate_hz: 1000.0,
        cal: rig::drivers::netft_rdt::CalInfo {
            force_unit: 2,
            torque_unit: 4,
            counts_per_force: 1_000_000,
            counts_per_torque: 1_000,
        },
        range: rig::ForceRange::NANO17,
        first_seq: (1, 1),
    })
    .unwrap()
}

/// A force-only protocol holding for `hold_s` while recording force at 50 Hz. The monitor
/// runs at 10 Hz, so a sample counts as stale only after 200 ms: the twin's stream thread,
/// delayed by a loaded machine running the suite in parallel, had tripped the default 40 ms
/// bound (56 ms once), which is not what these tests are about.
fn force_hold(dir: &Path, rig_text: &str, hold_s: f64) -> (PathBuf, PathBuf) {
    let rig = dir.join("rig.yaml");
    std::fs::write(&rig, rig_text).unwrap();
    let p = dir.join("p.yaml");
    std::fs::write(
        &p,
        format!(
            "name: force-hold\n\
             sensor: {{kind: box}}\n\
             indenter: {{shape: flat_circle, diameter: 9.5 mm}}\n\
             safety: {{max_fz: 40 N, max_fxy: 10 N, max_tz: 100 N·mm, monitor_rate: 10 Hz}}\n\
             sequence:\n\
             \x20 - tare: {{duration: 0.3 s}}\n\
             \x20 - record:\n\
             \x20     force: 50 Hz\n\
             \x20     blocks:\n\
             \x20       - hold: {{duration: {hold_s} s}}\n"
        ),
    )
    .unwrap();
    (rig, p)
}

/// Finding 1: one Net F/T record whose sequence jumps by 2³¹ − 1, then records carrying
/// 55 N against `max_fz: 40 N`. The monitor is never blind: the run stops (failed, the
/// watchdog naming the jump) instead of completing on a repeated 0 N; and without the jump
/// the same load aborts on the limit.
#[test]
fn a_force_stream_that_jumps_or_crosses_a_limit_stops_the_run() {
    use rig::{Wrench, lock};
    for jump in [true, false] {
        let ft = netft_twin();
        let tmp = tempfile::tempdir().unwrap();
        let rig_text = format!(
            "name: ft-only\nforce: {{driver: net_ft, model: nano17, address: '{}', calibration_port: {}}}\n",
            ft.rdt_addr(),
            ft.calibration_addr().port()
        );
        let (rig, p) = force_hold(tmp.path(), &rig_text, 6.0);
        let (faults, load) = (ft.faults().clone(), ft.load.clone());
        let outcome = run_on_real_rig(&rig, &p, move |out| {
            if wait_for_event(&out, "streams_begin") {
                std::thread::sleep(Duration::from_millis(500));
                if jump {
                    lock(&faults).jump_once = Some(0x7fff_ffff);
                }
                *lock(&load) = Wrench {
                    fz_n: 55.0,
                    ..Wrench::default()
                };
            }
        });
        let msg = outcome.message.clone().unwrap_or_default();
        if jump {
            assert_eq!(outcome.status, Status::Failed, "{msg}");
            assert!(
                msg.contains("safety monitor") && msg.contains("jumped"),
                "{msg}"
            );
        } else {
            assert_eq!(outcome.status, Status::Aborted, "{msg}");
            assert!(msg.contains("exceeds max_fz 40 N"), "{msg}");
        }
        let m = manifest(&outcome.dir);
        assert_eq!(m.safety_events.len(), 1, "{:?}", m.safety_events);
    }
}

/// Findings 3 and 11: a controller that reads back `NaN` or `1e308` is a device error,
/// never data — the run fails naming the axis and the value, steps.csv and run.yaml hold
/// no NaN, and `gelrig probe` marks the device FAIL; a 4 MiB garbage reply reaches the
/// manifest and the journal only as a short quote.
#[test]
fn absurd_or_flooded_replies_are_device_errors_not_data() {
    use rig::lock;
    use rig::twins::smc100::{Smc100Twin, TwinParams};
    for (fault, expect) in [
        ("NaN", "not a number"),
        ("1e308", "outside its travel"),
        ("flood", "bytes)"),
    ] {
        let twin = Smc100Twin::spawn(TwinParams {
            address: 1,
            limits: (0.0, 12.0),
            home_speed: 5.0,
            time_scale: 1.0,
        })
        .unwrap();
        let tmp = tempfile::tempdir().unwrap();
        let rig = tmp.path().join("rig.yaml");
        std::fs::write(
            &rig,
            format!(
                "name: smc\naxes:\n  shear: {{driver: smc100, port: {}, device: 1, travel: [0 mm, 12 mm], max_speed: 2 mm/s, resolution: 0.0001 mm}}\n",
                twin.path()
            ),
        )
        .unwrap();
        let p = tmp.path().join("p.yaml");
        std::fs::write(
            &p,
            "name: shear-move\n\
             sensor: {kind: box}\n\
             indenter: {shape: flat_circle, diameter: 9.5 mm}\n\
             safety: {max_fz: 40 N, max_fxy: 10 N, max_tz: 100 N·mm, retract: {shear: 0 mm}}\n\
             sequence:\n\
             \x20 - home: {axes: [shear]}\n\
             \x20 - move: {axis: shear, to: 1 mm, speed: 2 mm/s, settle: {fixed: 0.5 s}}\n\
             \x20 - move: {axis: shear, to: 2 mm, speed: 2 mm/s, settle: {fixed: 0.5 s}}\n",
        )
        .unwrap();
        let faults = twin.faults().clone();
        let outcome = run_on_real_rig(&rig, &p, move |out| {
            if !wait_for_event(&out, "step_end") {
                return;
            }
            if fault != "flood" {
                lock(&faults).position_reply = Some(fault.to_string());
                return;
            }
            // Every reply a 4 MiB line, until the run has given up on the device.
            while !wait_for_event_within(&out, "run_end", Duration::from_millis(5)) {
                lock(&faults).flood_next = Some(4 << 20);
            }
        });
        let msg = outcome.message.clone().unwrap_or_default();
        assert_eq!(outcome.status, Status::Failed, "{fault}: {msg}");
        assert!(msg.contains("shear") || msg.contains("SMC100"), "{msg}");
        if fault != "flood" {
            assert!(msg.contains(expect), "{fault}: {msg}");
        }
        let run_yaml = std::fs::read_to_string(outcome.dir.join("run.yaml")).unwrap();
        assert!(
            run_yaml.len() < 20_000,
            "{fault}: run.yaml is {} bytes",
            run_yaml.len()
        );
        assert!(!run_yaml.to_lowercase().contains(".nan"), "{run_yaml}");
        let journal = std::fs::read_to_string(outcome.dir.join("journal.jsonl")).unwrap();
        assert!(
            journal.len() < 100_000,
            "{fault}: journal is {} bytes",
            journal.len()
        );
        let steps = std::fs::read_to_string(outcome.dir.join("steps.csv")).unwrap();
        assert!(!steps.to_lowercase().contains("nan"), "{steps}");
        if fault == "NaN" {
            let rig_cfg = experiments::protocol::load_rig(&rig).unwrap().0;
            let rt = tokio::runtime::Builder::new_current_thread()
                .enable_all()
                .build()
                .unwrap();
            let probes = rt.block_on(simbench::bench::probe(&rig_cfg));
            let shear = probes.iter().find(|p| p.role == "shear").unwrap();
            assert!(
                !shear.ok && shear.detail.contains("not a number"),
                "{shear:?}"
            );
        }
    }
}

/// Finding 2: a stage stuck BUSY — it answers, reports itself moving, goes nowhere — ends
/// the run as failed naming the axis, the move and where it stands, within the move's
/// deadline (1.5 × its nominal time + 5 s), instead of "moving" forever.
#[test]
fn a_stage_stuck_busy_fails_the_run_within_the_move_deadline() {
    use rig::lock;
    use rig::twins::zaber::{TwinParams, ZaberTwin};
    const MICROSTEP_MM: f64 = 0.047625e-3;
    let zaber = ZaberTwin::spawn(TwinParams {
        device: 1,
        limits: (0, (25.0 / MICROSTEP_MM) as i64),
        require_checksum: true,
        time_scale: 1.0,
    })
    .unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let rig = tmp.path().join("rig.yaml");
    std::fs::write(
        &rig,
        format!(
            "name: stuck\naxes:\n  shear: {{driver: zaber, port: {}, device: 1, axis_number: 1, microstep: {MICROSTEP_MM}, checksum: true, travel: [0 mm, 25 mm], max_speed: 2 mm/s, resolution: 0.002 mm}}\n",
            zaber.path()
        ),
    )
    .unwrap();
    let p = tmp.path().join("p.yaml");
    std::fs::write(
        &p,
        "name: stuck-move\n\
         sensor: {kind: box}\n\
         indenter: {shape: flat_circle, diameter: 9.5 mm}\n\
         safety: {max_fz: 40 N, max_fxy: 10 N, max_tz: 100 N·mm, retract: {shear: 0 mm}}\n\
         sequence:\n\
         \x20 - home: {axes: [shear]}\n\
         \x20 - move: {axis: shear, to: 2 mm, speed: 2 mm/s}\n",
    )
    .unwrap();
    let faults = zaber.faults().clone();
    let t0 = Instant::now();
    let outcome = run_on_real_rig(&rig, &p, move |out| {
        if wait_for_event(&out, "home") {
            lock(&faults).stuck_busy = true;
        }
    });
    let elapsed = t0.elapsed();
    let msg = outcome.message.clone().unwrap_or_default();
    assert_eq!(outcome.status, Status::Failed, "{msg}");
    assert!(
        msg.contains("the shear axis did not come to rest within 6.5 s")
            && msg.contains("a move from 0 to 2 mm at 2 mm/s")
            && msg.contains("still busy"),
        "{msg}"
    );
    assert!(elapsed < Duration::from_secs(30), "took {elapsed:?}");
}
