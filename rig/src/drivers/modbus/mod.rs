//! A Modbus stage (e.g. an Oriental AZ drive, spec `devices.md` §2d) over Modbus TCP or
//! RTU (RS-485 serial) through `tokio-modbus`, with its register map in the rig file and
//! validated at load ([`map`]).
//!
//! A move is the map's sequence of writes (the long form), or target, speed and trigger
//! (the short form); the status register's bits say busy, alarm, homed and in-position.
//! Both error layers of `tokio-modbus` are kept apart: a transport error is a timeout or
//! I/O failure, an exception is the drive answering. Exceptions by their meaning (Modbus
//! application protocol §7): 05 Acknowledge and 06 Server Device Busy mean "try again
//! later" and are retried with backoff for the map's `busy_retry_ms`; 01 Illegal Function,
//! 02 Illegal Data Address, 03 Illegal Data Value and 04 Server Device Failure are
//! refusals naming the registers and values written. Every request has a timeout.

pub mod map;

use std::net::SocketAddr;
use std::time::{Duration, Instant};

use async_trait::async_trait;
use tokio_modbus::client::{Context, Reader, Writer};
use tokio_modbus::client::{rtu, tcp};
use tokio_modbus::{ExceptionCode, Slave};

pub use map::{Field, ModbusMap, Parity, Placeholder, RegWrite, WordOrder, WriteStep};

use super::serial_async::AsyncSerial;
use crate::RigError;
use crate::device::{Axis, AxisInfo, AxisStatus, AxisStopper};

/// What a drive's exception means, in words.
fn exception_meaning(e: ExceptionCode) -> String {
    let code = u8::from(e);
    let what = match code {
        0x01 => "illegal function: the drive does not implement this request",
        0x02 => "illegal data address: no such register on this drive",
        0x03 => "illegal data value: the drive rejects the value (a target beyond its limits?)",
        0x04 => "server device failure: the drive failed while acting on it",
        0x05 => "acknowledge: accepted, still being processed",
        0x06 => "server device busy",
        _ => "an exception the drive's manual explains",
    };
    format!("{what} (exception {code:02})")
}

/// How long the link waits for a request, and how long "busy" is asked again.
#[derive(Debug, Clone, Copy)]
struct Patience {
    timeout: Duration,
    busy_retry: Duration,
}

/// One Modbus request.
#[derive(Debug, Clone, Copy)]
enum Op<'a> {
    /// FC3: `n` holding registers from `addr`.
    Read(u16, u16),
    /// FC6: one register.
    WriteOne(u16, u16),
    /// FC16: a block.
    WriteMany(u16, &'a [u16]),
}

/// One request with its timeout, both error layers of `tokio-modbus` kept apart; 05 and
/// 06 asked again with backoff (10 ms doubling to 100 ms) for `busy_retry`. The timeout
/// covers the wait for the link too. Returns the registers read (empty for writes).
async fn call(
    ctx: &tokio::sync::Mutex<Context>,
    patience: Patience,
    name: &str,
    what: &str,
    op: Op<'_>,
) -> Result<Vec<u16>, RigError> {
    let started = Instant::now();
    let mut backoff = Duration::from_millis(10);
    loop {
        let r = tokio::time::timeout(patience.timeout, async {
            let mut c = ctx.lock().await;
            match op {
                Op::Read(a, n) => c.read_holding_registers(a, n).await,
                Op::WriteOne(a, w) => c
                    .write_single_register(a, w)
                    .await
                    .map(|r| r.map(|()| Vec::new())),
                Op::WriteMany(a, ws) => c
                    .write_multiple_registers(a, ws)
                    .await
                    .map(|r| r.map(|()| Vec::new())),
            }
        })
        .await;
        match r {
            Err(_) => {
                return Err(RigError::Timeout {
                    device: name.to_string(),
                    timeout_ms: patience.timeout.as_millis() as u64,
                });
            }
            Ok(Err(e)) => {
                return Err(RigError::Io {
                    device: name.to_string(),
                    source: std::io::Error::other(crate::quote(&e.to_string())),
                });
            }
            Ok(Ok(Err(e @ (ExceptionCode::Acknowledge | ExceptionCode::ServerDeviceBusy)))) => {
                if started.elapsed() + backoff > patience.busy_retry {
                    return Err(RigError::Rejected {
                        device: name.to_string(),
                        command: what.to_string(),
                        reason: format!(
                            "the drive answered {} for {} ms",
                            exception_meaning(e),
                            started.elapsed().as_millis()
                        ),
                    });
                }
                tokio::time::sleep(backoff).await;
                backoff = (backoff * 2).min(Duration::from_millis(100));
            }
            Ok(Ok(Err(e))) => {
                return Err(RigError::Rejected {
                    device: name.to_string(),
                    command: what.to_string(),
                    reason: exception_meaning(e),
                });
            }
            Ok(Ok(Ok(v))) => return Ok(v),
        }
    }
}

/// What a write is, for messages: `write 0x0058..0x0067 := [0, 1, 100, …]`.
fn describe(addr: u16, words: &[u16]) -> String {
    let shown: Vec<String> = words.iter().take(8).map(|w| w.to_string()).collect();
    let more = if words.len() > 8 { ", …" } else { "" };
    if words.len() == 1 {
        format!("write {addr:#06x} := {}", shown.join(""))
    } else {
        format!(
            "write {addr:#06x}..{:#06x} := [{}{more}]",
            addr.saturating_add(words.len() as u16 - 1),
            shown.join(", ")
        )
    }
}

/// One write: FC6 for a single register, FC16 for a block.
async fn write_words(
    ctx: &tokio::sync::Mutex<Context>,
    patience: Patience,
    name: &str,
    addr: u16,
    words: &[u16],
) -> Result<(), RigError> {
    let what = describe(addr, words);
    let op = match words {
        [w] => Op::WriteOne(addr, *w),
        _ => Op::WriteMany(addr, words),
    };
    call(ctx, patience, name, &what, op).await.map(|_| ())
}

/// Writes the map's stop register on the shared link.
struct ModbusStopper {
    ctx: std::sync::Arc<tokio::sync::Mutex<Context>>,
    stop: RegWrite,
    patience: Patience,
    name: String,
}

#[async_trait]
impl AxisStopper for ModbusStopper {
    async fn stop_now(&self) -> Result<(), RigError> {
        let w = self.stop;
        write_words(&self.ctx, self.patience, &self.name, w.addr, &[w.value]).await
    }
}

/// The driver.
pub struct ModbusAxis {
    info: AxisInfo,
    map: ModbusMap,
    /// Shared with the watchdog's stopper: Modbus has one request in flight per link (RTU
    /// has no transaction ids), so a stop waits for the request in flight (bounded by the
    /// map's timeout) and then goes first.
    ctx: std::sync::Arc<tokio::sync::Mutex<Context>>,
}

impl ModbusAxis {
    /// Connects to the drive, makes the map's writes on open, and reads its status once.
    pub async fn open(map: ModbusMap, mut info: AxisInfo) -> Result<Self, RigError> {
        let device = format!("Modbus drive {} unit {}", map.endpoint(), map.slave);
        if let Some((field, msg)) = map.problems().into_iter().next() {
            return Err(RigError::Unsupported {
                device,
                detail: format!("register map `{field}`: {msg}"),
            });
        }
        let timeout_ms = map.timeout().as_millis() as u64;
        let io = |source| RigError::Io {
            device: device.clone(),
            source,
        };
        let ctx = match (&map.address, &map.port) {
            (Some(address), _) => {
                let addr: SocketAddr = address.parse().map_err(|_| RigError::Unsupported {
                    device: device.clone(),
                    detail: "bad address".into(),
                })?;
                tokio::time::timeout(map.timeout(), tcp::connect_slave(addr, Slave(map.slave)))
                    .await
                    .map_err(|_| RigError::Timeout {
                        device: device.clone(),
                        timeout_ms,
                    })?
                    .map_err(io)?
            }
            (None, Some(port)) => {
                let serial = AsyncSerial::open(
                    port,
                    map.baud.unwrap_or(19200),
                    map.parity.unwrap_or_default(),
                )
                .map_err(|e| {
                    io(std::io::Error::new(
                        e.kind(),
                        format!("{e}; fix: check the `port:` path in the register map"),
                    ))
                })?;
                rtu::attach_slave(serial, Slave(map.slave))
            }
            (None, None) => {
                return Err(RigError::Unsupported {
                    device,
                    detail: "the register map has neither `address` nor `port`".into(),
                });
            }
        };
        info.identity = device;
        let a = Self {
            info,
            map,
            ctx: std::sync::Arc::new(tokio::sync::Mutex::new(ctx)),
        };
        for step in a.map.on_open.clone() {
            let words = step
                .words(a.map.word_order, |_| 0)
                .map_err(|detail| a.garbled(detail))?;
            write_words(&a.ctx, a.patience(), &a.name(), step.write, &words).await?;
        }
        let mut a = a;
        a.status().await?;
        Ok(a)
    }

    fn name(&self) -> String {
        self.info.identity.clone()
    }

    fn patience(&self) -> Patience {
        Patience {
            timeout: self.map.timeout(),
            busy_retry: self.map.busy_retry(),
        }
    }

    fn garbled(&self, detail: String) -> RigError {
        RigError::Garbled {
            device: self.name(),
            detail,
        }
    }

    async fn write(&mut self, w: RegWrite) -> Result<(), RigError> {
        write_words(&self.ctx, self.patience(), &self.name(), w.addr, &[w.value]).await
    }
}

#[async_trait]
impl Axis for ModbusAxis {
    fn info(&self) -> &AxisInfo {
        &self.info
    }

    fn stopper(&self) -> std::sync::Arc<dyn AxisStopper> {
        std::sync::Arc::new(ModbusStopper {
            ctx: self.ctx.clone(),
            stop: self.map.stop,
            patience: self.patience(),
            name: self.name(),
        })
    }

    async fn home(&mut self) -> Result<(), RigError> {
        let w = self.map.home;
        self.write(w).await
    }

    async fn move_to(&mut self, target: f64, speed: f64) -> Result<(), RigError> {
        self.info.check_target(target)?;
        self.info.check_speed(speed)?;
        let m = self.map.clone();
        let steps = (target * m.steps_per_unit).round() as i64;
        let sps = (speed * m.steps_per_unit).round().max(1.0) as i64;
        let value = |p: Placeholder| match p {
            Placeholder::Position => steps,
            Placeholder::Speed => sps,
            Placeholder::Acceleration => m.acceleration.unwrap_or(0),
            Placeholder::Deceleration => m.deceleration.unwrap_or(0),
            Placeholder::Current => m.current.unwrap_or(0),
        };
        let Some(sequence) = m.move_steps() else {
            return Err(self.garbled("the register map has no move".into()));
        };
        for step in sequence {
            let words = step
                .words(m.word_order, value)
                .map_err(|detail| self.garbled(detail))?;
            write_words(&self.ctx, self.patience(), &self.name(), step.write, &words).await?;
        }
        Ok(())
    }

    async fn status(&mut self) -> Result<AxisStatus, RigError> {
        let m = self.map.clone();
        let (patience, name) = (self.patience(), self.name());
        // The status word first: a stage that reads at rest stays there, so the position
        // read after it is where it rests. The other order lets a move that ends between
        // the two reads be reported at rest with a position from mid-move.
        let st = call(
            &self.ctx,
            patience,
            &name,
            &format!("read {:#06x} (status)", m.status),
            Op::Read(m.status, 1),
        )
        .await?;
        let pos = call(
            &self.ctx,
            patience,
            &name,
            &format!(
                "read {:#06x}..{:#06x} (position)",
                m.position,
                m.position + 1
            ),
            Op::Read(m.position, 2),
        )
        .await?;
        let (Some(&p0), Some(&p1), Some(&s)) = (pos.first(), pos.get(1), st.first()) else {
            return Err(self.garbled("short register reply".into()));
        };
        if s & (1 << m.alarm_bit) != 0 {
            return Err(RigError::Rejected {
                device: name,
                command: "status".into(),
                reason:
                    "the drive is in alarm; fix: clear it (ALM-RST) and check the travel limits"
                        .into(),
            });
        }
        Ok(AxisStatus {
            position: m.word_order.join([p0, p1]) as f64 / m.steps_per_unit,
            moving: s & (1 << m.busy_bit) != 0,
            referenced: m.homed_bit.is_none_or(|b| s & (1 << b) != 0),
            in_position: m.in_position_bit.map(|b| s & (1 << b) != 0),
        })
    }

    async fn stop(&mut self) -> Result<(), RigError> {
        let w = self.map.stop;
        self.write(w).await
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn short() -> ModbusMap {
        ModbusMap {
            address: Some("127.0.0.1:502".into()),
            port: None,
            baud: None,
            parity: None,
            slave: 1,
            word_order: WordOrder::HighFirst,
            steps_per_unit: 500.0,
            target: Some(0x5C),
            speed: Some(0x5E),
            trigger: Some(RegWrite {
                addr: 0x66,
                value: 1,
            }),
            move_writes: Vec::new(),
            on_open: Vec::new(),
            acceleration: None,
            deceleration: None,
            current: None,
            position: 0x120,
            status: 0x7F,
            busy_bit: 8,
            alarm_bit: 7,
            homed_bit: Some(4),
            in_position_bit: None,
            home: RegWrite {
                addr: 0x7D,
                value: 0x10,
            },
            stop: RegWrite {
                addr: 0x7D,
                value: 0x20,
            },
            timeout_ms: None,
            busy_retry_ms: None,
        }
    }

    #[test]
    fn words_and_map_checks() {
        for o in [WordOrder::HighFirst, WordOrder::LowFirst] {
            for v in [0, 1, -1, 123_456_789, i32::MIN, i32::MAX] {
                assert_eq!(o.join(o.split(v)), v);
            }
        }
        assert_eq!(WordOrder::HighFirst.split(0x0001_0002), [1, 2]);
        let mut m = short();
        assert!(m.problems().is_empty(), "{:?}", m.problems());
        m.speed = Some(0x5D);
        m.busy_bit = 16;
        m.port = Some("/dev/ttyUSB0".into());
        m.baud = Some(12345);
        let p = m.problems();
        for field in ["target", "busy_bit", "port", "baud"] {
            assert!(p.iter().any(|(f, _)| *f == field), "{field}: {p:?}");
        }
        m.address = None;
        assert!(!m.problems().iter().any(|(f, _)| *f == "port"));
    }

    /// The AZ's direct-data operation as one 16-register block, and the map errors a
    /// hand-written long form can have.
    #[test]
    fn the_long_form_and_its_checks() {
        use Field::{Number as N, Value as V};
        let az = WriteStep {
            write: 0x0058,
            values: vec![
                N(0),
                N(1),
                V(Placeholder::Position),
                V(Placeholder::Speed),
                V(Placeholder::Acceleration),
                V(Placeholder::Deceleration),
                V(Placeholder::Current),
                N(1),
            ],
            width: 32,
        };
        let mut m = ModbusMap {
            target: None,
            speed: None,
            trigger: None,
            move_writes: vec![az.clone()],
            acceleration: Some(30_000),
            deceleration: Some(30_000),
            current: Some(1000),
            ..short()
        };
        assert!(m.problems().is_empty(), "{:?}", m.problems());
        let words = az
            .words(WordOrder::HighFirst, |p| match p {
                Placeholder::Position => -200,
                _ => 7,
            })
            .expect("fits");
        assert_eq!(words.len(), 16);
        // The trigger is the 32-bit value 1: 0x0000, 0x0001.
        assert_eq!(&words[14..], &[0, 1]);
        assert_eq!(WordOrder::HighFirst.join([words[4], words[5]]), -200);
        // Missing placeholders' values, a position twice, both forms, an overlap.
        m.current = None;
        m.move_writes[0].values[6] = V(Placeholder::Position);
        m.target = Some(0x10);
        m.move_writes.push(WriteStep {
            write: 0x0120,
            values: vec![N(1)],
            width: 16,
        });
        let p: Vec<String> = m.problems().into_iter().map(|(_, s)| s).collect();
        for want in ["exactly once", "not both", "which is `position`"] {
            assert!(p.iter().any(|s| s.contains(want)), "{want}: {p:?}");
        }
    }
}
