//! ATI Net F/T (Nano17 and others) over RDT/UDP, with the calibration read from the box.
//!
//! On open the driver reads counts-per-force and counts-per-torque and their units from
//! the box (READCALINFO over TCP) — never a hard-coded 1e6 — then starts real-time
//! streaming. A task of the driver's own receives the stream and stamps each datagram as it
//! arrives; `read` returns the newest record, and [`ForceSensor::take_received`] every record.
//! Loss and reordering are counted as netft_utils does, `seqdiff = (i32)(rdt − last)`, but
//! only within what the stream can explain: a gap of `seqdiff − 1` lost records must fit
//! the time since the last record at the box's highest rate, and a late record must be
//! within a small reordering window. Anything else — one record whose sequence jumps by
//! 2³¹, say — is a sequence the driver cannot explain, and `read` reports it instead of
//! taking every later record for a stale one and repeating the last good value (which
//! once left the safety monitor reading 0 N while the sensor read 100 N). A datagram that
//! is not whole 36-byte records is reported the same way, and `read` never returns a
//! sample it returned before: no new record within the timeout is a timeout. The box's
//! `ft_sequence` is unwrapped to 64 bits (it is the sensor's own clock). Status bits 30/31
//! (out of range, error) surface as [`STATUS_SATURATED`] on the sample.
//!
//! **Sample times.** A record's arrival is late by the network's delay, which varies by
//! milliseconds. The box's sample counter is its own clock: the driver fits it against the
//! arrival times ([`CounterClock`], the lower envelope) and stamps each sample with when the
//! box took it, less a latency calibrated per setup ([`NetFtSettings::latency_s`]); until
//! the model has seen 2 s of records, samples carry their arrival time less that latency.

use std::collections::VecDeque;
use std::net::SocketAddr;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use async_trait::async_trait;
use std::sync::atomic::{AtomicBool, Ordering};
use tokio::io::{AsyncReadExt, AsyncWriteExt};

use tokio::net::TcpStream;
use tokio::sync::Notify;

use super::netft_rdt::{
    CMD_BIAS, CMD_START, CMD_STOP, CalInfo, READCALINFO, Record, STATUS_ERROR, STATUS_OUT_OF_RANGE,
    request,
};
use crate::clock_sync::CounterClock;
use crate::device::{
    DeviceTiming, ForceInfo, ForceRange, ForceSample, ForceSensor, STATUS_SATURATED, Wrench,
};
use crate::{Clock, RigError, lock};

/// Where the box is.
#[derive(Debug, Clone, PartialEq)]
pub struct NetFtSettings {
    /// RDT address (port 49152 on a real box).
    pub rdt: SocketAddr,
    /// Calibration address (TCP port 49151 on a real box).
    pub calibration: SocketAddr,
    /// How long to wait for the first record or a reply.
    pub timeout: Duration,
    /// Start requests sent before giving up (netft_utils retries 10×).
    pub retries: u32,
    /// Sensor ranges (Nano17: 70 N axial, 50 N tangential, 500 N·mm).
    pub range: ForceRange,
    /// The constant delay of records on their way to the host, s: subtracted from every
    /// sample time. No model of arrival times can tell it from a clock offset, so it is
    /// calibrated per setup (an event both the camera and the sensor see); 0 if unknown.
    pub latency_s: f64,
}

/// Stream health counters.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct StreamStats {
    /// Records received and used.
    pub received: u64,
    /// Records missing from the sequence.
    pub lost: u64,
    /// Records that arrived after a newer one (dropped).
    pub out_of_order: u64,
    /// Records whose sequence number the stream could not explain (reported).
    pub jumps: u64,
    /// Datagrams that were not whole records (reported).
    pub malformed: u64,
}

/// The box streams at most 7000 records/s (manual 9620-05-Net FT, RDT rates).
const MAX_RATE_HZ: f64 = 7000.0;
/// Records a reordering can put behind a newer one (UDP on a local link reorders by a few).
const REORDER_WINDOW: i64 = 64;

/// The largest forward step of `rdt_sequence` that loss can explain after `elapsed_s`:
/// every record the box could have sent meanwhile, twice over, plus a margin for records
/// queued in the socket before the clock was read.
fn explainable_gap(elapsed_s: f64) -> i64 {
    (elapsed_s.max(0.0) * MAX_RATE_HZ * 2.0) as i64 + 256
}

/// Samples kept for [`ForceSensor::take_received`] when nobody takes them: 10 s at 7 kHz.
const RECEIVED_KEPT: usize = 70_000;
/// The receive buffer asked for, bytes.
const RECEIVE_BUFFER_BYTES: usize = 4 << 20;
/// Errors kept for `read` (the stream goes on; the first ones say what happened).
const ERRORS_KEPT: usize = 16;

/// The box's sample counter, `ft_sequence`, counts at its internal rate (7000 Hz, manual
/// 9620-05-Net FT), fitted over 20 s in bins of 0.1 s (BENCHMARKS.md, "F/T clock model":
/// 6 µs worst error under 2 ms latency, ±5 ms jitter and 50 ppm drift, 12 ns per sample).
fn ft_clock(latency_ns: f64) -> CounterClock {
    CounterClock::new(MAX_RATE_HZ, 0.1, 20.0).with_known_latency_ns(latency_ns)
}

/// What the receive task has taken in, shared with `read`.
struct Stream {
    last_rdt: Option<u32>,
    /// Wall time of the last accepted record, for the explainable gap.
    last_at: Option<std::time::Instant>,
    ft_epoch: u64,
    last_ft: Option<u32>,
    latest: Option<ForceSample>,
    /// Samples not yet taken by [`ForceSensor::take_received`] (bounded).
    received: VecDeque<ForceSample>,
    /// Errors not yet reported by `read`, oldest first (bounded).
    errors: VecDeque<RigError>,
    /// The box's sample counter against arrival times: samples are stamped with when they
    /// were taken, not when their datagram came in.
    ft_clock: CounterClock,
    /// The last sample time given (times never go back).
    last_t_ns: u64,
    latency_ns: u64,
    stamped_on_arrival: u64,
    stats: StreamStats,
    n_per_count: f64,
    nmm_per_count: f64,
}

/// The driver. A task of its own receives the stream and stamps each datagram the moment
/// it arrives (a stamp taken when the runner next reads would be late by up to a read
/// period, and the clock model would inherit that); `read` takes what it has gathered.
pub struct NetFtSensor {
    info: ForceInfo,
    settings: NetFtSettings,
    socket: Arc<std::net::UdpSocket>,
    stream: Arc<Mutex<Stream>>,
    news: Arc<Notify>,
    /// Ends the receive thread (within its 100 ms read timeout).
    quit: Arc<AtomicBool>,
    _receiver: std::thread::JoinHandle<()>,
    /// `stats.received` when `read` last returned a sample.
    returned: u64,
}

/// `host` or `host:port` (default `port`) to a socket address.
pub fn resolve(address: &str, port: u16) -> Result<SocketAddr, RigError> {
    use std::net::ToSocketAddrs;
    let with_port = if address.contains(':') {
        address.to_string()
    } else {
        format!("{address}:{port}")
    };
    with_port
        .to_socket_addrs()
        .ok()
        .and_then(|mut a| a.next())
        .ok_or_else(|| RigError::Unsupported {
            device: format!("Net F/T at {address}"),
            detail:
                "the address does not resolve; fix: write `address: 192.168.1.1` or `host:port`"
                    .into(),
        })
}

fn name(s: &NetFtSettings) -> String {
    format!("Net F/T at {}", s.rdt)
}

impl NetFtSensor {
    /// Reads the calibration, binds a UDP socket and starts streaming.
    pub async fn open(settings: NetFtSettings, clock: Clock) -> Result<Self, RigError> {
        let dev = name(&settings);
        let io = |source: std::io::Error| RigError::Io {
            device: dev.clone(),
            source,
        };
        let timeout = |what: &str| RigError::Timeout {
            device: format!("{dev} ({what})"),
            timeout_ms: settings.timeout.as_millis() as u64,
        };
        let cal = tokio::time::timeout(settings.timeout, async {
            let mut tcp = TcpStream::connect(settings.calibration).await?;
            tcp.write_all(&READCALINFO).await?;
            let mut b = [0u8; 24];
            tcp.read_exact(&mut b).await?;
            Ok::<_, std::io::Error>(b)
        })
        .await
        .map_err(|_| timeout("calibration"))?
        .map_err(io)?;
        let cal = CalInfo::parse(&cal).map_err(|detail| RigError::Garbled {
            device: dev.clone(),
            detail,
        })?;
        let (n_per_count, nmm_per_count) = cal.scales().map_err(|detail| RigError::Garbled {
            device: dev.clone(),
            detail,
        })?;
        let socket = std::net::UdpSocket::bind(if settings.rdt.is_ipv4() {
            "0.0.0.0:0"
        } else {
            "[::]:0"
        })
        .map_err(io)?;
        socket.connect(settings.rdt).map_err(io)?;
        // At 7 kHz the default receive buffer (~200 small datagrams) holds 30 ms: room for
        // seconds (the kernel caps it at net.core.rmem_max).
        let _ = socket2::SockRef::from(&socket).set_recv_buffer_size(RECEIVE_BUFFER_BYTES);
        socket
            .set_read_timeout(Some(Duration::from_millis(100)))
            .map_err(io)?;
        let socket = Arc::new(socket);
        let latency_ns = (settings.latency_s.max(0.0) * 1e9).round() as u64;
        let stream = Arc::new(Mutex::new(Stream {
            last_rdt: None,
            last_at: None,
            ft_epoch: 0,
            last_ft: None,
            latest: None,
            received: VecDeque::new(),
            errors: VecDeque::new(),
            ft_clock: ft_clock(latency_ns as f64),
            last_t_ns: 0,
            latency_ns,
            stamped_on_arrival: 0,
            stats: StreamStats::default(),
            n_per_count,
            nmm_per_count,
        }));
        let news = Arc::new(Notify::new());
        let quit = Arc::new(AtomicBool::new(false));
        let receiver = {
            let (socket, stream, news, quit) = (
                Arc::clone(&socket),
                Arc::clone(&stream),
                Arc::clone(&news),
                Arc::clone(&quit),
            );
            let dev = dev.clone();
            std::thread::Builder::new()
                .name("netft-receive".into())
                .spawn(move || receive(&socket, &stream, &news, &quit, &clock, &dev))
                .map_err(io)?
        };
        let mut s = Self {
            info: ForceInfo {
                model: "Net F/T".into(),
                range: settings.range,
                max_rate_hz: MAX_RATE_HZ,
                identity: {
                    let (fu, tu) = cal.unit_names();
                    format!(
                        "{dev}, {} counts per {fu}, {} counts per {tu}",
                        cal.counts_per_force, cal.counts_per_torque
                    )
                },
            },
            settings,
            socket,
            stream,
            news,
            quit,
            _receiver: receiver,
            returned: 0,
        };
        s.start().await?;
        Ok(s)
    }

    /// Loss and reordering so far.
    pub fn stats(&self) -> StreamStats {
        lock(&self.stream).stats
    }

    /// Sends the start request until a record arrives (bounded).
    async fn start(&mut self) -> Result<(), RigError> {
        let dev = name(&self.settings);
        let per_try = self.settings.timeout / (self.settings.retries + 1).max(1);
        for _ in 0..=self.settings.retries {
            let news = self.news.notified();
            tokio::pin!(news);
            news.as_mut().enable();
            self.send(CMD_START).await?;
            let deadline = tokio::time::Instant::now() + per_try;
            loop {
                {
                    let mut st = lock(&self.stream);
                    // A refused request (nothing listening) is worth another try; the
                    // last try's error is the one reported.
                    st.errors.clear();
                    if st.latest.is_some() {
                        return Ok(());
                    }
                }
                if tokio::time::timeout_at(deadline, news.as_mut())
                    .await
                    .is_err()
                {
                    break;
                }
                news.set(self.news.notified());
                news.as_mut().enable();
            }
        }
        Err(RigError::Timeout {
            device: format!("{dev} (no records after the start request)"),
            timeout_ms: self.settings.timeout.as_millis() as u64,
        })
    }

    async fn send(&self, command: u16) -> Result<(), RigError> {
        self.socket
            .send(&request(command, 0))
            .map(|_| ())
            .map_err(|source| RigError::Io {
                device: name(&self.settings),
                source,
            })
    }

    /// Zeroes the box's reading at the current load (software bias).
    pub async fn bias(&mut self) -> Result<(), RigError> {
        self.send(CMD_BIAS).await
    }

    /// Stops the stream.
    pub async fn stop(&mut self) -> Result<(), RigError> {
        self.send(CMD_STOP).await
    }
}

impl Drop for NetFtSensor {
    fn drop(&mut self) {
        self.quit.store(true, Ordering::Relaxed);
    }
}

/// The receive thread: stamps each datagram on arrival and takes its records in. A
/// datagram that is not whole records, or a record the sequence cannot explain, is kept as
/// an error for `read`; the stream goes on. A thread, not a task: a stamp must not wait for
/// an async runtime busy with something else (rendering a frame, encoding a PNG).
fn receive(
    socket: &std::net::UdpSocket,
    stream: &Mutex<Stream>,
    news: &Notify,
    quit: &AtomicBool,
    clock: &Clock,
    dev: &str,
) {
    let mut buf = [0u8; 36 * 40];
    while !quit.load(Ordering::Relaxed) {
        let got = socket.recv(&mut buf);
        let t_ns = clock.now_ns();
        if let Err(e) = &got
            && matches!(
                e.kind(),
                std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
            )
        {
            continue;
        }
        let mut st = lock(stream);
        let error = match got {
            // A refused send (nothing listening) reads back as an error: report it.
            Err(source) => Some(RigError::Io {
                device: dev.to_string(),
                source,
            }),
            Ok(n) => match Record::parse_all(&buf[..n]) {
                None => {
                    st.stats.malformed += 1;
                    Some(RigError::Garbled {
                        device: dev.to_string(),
                        detail: format!(
                            "a datagram of {n} bytes is not whole 36-byte RDT records; \
                             fix: check that nothing else sends to this port"
                        ),
                    })
                }
                Some(records) => records
                    .into_iter()
                    .find_map(|r| st.take(r, t_ns).err())
                    .map(|detail| RigError::Garbled {
                        device: dev.to_string(),
                        detail,
                    }),
            },
        };
        if let Some(e) = error
            && st.errors.len() < ERRORS_KEPT
        {
            st.errors.push_back(e);
        }
        drop(st);
        news.notify_waiters();
    }
}

impl Stream {
    fn take(&mut self, r: Record, arrival_ns: u64) -> Result<(), String> {
        let now = std::time::Instant::now();
        if let (Some(last), Some(at), Some(last_ft)) = (self.last_rdt, self.last_at, self.last_ft) {
            let d = i64::from(r.rdt_seq.wrapping_sub(last) as i32);
            if d < 1 && d > -REORDER_WINDOW {
                self.stats.out_of_order += 1;
                return Ok(());
            }
            // Loss is explained by the time since the last record, or by the box's own
            // sample counter: it advances at least once per record sent, so records lost
            // while nobody read the socket (it holds a few hundred) show in both counters.
            let elapsed_s = now.duration_since(at).as_secs_f64();
            let ft_advance = i64::from(r.ft_seq.wrapping_sub(last_ft) as i32);
            let max_gap = explainable_gap(elapsed_s).max(ft_advance.saturating_add(64));
            if d < 1 || d > max_gap {
                self.stats.jumps += 1;
                return Err(format!(
                    "the RDT sequence jumped from {last} to {} ({d:+} records {:.0} ms after the \
                     last one, the sample counter {ft_advance:+}: at most {max_gap} can be lost); \
                     fix: check that only one program streams from this box, then restart the run",
                    r.rdt_seq,
                    elapsed_s * 1e3
                ));
            }
            self.stats.lost += (d - 1) as u64;
        }
        self.last_rdt = Some(r.rdt_seq);
        self.last_at = Some(now);
        if let Some(last) = self.last_ft
            && r.ft_seq < last
        {
            self.ft_epoch += 1 << 32;
        }
        self.last_ft = Some(r.ft_seq);
        self.stats.received += 1;
        let seq = self.ft_epoch + r.ft_seq as u64;
        self.ft_clock.observe(seq, arrival_ns);
        // Once the model has seen enough, the sample's time is when it was taken (never
        // after it arrived, never before the previous one); until then, its arrival less
        // the known latency.
        let t_ns = match self.ft_clock.time_of(seq) {
            Some(t) => t.min(arrival_ns),
            None => {
                self.stamped_on_arrival += 1;
                arrival_ns.saturating_sub(self.latency_ns)
            }
        }
        .max(self.last_t_ns);
        self.last_t_ns = t_ns;
        let c = r.counts.map(f64::from);
        let saturated = r.status & (STATUS_OUT_OF_RANGE | STATUS_ERROR) != 0;
        let sample = ForceSample {
            t_ns,
            ft_seq: seq,
            wrench: Wrench {
                fx_n: c[0] * self.n_per_count,
                fy_n: c[1] * self.n_per_count,
                fz_n: c[2] * self.n_per_count,
                tx_nmm: c[3] * self.nmm_per_count,
                ty_nmm: c[4] * self.nmm_per_count,
                tz_nmm: c[5] * self.nmm_per_count,
            },
            status: if saturated {
                r.status | STATUS_SATURATED
            } else {
                r.status
            },
        };
        if self.received.len() >= RECEIVED_KEPT {
            self.received.pop_front();
        }
        self.received.push_back(sample);
        self.latest = Some(sample);
        Ok(())
    }
}

#[async_trait]
impl ForceSensor for NetFtSensor {
    fn info(&self) -> &ForceInfo {
        &self.info
    }

    fn records_lost(&self) -> u64 {
        lock(&self.stream).stats.lost
    }

    fn take_received(&mut self) -> Vec<ForceSample> {
        lock(&self.stream).received.drain(..).collect()
    }

    fn timing(&self) -> Option<DeviceTiming> {
        let st = lock(&self.stream);
        Some(DeviceTiming {
            method: "the box's sample counter against arrival times (lower envelope)".into(),
            latency_s: st.latency_ns as f64 * 1e-9,
            drift_ppm: st.ft_clock.drift_ppm(),
            stamped_on_arrival: st.stamped_on_arrival,
        })
    }

    async fn read(&mut self) -> Result<ForceSample, RigError> {
        // Only a record newer than the last one returned ends the wait: reordered or
        // duplicate records are no news. Bounded by the timeout.
        let deadline = tokio::time::Instant::now() + self.settings.timeout;
        loop {
            let news = self.news.notified();
            tokio::pin!(news);
            news.as_mut().enable();
            {
                let mut st = lock(&self.stream);
                if let Some(e) = st.errors.pop_front() {
                    return Err(e);
                }
                if st.stats.received > self.returned
                    && let Some(s) = st.latest
                {
                    self.returned = st.stats.received;
                    return Ok(s);
                }
            }
            if tokio::time::timeout_at(deadline, news).await.is_err() {
                return Err(RigError::Timeout {
                    device: format!("{} (stream stopped)", name(&self.settings)),
                    timeout_ms: self.settings.timeout.as_millis() as u64,
                });
            }
        }
    }
}
