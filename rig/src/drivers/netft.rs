//! ATI Net F/T (Nano17 and others) over RDT/UDP, with the calibration read from the box.
//!
//! On open the driver reads counts-per-force and counts-per-torque and their units from
//! the box (READCALINFO over TCP) — never a hard-coded 1e6 — then starts real-time
//! streaming. `read` drains every datagram that arrived and returns the newest record.
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

use std::net::SocketAddr;
use std::time::Duration;

use async_trait::async_trait;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpStream, UdpSocket};

use super::netft_rdt::{
    CMD_BIAS, CMD_START, CMD_STOP, CalInfo, READCALINFO, Record, STATUS_ERROR, STATUS_OUT_OF_RANGE,
    request,
};
use crate::device::{ForceInfo, ForceRange, ForceSample, ForceSensor, STATUS_SATURATED, Wrench};
use crate::{Clock, RigError};

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

/// The driver.
pub struct NetFtSensor {
    info: ForceInfo,
    settings: NetFtSettings,
    socket: UdpSocket,
    n_per_count: f64,
    nmm_per_count: f64,
    last_rdt: Option<u32>,
    /// Wall time of the last accepted record, for the explainable gap.
    last_at: Option<std::time::Instant>,
    ft_epoch: u64,
    last_ft: Option<u32>,
    latest: Option<ForceSample>,
    clock: Clock,
    /// Loss and reordering so far.
    pub stats: StreamStats,
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
        let socket = UdpSocket::bind(if settings.rdt.is_ipv4() {
            "0.0.0.0:0"
        } else {
            "[::]:0"
        })
        .await
        .map_err(io)?;
        socket.connect(settings.rdt).await.map_err(io)?;
        let mut s = Self {
            info: ForceInfo {
                model: "Net F/T".into(),
                range: settings.range,
                max_rate_hz: 7000.0,
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
            n_per_count,
            nmm_per_count,
            last_rdt: None,
            last_at: None,
            ft_epoch: 0,
            last_ft: None,
            latest: None,
            clock,
            stats: StreamStats::default(),
        };
        s.start().await?;
        Ok(s)
    }

    /// Sends the start request until a record arrives (bounded).
    async fn start(&mut self) -> Result<(), RigError> {
        let dev = name(&self.settings);
        for _ in 0..=self.settings.retries {
            self.socket
                .send(&request(CMD_START, 0))
                .await
                .map_err(|source| RigError::Io {
                    device: dev.clone(),
                    source,
                })?;
            let per_try = self.settings.timeout / (self.settings.retries + 1).max(1);
            if tokio::time::timeout(per_try, self.receive(true))
                .await
                .is_ok_and(|r| r.is_ok())
                && self.latest.is_some()
            {
                return Ok(());
            }
        }
        Err(RigError::Timeout {
            device: format!("{dev} (no records after the start request)"),
            timeout_ms: self.settings.timeout.as_millis() as u64,
        })
    }

    /// Zeroes the box's reading at the current load (software bias).
    pub async fn bias(&mut self) -> Result<(), RigError> {
        let dev = name(&self.settings);
        self.socket
            .send(&request(CMD_BIAS, 0))
            .await
            .map(|_| ())
            .map_err(|source| RigError::Io {
                device: dev,
                source,
            })
    }

    /// Stops the stream.
    pub async fn stop(&mut self) -> Result<(), RigError> {
        let dev = name(&self.settings);
        self.socket
            .send(&request(CMD_STOP, 0))
            .await
            .map(|_| ())
            .map_err(|source| RigError::Io {
                device: dev,
                source,
            })
    }

    /// Takes in datagrams: waits for one if `wait`, then drains what is queued. A datagram
    /// that is not whole records, or a record the sequence cannot explain, ends the call
    /// with an error (the rest of the queue is taken by the next call).
    async fn receive(&mut self, wait: bool) -> Result<(), RigError> {
        let dev = name(&self.settings);
        let mut buf = [0u8; 36 * 40];
        let mut first = wait;
        loop {
            let n = if first {
                first = false;
                self.socket.recv(&mut buf).await
            } else {
                match self.socket.try_recv(&mut buf) {
                    Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => return Ok(()),
                    r => r,
                }
            };
            let n = match n {
                Ok(n) => n,
                // A refused send (nothing listening) reads back as an error: report it.
                Err(source) => {
                    return Err(RigError::Io {
                        device: dev.clone(),
                        source,
                    });
                }
            };
            let t_ns = self.clock.now_ns();
            let Some(records) = Record::parse_all(&buf[..n]) else {
                self.stats.malformed += 1;
                return Err(RigError::Garbled {
                    device: dev,
                    detail: format!(
                        "a datagram of {n} bytes is not whole 36-byte RDT records; \
                         fix: check that nothing else sends to this port"
                    ),
                });
            };
            for r in records {
                self.take(r, t_ns).map_err(|detail| RigError::Garbled {
                    device: dev.clone(),
                    detail,
                })?;
            }
        }
    }

    fn take(&mut self, r: Record, t_ns: u64) -> Result<(), String> {
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
        let c = r.counts.map(f64::from);
        let saturated = r.status & (STATUS_OUT_OF_RANGE | STATUS_ERROR) != 0;
        self.latest = Some(ForceSample {
            t_ns,
            ft_seq: self.ft_epoch + r.ft_seq as u64,
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
        });
        Ok(())
    }
}

#[async_trait]
impl ForceSensor for NetFtSensor {
    fn info(&self) -> &ForceInfo {
        &self.info
    }

    fn records_lost(&self) -> u64 {
        self.stats.lost
    }

    async fn read(&mut self) -> Result<ForceSample, RigError> {
        let before = self.stats.received;
        self.receive(false).await?;
        // Nothing new queued: wait for the next record, boundedly. Reordered or duplicate
        // records are no news; only a newer record ends the wait.
        let deadline = tokio::time::Instant::now() + self.settings.timeout;
        while self.stats.received == before {
            match tokio::time::timeout_at(deadline, self.receive(true)).await {
                Ok(r) => r?,
                Err(_) => {
                    return Err(RigError::Timeout {
                        device: format!("{} (stream stopped)", name(&self.settings)),
                        timeout_ms: self.settings.timeout.as_millis() as u64,
                    });
                }
            }
        }
        self.latest.ok_or_else(|| RigError::Timeout {
            device: name(&self.settings),
            timeout_ms: self.settings.timeout.as_millis() as u64,
        })
    }
}
