//! A Modbus stage (e.g. an Oriental AZ drive, spec `devices.md` §2d) over Modbus TCP or
//! RTU (RS-485 serial) through `tokio-modbus`, with its register map in the rig file and
//! validated at load.
//!
//! A move writes the target and speed (32-bit, two registers each, in the map's word
//! order) and then the trigger; the status register's bits say busy, alarm and homed.
//! Both error layers of `tokio-modbus` are kept apart: a transport error is a timeout or
//! I/O failure, an exception is the drive refusing (`IllegalDataValue` for a target beyond
//! its limits, `ServerDeviceBusy`, …). Every request has a timeout.

use std::net::SocketAddr;
use std::time::Duration;

use async_trait::async_trait;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use tokio_modbus::Slave;
use tokio_modbus::client::{Context, Reader, Writer};
use tokio_modbus::client::{rtu, tcp};

pub use super::serial_async::Parity;
use super::serial_async::{AsyncSerial, baud_rate};
use crate::RigError;
use crate::device::{Axis, AxisInfo, AxisStatus, AxisStopper};

/// Order of the two 16-bit words of a 32-bit value.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema, Default)]
#[serde(rename_all = "snake_case")]
pub enum WordOrder {
    /// Upper word first (Oriental, most drives).
    #[default]
    HighFirst,
    /// Lower word first.
    LowFirst,
}

impl WordOrder {
    /// A 32-bit value as two registers.
    pub fn split(self, v: i32) -> [u16; 2] {
        let (hi, lo) = ((v as u32 >> 16) as u16, v as u32 as u16);
        match self {
            WordOrder::HighFirst => [hi, lo],
            WordOrder::LowFirst => [lo, hi],
        }
    }

    /// Two registers as a 32-bit value.
    pub fn join(self, w: [u16; 2]) -> i32 {
        let (hi, lo) = match self {
            WordOrder::HighFirst => (w[0], w[1]),
            WordOrder::LowFirst => (w[1], w[0]),
        };
        ((hi as u32) << 16 | lo as u32) as i32
    }
}

/// One register write.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct RegWrite {
    /// Register address.
    pub addr: u16,
    /// Value written.
    pub value: u16,
}

/// The drive's register map.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ModbusMap {
    /// Modbus TCP address of the drive (`host:502`); or give `port` for RTU.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub address: Option<String>,
    /// Serial device of a Modbus RTU drive (`/dev/ttyUSB0`; a twin's `/dev/pts/N`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub port: Option<String>,
    /// RTU baud rate (default 19200, the Modbus serial line default).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub baud: Option<u32>,
    /// RTU parity (default even; `none` uses two stop bits).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub parity: Option<Parity>,
    /// Slave (unit) id.
    pub slave: u8,
    /// Word order of 32-bit values.
    #[serde(default)]
    pub word_order: WordOrder,
    /// Drive steps per axis unit (mm or deg).
    pub steps_per_unit: f64,
    /// First of two registers taking the target position, steps.
    pub target: u16,
    /// First of two registers taking the speed, steps/s.
    pub speed: u16,
    /// Written after target and speed to start the move.
    pub trigger: RegWrite,
    /// First of two registers holding the actual position, steps.
    pub position: u16,
    /// Status register.
    pub status: u16,
    /// Status bit set while moving.
    pub busy_bit: u8,
    /// Status bit set on an alarm.
    pub alarm_bit: u8,
    /// Status bit set once homed (absent: always referenced).
    #[serde(default)]
    pub homed_bit: Option<u8>,
    /// Starts homing.
    pub home: RegWrite,
    /// Stops motion.
    pub stop: RegWrite,
    /// Reply timeout, ms (default 200).
    #[serde(default)]
    pub timeout_ms: Option<u64>,
}

impl ModbusMap {
    /// What is wrong with the map, as (field, message) pairs; empty when usable.
    pub fn problems(&self) -> Vec<(&'static str, String)> {
        let mut p = Vec::new();
        if !(self.steps_per_unit.is_finite() && self.steps_per_unit > 0.0) {
            p.push(("steps_per_unit", "must be a positive number".to_string()));
        }
        for (name, bit) in [
            ("busy_bit", Some(self.busy_bit)),
            ("alarm_bit", Some(self.alarm_bit)),
            ("homed_bit", self.homed_bit),
        ] {
            if bit.is_some_and(|b| b > 15) {
                p.push((name, "a register has bits 0–15".to_string()));
            }
        }
        // 32-bit values take two registers; no two fields may share one.
        let mut used: Vec<(u16, &'static str)> = Vec::new();
        for (name, addr, n) in [
            ("target", self.target, 2u16),
            ("speed", self.speed, 2),
            ("position", self.position, 2),
            ("status", self.status, 1),
        ] {
            for a in addr..addr.saturating_add(n) {
                if let Some((_, other)) = used.iter().find(|(u, _)| *u == a) {
                    p.push((name, format!("register {a:#06x} is also `{other}`")));
                }
                used.push((a, name));
            }
        }
        match (&self.address, &self.port) {
            (Some(a), None) if a.parse::<SocketAddr>().is_err() => {
                p.push(("address", format!("`{a}` is not host:port")));
            }
            (Some(_), Some(_)) => p.push((
                "port",
                "give `address` (Modbus TCP) or `port` (RTU), not both".to_string(),
            )),
            (None, None) => p.push((
                "address",
                "missing: give `address: host:502` (Modbus TCP) or `port: /dev/ttyUSB0` (RTU)"
                    .to_string(),
            )),
            _ => {}
        }
        if let Some(b) = self.baud
            && baud_rate(b).is_none()
        {
            p.push((
                "baud",
                format!("{b} is not a standard rate (9600, 19200, 115200, …)"),
            ));
        }
        p
    }

    /// Where the drive is, for messages.
    pub fn endpoint(&self) -> String {
        match (&self.address, &self.port) {
            (Some(a), _) => a.clone(),
            (None, Some(p)) => format!("{p} (RTU)"),
            (None, None) => "(no address)".into(),
        }
    }

    fn timeout(&self) -> Duration {
        Duration::from_millis(self.timeout_ms.unwrap_or(200))
    }
}

/// One request with its timeout, both error layers of `tokio-modbus` kept apart. The
/// timeout covers the wait for the link too.
async fn call<T>(
    ctx: &tokio::sync::Mutex<Context>,
    timeout: Duration,
    name: &str,
    what: &str,
    f: impl AsyncFnOnce(&mut Context) -> tokio_modbus::Result<T>,
) -> Result<T, RigError> {
    let r = tokio::time::timeout(timeout, async {
        let mut c = ctx.lock().await;
        f(&mut c).await
    })
    .await;
    match r {
        Err(_) => Err(RigError::Timeout {
            device: name.to_string(),
            timeout_ms: timeout.as_millis() as u64,
        }),
        Ok(Err(e)) => Err(RigError::Io {
            device: name.to_string(),
            source: std::io::Error::other(e.to_string()),
        }),
        Ok(Ok(Err(exception))) => Err(RigError::Rejected {
            device: name.to_string(),
            command: what.to_string(),
            reason: exception.to_string(),
        }),
        Ok(Ok(Ok(v))) => Ok(v),
    }
}

/// Writes the map's stop register on the shared link.
struct ModbusStopper {
    ctx: std::sync::Arc<tokio::sync::Mutex<Context>>,
    stop: RegWrite,
    timeout: Duration,
    name: String,
}

#[async_trait]
impl AxisStopper for ModbusStopper {
    async fn stop_now(&self) -> Result<(), RigError> {
        let w = self.stop;
        call(
            &self.ctx,
            self.timeout,
            &self.name,
            "stop",
            async |c: &mut Context| c.write_single_register(w.addr, w.value).await,
        )
        .await
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
    /// Connects to the drive and reads its status once.
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
        let mut a = Self {
            info,
            map,
            ctx: std::sync::Arc::new(tokio::sync::Mutex::new(ctx)),
        };
        a.status().await?;
        Ok(a)
    }

    fn name(&self) -> String {
        self.info.identity.clone()
    }

    /// Maps both error layers of a request.
    async fn call<T>(
        &mut self,
        what: &str,
        f: impl AsyncFnOnce(&mut Context) -> tokio_modbus::Result<T>,
    ) -> Result<T, RigError> {
        call(&self.ctx, self.map.timeout(), &self.name(), what, f).await
    }

    async fn write(&mut self, what: &str, w: RegWrite) -> Result<(), RigError> {
        self.call(what, async |c: &mut Context| {
            c.write_single_register(w.addr, w.value).await
        })
        .await
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
            timeout: self.map.timeout(),
            name: self.name(),
        })
    }

    async fn home(&mut self) -> Result<(), RigError> {
        let w = self.map.home;
        self.write("home", w).await
    }

    async fn move_to(&mut self, target: f64, speed: f64) -> Result<(), RigError> {
        self.info.check_target(target)?;
        self.info.check_speed(speed)?;
        let m = self.map.clone();
        let steps = (target * m.steps_per_unit).round() as i32;
        let sps = (speed * m.steps_per_unit).round().max(1.0) as i32;
        self.call("target", async |c: &mut Context| {
            c.write_multiple_registers(m.target, &m.word_order.split(steps))
                .await
        })
        .await?;
        self.call("speed", async |c: &mut Context| {
            c.write_multiple_registers(m.speed, &m.word_order.split(sps))
                .await
        })
        .await?;
        self.write("move", m.trigger).await
    }

    async fn status(&mut self) -> Result<AxisStatus, RigError> {
        let m = self.map.clone();
        let pos = self
            .call("read position", async |c: &mut Context| {
                c.read_holding_registers(m.position, 2).await
            })
            .await?;
        let st = self
            .call("read status", async |c: &mut Context| {
                c.read_holding_registers(m.status, 1).await
            })
            .await?;
        let (Some(&p0), Some(&p1), Some(&s)) = (pos.first(), pos.get(1), st.first()) else {
            return Err(RigError::Garbled {
                device: self.name(),
                detail: "short register reply".into(),
            });
        };
        if s & (1 << m.alarm_bit) != 0 {
            return Err(RigError::Rejected {
                device: self.name(),
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
        })
    }

    async fn stop(&mut self) -> Result<(), RigError> {
        let w = self.map.stop;
        self.write("stop", w).await
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn words_and_map_checks() {
        for o in [WordOrder::HighFirst, WordOrder::LowFirst] {
            for v in [0, 1, -1, 123_456_789, i32::MIN, i32::MAX] {
                assert_eq!(o.join(o.split(v)), v);
            }
        }
        assert_eq!(WordOrder::HighFirst.split(0x0001_0002), [1, 2]);
        let mut m = ModbusMap {
            address: Some("127.0.0.1:502".into()),
            port: None,
            baud: None,
            parity: None,
            slave: 1,
            word_order: WordOrder::HighFirst,
            steps_per_unit: 500.0,
            target: 0x5C,
            speed: 0x5E,
            trigger: RegWrite {
                addr: 0x66,
                value: 1,
            },
            position: 0x120,
            status: 0x7F,
            busy_bit: 8,
            alarm_bit: 7,
            homed_bit: Some(4),
            home: RegWrite {
                addr: 0x7D,
                value: 0x10,
            },
            stop: RegWrite {
                addr: 0x7D,
                value: 0x20,
            },
            timeout_ms: None,
        };
        assert!(m.problems().is_empty(), "{:?}", m.problems());
        m.speed = 0x5D;
        m.busy_bit = 16;
        m.port = Some("/dev/ttyUSB0".into());
        m.baud = Some(12345);
        let p = m.problems();
        for field in ["speed", "busy_bit", "port", "baud"] {
            assert!(p.iter().any(|(f, _)| *f == field), "{field}: {p:?}");
        }
        m.address = None;
        assert!(!m.problems().iter().any(|(f, _)| *f == "port"));
    }
}
