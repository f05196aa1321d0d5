//! The Modbus driver against an independent implementation of the protocol and of the drive:
//! an Oriental AZ in direct-data operation written on pymodbus (`tests/peers/az_drive.py`),
//! over Modbus TCP and over RTU on a pair of pseudo-terminals joined by socat. gelrig's own
//! twin shares the driver's reading of the manual; this drive does not.
//!
//! Needs `python3` with `pymodbus` and `pyserial`, and `socat` (`.ci/run` installs them).
//! Where they are missing the tests print a visible skip line — unless
//! `GELRIG_REQUIRE_PEERS=1` (set by CI), which makes a missing peer a failure.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use rundir::write::Status;

use crate::support::{col, csv_rows, root, run_on_real_rig, sim_wire_rotation, to_short_form};

/// A process killed when dropped.
struct Proc(Child);

impl Drop for Proc {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Whether the peers can run here; prints the skip line (or fails under CI) when not.
fn peers_available() -> bool {
    let python = Command::new("python3")
        .args(["-c", "import pymodbus, serial"])
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    let socat = Command::new("socat")
        .arg("-V")
        .stdout(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if python && socat {
        return true;
    }
    testkit::skip(
        testkit::Need::Peers,
        "the independent Modbus peer",
        "it needs python3 with pymodbus and pyserial, and socat; install them",
    );
    false
}

/// Two joined pseudo-terminals: the peer serves on the first, the driver opens the second.
fn pty_pair() -> (Proc, String, String) {
    let mut child = Command::new("socat")
        .args(["-d", "-d", "pty,raw,echo=0", "pty,raw,echo=0"])
        .stderr(Stdio::piped())
        .stdout(Stdio::null())
        .spawn()
        .unwrap();
    let err = child.stderr.take().unwrap();
    let mut paths = Vec::new();
    for line in BufReader::new(err).lines().map_while(Result::ok) {
        if let Some(i) = line.find("PTY is ") {
            paths.push(line[i + 7..].trim().to_string());
            if paths.len() == 2 {
                break;
            }
        }
    }
    assert_eq!(paths.len(), 2, "socat gave no pty pair");
    (Proc(child), paths[0].clone(), paths[1].clone())
}

/// Starts the peer with `args` (after `--tcp` or `--serial PATH`); returns it and what the
/// driver connects to (`host:port`, or `None` for serial).
fn peer(transport: &[&str], args: &[&str]) -> (Proc, Option<String>) {
    let mut child = Command::new("python3")
        .arg(root().join("tests/peers/az_drive.py"))
        .args(transport)
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .unwrap();
    let out = child.stdout.take().unwrap();
    let mut first = String::new();
    BufReader::new(out).read_line(&mut first).unwrap();
    let address = first.strip_prefix("LISTEN ").map(|a| a.trim().to_string());
    assert!(
        address.is_some() || first.starts_with("SERIAL"),
        "the peer said {first:?}"
    );
    // pymodbus binds after printing: give it a moment.
    std::thread::sleep(Duration::from_millis(300));
    (Proc(child), address)
}

/// A rig whose rotation axis is `sim-wire.yaml`'s AZ-true map at `address` (TCP) or `port`
/// (RTU), with `edit` applied to the map.
fn rig(
    dir: &Path,
    address: Option<&str>,
    port: Option<&str>,
    edit: impl FnOnce(&mut serde_yaml::Mapping),
) -> PathBuf {
    let axis = sim_wire_rotation(|m| {
        m.remove("port");
        if let Some(a) = address {
            m.insert("address".into(), a.into());
        }
        if let Some(p) = port {
            m.insert("port".into(), p.into());
        }
        edit(m);
    });
    let mut axes = serde_yaml::Mapping::new();
    axes.insert("rotation".into(), axis);
    let mut r = serde_yaml::Mapping::new();
    r.insert("name".into(), "az-peer".into());
    r.insert("axes".into(), axes.into());
    let p = dir.join("rig.yaml");
    std::fs::write(&p, serde_yaml::to_string(&r).unwrap()).unwrap();
    p
}

fn rotation_steps(dir: &Path) -> PathBuf {
    let p = dir.join("p.yaml");
    std::fs::write(
        &p,
        "name: rotation-steps\n\
         sensor: {kind: portable}\n\
         indenter: {shape: flat_circle, diameter: 9.5 mm}\n\
         safety: {max_fz: 40 N, max_fxy: 10 N, max_tz: 100 N·mm, retract: {rotation: 0 deg}}\n\
         sequence:\n\
         \x20 - home: {axes: [rotation]}\n\
         \x20 - stepped: {axis: rotation, from: 0 deg, to: 3 deg, step: 1 deg, speed: 5 deg/s, settle: {fixed: 0.1 s}, capture: {force_window: 0 s}}\n",
    )
    .unwrap();
    p
}

/// Against the independent AZ, over TCP and RTU, with BUSY 20 and 200 ms late, a one-step
/// overshoot and one "busy" answer to a trigger: every step lands within 0.01 deg.
#[test]
fn an_independent_az_drive_on_pymodbus_lands_every_step() {
    if !peers_available() {
        return;
    }
    for latency in ["20", "200"] {
        for rtu in [false, true] {
            let tmp = tempfile::tempdir().unwrap();
            let args = [
                "--busy-latency-ms",
                latency,
                "--overshoot-steps",
                "1",
                "--busy-once",
            ];
            let (_socat, _peer, rig_path) = if rtu {
                // A pseudo-terminal carries no parity bit (Linux refuses PARENB on one):
                // both ends run without, as `parity: none` (two stop bits) in the map.
                let (socat, a, b) = pty_pair();
                let (p, _) = peer(&["--serial", &a, "--parity", "N"], &args);
                let r = rig(tmp.path(), None, Some(&b), |m| {
                    m.insert("parity".into(), "none".into());
                });
                (Some(socat), p, r)
            } else {
                let (p, address) = peer(&["--tcp"], &args);
                let r = rig(tmp.path(), address.as_deref(), None, |_| {});
                (None, p, r)
            };
            let out = run_on_real_rig(&rig_path, &rotation_steps(tmp.path()), |_| {});
            let what = format!("{} at {latency} ms", if rtu { "rtu" } else { "tcp" });
            assert_eq!(out.status, Status::Completed, "{what}: {:?}", out.message);
            let rows = csv_rows(&out.dir.join("steps.csv"));
            assert_eq!(rows.len(), 3, "{what}");
            for (t, p) in col(&rows, "target").iter().zip(col(&rows, "position")) {
                assert!((t - p).abs() <= 0.01 + 1e-9, "{what}: at {p} for {t}");
            }
        }
    }
}

/// Against the independent AZ: a drive that takes its triggers and never moves fails the
/// run naming the axis, and the short form's lone `0x0066 := 1` (trigger 0x00010000) is
/// not a move either — never a run `completed` with every step at 0 deg.
#[test]
fn an_independent_az_that_does_not_move_fails_the_run() {
    if !peers_available() {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let (_peer, address) = peer(&["--tcp"], &["--ignore-trigger"]);
    let r = rig(tmp.path(), address.as_deref(), None, |_| {});
    let t0 = Instant::now();
    let out = run_on_real_rig(&r, &rotation_steps(tmp.path()), |_| {});
    let msg = out.message.clone().unwrap_or_default();
    assert_eq!(out.status, Status::Failed, "{msg}");
    assert!(msg.contains("the rotation axis showed no motion"), "{msg}");
    assert!(t0.elapsed() < Duration::from_secs(20));

    let tmp = tempfile::tempdir().unwrap();
    let (_peer, address) = peer(&["--tcp"], &[]);
    let r = rig(tmp.path(), address.as_deref(), None, to_short_form);
    let out = run_on_real_rig(&r, &rotation_steps(tmp.path()), |_| {});
    let msg = out.message.clone().unwrap_or_default();
    assert_eq!(out.status, Status::Failed, "{msg}");
    assert!(msg.contains("showed no motion"), "{msg}");
}
