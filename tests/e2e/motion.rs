//! Moves that end where they were sent (issue "Moves that end where they were sent"): the
//! production drivers against twins that behave like drives — BUSY shown 20 to 200 ms after
//! the command, a one-step overshoot, settling into in-position, a "busy" exception — and
//! against drives that never move, through the runner on the monotonic clock.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use rig::drivers::modbus::ModbusMap;
use rig::lock;
use rig::twins::modbus::ModbusTwin;
use rig::twins::motion::Timing;
use rundir::write::Status;

use crate::support::{
    col, csv_rows, run_on_real_rig, sim_wire_rotation, to_short_form, wait_for_event,
};

const MICROSTEP_MM: f64 = 0.047625e-3;

/// A protocol stepping a non-pressing axis three times and back to zero at the end.
fn stepped(dir: &Path, axis: &str, unit: &str, step: f64, speed: f64) -> PathBuf {
    let p = dir.join("p.yaml");
    std::fs::write(
        &p,
        format!(
            "name: {axis}-steps\n\
             sensor: {{kind: portable}}\n\
             indenter: {{shape: flat_circle, diameter: 9.5 mm}}\n\
             safety: {{max_fz: 40 N, max_fxy: 10 N, max_tz: 100 N·mm, retract: {{{axis}: 0 {unit}}}}}\n\
             sequence:\n\
             \x20 - home: {{axes: [{axis}]}}\n\
             \x20 - stepped: {{axis: {axis}, from: 0 {unit}, to: {} {unit}, step: {step} {unit}, speed: {speed} {unit}/s, settle: {{fixed: 0.1 s}}, capture: {{force_window: 0 s}}}}\n",
            3.0 * step
        ),
    )
    .unwrap();
    p
}

/// `rig` written to `dir`.
fn rig_file(dir: &Path, rig: &str) -> PathBuf {
    let p = dir.join("rig.yaml");
    std::fs::write(&p, rig).unwrap();
    p
}

/// The Modbus rotation axis of `sim-wire.yaml` (the AZ-true map), edited.
fn az_map(edit: impl FnOnce(&mut serde_yaml::Mapping)) -> serde_yaml::Value {
    sim_wire_rotation(edit)
}

fn modbus_rig(axis: serde_yaml::Value) -> String {
    let mut axes = serde_yaml::Mapping::new();
    axes.insert("rotation".into(), axis);
    let mut doc = serde_yaml::Mapping::new();
    doc.insert("name".into(), "modbus-drive".into());
    doc.insert("axes".into(), axes.into());
    serde_yaml::to_string(&doc).unwrap()
}

/// Every step of steps.csv within `window` of its target, and the count.
fn landed(dir: &Path, window: f64) {
    let rows = csv_rows(&dir.join("steps.csv"));
    assert_eq!(rows.len(), 3, "{rows:?}");
    let (targets, positions) = (col(&rows, "target"), col(&rows, "position"));
    for (t, p) in targets.iter().zip(&positions) {
        assert!(
            (t - p).abs() <= window + 1e-9,
            "step at {p}, target {t}: {rows:?}"
        );
    }
}

/// A drive that shows BUSY 20 or 200 ms late, overshoots by one step and (Modbus) answers
/// "busy" once: every step of the protocol still lands within the axis resolution, on the
/// Zaber and SMC100 stages over their ptys and the AZ drive over Modbus TCP and RTU.
#[test]
fn late_busy_overshoot_and_a_busy_reply_still_land_every_step() {
    let rt = tokio::runtime::Runtime::new().unwrap();
    for latency_ms in [20u64, 200] {
        let delay = Duration::from_millis(latency_ms);
        // Zaber, shear axis, one microstep of overshoot.
        let tmp = tempfile::tempdir().unwrap();
        let z = rig::twins::zaber::ZaberTwin::spawn(rig::twins::zaber::TwinParams {
            device: 1,
            limits: (0, (25.0 / MICROSTEP_MM) as i64),
            require_checksum: true,
            time_scale: 1.0,
        })
        .unwrap();
        z.set_timing(Timing {
            delay_before_busy: delay,
            settle_to_in_position: Duration::from_millis(5),
            overshoot: 1.0,
        });
        let rig = rig_file(
            tmp.path(),
            &format!(
                "name: zaber\naxes:\n  shear: {{driver: zaber, port: {}, device: 1, axis_number: 1, microstep: {MICROSTEP_MM}, checksum: true, travel: [0 mm, 25 mm], max_speed: 2 mm/s, resolution: 0.002 mm}}\n",
                z.path()
            ),
        );
        let out = run_on_real_rig(&rig, &stepped(tmp.path(), "shear", "mm", 0.1, 1.0), |_| {});
        assert_eq!(
            out.status,
            Status::Completed,
            "zaber {latency_ms} ms: {:?}",
            out.message
        );
        landed(&out.dir, 0.002);

        // SMC100, shear axis, one 0.1 µm step of overshoot.
        let tmp = tempfile::tempdir().unwrap();
        let s = rig::twins::smc100::Smc100Twin::spawn(rig::twins::smc100::TwinParams {
            address: 1,
            limits: (0.0, 12.0),
            home_speed: 5.0,
            time_scale: 1.0,
        })
        .unwrap();
        s.set_timing(Timing {
            delay_before_busy: delay,
            settle_to_in_position: Duration::from_millis(5),
            overshoot: 0.0001,
        });
        let rig = rig_file(
            tmp.path(),
            &format!(
                "name: smc\naxes:\n  shear: {{driver: smc100, port: {}, device: 1, travel: [0 mm, 12 mm], max_speed: 2 mm/s, resolution: 0.0001 mm}}\n",
                s.path()
            ),
        );
        let out = run_on_real_rig(&rig, &stepped(tmp.path(), "shear", "mm", 0.1, 1.0), |_| {});
        assert_eq!(
            out.status,
            Status::Completed,
            "smc100 {latency_ms} ms: {:?}",
            out.message
        );
        landed(&out.dir, 0.0001);

        // The AZ over TCP and over RTU, one step (0.01 deg) of overshoot, one busy reply.
        for rtu in [false, true] {
            let tmp = tempfile::tempdir().unwrap();
            let axis = az_map(|_| {});
            let map: ModbusMap = serde_yaml::from_value(axis["modbus"].clone()).unwrap();
            let twin = if rtu {
                ModbusTwin::spawn_rtu(map, (-18000, 18000), 1.0).unwrap()
            } else {
                rt.block_on(ModbusTwin::spawn(map, (-18000, 18000), 1.0))
                    .unwrap()
            };
            twin.set_timing(Timing {
                delay_before_busy: delay,
                settle_to_in_position: Duration::from_millis(5),
                overshoot: 1.0,
            });
            let axis = az_map(|m| {
                m.remove("port");
                if rtu {
                    m.insert("port".into(), twin.address().into());
                } else {
                    m.insert("address".into(), twin.address().into());
                }
            });
            let rig = rig_file(tmp.path(), &modbus_rig(axis));
            let faults = twin.faults.clone();
            let p = stepped(tmp.path(), "rotation", "deg", 1.0, 5.0);
            let out = run_on_real_rig(&rig, &p, move |out| {
                if wait_for_event(&out, "home") {
                    lock(&faults).busy_replies = 1;
                }
            });
            let what = format!("az {} {latency_ms} ms", if rtu { "rtu" } else { "tcp" });
            assert_eq!(out.status, Status::Completed, "{what}: {:?}", out.message);
            landed(&out.dir, 0.01);
        }
    }
}

/// A drive that accepts its moves and never moves ends the run failed, naming the axis,
/// within the move's deadline — never a step recorded as reached.
#[test]
fn a_drive_that_never_moves_fails_naming_the_axis() {
    let rt = tokio::runtime::Runtime::new().unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let map: ModbusMap = serde_yaml::from_value(az_map(|_| {})["modbus"].clone()).unwrap();
    let twin = rt
        .block_on(ModbusTwin::spawn(map, (-18000, 18000), 1.0))
        .unwrap();
    let axis = az_map(|m| {
        m.remove("port");
        m.insert("address".into(), twin.address().into());
    });
    let rig = rig_file(tmp.path(), &modbus_rig(axis));
    // Homing (ZHOME) works; moves (the trigger) are accepted and ignored.
    lock(&twin.faults).ignore_triggers = true;
    let t0 = Instant::now();
    let out = run_on_real_rig(
        &rig,
        &stepped(tmp.path(), "rotation", "deg", 1.0, 5.0),
        |_| {},
    );
    let msg = out.message.clone().unwrap_or_default();
    assert_eq!(out.status, Status::Failed, "{msg}");
    assert!(
        msg.contains("the rotation axis showed no motion 0.5 s after the move to 1 deg was sent"),
        "{msg}"
    );
    assert!(t0.elapsed() < Duration::from_secs(15), "{:?}", t0.elapsed());
    assert_eq!(csv_rows(&out.dir.join("steps.csv")).len(), 0);
}

/// The AZ's direct-data operation: the short-form map's lone `0x0066 := 1` leaves the
/// 32-bit trigger at 0x00010000 and the drive never moves — the run fails instead of
/// completing with every step at 0 deg — while the AZ-true map's one FC16 block moves it.
#[test]
fn the_direct_data_block_moves_an_az_that_ignores_a_lone_trigger() {
    let rt = tokio::runtime::Runtime::new().unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let map: ModbusMap = serde_yaml::from_value(az_map(|_| {})["modbus"].clone()).unwrap();
    let twin = rt
        .block_on(ModbusTwin::spawn(map, (-18000, 18000), 1.0))
        .unwrap();
    assert_eq!(twin.kind(), rig::twins::modbus::Kind::Az);
    let address = twin.address();
    let short = az_map(|m| {
        m.remove("port");
        m.insert("address".into(), address.clone().into());
        to_short_form(m);
    });
    let rig = rig_file(tmp.path(), &modbus_rig(short));
    let p = stepped(tmp.path(), "rotation", "deg", 1.0, 5.0);
    let out = run_on_real_rig(&rig, &p, |_| {});
    let msg = out.message.clone().unwrap_or_default();
    assert_eq!(out.status, Status::Failed, "{msg}");
    assert!(msg.contains("showed no motion"), "{msg}");
    let long = az_map(|m| {
        m.remove("port");
        m.insert("address".into(), address.clone().into());
    });
    let tmp = tempfile::tempdir().unwrap();
    let rig = rig_file(tmp.path(), &modbus_rig(long));
    let out = run_on_real_rig(
        &rig,
        &stepped(tmp.path(), "rotation", "deg", 1.0, 5.0),
        |_| {},
    );
    assert_eq!(out.status, Status::Completed, "{:?}", out.message);
    landed(&out.dir, 0.01);
}

/// `gelrig probe` against a drive answering "busy" says what it answered — it is not "no
/// answer" — and tells it apart from a drive that is silent.
#[test]
fn probe_tells_a_busy_drive_from_a_silent_one() {
    let rt = tokio::runtime::Runtime::new().unwrap();
    let map: ModbusMap = serde_yaml::from_value(az_map(|_| {})["modbus"].clone()).unwrap();
    let twin = rt
        .block_on(ModbusTwin::spawn(map, (-18000, 18000), 1.0))
        .unwrap();
    let axis = az_map(|m| {
        m.remove("port");
        m.insert("address".into(), twin.address().into());
        m.insert("busy_retry_ms".into(), 100.into());
    });
    let tmp = tempfile::tempdir().unwrap();
    let rig_path = rig_file(tmp.path(), &modbus_rig(axis));
    let rig = experiments::protocol::load_rig(&rig_path).unwrap().0;
    for (busy, silent) in [(true, false), (false, true)] {
        {
            let mut f = lock(&twin.faults);
            f.busy = busy;
            f.silent = silent;
        }
        let probes = rt.block_on(simbench::bench::probe(&rig));
        let p = probes.iter().find(|p| p.role == "rotation").unwrap();
        assert!(!p.ok, "{p:?}");
        assert_eq!(p.silent, silent, "{p:?}");
        if busy {
            assert!(
                p.detail.contains("server device busy (exception 06)"),
                "{p:?}"
            );
        }
    }
}
