//! Zaber ASCII stages (linear and rotary) over a serial line.
//!
//! One transaction at a time: send a command with a message id (so a late reply to an
//! earlier command is never taken for this one), read lines until the reply with that id,
//! skipping `#` info and `!` alert lines. A missing or garbled reply is retried a bounded
//! number of times, then reported; a rejection (`RJ`) is reported with its reason at once.
//! Positions travel as microsteps; the rig file gives the microstep size in the axis unit.
//! Serial I/O is blocking, so each transaction runs on tokio's blocking pool.

use std::io::{BufRead, BufReader, Write};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use async_trait::async_trait;

use super::zaber_ascii::{Reply, parse_reply, with_checksum};
use crate::device::{Axis, AxisInfo, AxisStatus};
use crate::{RigError, lock};

/// How to reach one Zaber axis.
#[derive(Debug, Clone, PartialEq)]
pub struct ZaberSettings {
    /// Serial device path (`/dev/ttyUSB0`, or a twin's `/dev/pts/N`).
    pub port: String,
    /// Device address on the daisy chain (1…99).
    pub device: u8,
    /// Axis number on the device (1 for single-axis devices).
    pub axis: u8,
    /// Size of one microstep in the axis unit (0.047625e-3 mm on lead-screw stages,
    /// 0.000234375 deg on X-RSW rotary stages).
    pub microstep: f64,
    /// Append and require LRC checksums.
    pub checksum: bool,
    /// How long to wait for a reply.
    pub timeout: Duration,
    /// Extra attempts after a missing or garbled reply.
    pub retries: u32,
}

type Port = Box<dyn serialport::SerialPort>;

/// A Zaber axis behind [`Axis`].
pub struct ZaberAxis {
    info: AxisInfo,
    settings: ZaberSettings,
    port: Arc<Mutex<BufReader<Port>>>,
    next_id: u8,
    /// Last warning flag seen (e.g. `NI` after an interrupted move), for diagnostics.
    pub last_warning: Option<String>,
}

fn device_name(s: &ZaberSettings) -> String {
    format!("Zaber device {} axis {} on {}", s.device, s.axis, s.port)
}

impl ZaberAxis {
    /// Opens the port and asks the device who it is. `info` gives role, unit, travel and
    /// speed from the rig file; its identity is filled from the device.
    pub async fn open(settings: ZaberSettings, mut info: AxisInfo) -> Result<Self, RigError> {
        let name = device_name(&settings);
        let port = serialport::new(&settings.port, 115_200)
            .timeout(Duration::from_millis(20))
            .open()
            .map_err(|e| RigError::Io {
                device: name.clone(),
                source: std::io::Error::other(format!(
                    "{e}; fix: check the `port:` path in the rig file"
                )),
            })?;
        let mut axis = Self {
            info: info.clone(),
            settings,
            port: Arc::new(Mutex::new(BufReader::new(port))),
            next_id: 0,
            last_warning: None,
        };
        let id = axis.command_device("get deviceid").await?;
        let fw = axis.command_device("get version").await?;
        info.identity = format!("Zaber device id {} firmware {} ({name})", id.data, fw.data);
        axis.info = info;
        Ok(axis)
    }

    async fn command_device(&mut self, cmd: &str) -> Result<Reply, RigError> {
        self.transact(cmd, false).await
    }

    /// Sends `cmd` to this axis (or the device when `on_axis` is false) and returns the
    /// accepted reply.
    async fn transact(&mut self, cmd: &str, on_axis: bool) -> Result<Reply, RigError> {
        let s = self.settings.clone();
        let name = device_name(&s);
        let mut last_problem = None;
        for _ in 0..=s.retries {
            self.next_id = (self.next_id + 1) % 100;
            let id = self.next_id;
            let body = format!(
                "{} {} {id} {cmd}",
                s.device,
                if on_axis { s.axis } else { 0 }
            );
            let line = format!("/{}\n", with_checksum(&body, s.checksum));
            let port = self.port.clone();
            let timeout = s.timeout;
            let checksum = s.checksum;
            let result =
                tokio::task::spawn_blocking(move || exchange(&port, &line, id, timeout, checksum))
                    .await
                    .map_err(|e| RigError::Io {
                        device: name.clone(),
                        source: std::io::Error::other(e.to_string()),
                    })?;
            match result {
                Ok(reply) => {
                    self.last_warning = reply.warning.clone();
                    if !reply.ok {
                        return Err(RigError::Rejected {
                            device: name,
                            command: cmd.to_string(),
                            reason: reply.data.clone(),
                        });
                    }
                    return Ok(reply);
                }
                Err(Exchange::Io(e)) => {
                    return Err(RigError::Io {
                        device: name,
                        source: e,
                    });
                }
                Err(e) => last_problem = Some(e),
            }
        }
        Err(match last_problem {
            Some(Exchange::Garbled(detail)) => RigError::Garbled {
                device: name,
                detail,
            },
            _ => RigError::Timeout {
                device: name,
                timeout_ms: s.timeout.as_millis() as u64,
            },
        })
    }

    fn to_microsteps(&self, v: f64) -> i64 {
        (v / self.settings.microstep).round() as i64
    }
}

enum Exchange {
    Timeout,
    Garbled(String),
    Io(std::io::Error),
}

/// One request/reply on the blocking pool.
fn exchange(
    port: &Mutex<BufReader<Port>>,
    line: &str,
    id: u8,
    timeout: Duration,
    checksum: bool,
) -> Result<Reply, Exchange> {
    let mut p = lock(port);
    p.get_mut()
        .write_all(line.as_bytes())
        .map_err(Exchange::Io)?;
    p.get_mut().flush().map_err(Exchange::Io)?;
    let deadline = Instant::now() + timeout;
    let mut buf = String::new();
    let mut garbled = None;
    while Instant::now() < deadline {
        match p.read_line(&mut buf) {
            Ok(0) => {
                return Err(Exchange::Io(std::io::Error::other(
                    "the port closed; fix: check the cable",
                )));
            }
            Ok(_) if buf.ends_with('\n') => {
                let l = std::mem::take(&mut buf);
                let l = l.trim();
                if l.is_empty() || l.starts_with('#') || l.starts_with('!') {
                    continue;
                }
                if checksum && l.starts_with('@') && !l.contains(':') {
                    garbled = Some(format!("`{l}` lacks its checksum"));
                    continue;
                }
                match parse_reply(l) {
                    Ok(r) if r.id == Some(id) => return Ok(r),
                    // A late reply to an earlier (timed-out) command: not ours.
                    Ok(_) => continue,
                    Err(e) => garbled = Some(e),
                }
            }
            Ok(_) => continue,
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::TimedOut | std::io::ErrorKind::WouldBlock
                ) =>
            {
                continue;
            }
            Err(e) => return Err(Exchange::Io(e)),
        }
    }
    Err(garbled.map_or(Exchange::Timeout, Exchange::Garbled))
}

#[async_trait]
impl Axis for ZaberAxis {
    fn info(&self) -> &AxisInfo {
        &self.info
    }

    async fn home(&mut self) -> Result<(), RigError> {
        self.transact("home", true).await.map(|_| ())
    }

    async fn move_to(&mut self, target: f64, speed: f64) -> Result<(), RigError> {
        self.info.check_target(target)?;
        let i = &self.info;
        if !(speed > 0.0 && speed <= i.max_speed) {
            return Err(RigError::BadSpeed {
                axis: i.role.clone(),
                speed,
                max: i.max_speed,
                unit: i.unit,
            });
        }
        // Speed data = microsteps/s × 1.6384 (Zaber ASCII manual, `maxspeed`).
        let speed_data = ((speed / self.settings.microstep) * 1.6384)
            .round()
            .max(1.0) as i64;
        let steps = self.to_microsteps(target);
        let reply = self
            .transact(&format!("move abs {steps} {speed_data}"), true)
            .await;
        match reply {
            Err(RigError::Rejected { reason, .. })
                if reason == "BADDATA" && self.last_warning.as_deref() == Some("WR") =>
            {
                Err(RigError::NotReferenced {
                    axis: self.info.role.clone(),
                })
            }
            other => other.map(|_| ()),
        }
    }

    async fn status(&mut self) -> Result<AxisStatus, RigError> {
        let r = self.transact("get pos", true).await?;
        let steps: f64 = r.data.trim().parse().map_err(|_| RigError::Garbled {
            device: device_name(&self.settings),
            detail: format!("position `{}` is not a number", r.data),
        })?;
        Ok(AxisStatus {
            position: steps * self.settings.microstep,
            moving: r.busy,
            referenced: r.warning.as_deref() != Some("WR"),
        })
    }

    async fn stop(&mut self) -> Result<(), RigError> {
        self.transact("stop", true).await.map(|_| ())
    }
}
