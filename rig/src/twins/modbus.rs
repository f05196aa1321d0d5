//! A Modbus drive reading the same register map as the driver (spec `devices.md` §5,
//! "Modbus drive"), on loopback TCP or as an RTU slave on a pseudo-terminal. FC3 reads,
//! FC6 and FC16 writes; unmapped addresses answer IllegalDataAddress (0x02). The trigger
//! starts a move at the written speed (busy until done); a target beyond the drive's
//! limits raises the alarm bit and answers IllegalDataValue (0x03); homing runs to 0 and
//! sets the homed bit; requests for another unit id get no reply (the driver times out).
//! Faults: busy exceptions (0x06), silence, a drive stuck busy, and (RTU) garbled replies.
//!
//! `tokio-modbus`'s RTU server needs `tokio-serial` (libudev), so the RTU side frames by
//! hand: requests are cut by their function code's length, CRC-16/MODBUS checked (a bad
//! CRC is ignored, as a slave does), and answered through the same register logic as TCP.

use std::collections::HashMap;
use std::future::{Ready, ready};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Instant;

use serialport::SerialPort;
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
    /// Corrupt the next N replies (RTU: the CRC no longer matches).
    pub garble_next: u32,
    /// The drive keeps its busy bit set and goes nowhere (a jam, a stalled motor).
    pub stuck_busy: bool,
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
    time_scale: f64,
}

impl Service {
    fn read(&self, addr: u16, n: u16) -> Result<Vec<u16>, ExceptionCode> {
        let m = &self.map;
        let stuck = lock(&self.faults).stuck_busy;
        let mut d = lock(&self.drive);
        let (pos, moving) = d.at();
        if stuck {
            d.from = pos;
            d.to = pos;
        }
        let moving = moving || stuck;
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
                speed: speed as f64 * self.time_scale,
                regs: std::mem::take(&mut d.regs),
                ..*d
            };
        } else if addr == m.home.addr && words.first() == Some(&m.home.value) {
            *d = Drive {
                from: pos,
                to: 0.0,
                start: Instant::now(),
                speed: 20_000.0 * self.time_scale,
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

impl Service {
    /// The answer to one request: `None` for silence (another unit, or the fault).
    fn handle(&self, slave: u8, request: Request<'_>) -> Option<Result<Response, ExceptionCode>> {
        let f = lock(&self.faults).clone();
        if f.silent || slave != self.map.slave {
            return None;
        }
        if f.busy {
            return Some(Err(ExceptionCode::ServerDeviceBusy));
        }
        Some(match request {
            Request::ReadHoldingRegisters(a, n) => {
                self.read(a, n).map(Response::ReadHoldingRegisters)
            }
            Request::WriteSingleRegister(a, w) => self
                .write(a, &[w])
                .map(|_| Response::WriteSingleRegister(a, w)),
            Request::WriteMultipleRegisters(a, ws) => self
                .write(a, &ws)
                .map(|_| Response::WriteMultipleRegisters(a, ws.len() as u16)),
            _ => Err(ExceptionCode::IllegalFunction),
        })
    }
}

impl tokio_modbus::server::Service for Service {
    type Request = SlaveRequest<'static>;
    type Response = Option<Response>;
    type Exception = ExceptionCode;
    type Future = Ready<Result<Self::Response, Self::Exception>>;

    fn call(&self, req: Self::Request) -> Self::Future {
        ready(self.handle(req.slave, req.request).transpose())
    }
}

/// Where a twin listens.
#[derive(Debug, Clone, PartialEq)]
pub enum Endpoint {
    /// Modbus TCP on loopback.
    Tcp(std::net::SocketAddr),
    /// Modbus RTU on this pseudo-terminal.
    Rtu(String),
}

/// A running drive.
pub struct ModbusTwin {
    /// Where it listens.
    pub endpoint: Endpoint,
    /// Fault switches.
    pub faults: Arc<Mutex<Faults>>,
    drive: Arc<Mutex<Drive>>,
    task: Option<tokio::task::JoinHandle<()>>,
    rtu: Option<(Arc<AtomicBool>, std::thread::JoinHandle<()>)>,
}

impl Drop for ModbusTwin {
    fn drop(&mut self) {
        if let Some(t) = self.task.take() {
            t.abort();
        }
        if let Some((stop, thread)) = self.rtu.take() {
            stop.store(true, Ordering::Relaxed);
            let _ = thread.join();
        }
    }
}

fn service(map: ModbusMap, limits_steps: (i32, i32), time_scale: f64) -> Service {
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
    Service {
        map,
        limits: limits_steps,
        drive: Arc::new(Mutex::new(Drive {
            regs,
            from: 1234.0,
            to: 1234.0,
            start: Instant::now(),
            speed: 1.0,
            homing: false,
            homed: false,
            alarm: false,
        })),
        faults: Arc::new(Mutex::new(Faults::default())),
        time_scale,
    }
}

impl ModbusTwin {
    /// Serves `map` over Modbus TCP (its `address` is ignored: the twin binds 127.0.0.1 on
    /// a free port) with travel limits in steps, moving `time_scale` times faster than the
    /// wall. Must run inside a tokio runtime.
    pub async fn spawn(
        map: ModbusMap,
        limits_steps: (i32, i32),
        time_scale: f64,
    ) -> std::io::Result<Self> {
        let listener = TcpListener::bind("127.0.0.1:0").await?;
        let address = listener.local_addr()?;
        let svc = service(map, limits_steps, time_scale);
        let (faults, drive) = (svc.faults.clone(), svc.drive.clone());
        let task = tokio::spawn(async move {
            let server = Server::new(listener);
            let on_connected = |stream, addr| {
                let svc = svc.clone();
                async move { accept_tcp_connection(stream, addr, move |_| Ok(Some(svc.clone()))) }
            };
            let _ = server.serve(&on_connected, |_| {}).await;
        });
        Ok(Self {
            endpoint: Endpoint::Tcp(address),
            faults,
            drive,
            task: Some(task),
            rtu: None,
        })
    }

    /// Serves `map` as a Modbus RTU slave on a new pseudo-terminal (the driver opens its
    /// `/dev/pts/N` path as it would an RS-485 adapter).
    pub fn spawn_rtu(
        map: ModbusMap,
        limits_steps: (i32, i32),
        time_scale: f64,
    ) -> std::io::Result<Self> {
        let (mut master, path) = super::pty::open_pair()?;
        master
            .set_timeout(std::time::Duration::from_millis(5))
            .map_err(std::io::Error::other)?;
        let svc = service(map, limits_steps, time_scale);
        let (faults, drive) = (svc.faults.clone(), svc.drive.clone());
        let stop = Arc::new(AtomicBool::new(false));
        let s = stop.clone();
        let thread = std::thread::spawn(move || serve_rtu(&mut master, &svc, &s));
        Ok(Self {
            endpoint: Endpoint::Rtu(path),
            faults,
            drive,
            task: None,
            rtu: Some((stop, thread)),
        })
    }

    /// The address a driver connects to: `host:port` (TCP) or the pty path (RTU).
    pub fn address(&self) -> String {
        match &self.endpoint {
            Endpoint::Tcp(a) => a.to_string(),
            Endpoint::Rtu(p) => p.clone(),
        }
    }

    /// Where the drive is, steps.
    pub fn position_steps(&self) -> f64 {
        (self.position_probe())()
    }

    /// A handle reading the position in steps, for a plant that follows the drive.
    pub fn position_probe(&self) -> impl Fn() -> f64 + Send + 'static {
        let d = self.drive.clone();
        move || lock(&d).at().0
    }
}

const RTU_CRC: crc::Crc<u16> = crc::Crc::<u16>::new(&crc::CRC_16_MODBUS);

/// Appends the CRC, low byte first (Modbus serial line spec §2.5.1.2).
fn with_crc(mut frame: Vec<u8>) -> Vec<u8> {
    let c = RTU_CRC.checksum(&frame);
    frame.extend_from_slice(&c.to_le_bytes());
    frame
}

/// Length of the request starting `buf` (slave id, function code, …, CRC), if it can be
/// told yet; `Some(None)` for a function this drive does not implement.
fn request_len(buf: &[u8]) -> Option<Option<usize>> {
    let fc = *buf.get(1)?;
    Some(match fc {
        0x03 | 0x06 => Some(8),
        0x10 => Some(9 + *buf.get(6)? as usize),
        _ => None,
    })
}

fn be(b: &[u8], i: usize) -> u16 {
    u16::from_be_bytes([b[i], b[i + 1]])
}

/// The reply frame (CRC included) to one CRC-checked request frame, if any.
fn rtu_reply(svc: &Service, frame: &[u8]) -> Option<Vec<u8>> {
    let (slave, fc) = (frame[0], frame[1]);
    let request = match fc {
        0x03 => Request::ReadHoldingRegisters(be(frame, 2), be(frame, 4)),
        0x06 => Request::WriteSingleRegister(be(frame, 2), be(frame, 4)),
        0x10 => {
            let n = frame[6] as usize / 2;
            let words: Vec<u16> = (0..n).map(|k| be(frame, 7 + 2 * k)).collect();
            Request::WriteMultipleRegisters(be(frame, 2), words.into())
        }
        _ => Request::Custom(fc, Vec::new().into()),
    };
    let mut out = vec![slave];
    match svc.handle(slave, request)? {
        Ok(Response::ReadHoldingRegisters(words)) => {
            out.extend([fc, (2 * words.len()) as u8]);
            words.iter().for_each(|w| out.extend(w.to_be_bytes()));
        }
        Ok(Response::WriteSingleRegister(a, w)) => {
            out.push(fc);
            out.extend(a.to_be_bytes());
            out.extend(w.to_be_bytes());
        }
        Ok(Response::WriteMultipleRegisters(a, n)) => {
            out.push(fc);
            out.extend(a.to_be_bytes());
            out.extend(n.to_be_bytes());
        }
        Ok(_) => return None,
        Err(code) => out.extend([fc | 0x80, u8::from(code)]),
    }
    Some(with_crc(out))
}

fn serve_rtu(master: &mut serialport::TTYPort, svc: &Service, stop: &AtomicBool) {
    use std::io::{Read, Write};
    let mut pending: Vec<u8> = Vec::new();
    let mut buf = [0u8; 256];
    while !stop.load(Ordering::Relaxed) {
        match master.read(&mut buf) {
            Ok(n) => pending.extend_from_slice(&buf[..n]),
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::TimedOut | std::io::ErrorKind::WouldBlock
                ) =>
            {
                // Silence ends a frame (t3.5): whatever is pending and incomplete is noise.
                pending.clear();
                continue;
            }
            // EIO while no driver holds the slave side open: wait for the next one.
            Err(_) => {
                pending.clear();
                std::thread::sleep(std::time::Duration::from_millis(10));
                continue;
            }
        }
        while let Some(len) = request_len(&pending) {
            let len = len.unwrap_or(4).max(4);
            if pending.len() < len {
                break;
            }
            let frame: Vec<u8> = pending.drain(..len).collect();
            if RTU_CRC.checksum(&frame[..len - 2]).to_le_bytes() != frame[len - 2..] {
                // A slave ignores a frame with a bad CRC; resynchronise on the next one.
                pending.clear();
                break;
            }
            let Some(mut reply) = rtu_reply(svc, &frame) else {
                continue;
            };
            {
                let mut f = lock(&svc.faults);
                if f.garble_next > 0 {
                    f.garble_next -= 1;
                    let last = reply.len() - 1;
                    reply[last] ^= 0x5A;
                }
            }
            let _ = master.write_all(&reply);
        }
    }
}
