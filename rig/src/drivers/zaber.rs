//! Zaber ASCII stages (linear and rotary) over a serial line.
//!
//! One transaction at a time: send a command with a message id (so a late reply to an
//! earlier command is never taken for this one), read lines until the reply with that id,
//! skipping `#` info and `!` alert lines. A missing or garbled reply is retried a bounded
//! number of times, then reported; a rejection (`RJ`) is reported with its reason at once.
//! Positions travel as microsteps; the rig file gives the microstep size in the axis unit.
//! Serial I/O is blocking, so each transaction runs on tokio's blocking pool.

use std::time::Duration;

use async_trait::async_trait;

use super::serial_line::{self, LinePort, LineWriter, Outcome};
use super::zaber_ascii::{Reply, parse_reply, with_checksum};
use crate::RigError;
use crate::device::{Axis, AxisInfo, AxisStatus, AxisStopper};

/// Message id kept for the watchdog's stop: transactions use 0–98, so the stop's reply is
/// never taken for a transaction's.
const STOP_ID: u8 = 99;

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

/// A Zaber axis behind [`Axis`].
pub struct ZaberAxis {
    info: AxisInfo,
    settings: ZaberSettings,
    port: LinePort,
    stop_line: LineWriter,
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
        let port = serial_line::open(&settings.port, 115_200, false, &name)?;
        let stop_line = serial_line::writer(&port, &name)?;
        let mut axis = Self {
            info: info.clone(),
            settings,
            port,
            stop_line,
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
            self.next_id = (self.next_id + 1) % STOP_ID;
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
                            reason: crate::quote(&reply.data),
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

/// One request/reply on the blocking pool: the reply carrying our message id; `#` info and
/// `!` alert lines and late replies to earlier ids are skipped.
fn exchange(
    port: &LinePort,
    line: &str,
    id: u8,
    timeout: Duration,
    checksum: bool,
) -> Result<Reply, Exchange> {
    let judge = |l: &str| -> Result<Option<Reply>, String> {
        if l.starts_with('#') || l.starts_with('!') {
            return Ok(None);
        }
        if checksum && l.starts_with('@') && !l.contains(':') {
            return Err(format!("`{}` lacks its checksum", crate::quote(l)));
        }
        parse_reply(l).map(|r| (r.id == Some(id)).then_some(r))
    };
    match serial_line::exchange(port, line, timeout, judge) {
        Ok(Outcome::Answer(r)) => Ok(r),
        Ok(Outcome::Nothing(Some(g))) => Err(Exchange::Garbled(g)),
        Ok(Outcome::Nothing(None)) => Err(Exchange::Timeout),
        Err(e) => Err(Exchange::Io(e)),
    }
}

#[async_trait]
impl Axis for ZaberAxis {
    fn info(&self) -> &AxisInfo {
        &self.info
    }

    fn stopper(&self) -> std::sync::Arc<dyn AxisStopper> {
        let s = &self.settings;
        let body = format!("{} {} {STOP_ID} stop", s.device, s.axis);
        std::sync::Arc::new(serial_line::LineStopper {
            line: format!("/{}\n", with_checksum(&body, s.checksum)),
            writer: self.stop_line.clone(),
            name: device_name(s),
        })
    }

    async fn home(&mut self) -> Result<(), RigError> {
        self.transact("home", true).await.map(|_| ())
    }

    async fn move_to(&mut self, target: f64, speed: f64) -> Result<(), RigError> {
        self.info.check_target(target)?;
        self.info.check_speed(speed)?;
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
            detail: format!("position `{}` is not a number", crate::quote(&r.data)),
        })?;
        Ok(AxisStatus {
            position: steps * self.settings.microstep,
            moving: r.busy,
            referenced: r.warning.as_deref() != Some("WR"),
            in_position: None,
        })
    }

    async fn stop(&mut self) -> Result<(), RigError> {
        self.transact("stop", true).await.map(|_| ())
    }
}
