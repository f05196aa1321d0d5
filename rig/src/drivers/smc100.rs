//! Newport SMC100 / CONEX-CC stage controllers over a serial line (spec `devices.md` §2b).
//!
//! Commands are `<addr><CMD><value>` with CRLF. Set commands (`OR`, `PA`, `VA`, `ST`) never
//! reply, so after each one the driver asks `TE` (last error): `@` means accepted, a letter
//! is the controller's refusal (C out of range, H not allowed in NOT REFERENCED, M not
//! allowed while moving, …). Queries reply `<addr><CMD><value>`. `TS` gives 4 hex digits
//! of positioner errors and the state: 0A–11 NOT REFERENCED, 14 CONFIG, 1E/1F HOMING,
//! 28 MOVING, 32–35 READY, 3C–3E DISABLE. A missing reply is retried a bounded number of
//! times; blocking serial I/O runs on tokio's blocking pool.

use std::time::Duration;

use async_trait::async_trait;

use super::serial_line::{self, LinePort, LineWriter, Outcome};
use crate::RigError;
use crate::device::{Axis, AxisInfo, AxisStatus, AxisStopper};

/// How to reach one controller.
#[derive(Debug, Clone, PartialEq)]
pub struct Smc100Settings {
    /// Serial device path.
    pub port: String,
    /// Controller address (1–31).
    pub address: u8,
    /// Reply timeout.
    pub timeout: Duration,
    /// Extra attempts after a missing or garbled reply.
    pub retries: u32,
}

/// An SMC100 axis behind [`Axis`].
pub struct Smc100Axis {
    info: AxisInfo,
    s: Smc100Settings,
    port: LinePort,
    stop_line: LineWriter,
}

/// The meaning of a `TE` error letter.
pub fn te_meaning(code: char) -> &'static str {
    match code {
        'A' => "unknown command",
        'B' => "bad address",
        'C' => "parameter out of range",
        'D' => "command not allowed",
        'E' => "home sequence already started",
        'H' => "not allowed in NOT REFERENCED state (home first)",
        'I' => "not allowed in CONFIGURATION state",
        'J' => "not allowed in DISABLE state",
        'K' => "not allowed in READY state",
        'L' => "not allowed while homing",
        'M' => "not allowed while moving",
        _ => "unlisted error",
    }
}

impl Smc100Axis {
    /// Opens the port and reads the controller's identity (`ID?`).
    pub async fn open(s: Smc100Settings, mut info: AxisInfo) -> Result<Self, RigError> {
        let name = format!("SMC100 #{} on {}", s.address, s.port);
        let port = serial_line::open(&s.port, 57_600, true, &name)?;
        let stop_line = serial_line::writer(&port, &name)?;
        let mut a = Self {
            info: info.clone(),
            s,
            port,
            stop_line,
        };
        let id = a.query("ID?").await?;
        info.identity = format!("Newport {id} (address {} on {})", a.s.address, a.s.port);
        a.info = info;
        Ok(a)
    }

    fn name(&self) -> String {
        format!("SMC100 #{} on {}", self.s.address, self.s.port)
    }

    /// Sends `cmd` and returns the reply's value (after the echoed `<addr><CMD>`).
    async fn query(&mut self, cmd: &str) -> Result<String, RigError> {
        let echo = format!("{}{}", self.s.address, cmd.trim_end_matches('?'));
        let line = format!("{}{}\r\n", self.s.address, cmd);
        let mut last = None;
        for _ in 0..=self.s.retries {
            let (port, line, echo, timeout) = (
                self.port.clone(),
                line.clone(),
                echo.clone(),
                self.s.timeout,
            );
            let r =
                tokio::task::spawn_blocking(move || exchange(&port, &line, Some(&echo), timeout))
                    .await
                    .map_err(|e| RigError::Io {
                        device: self.name(),
                        source: std::io::Error::other(e.to_string()),
                    })?;
            match r {
                Ok(Some(v)) => return Ok(v),
                Ok(None) => last = None,
                Err(Err(e)) => {
                    return Err(RigError::Io {
                        device: self.name(),
                        source: e,
                    });
                }
                Err(Ok(garbled)) => last = Some(garbled),
            }
        }
        Err(match last {
            Some(detail) => RigError::Garbled {
                device: self.name(),
                detail,
            },
            None => RigError::Timeout {
                device: self.name(),
                timeout_ms: self.s.timeout.as_millis() as u64,
            },
        })
    }

    /// Sends a set command (no reply), then checks `TE`.
    async fn set(&mut self, cmd: &str) -> Result<(), RigError> {
        let line = format!("{}{}\r\n", self.s.address, cmd);
        let port = self.port.clone();
        tokio::task::spawn_blocking(move || exchange(&port, &line, None, Duration::ZERO))
            .await
            .map_err(|e| RigError::Io {
                device: self.name(),
                source: std::io::Error::other(e.to_string()),
            })?
            .map_err(|e| match e {
                Err(source) => RigError::Io {
                    device: self.name(),
                    source,
                },
                Ok(detail) => RigError::Garbled {
                    device: self.name(),
                    detail,
                },
            })?;
        let te = self.query("TE").await?;
        match te.chars().next() {
            Some('@') => Ok(()),
            Some(c) => Err(RigError::Rejected {
                device: self.name(),
                command: cmd.into(),
                reason: format!("{c}: {}", te_meaning(c)),
            }),
            None => Err(RigError::Garbled {
                device: self.name(),
                detail: "empty TE reply".into(),
            }),
        }
    }

    async fn state(&mut self) -> Result<u8, RigError> {
        let ts = self.query("TS").await?;
        ts.get(4..6)
            .and_then(|h| u8::from_str_radix(h, 16).ok())
            .ok_or_else(|| RigError::Garbled {
                device: self.name(),
                detail: format!("TS reply `{}`", crate::quote(&ts)),
            })
    }
}

/// Writes `line`; with `echo`, reads lines until one starting with it and returns the rest
/// (`Ok(None)` on timeout). `Err(Ok(_))` is a garbled reply, `Err(Err(_))` an I/O error.
type ExchangeResult = Result<Option<String>, Result<String, std::io::Error>>;

fn exchange(port: &LinePort, line: &str, echo: Option<&str>, timeout: Duration) -> ExchangeResult {
    let Some(echo) = echo else {
        // A set command: written, no reply expected.
        return match serial_line::exchange(port, line, Duration::ZERO, |_| Ok(Some(()))) {
            Ok(_) => Ok(None),
            Err(e) => Err(Err(e)),
        };
    };
    let judge = |l: &str| match l.strip_prefix(echo) {
        Some(v) => Ok(Some(v.trim().to_string())),
        None => Err(format!(
            "`{}` does not answer `{}`",
            crate::quote(l),
            line.trim()
        )),
    };
    match serial_line::exchange(port, line, timeout, judge) {
        Ok(Outcome::Answer(v)) => Ok(Some(v)),
        Ok(Outcome::Nothing(None)) => Ok(None),
        Ok(Outcome::Nothing(Some(g))) => Err(Ok(g)),
        Err(e) => Err(Err(e)),
    }
}

#[async_trait]
impl Axis for Smc100Axis {
    fn info(&self) -> &AxisInfo {
        &self.info
    }

    fn stopper(&self) -> std::sync::Arc<dyn AxisStopper> {
        std::sync::Arc::new(serial_line::LineStopper {
            line: format!("{}ST\r\n", self.s.address),
            writer: self.stop_line.clone(),
            name: self.name(),
        })
    }

    async fn home(&mut self) -> Result<(), RigError> {
        // OR is only allowed from NOT REFERENCED; a referenced stage is already homed and
        // goes back to its zero, where homing leaves it.
        if (0x0A..=0x11).contains(&self.state().await?) {
            self.set("OR").await
        } else {
            let max = self.info.max_speed;
            self.move_to(0.0_f64.max(self.info.travel_min), max).await
        }
    }

    async fn move_to(&mut self, target: f64, speed: f64) -> Result<(), RigError> {
        self.info.check_target(target)?;
        self.info.check_speed(speed)?;
        self.set(&format!("VA{speed}")).await?;
        match self.set(&format!("PA{target}")).await {
            Err(RigError::Rejected { reason, .. }) if reason.starts_with('H') => {
                Err(RigError::NotReferenced {
                    axis: self.info.role.clone(),
                })
            }
            r => r,
        }
    }

    async fn status(&mut self) -> Result<AxisStatus, RigError> {
        // The state first: a stage that reads at rest stays there, so `TP` after it is where
        // it rests; the other order reports a move that ends between the two at rest with a
        // position from mid-move.
        let st = self.state().await?;
        let tp = self.query("TP").await?;
        let position = tp.parse::<f64>().map_err(|_| RigError::Garbled {
            device: self.name(),
            detail: format!("TP value `{}`", crate::quote(&tp)),
        })?;
        Ok(AxisStatus {
            position,
            moving: matches!(st, 0x1E | 0x1F | 0x28),
            referenced: !(0x0A..=0x11).contains(&st),
            in_position: None,
        })
    }

    async fn stop(&mut self) -> Result<(), RigError> {
        self.set("ST").await
    }
}
