//! The Modbus driver against its twin over loopback Modbus TCP and over RTU on a
//! pseudo-terminal: the register map in both, moves, homing, the drive's own limits (alarm,
//! exception 0x03), busy exceptions, a wrong unit id (no reply: a bounded timeout), and
//! (RTU) replies with a bad CRC.

use std::time::Duration;

use rig::device::{Axis, AxisInfo};
use rig::drivers::modbus::{ModbusAxis, ModbusMap, RegWrite, WordOrder};
use rig::twins::modbus::ModbusTwin;
use rig::units::AxisUnit;
use rig::{RigError, lock};

mod common;
use common::{rest_position, wait_idle};

fn map(address: String, slave: u8) -> ModbusMap {
    // An Oriental AZ-like map (spec devices.md §2d), upper word first.
    ModbusMap {
        address: Some(address),
        port: None,
        baud: None,
        parity: None,
        slave,
        word_order: WordOrder::HighFirst,
        steps_per_unit: 500.0,
        target: Some(0x005C),
        speed: Some(0x005E),
        trigger: Some(RegWrite {
            addr: 0x0066,
            value: 1,
        }),
        move_writes: Vec::new(),
        on_open: Vec::new(),
        acceleration: None,
        deceleration: None,
        current: None,
        in_position_bit: None,
        busy_retry_ms: Some(300),
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

/// The same map on an RTU line: `port` instead of `address`.
fn rtu_map(port: String, slave: u8) -> ModbusMap {
    ModbusMap {
        address: None,
        port: Some(port),
        baud: Some(19200),
        ..map(String::new(), slave)
    }
}

#[tokio::test]
async fn moves_homes_and_keeps_the_two_error_layers_apart() {
    let twin = ModbusTwin::spawn(map(String::new(), 1), (0, 6000), 1.0)
        .await
        .expect("twin");
    exercise(&twin, map(twin.address(), 1)).await;
}

#[tokio::test]
async fn the_same_over_rtu_on_a_pseudo_terminal() {
    let twin = ModbusTwin::spawn_rtu(map(String::new(), 1), (0, 6000), 1.0).expect("twin");
    assert!(twin.address().starts_with("/dev/pts/"));
    exercise(&twin, rtu_map(twin.address(), 1)).await;
}

/// Moves, homing, limits, busy and silence against `twin` through `m`.
async fn exercise(twin: &ModbusTwin, m: ModbusMap) {
    // The rig file allows 20 mm; the drive only 12 mm (6000 steps).
    let mut a = ModbusAxis::open(m, info(20.0)).await.expect("opens");
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
    lock(&twin.faults).silent = false;
    a.status().await.expect("answers again after the silence");
}

#[tokio::test]
async fn rtu_replies_with_a_bad_crc_are_errors_and_the_line_recovers() {
    let twin = ModbusTwin::spawn_rtu(map(String::new(), 1), (0, 6000), 1.0).expect("twin");
    let mut a = ModbusAxis::open(rtu_map(twin.address(), 1), info(12.0))
        .await
        .expect("opens");
    lock(&twin.faults).garble_next = 1;
    let t0 = std::time::Instant::now();
    let e = a.status().await.expect_err("garbled reply");
    assert!(
        matches!(e, RigError::Io { .. } | RigError::Timeout { .. }),
        "{e}"
    );
    assert!(t0.elapsed() < Duration::from_secs(2));
    let s = a.status().await.expect("the next request is answered");
    assert!((s.position - 1234.0 / 500.0).abs() < 1e-9, "{s:?}");
    // A wrong unit id on the line: silence, a bounded timeout.
    drop(a);
    let e = ModbusAxis::open(rtu_map(twin.address(), 7), info(12.0))
        .await
        .err()
        .expect("no reply");
    assert!(matches!(e, RigError::Timeout { .. }), "{e}");
    // A port that does not exist names the fix.
    let e = ModbusAxis::open(rtu_map("/dev/ttyNOPE9".into(), 1), info(12.0))
        .await
        .err()
        .expect("no such port");
    assert!(e.to_string().contains("port:"), "{e}");
}

#[tokio::test]
async fn a_wrong_unit_id_or_a_bad_map_is_refused() {
    let twin = ModbusTwin::spawn(map(String::new(), 1), (0, 6000), 1.0)
        .await
        .expect("twin");
    let e = ModbusAxis::open(map(twin.address(), 9), info(12.0))
        .await
        .err()
        .expect("no reply");
    assert!(matches!(e, RigError::Timeout { .. }), "{e}");
    let mut bad = map(twin.address(), 1);
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
            .any(|t| t.contains("modbus.target") && t.contains("writes register 0x005d twice")),
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

/// The AZ-true map (long form, as in `sim-wire.yaml`) on `address` or an RTU `port`.
fn az_map(address: Option<String>, port: Option<String>) -> ModbusMap {
    use rig::drivers::modbus::{Field, Placeholder, WriteStep};
    let values = vec![
        Field::Number(0),
        Field::Number(1),
        Field::Value(Placeholder::Position),
        Field::Value(Placeholder::Speed),
        Field::Value(Placeholder::Acceleration),
        Field::Value(Placeholder::Deceleration),
        Field::Value(Placeholder::Current),
        Field::Number(1),
    ];
    ModbusMap {
        address,
        port,
        target: None,
        speed: None,
        trigger: None,
        move_writes: vec![WriteStep {
            write: 0x0058,
            values,
            width: 32,
        }],
        acceleration: Some(30_000),
        deceleration: Some(30_000),
        current: Some(1000),
        in_position_bit: Some(14),
        ..map(String::new(), 1)
    }
}

/// Both transports answer a function the drive does not implement (FC4, read input
/// registers) with exception 01, as Modbus requires — the RTU twin used to stay silent.
#[tokio::test]
async fn unsupported_functions_answer_illegal_function_on_both_transports() {
    use std::io::{Read, Write};
    let twin = ModbusTwin::spawn(az_map(None, None), (-18000, 18000), 1.0)
        .await
        .expect("twin");
    let addr: std::net::SocketAddr = twin.address().parse().expect("address");
    let mut ctx = tokio_modbus::client::tcp::connect_slave(addr, tokio_modbus::Slave(1))
        .await
        .expect("connects");
    use tokio_modbus::client::Reader;
    let r = ctx.read_input_registers(0x0120, 2).await.expect("answered");
    assert_eq!(r, Err(tokio_modbus::ExceptionCode::IllegalFunction));

    let rtu = ModbusTwin::spawn_rtu(az_map(None, None), (-18000, 18000), 1.0).expect("twin");
    let mut port = serialport::new(rtu.address(), 19200)
        .timeout(Duration::from_millis(500))
        .open_native()
        .expect("opens the pty");
    // Unit 1, FC4, address 0x0120, 2 registers, CRC-16/MODBUS low byte first.
    let mut frame = vec![1u8, 4, 0x01, 0x20, 0, 2];
    let crc = crc::Crc::<u16>::new(&crc::CRC_16_MODBUS).checksum(&frame);
    frame.extend(crc.to_le_bytes());
    port.write_all(&frame).expect("writes");
    let mut reply = [0u8; 5];
    port.read_exact(&mut reply).expect("an answer, not silence");
    assert_eq!(
        &reply[..3],
        &[1, 0x84, 0x01],
        "exception 01 to FC4: {reply:?}"
    );
}

/// The AZ twin takes the direct-data block (one FC16 of 16 registers) and moves; a lone
/// `0x0066 := 1` leaves the 32-bit trigger at 0x00010000 and does nothing; exception 06
/// once on a trigger is asked again and the move goes through; exception 03 is a refusal
/// naming the registers and values written.
#[tokio::test]
async fn the_az_block_moves_a_lone_trigger_does_not_and_busy_is_asked_again() {
    use rig::twins::motion::Timing;
    let twin = ModbusTwin::spawn(az_map(None, None), (-18000, 18000), 1.0)
        .await
        .expect("twin");
    let deg = |max: f64| AxisInfo {
        role: "rotation".into(),
        unit: AxisUnit::Deg,
        travel_min: -max,
        travel_max: max,
        max_speed: 100.0,
        resolution: 0.01,
        identity: String::new(),
    };
    let mut a = ModbusAxis::open(az_map(Some(twin.address()), None), deg(180.0))
        .await
        .expect("opens");
    a.home().await.expect("home");
    wait_idle(&mut a).await;
    a.move_to(1.5, 50.0).await.expect("block write");
    assert!((wait_idle(&mut a).await - 1.5).abs() < 1e-9);
    assert!((twin.position_steps() - 750.0).abs() < 1e-9);
    // A short-form map against the same drive: the writes are accepted, nothing moves.
    let short = ModbusMap {
        target: Some(0x005C),
        speed: Some(0x005E),
        trigger: Some(RegWrite {
            addr: 0x0066,
            value: 1,
        }),
        move_writes: Vec::new(),
        ..az_map(Some(twin.address()), None)
    };
    let mut b = ModbusAxis::open(short, deg(180.0)).await.expect("opens");
    b.move_to(3.0, 50.0).await.expect("accepted");
    tokio::time::sleep(Duration::from_millis(200)).await;
    assert!(
        (twin.position_steps() - 750.0).abs() < 1e-9,
        "a lone trigger moved it to {}",
        twin.position_steps()
    );
    // Busy once on the trigger: asked again, and the move happens.
    twin.set_timing(Timing::default());
    lock(&twin.faults).busy_replies = 1;
    a.move_to(2.0, 50.0)
        .await
        .expect("busy once is not a refusal");
    assert!((wait_idle(&mut a).await - 2.0).abs() < 1e-9);
    // Beyond the drive's limits: a refusal naming what was written.
    let mut small = ModbusAxis::open(az_map(Some(twin.address()), None), deg(300.0))
        .await
        .expect("opens");
    let e = small
        .move_to(250.0, 50.0)
        .await
        .expect_err("beyond the drive");
    let text = e.to_string();
    assert!(
        text.contains("write 0x0058..0x0067") && text.contains("exception 03"),
        "{text}"
    );
}

/// A long-form map is checked at load: `position` exactly once, a value for every
/// placeholder used, both forms at once refused — each located at the map's `move`.
#[test]
fn a_long_form_map_is_checked_at_load() {
    let text = r#"
name: az-bench
axes:
  rotation:
    driver: modbus
    travel: [-180 deg, 180 deg]
    max_speed: 10 deg/s
    resolution: 0.01 deg
    modbus:
      address: 192.168.1.20:502
      slave: 1
      steps_per_unit: 100
      move:
        - write: 0x0058
          values: [0, 1, speed, speed, acceleration, deceleration, current, 1]
      acceleration: 1000
      trigger: {addr: 0x0066, value: 1}
      position: 0x0120
      status: 0x007F
      busy_bit: 8
      alarm_bit: 7
      home: {addr: 0x007D, value: 0x0010}
      stop: {addr: 0x007D, value: 0x0020}
"#;
    let rig = rig::config::RigConfig::from_yaml_str(text).expect("parses");
    let text: Vec<String> = rig
        .check()
        .iter()
        .map(|i| format!("{}: {}", i.path, i.message))
        .collect();
    for want in [
        "axes.rotation.modbus.move: register map: `position` must appear exactly once",
        "the move uses `deceleration`, but the map gives no `deceleration:` value",
        "not both",
    ] {
        assert!(text.iter().any(|t| t.contains(want)), "{want}: {text:?}");
    }
}

/// A status poll is two reads (position, then the status word would be the natural order):
/// a move that ends between them would read "at rest" with a position from mid-move, and a
/// runner would take the stage as short of its target (on a loaded host, a late-drive run
/// once stopped "at rest at 9.79 deg" of a move to 10). With every reply 15 ms late, no poll
/// that says "at rest" may carry any position but the target.
#[tokio::test]
async fn a_move_ending_between_the_reads_of_one_poll_is_not_at_rest_short_of_its_target() {
    let twin = ModbusTwin::spawn(map(String::new(), 1), (0, 6000), 1.0)
        .await
        .expect("twin");
    let mut a = ModbusAxis::open(map(twin.address(), 1), info(20.0))
        .await
        .expect("opens");
    a.home().await.expect("home");
    wait_idle(&mut a).await;
    lock(&twin.faults).reply_delay = Duration::from_millis(15);
    for k in 0..8 {
        // 1 mm at 50 mm/s: 20 ms, about the length of one poll.
        let target = if k % 2 == 0 { 2.0 } else { 1.0 };
        a.move_to(target, 50.0).await.expect("move");
        let at = rest_position(&mut a).await;
        assert!(
            (at - target).abs() < 1e-9,
            "move {k}: at rest at {at} mm, the target {target} mm"
        );
    }
}
