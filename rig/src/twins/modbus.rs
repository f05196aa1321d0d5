//! A Modbus TCP drive on loopback, reading the same register map as the driver (spec
//! `devices.md` §5, "Modbus drive"). FC3 reads, FC6 and FC16 writes; unmapped addresses
//! answer IllegalDataAddress (0x02). The trigger starts a move at the written speed (busy
//! until done); a target beyond the drive's limits raises the alarm bit and answers
//! IllegalDataValue (0x03); homing runs to 0 and sets the homed bit; requests for another
//! unit id get no reply (the driver times out). Faults: busy exceptions (0x06), silence.

use std::collections::HashMap;
use std::future::{Ready, ready};
use std::sync::{Arc, Mutex};
use std::time::Instant;

use tokio::net::TcpListener;
use tokio_modbus::server::tcp::{Server, accept_tcp_connection};
use tokio_modbus::{ExceptionCode, Request, Response, SlaveRequest};

use crate::drivers::modbus::ModbusMap;
use crate::lock;

/// Faults to inject.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Faults {
    /// Answer every request with ServerDeviceBusy.
    pub busy: bool,
    /// Answer nothing.
    pub silent: bool,
}

struct Drive {
    regs: HashMap<u16, u16>,
    from: f64,
    to: f64,
    start: Instant,
    speed: f64,
    homing: bool,
    homed: bool,
    alarm: bool,
}

impl Drive {
    fn at(&self) -> (f64, bool) {
        let d = self.to - self.from;
        let travelled = self.speed * self.start.elapsed().as_secs_f64();
        if travelled >= d.abs() {
            (self.to, false)
        } else {
            (self.from + d.signum() * travelled, true)
        }
    }
}

#[derive(Clone)]
struct Service {
    map: ModbusMap,
    limits: (i32, i32),
    drive: Arc<Mutex<Drive>>,
    faults: Arc<Mutex<Faults>>,
}

impl Service {
    fn read(&self, addr: u16, n: u16) -> Result<Vec<u16>, ExceptionCode> {
        let m = &self.map;
        let mut d = lock(&self.drive);
        let (pos, moving) = d.at();
        if !moving && d.homing {
            d.homing = false;
            d.homed = true;
        }
        let pos_words = m.word_order.split(pos.round() as i32);
        let mut status = 0u16;
        if moving {
            status |= 1 << m.busy_bit;
        }
        if d.alarm {
            status |= 1 << m.alarm_bit;
        }
        if let Some(b) = m.homed_bit
            && d.homed
        {
            status |= 1 << b;
        }
        (addr..addr.saturating_add(n))
            .map(|a| {
                if a == m.position {
                    Ok(pos_words[0])
                } else if a == m.position + 1 {
                    Ok(pos_words[1])
                } else if a == m.status {
                    Ok(status)
                } else {
                    d.regs
                        .get(&a)
                        .copied()
                        .ok_or(ExceptionCode::IllegalDataAddress)
                }
            })
            .collect()
    }

    fn write(&self, addr: u16, words: &[u16]) -> Result<(), ExceptionCode> {
        let m = &self.map;
        let mut d = lock(&self.drive);
        for (k, w) in words.iter().enumerate() {
            let a = addr + k as u16;
            if !d.regs.contains_key(&a) {
                return Err(ExceptionCode::IllegalDataAddress);
            }
            d.regs.insert(a, *w);
        }
        let (pos, moving) = d.at();
        let get2 = |d: &Drive, a: u16| m.word_order.join([d.regs[&a], d.regs[&(a + 1)]]);
        if addr == m.trigger.addr && words.first() == Some(&m.trigger.value) {
            let (target, speed) = (get2(&d, m.target), get2(&d, m.speed));
            if target < self.limits.0 || target > self.limits.1 || speed <= 0 {
                d.alarm = true;
                return Err(ExceptionCode::IllegalDataValue);
            }
            if moving {
                return Err(ExceptionCode::ServerDeviceBusy);
            }
            *d = Drive {
                from: pos,
                to: target as f64,
                start: Instant::now(),
                speed: speed as f64,
                regs: std::mem::take(&mut d.regs),
                ..*d
            };
        } else if addr == m.home.addr && words.first() == Some(&m.home.value) {
            *d = Drive {
                from: pos,
                to: 0.0,
                start: Instant::now(),
                speed: 20_000.0,
                homing: true,
                alarm: false,
                regs: std::mem::take(&mut d.regs),
                ..*d
            };
        } else if addr == m.stop.addr && words.first() == Some(&m.stop.value) {
            *d = Drive {
                from: pos,
                to: pos,
                start: Instant::now(),
                homing: false,
                regs: std::mem::take(&mut d.regs),
                ..*d
            };
        }
        Ok(())
    }
}

impl tokio_modbus::server::Service for Service {
    type Request = SlaveRequest<'static>;
    type Response = Option<Response>;
    type Exception = ExceptionCode;
    type Future = Ready<Result<Self::Response, Self::Exception>>;

    fn call(&self, req: Self::Request) -> Self::Future {
        let f = lock(&self.faults).clone();
        if f.silent || req.slave != self.map.slave {
            return ready(Ok(None));
        }
        if f.busy {
            return ready(Err(ExceptionCode::ServerDeviceBusy));
        }
        let r = match req.request {
            Request::ReadHoldingRegisters(a, n) => self
                .read(a, n)
                .map(|v| Some(Response::ReadHoldingRegisters(v))),
            Request::WriteSingleRegister(a, w) => self
                .write(a, &[w])
                .map(|_| Some(Response::WriteSingleRegister(a, w))),
            Request::WriteMultipleRegisters(a, ws) => self
                .write(a, &ws)
                .map(|_| Some(Response::WriteMultipleRegisters(a, ws.len() as u16))),
            _ => Err(ExceptionCode::IllegalFunction),
        };
        ready(r)
    }
}

/// A running drive.
pub struct ModbusTwin {
    /// Where it listens.
    pub address: std::net::SocketAddr,
    /// Fault switches.
    pub faults: Arc<Mutex<Faults>>,
    drive: Arc<Mutex<Drive>>,
    task: tokio::task::JoinHandle<()>,
}

impl Drop for ModbusTwin {
    fn drop(&mut self) {
        self.task.abort();
    }
}

impl ModbusTwin {
    /// Serves `map` (its `address` is ignored: the twin binds 127.0.0.1 on a free port)
    /// with travel limits in steps.
    pub async fn spawn(map: ModbusMap, limits_steps: (i32, i32)) -> std::io::Result<Self> {
        let listener = TcpListener::bind("127.0.0.1:0").await?;
        let address = listener.local_addr()?;
        let mut regs = HashMap::new();
        for a in [
            map.target,
            map.target + 1,
            map.speed,
            map.speed + 1,
            map.trigger.addr,
            map.home.addr,
            map.stop.addr,
        ] {
            regs.insert(a, 0);
        }
        let drive = Arc::new(Mutex::new(Drive {
            regs,
            from: 1234.0,
            to: 1234.0,
            start: Instant::now(),
            speed: 1.0,
            homing: false,
            homed: false,
            alarm: false,
        }));
        let faults = Arc::new(Mutex::new(Faults::default()));
        let svc = Service {
            map,
            limits: limits_steps,
            drive: drive.clone(),
            faults: faults.clone(),
        };
        let task = tokio::spawn(async move {
            let server = Server::new(listener);
            let on_connected = |stream, addr| {
                let svc = svc.clone();
                async move { accept_tcp_connection(stream, addr, move |_| Ok(Some(svc.clone()))) }
            };
            let _ = server.serve(&on_connected, |_| {}).await;
        });
        Ok(Self {
            address,
            faults,
            drive,
            task,
        })
    }

    /// Where the drive is, steps.
    pub fn position_steps(&self) -> f64 {
        lock(&self.drive).at().0
    }
}
