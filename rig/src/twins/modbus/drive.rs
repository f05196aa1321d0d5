//! What the twin's drive does with its registers: the short form's target, speed and
//! trigger, or the Oriental AZ's direct-data operation as its manual documents it.
//!
//! AZ (`Kind::Az`): every object is 32-bit, two registers in the configured word order —
//! data number 0x0058, operation type 0x005A (1 absolute, 2 incremental), position 0x005C,
//! speed 0x005E, acceleration 0x0060, deceleration 0x0062, current 0x0064, trigger 0x0066.
//! Writing trigger = 1 starts the operation with the data written (and the drive clears the
//! trigger back to 0); any other trigger value starts nothing — so a lone FC6
//! `0x0066 := 1`, which leaves the 32-bit trigger at 0x00010000, never moves the drive.
//! Input command 0x007D: bit 4 ZHOME, bit 5 STOP, bit 7 ALM-RST. Output status 0x007F: bit 4 HOME-END,
//! bit 7 ALM, bit 8 BUSY, bit 14 IN-POS. Feedback position 0x0120 (32-bit).
//!
//! Both kinds move through [`Motion`] with injectable [`Timing`]: a drive that shows BUSY
//! late, settles into IN-POS after a while, and lands a step off.

use std::collections::HashMap;
use std::time::Instant;

use tokio_modbus::ExceptionCode;

use crate::drivers::modbus::{ModbusMap, WordOrder};
use crate::twins::motion::{Motion, Timing};

/// AZ register addresses and status bits (manual: direct data operation).
pub mod az {
    /// First register of the direct-data block.
    pub const DATA_NUMBER: u16 = 0x0058;
    /// Operation type: 1 absolute positioning, 2 incremental.
    pub const OPERATION: u16 = 0x005A;
    /// Target position, steps.
    pub const POSITION: u16 = 0x005C;
    /// Speed, steps/s.
    pub const SPEED: u16 = 0x005E;
    /// Acceleration.
    pub const ACCELERATION: u16 = 0x0060;
    /// Deceleration.
    pub const DECELERATION: u16 = 0x0062;
    /// Operating current, 0.1 %.
    pub const CURRENT: u16 = 0x0064;
    /// Trigger: 1 starts the operation with all the data.
    pub const TRIGGER: u16 = 0x0066;
    /// Input command register.
    pub const INPUT: u16 = 0x007D;
    /// ZHOME bit of the input command.
    pub const ZHOME: u16 = 1 << 4;
    /// STOP bit of the input command.
    pub const STOP: u16 = 1 << 5;
    /// ALM-RST bit of the input command: clears a latched alarm.
    pub const ALARM_RESET: u16 = 1 << 7;
    /// Output status register.
    pub const STATUS: u16 = 0x007F;
    /// HOME-END bit.
    pub const HOME_END: u8 = 4;
    /// ALM bit.
    pub const ALARM: u8 = 7;
    /// BUSY bit.
    pub const BUSY: u8 = 8;
    /// IN-POS bit.
    pub const IN_POS: u8 = 14;
    /// Feedback position, 32-bit.
    pub const FEEDBACK: u16 = 0x0120;
}

/// Which drive the twin is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// A simple drive following the map's short form.
    Simple,
    /// An Oriental AZ in direct-data operation.
    Az,
}

/// The drive's state.
pub(super) struct Drive {
    pub(super) kind: Kind,
    pub(super) regs: HashMap<u16, u16>,
    pub(super) motion: Motion,
    pub(super) timing: Timing,
    pub(super) homing: bool,
    pub(super) homed: bool,
    pub(super) alarm: bool,
    /// Accept trigger writes but never start (a drive in the wrong mode).
    pub(super) ignore_triggers: bool,
    /// Keep BUSY and go nowhere.
    pub(super) stuck: bool,
}

/// Status and position registers, and the bits of the status, for a kind of drive.
struct Layout {
    position: u16,
    status: u16,
    busy: u8,
    alarm: u8,
    homed: Option<u8>,
    in_position: Option<u8>,
}

impl Drive {
    /// A drive of `kind` at rest at an unknown position, not homed, with the registers a
    /// driver may write.
    pub(super) fn new(kind: Kind, map: &ModbusMap) -> Self {
        let mut regs = HashMap::new();
        let writable: Vec<u16> = match kind {
            Kind::Az => (az::DATA_NUMBER..az::TRIGGER + 2)
                .chain([az::INPUT])
                .collect(),
            Kind::Simple => [map.target, map.speed]
                .into_iter()
                .flatten()
                .flat_map(|a| [a, a + 1])
                .chain(map.trigger.map(|t| t.addr))
                .chain([map.home.addr, map.stop.addr])
                .collect(),
        };
        for a in writable {
            regs.insert(a, 0);
        }
        for s in &map.on_open {
            for k in 0..s.registers() as u16 {
                regs.insert(s.write + k, 0);
            }
        }
        Self {
            kind,
            regs,
            motion: Motion::at_rest(1234.0),
            timing: Timing::default(),
            homing: false,
            homed: false,
            alarm: false,
            ignore_triggers: false,
            stuck: false,
        }
    }

    fn layout(&self, map: &ModbusMap) -> Layout {
        match self.kind {
            Kind::Az => Layout {
                position: az::FEEDBACK,
                status: az::STATUS,
                busy: az::BUSY,
                alarm: az::ALARM,
                homed: Some(az::HOME_END),
                in_position: Some(az::IN_POS),
            },
            Kind::Simple => Layout {
                position: map.position,
                status: map.status,
                busy: map.busy_bit,
                alarm: map.alarm_bit,
                homed: map.homed_bit,
                in_position: map.in_position_bit,
            },
        }
    }

    /// Position (steps), busy, in position, now.
    pub(super) fn reading(&mut self) -> (f64, bool, bool) {
        let r = self.motion.at(Instant::now());
        if self.stuck {
            self.motion = Motion::at_rest(r.position);
            return (r.position, true, false);
        }
        if !r.busy && self.homing && r.in_position {
            self.homing = false;
            self.homed = true;
        }
        (r.position, r.busy, r.in_position)
    }

    /// FC3: the registers from `addr`.
    pub(super) fn read(
        &mut self,
        map: &ModbusMap,
        addr: u16,
        n: u16,
    ) -> Result<Vec<u16>, ExceptionCode> {
        let l = self.layout(map);
        let (pos, busy, in_pos) = self.reading();
        let pos_words = map.word_order.split(pos.round() as i32);
        let mut status = 0u16;
        let mut set = |bit: Option<u8>, on: bool| {
            if let Some(b) = bit
                && on
            {
                status |= 1 << b;
            }
        };
        set(Some(l.busy), busy);
        set(Some(l.alarm), self.alarm);
        set(l.homed, self.homed);
        set(l.in_position, in_pos && !busy);
        (addr..addr.saturating_add(n))
            .map(|a| {
                if a == l.position {
                    Ok(pos_words[0])
                } else if a == l.position + 1 {
                    Ok(pos_words[1])
                } else if a == l.status {
                    Ok(status)
                } else {
                    self.regs
                        .get(&a)
                        .copied()
                        .ok_or(ExceptionCode::IllegalDataAddress)
                }
            })
            .collect()
    }

    fn get32(&self, order: WordOrder, a: u16) -> i32 {
        let r = |a: u16| self.regs.get(&a).copied().unwrap_or(0);
        order.join([r(a), r(a + 1)])
    }

    /// FC6 and FC16: stores `words` from `addr`, then acts on what was written.
    pub(super) fn write(
        &mut self,
        map: &ModbusMap,
        limits: (i32, i32),
        time_scale: f64,
        addr: u16,
        words: &[u16],
    ) -> Result<(), ExceptionCode> {
        for k in 0..words.len() as u16 {
            if !self.regs.contains_key(&(addr + k)) {
                return Err(ExceptionCode::IllegalDataAddress);
            }
        }
        for (k, w) in words.iter().enumerate() {
            self.regs.insert(addr + k as u16, *w);
        }
        let covers = |a: u16| (addr..addr + words.len() as u16).contains(&a);
        let (pos, busy, _) = self.reading();
        let start = match self.kind {
            Kind::Az if covers(az::TRIGGER) || covers(az::TRIGGER + 1) => {
                let trigger = self.get32(map.word_order, az::TRIGGER);
                if trigger != 1 {
                    None
                } else {
                    // The drive clears the trigger once it takes the data.
                    self.regs.insert(az::TRIGGER, 0);
                    self.regs.insert(az::TRIGGER + 1, 0);
                    let target = self.get32(map.word_order, az::POSITION);
                    match self.get32(map.word_order, az::OPERATION) {
                        1 => Some((target, self.get32(map.word_order, az::SPEED))),
                        2 => Some((
                            (pos.round() as i32).saturating_add(target),
                            self.get32(map.word_order, az::SPEED),
                        )),
                        _ => return Err(ExceptionCode::IllegalDataValue),
                    }
                }
            }
            Kind::Simple => match (map.trigger, map.target, map.speed) {
                (Some(t), Some(target), Some(speed))
                    if covers(t.addr) && self.regs.get(&t.addr) == Some(&t.value) =>
                {
                    Some((
                        self.get32(map.word_order, target),
                        self.get32(map.word_order, speed),
                    ))
                }
                _ => None,
            },
            Kind::Az => None,
        };
        if let Some((target, speed)) = start {
            if target < limits.0 || target > limits.1 || speed <= 0 {
                self.alarm = true;
                return Err(ExceptionCode::IllegalDataValue);
            }
            if busy {
                return Err(ExceptionCode::ServerDeviceBusy);
            }
            if !self.ignore_triggers {
                self.motion =
                    Motion::new(pos, target as f64, speed as f64 * time_scale, self.timing);
            }
            return Ok(());
        }
        let (home, stop) = match self.kind {
            Kind::Az => (
                covers(az::INPUT) && self.regs.get(&az::INPUT) == Some(&az::ZHOME),
                covers(az::INPUT) && self.regs.get(&az::INPUT) == Some(&az::STOP),
            ),
            Kind::Simple => (
                covers(map.home.addr) && words.first() == Some(&map.home.value),
                covers(map.stop.addr) && words.first() == Some(&map.stop.value),
            ),
        };
        if home {
            // Homing finds its sensor: it lands on 0, no overshoot.
            let timing = Timing {
                overshoot: 0.0,
                ..self.timing
            };
            self.motion = Motion::new(pos, 0.0, 20_000.0 * time_scale, timing);
            self.homing = true;
            self.alarm = false;
        } else if stop {
            self.motion = Motion::at_rest(pos);
            self.homing = false;
        } else if self.kind == Kind::Az
            && covers(az::INPUT)
            && self.regs.get(&az::INPUT) == Some(&az::ALARM_RESET)
        {
            self.alarm = false;
        }
        Ok(())
    }
}
