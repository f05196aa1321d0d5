//! A Modbus drive on loopback TCP or as an RTU slave on a pseudo-terminal (spec
//! `devices.md` §5, "Modbus drive"): a simple drive following the map's short form, or an
//! Oriental AZ in direct-data operation as its manual documents it ([`drive`]), whichever
//! the map describes. FC3 reads, FC6 and FC16 writes; any other function answers Illegal
//! Function (0x01) on both transports; unmapped addresses answer Illegal Data Address
//! (0x02); a target beyond the drive's limits raises the alarm bit and answers Illegal
//! Data Value (0x03); a move while moving answers Server Device Busy (0x06); requests for
//! another unit id get no reply (the driver times out). Motion follows injectable
//! [`Timing`] (late BUSY, settling into IN-POS, overshoot). Faults: every reply busy, the
//! next N replies busy, silence, a drive stuck busy, a drive that ignores triggers, late
//! replies, and (RTU) garbled replies.
//!
//! `tokio-modbus`'s RTU server needs `tokio-serial` (libudev), so the RTU side frames by
//! hand ([`rtu`]): requests are cut by their function code's length (or, for a function
//! with no known length, by the silence after it), CRC-16/MODBUS checked (a bad CRC is
//! ignored, as a slave does), and answered through the same register logic as TCP.

pub mod drive;
mod rtu;

use std::future::ready;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

use serialport::SerialPort;
use tokio::net::TcpListener;
use tokio_modbus::server::tcp::{Server, accept_tcp_connection};
use tokio_modbus::{ExceptionCode, Request, Response, SlaveRequest};

use crate::drivers::modbus::ModbusMap;
use crate::lock;
use crate::twins::motion::Timing;
use drive::Drive;
pub use drive::Kind;

/// Faults to inject.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Faults {
    /// Answer every request with ServerDeviceBusy.
    pub busy: bool,
    /// Answer the next N requests with ServerDeviceBusy (a drive still digesting a command).
    pub busy_replies: u32,
    /// Answer nothing.
    pub silent: bool,
    /// Corrupt the next N replies (RTU: the CRC no longer matches).
    pub garble_next: u32,
    /// The drive keeps its busy bit set and goes nowhere (a jam, a stalled motor).
    pub stuck_busy: bool,
    /// The drive accepts trigger writes and never moves (a drive in the wrong mode).
    pub ignore_triggers: bool,
    /// Each request is answered this long after it arrives, from the drive's state at the
    /// answer (a slow bus, a loaded host): two reads of one status poll see two instants.
    pub reply_delay: std::time::Duration,
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
    /// How long the next reply waits (the fault).
    fn reply_delay(&self) -> std::time::Duration {
        lock(&self.faults).reply_delay
    }

    /// The answer to one request: `None` for silence (another unit, or the fault).
    fn handle(&self, slave: u8, request: Request<'_>) -> Option<Result<Response, ExceptionCode>> {
        let f = {
            let mut f = lock(&self.faults);
            let now = f.clone();
            f.busy_replies = f.busy_replies.saturating_sub(1);
            now
        };
        if f.silent || slave != self.map.slave {
            return None;
        }
        if f.busy || f.busy_replies > 0 {
            return Some(Err(ExceptionCode::ServerDeviceBusy));
        }
        let mut d = lock(&self.drive);
        d.stuck = f.stuck_busy;
        d.ignore_triggers = f.ignore_triggers;
        Some(match request {
            Request::ReadHoldingRegisters(a, n) => {
                d.read(&self.map, a, n).map(Response::ReadHoldingRegisters)
            }
            Request::WriteSingleRegister(a, w) => d
                .write(&self.map, self.limits, self.time_scale, a, &[w])
                .map(|_| Response::WriteSingleRegister(a, w)),
            Request::WriteMultipleRegisters(a, ws) => d
                .write(&self.map, self.limits, self.time_scale, a, &ws)
                .map(|_| Response::WriteMultipleRegisters(a, ws.len() as u16)),
            _ => Err(ExceptionCode::IllegalFunction),
        })
    }
}

impl tokio_modbus::server::Service for Service {
    type Request = SlaveRequest<'static>;
    type Response = Option<Response>;
    type Exception = ExceptionCode;
    type Future = std::pin::Pin<
        Box<dyn std::future::Future<Output = Result<Self::Response, Self::Exception>> + Send>,
    >;

    fn call(&self, req: Self::Request) -> Self::Future {
        let delay = self.reply_delay();
        if delay.is_zero() {
            return Box::pin(ready(self.handle(req.slave, req.request).transpose()));
        }
        let svc = self.clone();
        Box::pin(async move {
            tokio::time::sleep(delay).await;
            svc.handle(req.slave, req.request).transpose()
        })
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

/// The drive a map describes: the long form is an AZ's direct-data block.
fn service(map: ModbusMap, limits_steps: (i32, i32), time_scale: f64) -> Service {
    let kind = if map.move_writes.is_empty() {
        Kind::Simple
    } else {
        Kind::Az
    };
    Service {
        drive: Arc::new(Mutex::new(Drive::new(kind, &map))),
        map,
        limits: limits_steps,
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
        let thread = std::thread::spawn(move || rtu::serve(&mut master, &svc, &s));
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

    /// Which drive this is.
    pub fn kind(&self) -> Kind {
        lock(&self.drive).kind
    }

    /// How moves from now on behave: latency to BUSY, settling into IN-POS, overshoot
    /// (steps).
    pub fn set_timing(&self, timing: Timing) {
        lock(&self.drive).timing = timing;
    }

    /// Where the drive is, steps.
    pub fn position_steps(&self) -> f64 {
        (self.position_probe())()
    }

    /// A handle reading the position in steps, for a plant that follows the drive.
    pub fn position_probe(&self) -> impl Fn() -> f64 + Send + 'static {
        let d = self.drive.clone();
        move || lock(&d).reading().0
    }
}
