//! The Modbus driver against its twin over loopback Modbus TCP: the register map in both,
//! moves, homing, the drive's own limits (alarm, exception 0x03), busy exceptions, and a
//! wrong unit id (no reply: a bounded timeout).

use std::time::Duration;

use rig::device::{Axis, AxisInfo};
use rig::drivers::modbus::{ModbusAxis, ModbusMap, RegWrite, WordOrder};
use rig::twins::modbus::ModbusTwin;
use rig::units::AxisUnit;
use rig::{RigError, lock};

mod common;
use common::wait_idle;

fn map(address: String, slave: u8) -> ModbusMap {
    // An Oriental AZ-like map (spec devices.md §2d), upper word first.
    ModbusMap {
        address,
        slave,
        word_order: WordOrder::HighFirst,
        steps_per_unit: 500.0,
        target: 0x005C,
        speed: 0x005E,
        trigger: RegWrite {
            addr: 0x0066,
            value: 1,
        },
        position: 0x0120,
        status: 0x007F,
        busy_bit: 8,
        alarm_bit: 7,
        homed_bit: Some(4),
        home: RegWrite {
            addr: 0x007D,
            value: 0x0010,
        },
        stop: RegWrite {
            addr: 0x007D,
            value: 0x0020,
        },
        timeout_ms: Some(200),
    }
}

fn info(max: f64) -> AxisInfo {
    AxisInfo {
        role: "normal".into(),
        unit: AxisUnit::Mm,
        travel_min: 0.0,
        travel_max: max,
        max_speed: 100.0,
        resolution: 0.002,
        identity: String::new(),
    }
}

#[tokio::test]
async fn moves_homes_and_keeps_the_two_error_layers_apart() {
    let twin = ModbusTwin::spawn(map(String::new(), 1), (0, 6000))
        .await
        .expect("twin");
    // The rig file allows 20 mm; the drive only 12 mm (6000 steps).
    let mut a = ModbusAxis::open(map(twin.address.to_string(), 1), info(20.0))
        .await
        .expect("opens");
    let s = a.status().await.expect("status");
    assert!(
        !s.referenced && (s.position - 1234.0 / 500.0).abs() < 1e-9,
        "{s:?}"
    );
    a.home().await.expect("home");
    wait_idle(&mut a).await;
    assert!(a.status().await.expect("status").referenced);
    a.move_to(4.2, 50.0).await.expect("move");
    assert!(a.status().await.expect("status").moving);
    assert!((wait_idle(&mut a).await - 4.2).abs() < 1e-9);
    assert!((twin.position_steps() - 2100.0).abs() < 1e-9);
    // Beyond the drive's limit: exception 0x03 reported as a refusal, then the alarm bit.
    let e = a
        .move_to(15.0, 50.0)
        .await
        .expect_err("beyond the drive's travel");
    assert!(matches!(e, RigError::Rejected { .. }), "{e}");
    let e = a.status().await.expect_err("alarm");
    assert!(e.to_string().contains("alarm"), "{e}");
    a.home().await.expect("homing clears the alarm");
    wait_idle(&mut a).await;
    // Busy exceptions.
    lock(&twin.faults).busy = true;
    let e = a.status().await.expect_err("busy");
    assert!(
        matches!(&e, RigError::Rejected { reason, .. } if reason.to_lowercase().contains("busy")),
        "{e}"
    );
    lock(&twin.faults).busy = false;
    // Silence: a bounded timeout.
    lock(&twin.faults).silent = true;
    let t0 = std::time::Instant::now();
    assert!(matches!(a.status().await, Err(RigError::Timeout { .. })));
    assert!(t0.elapsed() < Duration::from_secs(2));
}

#[tokio::test]
async fn a_wrong_unit_id_or_a_bad_map_is_refused() {
    let twin = ModbusTwin::spawn(map(String::new(), 1), (0, 6000))
        .await
        .expect("twin");
    let e = ModbusAxis::open(map(twin.address.to_string(), 9), info(12.0))
        .await
        .err()
        .expect("no reply");
    assert!(matches!(e, RigError::Timeout { .. }), "{e}");
    let mut bad = map(twin.address.to_string(), 1);
    bad.position = 0x005D; // overlaps the target
    let e = ModbusAxis::open(bad, info(12.0))
        .await
        .err()
        .expect("bad map");
    assert!(e.to_string().contains("register map"), "{e}");
}

#[test]
fn the_rig_file_register_map_is_validated_at_load() {
    let text = r#"
name: modbus-bench
axes:
  normal:
    driver: modbus
    travel: [0 mm, 12 mm]
    max_speed: 2 mm/s
    resolution: 0.002 mm
    modbus:
      address: 192.168.1.20:502
      slave: 1
      word_order: high_first
      steps_per_unit: 500
      target: 0x005C
      speed: 0x005D
      trigger: {addr: 0x0066, value: 1}
      position: 0x0120
      status: 0x007F
      busy_bit: 8
      alarm_bit: 17
      homed_bit: 4
      home: {addr: 0x007D, value: 0x0010}
      stop: {addr: 0x007D, value: 0x0020}
"#;
    let rig = rig::config::RigConfig::from_yaml_str(text).expect("parses");
    let issues = rig.check();
    let text: Vec<String> = issues
        .iter()
        .map(|i| format!("{}: {}", i.path, i.message))
        .collect();
    assert!(
        text.iter()
            .any(|t| t.contains("speed") && t.contains("also `target`")),
        "{text:?}"
    );
    assert!(text.iter().any(|t| t.contains("alarm_bit")), "{text:?}");
    // Without a map at all.
    let rig = rig::config::RigConfig::from_yaml_str(
        "name: x\naxes:\n  normal: {driver: modbus, travel: [0 mm, 1 mm], max_speed: 1 mm/s, resolution: 0.01 mm}\n",
    )
    .expect("parses");
    assert!(
        rig.check()
            .iter()
            .any(|i| i.message.contains("register map"))
    );
}
