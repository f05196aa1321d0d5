//! An operator-turned micrometer (the thesis's bench, §3.3): gelrig says where to set it
//! and waits for the operator to confirm, optionally with the value actually read off the
//! barrel. The prompt goes to any writer and the answer comes from any reader, so tests
//! drive it through a pipe exactly as an operator drives it through a terminal.

use std::io::{BufRead, Write};
use std::sync::{Arc, Mutex};

use async_trait::async_trait;

use crate::device::{Axis, AxisInfo, AxisStatus, AxisStopper};
use crate::{RigError, lock};

/// The operator's terminal.
pub type Terminal = Arc<Mutex<(Box<dyn BufRead + Send>, Box<dyn Write + Send>)>>;

/// A manual axis.
pub struct ManualAxis {
    info: AxisInfo,
    terminal: Terminal,
    position: f64,
    referenced: bool,
}

impl ManualAxis {
    /// A manual axis described by `info` (travel, unit; speed is irrelevant).
    pub fn new(mut info: AxisInfo, terminal: Terminal) -> Self {
        info.identity = format!("manual micrometer ({})", info.role);
        Self {
            info,
            terminal,
            position: 0.0,
            referenced: false,
        }
    }

    /// Prints `prompt`, reads one line: empty confirms `expected`, a number is the value
    /// the operator read instead (it must be within travel).
    fn ask(&mut self, prompt: &str, expected: f64) -> Result<f64, RigError> {
        let device = format!("manual {} axis", self.info.role);
        let io = |source| RigError::Io {
            device: device.clone(),
            source,
        };
        let mut t = lock(&self.terminal);
        loop {
            writeln!(t.1, "{prompt}").map_err(io)?;
            t.1.flush().map_err(io)?;
            let mut line = String::new();
            if t.0.read_line(&mut line).map_err(io)? == 0 {
                return Err(RigError::Unsupported {
                    device: device.clone(),
                    detail: "the operator's input closed; fix: run from a terminal, or use a motorised axis".into(),
                });
            }
            let line = line.trim();
            if line.is_empty() {
                return Ok(expected);
            }
            match line
                .trim_end_matches(self.info.unit.symbol())
                .trim()
                .parse::<f64>()
            {
                Ok(v) if (self.info.travel_min..=self.info.travel_max).contains(&v) => {
                    return Ok(v);
                }
                _ => {
                    writeln!(
                        t.1,
                        "`{line}` is not a position within [{}, {}] {}: press Enter to confirm {expected} or type the value you set",
                        self.info.travel_min,
                        self.info.travel_max,
                        self.info.unit.symbol()
                    )
                    .map_err(io)?;
                }
            }
        }
    }
}

/// Nothing can stop a hand-turned micrometer but its operator: tell them.
struct ManualStopper {
    role: String,
}

#[async_trait]
impl AxisStopper for ManualStopper {
    async fn stop_now(&self) -> Result<(), RigError> {
        eprintln!(
            "STOP: do not turn the {} micrometer any further; gelrig stopped the run",
            self.role
        );
        Ok(())
    }
}

#[async_trait]
impl Axis for ManualAxis {
    fn info(&self) -> &AxisInfo {
        &self.info
    }

    fn stopper(&self) -> Arc<dyn AxisStopper> {
        Arc::new(ManualStopper {
            role: self.info.role.clone(),
        })
    }

    async fn home(&mut self) -> Result<(), RigError> {
        let u = self.info.unit.symbol();
        let p = format!(
            "set the {} micrometer to its zero (0 {u}), then press Enter",
            self.info.role
        );
        self.position = self.ask(&p, 0.0)?;
        self.referenced = true;
        Ok(())
    }

    async fn move_to(&mut self, target: f64, _speed: f64) -> Result<(), RigError> {
        self.info.check_target(target)?;
        let i = &self.info;
        if !self.referenced {
            return Err(RigError::NotReferenced {
                axis: i.role.clone(),
            });
        }
        let p = format!(
            "set the {} micrometer to {target:.3} {}, then press Enter (or type the value you set)",
            i.role,
            i.unit.symbol()
        );
        self.position = self.ask(&p, target)?;
        Ok(())
    }

    async fn status(&mut self) -> Result<AxisStatus, RigError> {
        Ok(AxisStatus {
            position: self.position,
            moving: false,
            referenced: self.referenced,
            in_position: None,
        })
    }

    async fn stop(&mut self) -> Result<(), RigError> {
        Ok(())
    }
}
