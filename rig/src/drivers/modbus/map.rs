//! The register map of a Modbus drive, as the rig file writes it, and its checks.
//!
//! Two forms. The **short form** is for simple drives: a target register pair, a speed
//! register pair and one trigger write. The **long form** describes a move as a sequence
//! of writes, each a single register or a block of 16- or 32-bit fields, with placeholders
//! for what the run supplies (`position`, `speed`) and what the map states
//! (`acceleration`, `deceleration`, `current`). The Oriental AZ's direct-data operation —
//! every object 32-bit: data number 0x0058, operation type 0x005A, position 0x005C, speed
//! 0x005E, acceleration 0x0060, deceleration 0x0062, current 0x0064, trigger 0x0066 — is
//! one FC16 block in the long form; in the short form its trigger written alone as
//! `0x0066 := 1` reads back as 0x00010000 and the drive never moves. Writes on open (an
//! alarm reset, an operation mode) and an in-position status bit complete the map.

use std::net::SocketAddr;
use std::time::Duration;

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

pub use crate::drivers::serial_async::Parity;
use crate::drivers::serial_async::baud_rate;

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

/// What a move supplies to a field of a write.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Placeholder {
    /// The target, in drive steps.
    Position,
    /// The speed, in drive steps per second.
    Speed,
    /// The map's `acceleration`.
    Acceleration,
    /// The map's `deceleration`.
    Deceleration,
    /// The map's `current`.
    Current,
}

impl Placeholder {
    fn name(self) -> &'static str {
        match self {
            Placeholder::Position => "position",
            Placeholder::Speed => "speed",
            Placeholder::Acceleration => "acceleration",
            Placeholder::Deceleration => "deceleration",
            Placeholder::Current => "current",
        }
    }
}

/// One field of a write: a number, or what a move supplies.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(untagged)]
pub enum Field {
    /// A literal value (an operation type, a trigger).
    Number(i64),
    /// Filled in at each move.
    Value(Placeholder),
}

fn default_width() -> u8 {
    32
}

/// One write of a sequence: one register (FC6) or a block (FC16) from `write`.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct WriteStep {
    /// First register written.
    pub write: u16,
    /// The fields, in order.
    pub values: Vec<Field>,
    /// Bits per field: 32 (two registers each, in the map's word order; the default) or 16.
    #[serde(default = "default_width")]
    pub width: u8,
}

impl WriteStep {
    /// Registers the step writes.
    pub fn registers(&self) -> usize {
        self.values.len() * if self.width == 32 { 2 } else { 1 }
    }

    /// The words to write, with `value` filling each placeholder; `Err` names a value that
    /// does not fit its width.
    pub fn words(
        &self,
        order: WordOrder,
        mut value: impl FnMut(Placeholder) -> i64,
    ) -> Result<Vec<u16>, String> {
        let mut out = Vec::with_capacity(self.registers());
        for f in &self.values {
            let (v, what) = match *f {
                Field::Number(n) => (n, "a number".to_string()),
                Field::Value(p) => (value(p), format!("`{}`", p.name())),
            };
            if self.width == 32 {
                let v = i32::try_from(v).map_err(|_| {
                    format!(
                        "{what} = {v} does not fit a 32-bit field at {:#06x}",
                        self.write
                    )
                })?;
                out.extend(order.split(v));
            } else {
                if !(-32768..=65535).contains(&v) {
                    return Err(format!(
                        "{what} = {v} does not fit a 16-bit register at {:#06x}",
                        self.write
                    ));
                }
                out.push(v as u16);
            }
        }
        Ok(out)
    }

    fn uses(&self, p: Placeholder) -> usize {
        self.values
            .iter()
            .filter(|f| **f == Field::Value(p))
            .count()
    }
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
    /// Short form: first of two registers taking the target position, steps.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub target: Option<u16>,
    /// Short form: first of two registers taking the speed, steps/s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub speed: Option<u16>,
    /// Short form: written after target and speed to start the move.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub trigger: Option<RegWrite>,
    /// Long form: the writes that make one move, in order.
    #[serde(default, rename = "move", skip_serializing_if = "Vec::is_empty")]
    pub move_writes: Vec<WriteStep>,
    /// Writes made once when the driver opens (alarm reset, operation mode); numbers only.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub on_open: Vec<WriteStep>,
    /// Value of the `acceleration` placeholder, in the drive's units.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub acceleration: Option<i64>,
    /// Value of the `deceleration` placeholder, in the drive's units.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub deceleration: Option<i64>,
    /// Value of the `current` placeholder, in the drive's units (0.1 % on the AZ).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub current: Option<i64>,
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
    /// Status bit set once the position has settled at the target (absent: not reported).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub in_position_bit: Option<u8>,
    /// Starts homing.
    pub home: RegWrite,
    /// Stops motion.
    pub stop: RegWrite,
    /// Reply timeout, ms (default 200).
    #[serde(default)]
    pub timeout_ms: Option<u64>,
    /// How long a drive answering "busy" (exception 06) or "acknowledge" (05) is asked
    /// again, with backoff, before it is an error, ms (default 1000).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub busy_retry_ms: Option<u64>,
}

/// Registers of one FC16 request at most (Modbus application protocol §6.12).
const MAX_BLOCK: usize = 123;

impl ModbusMap {
    /// The writes of one move: the long form, or the short form as two blocks and the
    /// trigger (`None` if the map has neither; [`ModbusMap::problems`] says so).
    pub fn move_steps(&self) -> Option<Vec<WriteStep>> {
        if !self.move_writes.is_empty() {
            return Some(self.move_writes.clone());
        }
        let (target, speed, trigger) = (self.target?, self.speed?, self.trigger?);
        Some(vec![
            WriteStep {
                write: target,
                values: vec![Field::Value(Placeholder::Position)],
                width: 32,
            },
            WriteStep {
                write: speed,
                values: vec![Field::Value(Placeholder::Speed)],
                width: 32,
            },
            WriteStep {
                write: trigger.addr,
                values: vec![Field::Number(i64::from(trigger.value))],
                width: 16,
            },
        ])
    }

    /// What is wrong with the map, as (field, message) pairs; empty when usable.
    pub fn problems(&self) -> Vec<(&'static str, String)> {
        let mut p = Vec::new();
        if !(self.steps_per_unit.is_finite()
            && self.steps_per_unit > 0.0
            && self.steps_per_unit < 1e9)
        {
            p.push((
                "steps_per_unit",
                "must be a positive number below 1e9".to_string(),
            ));
        }
        for (name, bit) in [
            ("busy_bit", Some(self.busy_bit)),
            ("alarm_bit", Some(self.alarm_bit)),
            ("homed_bit", self.homed_bit),
            ("in_position_bit", self.in_position_bit),
        ] {
            if bit.is_some_and(|b| b > 15) {
                p.push((name, "a register has bits 0–15".to_string()));
            }
        }
        self.check_forms(&mut p);
        // Registers read back: 32-bit position and the status.
        let mut read: Vec<(u16, &'static str)> = Vec::new();
        for (name, addr, n) in [
            ("position", self.position, 2u16),
            ("status", self.status, 1),
        ] {
            for a in addr..addr.saturating_add(n) {
                if let Some((_, other)) = read.iter().find(|(u, _)| *u == a) {
                    p.push((name, format!("register {a:#06x} is also `{other}`")));
                }
                read.push((a, name));
            }
        }
        // Registers a move writes: none twice, none that is read back.
        let mut written: Vec<u16> = Vec::new();
        for step in self.move_steps().unwrap_or_default() {
            for k in 0..step.registers() as u16 {
                let a = step.write.saturating_add(k);
                let field = if self.move_writes.is_empty() {
                    "target"
                } else {
                    "move"
                };
                if written.contains(&a) {
                    p.push((field, format!("a move writes register {a:#06x} twice")));
                }
                if let Some((_, what)) = read.iter().find(|(r, _)| *r == a) {
                    p.push((
                        field,
                        format!("a move writes register {a:#06x}, which is `{what}`"),
                    ));
                }
                written.push(a);
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
        if self.timeout_ms.is_some_and(|t| !(1..=60_000).contains(&t)) {
            p.push(("timeout_ms", "must be 1 to 60000 ms".to_string()));
        }
        if self.busy_retry_ms.is_some_and(|t| t > 60_000) {
            p.push(("busy_retry_ms", "must be at most 60000 ms".to_string()));
        }
        p
    }

    /// The short form complete, or the long form with its placeholders, not both.
    fn check_forms(&self, p: &mut Vec<(&'static str, String)>) {
        let short = [
            self.target.is_some(),
            self.speed.is_some(),
            self.trigger.is_some(),
        ];
        let long = !self.move_writes.is_empty();
        if long && short.iter().any(|s| *s) {
            p.push((
                "move",
                "give `move` (a sequence of writes) or the short form (`target`, `speed`, `trigger`), not both"
                    .to_string(),
            ));
        } else if !long && short.iter().any(|s| !*s) {
            let missing: Vec<&str> = ["target", "speed", "trigger"]
                .iter()
                .zip(short)
                .filter(|(_, s)| !s)
                .map(|(n, _)| *n)
                .collect();
            p.push((
                "move",
                format!(
                    "a move is neither `move:` nor the short form: {} missing",
                    missing.join(", ")
                ),
            ));
        }
        for (field, steps) in [("move", &self.move_writes), ("on_open", &self.on_open)] {
            for s in steps {
                if s.values.is_empty() {
                    p.push((
                        field,
                        format!("the write at {:#06x} has no values", s.write),
                    ));
                }
                if s.width != 16 && s.width != 32 {
                    p.push((field, format!("width {} is not 16 or 32", s.width)));
                }
                if s.registers() > MAX_BLOCK {
                    p.push((
                        field,
                        format!(
                            "the write at {:#06x} is over {MAX_BLOCK} registers",
                            s.write
                        ),
                    ));
                }
                if let Err(e) = s.words(self.word_order, |_| 0) {
                    p.push((field, e));
                }
            }
        }
        if long {
            let count = |ph| self.move_writes.iter().map(|s| s.uses(ph)).sum::<usize>();
            if count(Placeholder::Position) != 1 {
                p.push((
                    "move",
                    format!(
                        "`position` must appear exactly once in a move (it appears {} times)",
                        count(Placeholder::Position)
                    ),
                ));
            }
            for (ph, value) in [
                (Placeholder::Acceleration, self.acceleration),
                (Placeholder::Deceleration, self.deceleration),
                (Placeholder::Current, self.current),
            ] {
                if count(ph) > 0 && value.is_none() {
                    p.push((
                        "move",
                        format!(
                            "the move uses `{}`, but the map gives no `{}:` value",
                            ph.name(),
                            ph.name()
                        ),
                    ));
                }
            }
        }
        for s in &self.on_open {
            if s.values.iter().any(|f| matches!(f, Field::Value(_))) {
                p.push((
                    "on_open",
                    "writes on open take numbers only (no move is known yet)".to_string(),
                ));
            }
        }
    }

    /// Where the drive is, for messages.
    pub fn endpoint(&self) -> String {
        match (&self.address, &self.port) {
            (Some(a), _) => a.clone(),
            (None, Some(p)) => format!("{p} (RTU)"),
            (None, None) => "(no address)".into(),
        }
    }

    /// Reply timeout.
    pub fn timeout(&self) -> Duration {
        Duration::from_millis(self.timeout_ms.unwrap_or(200))
    }

    /// How long "busy" and "acknowledge" are retried.
    pub fn busy_retry(&self) -> Duration {
        Duration::from_millis(self.busy_retry_ms.unwrap_or(1000))
    }
}
