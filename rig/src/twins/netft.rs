//! An ATI Net F/T box on loopback: RDT over UDP and READCALINFO over TCP (spec
//! `devices.md` §5, "Net F/T"). Counts per unit are deliberately not 1e6, so a driver that
//! hard-codes the scaling fails. The load comes from a shared [`Wrench`] the caller sets
//! (a test, or `gelrig sim serve` from the simulated plant).
//!
//! Streaming follows the box: `0x0002 N` streams N records (0 = forever) to the latest
//! requester at `rate_hz`; `0x0000` stops; `0x0042` biases to the current load. Counters:
//! `rdt_seq` from 1 per packet, `ft_seq` at 7000 Hz; both wrap at 2³² and can be started
//! near the wrap. Saturation sets status bits 31|30. Faults: loss, reordering,
//! duplication, ignoring requests, a stopped stream, a one-off sequence jump, a short or
//! empty datagram, and the link's latency and jitter and the box's clock drift (with the
//! time each record was sampled kept as the truth a clock model is measured against).

use std::net::{SocketAddr, TcpListener, UdpSocket};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crate::device::{ForceRange, Wrench};
use crate::drivers::netft_rdt::{
    CMD_BIAS, CMD_START, CMD_START_BUFFERED, CMD_STOP, CalInfo, Record, STATUS_ERROR,
    STATUS_OUT_OF_RANGE, parse_request,
};
use crate::lock;

/// Faults to inject.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Faults {
    /// Drop every Nth packet (0: none).
    pub drop_every: u32,
    /// Swap every Nth packet with the next (0: none).
    pub reorder_every: u32,
    /// Send every Nth packet twice (0: none).
    pub duplicate_every: u32,
    /// Ignore every request (the box is unreachable).
    pub ignore_requests: bool,
    /// Stop sending records (the box hung).
    pub silent: bool,
    /// Add this to the next record's `rdt_sequence`, once (a corrupted or foreign record;
    /// the records after it continue the real sequence).
    pub jump_once: Option<u32>,
    /// Send a datagram of this many zero bytes in place of the next record, once (a short
    /// or empty datagram: not whole records).
    pub short_once: Option<usize>,
    /// Network latency every record has, ms.
    pub latency_ms: f64,
    /// Extra delay of each record, in 0…2× this, ms ("± jitter" about its middle): the link
    /// delivers in bursts and stays first-in first-out, as one cable is.
    pub jitter_ms: f64,
    /// The box's crystal runs this many ppm slow: its records (and `ft_seq`) come that much
    /// further apart in host time.
    pub drift_ppm: f64,
}

/// Box parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct TwinParams {
    /// Records per second.
    pub rate_hz: f64,
    /// Calibration reported over TCP.
    pub cal: CalInfo,
    /// Sensor range (saturation).
    pub range: ForceRange,
    /// First `rdt_seq` and `ft_seq` (to force a wrap).
    pub first_seq: (u32, u32),
}

/// What the box reads at each record, if not the fixed [`NetFtTwin::load`]: the wrench and
/// whether the transducer saturated (a simulated plant clips at the range itself).
pub type LoadSource = Box<dyn FnMut() -> (Wrench, bool) + Send>;

/// The box's load: fixed, or read from a plant at every record.
struct Loads {
    fixed: Arc<Mutex<Wrench>>,
    source: Arc<Mutex<Option<LoadSource>>>,
}

impl Loads {
    fn now(&self, range: &ForceRange) -> (Wrench, bool) {
        if let Some(f) = lock(&self.source).as_mut() {
            return f();
        }
        let w = *lock(&self.fixed);
        let out = |v: f64, range: f64| v.abs() > range;
        let saturated = out(w.fz_n, range.fz_n)
            || out(w.fx_n, range.fxy_n)
            || out(w.fy_n, range.fxy_n)
            || out(w.tz_nmm, range.torque_nmm);
        (w, saturated)
    }
}

/// A running box.
pub struct NetFtTwin {
    rdt: SocketAddr,
    calibration: SocketAddr,
    /// The load the box reads (unless a [`LoadSource`] drives it).
    pub load: Arc<Mutex<Wrench>>,
    source: Arc<Mutex<Option<LoadSource>>>,
    faults: Arc<Mutex<Faults>>,
    /// When each of the last records was sampled, by its `ft_seq` (the truth a clock model is
    /// measured against).
    sampled: Arc<Mutex<std::collections::VecDeque<(u32, Instant)>>>,
    stop: Arc<AtomicBool>,
    threads: Vec<JoinHandle<()>>,
}

/// Sample times kept for [`NetFtTwin::sample_times`].
const SAMPLED_KEPT: usize = 1 << 20;

impl NetFtTwin {
    /// Binds UDP and TCP on 127.0.0.1 (ephemeral ports) and starts serving.
    pub fn spawn(params: TwinParams) -> std::io::Result<Self> {
        let udp = UdpSocket::bind("127.0.0.1:0")?;
        // Polled between sleeps: a socket timeout is counted in scheduler ticks (4–8 ms),
        // which would send the records in bursts; a sleep is a high-resolution timer.
        udp.set_nonblocking(true)?;
        let tcp = TcpListener::bind("127.0.0.1:0")?;
        tcp.set_nonblocking(true)?;
        let (rdt, calibration) = (udp.local_addr()?, tcp.local_addr()?);
        let load = Arc::new(Mutex::new(Wrench::default()));
        let source = Arc::new(Mutex::new(None));
        let faults = Arc::new(Mutex::new(Faults::default()));
        let stop = Arc::new(AtomicBool::new(false));
        let l = Loads {
            fixed: load.clone(),
            source: Arc::clone(&source),
        };
        let sampled = Arc::new(Mutex::new(std::collections::VecDeque::new()));
        let (f, s, p, log) = (
            faults.clone(),
            stop.clone(),
            params.clone(),
            Arc::clone(&sampled),
        );
        let stream = std::thread::spawn(move || serve_rdt(&udp, &p, &l, &f, &s, &log));
        let (s2, cal) = (stop.clone(), params.cal);
        let calib = std::thread::spawn(move || serve_cal(&tcp, cal, &s2));
        Ok(Self {
            rdt,
            calibration,
            load,
            source,
            faults,
            sampled,
            stop,
            threads: vec![stream, calib],
        })
    }

    /// Reads every record's load from `source` from now on (a simulated plant following
    /// the stage twins) instead of the fixed [`Self::load`].
    pub fn drive_with(&self, source: LoadSource) {
        *lock(&self.source) = Some(source);
    }

    /// The RDT address.
    pub fn rdt_addr(&self) -> SocketAddr {
        self.rdt
    }

    /// The calibration (TCP) address.
    pub fn calibration_addr(&self) -> SocketAddr {
        self.calibration
    }

    /// Fault switches.
    pub fn faults(&self) -> &Arc<Mutex<Faults>> {
        &self.faults
    }

    /// When the box sampled each of its last records (up to 2²⁰), by `ft_seq`.
    pub fn sample_times(&self) -> Vec<(u32, Instant)> {
        lock(&self.sampled).iter().copied().collect()
    }
}

impl Drop for NetFtTwin {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}

fn serve_cal(tcp: &TcpListener, cal: CalInfo, stop: &AtomicBool) {
    use std::io::{Read, Write};
    while !stop.load(Ordering::Relaxed) {
        match tcp.accept() {
            Ok((mut c, _)) => {
                let _ = c.set_read_timeout(Some(Duration::from_millis(200)));
                let mut req = [0u8; 20];
                if c.read_exact(&mut req).is_ok() && req[0] == 0x01 {
                    let _ = c.write_all(&cal.to_bytes());
                }
            }
            Err(_) => std::thread::sleep(Duration::from_millis(2)),
        }
    }
}

/// Records on their way to the host. Jitter is modelled as a link that delivers in bursts
/// — it holds what is sent for a random 0…2×`jitter_ms`, then releases it together (a busy
/// switch, interrupt coalescing, a scheduler) — so every record's extra delay lies in
/// 0…2×jitter and the link stays first-in first-out, as one cable is. (Independent delays
/// per record kept in order would at 7 kHz make nearly every record wait for the slowest
/// of the last seventy: the delay would sit at its maximum, not spread over the range.)
struct Link {
    pending: std::collections::VecDeque<(Instant, Vec<u8>, SocketAddr)>,
    /// The current burst is released then.
    hold_until: Option<Instant>,
    rng: rand::rngs::StdRng,
}

impl Link {
    /// Queues `bytes` to leave after the injected delay.
    fn send(&mut self, udp: &UdpSocket, bytes: Vec<u8>, to: SocketAddr, f: &Faults) {
        use rand::Rng;
        if f.latency_ms <= 0.0 && f.jitter_ms <= 0.0 && self.pending.is_empty() {
            let _ = udp.send_to(&bytes, to);
            return;
        }
        let now = Instant::now();
        let release = match self.hold_until {
            Some(h) if h > now => h,
            _ => {
                let hold_ms = if f.jitter_ms > 0.0 {
                    self.rng.random_range(0.0..2.0 * f.jitter_ms)
                } else {
                    0.0
                };
                let h = now + Duration::from_secs_f64(hold_ms * 1e-3);
                self.hold_until = Some(h);
                h
            }
        };
        let at = release + Duration::from_secs_f64(f.latency_ms.max(0.0) * 1e-3);
        self.pending.push_back((at, bytes, to));
    }

    /// When the next queued record is due.
    fn due(&self) -> Option<Instant> {
        self.pending.front().map(|(at, _, _)| *at)
    }

    /// Sends what is due.
    fn flush(&mut self, udp: &UdpSocket) {
        let now = Instant::now();
        while self.pending.front().is_some_and(|(at, _, _)| *at <= now) {
            if let Some((_, bytes, to)) = self.pending.pop_front() {
                let _ = udp.send_to(&bytes, to);
            }
        }
    }
}

fn serve_rdt(
    udp: &UdpSocket,
    p: &TwinParams,
    load: &Loads,
    faults: &Mutex<Faults>,
    stop: &AtomicBool,
    sampled: &Mutex<std::collections::VecDeque<(u32, Instant)>>,
) {
    use rand::SeedableRng;
    let mut link = Link {
        pending: std::collections::VecDeque::new(),
        hold_until: None,
        rng: rand::rngs::StdRng::seed_from_u64(u64::from(p.first_seq.1)),
    };
    let (n_per_count, nmm_per_count) = p.cal.scales().unwrap_or((1e-6, 1e-6));
    let mut client: Option<SocketAddr> = None;
    let mut remaining: Option<u32> = None;
    let mut bias = Wrench::default();
    let (mut rdt_seq, mut ft_seq) = p.first_seq;
    let period = Duration::from_secs_f64(1.0 / p.rate_hz.max(1.0));
    let ft_step = (7000.0 / p.rate_hz.max(1.0)).round().max(1.0) as u32;
    let mut next = Instant::now();
    let mut held: Option<Vec<u8>> = None;
    let mut buf = [0u8; 64];
    while !stop.load(Ordering::Relaxed) {
        while let Ok((n, from)) = udp.recv_from(&mut buf) {
            let f = lock(faults).clone();
            if let (false, Some((cmd, count))) = (f.ignore_requests, parse_request(&buf[..n])) {
                match cmd {
                    CMD_START | CMD_START_BUFFERED => {
                        client = Some(from);
                        remaining = (count > 0).then_some(count);
                    }
                    CMD_STOP => client = None,
                    CMD_BIAS => bias = load.now(&p.range).0,
                    _ => {}
                }
            }
        }
        link.flush(udp);
        // Send every record that is due (the socket timeout is coarse under load); after a
        // stall of more than 50 records the box skips ahead, as a real one drops them.
        let drift = 1.0 + lock(faults).drift_ppm * 1e-6;
        let period = period.mul_f64(drift.max(1e-3));
        let now = Instant::now();
        if now < next {
            sleep_until(&[Some(next), link.due()], now);
            continue;
        }
        if now > next + 50 * period {
            // The box's own counter kept counting through the records it could not send.
            let skipped = ((now - next).as_secs_f64() / period.as_secs_f64()) as u32;
            ft_seq = ft_seq.wrapping_add(skipped.wrapping_mul(ft_step));
            next = now;
        }
        while next <= now && client.is_some() {
            let sampled_at = next;
            next += period;
            let ft = ft_seq;
            let sent = send_one(
                udp,
                &mut link,
                p,
                load,
                faults,
                &mut client,
                &mut remaining,
                &bias,
                &mut rdt_seq,
                &mut ft_seq,
                ft_step,
                &mut held,
                (n_per_count, nmm_per_count),
            );
            if sent {
                let mut log = lock(sampled);
                if log.len() >= SAMPLED_KEPT {
                    log.pop_front();
                }
                log.push_back((ft, sampled_at));
            }
        }
        if client.is_none() {
            next = now;
        }
        sleep_until(&[client.map(|_| next), link.due()], Instant::now());
    }
}

/// Sleeps until the earliest of `events`, and at most 1 ms (requests are polled).
fn sleep_until(events: &[Option<Instant>], now: Instant) {
    let limit = now + Duration::from_millis(1);
    let wake = events.iter().flatten().copied().fold(limit, Instant::min);
    if wake > now {
        std::thread::sleep(wake - now);
    }
}

/// Sends (or, as a fault, withholds) one record; true if a record was sampled.
#[allow(clippy::too_many_arguments)]
fn send_one(
    udp: &UdpSocket,
    link: &mut Link,
    p: &TwinParams,
    load: &Loads,
    faults: &Mutex<Faults>,
    client: &mut Option<SocketAddr>,
    remaining: &mut Option<u32>,
    bias: &Wrench,
    rdt_seq: &mut u32,
    ft_seq: &mut u32,
    ft_step: u32,
    held: &mut Option<Vec<u8>>,
    (n_per_count, nmm_per_count): (f64, f64),
) -> bool {
    {
        let Some(to) = *client else { return false };
        let f = {
            let mut f = lock(faults);
            let now = f.clone();
            f.jump_once = None;
            f.short_once = None;
            now
        };
        if f.silent {
            return false;
        }
        if let Some(n) = f.short_once {
            let _ = udp.send_to(&vec![0u8; n], to);
            return false;
        }
        let (w, saturated) = load.now(&p.range);
        let net = w.minus(bias).as_array();
        let counts: [i32; 6] = std::array::from_fn(|k| {
            let per = if k < 3 { n_per_count } else { nmm_per_count };
            (net[k] / per)
                .round()
                .clamp(i32::MIN as f64, i32::MAX as f64) as i32
        });
        let rec = Record {
            rdt_seq: rdt_seq.wrapping_add(f.jump_once.unwrap_or(0)),
            ft_seq: *ft_seq,
            status: if saturated {
                STATUS_ERROR | STATUS_OUT_OF_RANGE
            } else {
                0
            },
            counts,
        };
        let k = *rdt_seq;
        *rdt_seq = rdt_seq.wrapping_add(1);
        *ft_seq = ft_seq.wrapping_add(ft_step);
        if let Some(left) = remaining.as_mut() {
            *left -= 1;
            if *left == 0 {
                *client = None;
            }
        }
        let every = |n: u32| n > 0 && k.is_multiple_of(n);
        if every(f.drop_every) {
            return true;
        }
        let bytes = rec.to_bytes().to_vec();
        if every(f.reorder_every) && held.is_none() {
            *held = Some(bytes);
            return true;
        }
        link.send(udp, bytes.clone(), to, &f);
        if let Some(h) = held.take() {
            link.send(udp, h, to, &f);
        }
        if every(f.duplicate_every) {
            link.send(udp, bytes, to, &f);
        }
        true
    }
}
