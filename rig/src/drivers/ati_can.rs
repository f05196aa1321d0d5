//! ATI Net F/T over CAN, short-data mode (manual 9620-05-Net FT §15; spec `devices.md`
//! §1b(i)): a request byte `0x02` at the base id; the box answers with two frames,
//! base+5 = Fx, Tx, Fy, Ty and base+6 = Fz, Tz, status, sample number, each an i16,
//! **little-endian**. `0x04` biases. A new request aborts a reply in progress, so one
//! request is outstanding at a time. Counts per unit come from the rig file (the box's
//! configuration; CAN short data carries no calibration query), never a built-in constant.

use std::time::Duration;

use async_trait::async_trait;

use super::can::{CanBus, RawFrame};
use crate::device::{ForceInfo, ForceRange, ForceSample, ForceSensor, STATUS_SATURATED, Wrench};
use crate::{Clock, RigError};

/// Request byte: short data.
pub const REQ_SHORT: u8 = 0x02;
/// Request byte: bias.
pub const REQ_BIAS: u8 = 0x04;

/// How to reach the box.
#[derive(Debug, Clone, PartialEq)]
pub struct AtiCanSettings {
    /// Base id (DIP switches).
    pub base_id: u32,
    /// Counts per N in short data.
    pub counts_per_n: f64,
    /// Counts per N·mm in short data.
    pub counts_per_nmm: f64,
    /// Reply timeout.
    pub timeout: Duration,
    /// Extra attempts after a missing or incomplete reply.
    pub retries: u32,
    /// Sensor ranges.
    pub range: ForceRange,
}

/// The driver.
pub struct AtiCanSensor {
    info: ForceInfo,
    s: AtiCanSettings,
    bus: Box<dyn CanBus>,
    clock: Clock,
    seq_epoch: u64,
    last_seq: Option<u16>,
}

fn i16s(f: &RawFrame) -> [i16; 4] {
    std::array::from_fn(|k| i16::from_le_bytes([f.data[2 * k], f.data[2 * k + 1]]))
}

impl AtiCanSensor {
    /// A sensor on `bus`; asks once for a reading to prove the box answers.
    pub async fn open(
        s: AtiCanSettings,
        bus: Box<dyn CanBus>,
        clock: Clock,
    ) -> Result<Self, RigError> {
        let mut me = Self {
            info: ForceInfo {
                model: "Net F/T (CAN)".into(),
                range: s.range,
                max_rate_hz: 1000.0,
                identity: format!(
                    "ATI Net F/T on CAN base id {:#x}, {} counts/N, {} counts/N·mm",
                    s.base_id, s.counts_per_n, s.counts_per_nmm
                ),
            },
            s,
            bus,
            clock,
            seq_epoch: 0,
            last_seq: None,
        };
        me.read().await?;
        Ok(me)
    }

    fn name(&self) -> String {
        format!("ATI Net F/T on CAN base id {:#x}", self.s.base_id)
    }

    /// Software bias.
    pub async fn bias(&mut self) -> Result<(), RigError> {
        self.bus
            .send(RawFrame::new(self.s.base_id, &[REQ_BIAS]))
            .await
    }

    async fn one(&mut self) -> Result<Option<([i16; 4], [i16; 4])>, RigError> {
        self.bus
            .send(RawFrame::new(self.s.base_id, &[REQ_SHORT]))
            .await?;
        let (mut a, mut b) = (None, None);
        let wait = async {
            while a.is_none() || b.is_none() {
                let f = self.bus.recv().await?;
                if f.id == self.s.base_id + 5 && f.len == 8 {
                    a = Some(i16s(&f));
                } else if f.id == self.s.base_id + 6 && f.len == 8 {
                    b = Some(i16s(&f));
                }
            }
            Ok::<_, RigError>(())
        };
        match tokio::time::timeout(self.s.timeout, wait).await {
            Ok(r) => r?,
            Err(_) => return Ok(None),
        }
        Ok(a.zip(b))
    }
}

#[async_trait]
impl ForceSensor for AtiCanSensor {
    fn info(&self) -> &ForceInfo {
        &self.info
    }

    async fn read(&mut self) -> Result<ForceSample, RigError> {
        for _ in 0..=self.s.retries {
            let Some((a, b)) = self.one().await? else {
                continue;
            };
            let t_ns = self.clock.now_ns();
            let seq = b[3] as u16;
            if let Some(last) = self.last_seq
                && seq < last
            {
                self.seq_epoch += 1 << 16;
            }
            self.last_seq = Some(seq);
            let (n, t) = (1.0 / self.s.counts_per_n, 1.0 / self.s.counts_per_nmm);
            let status = b[2] as u16 as u32;
            return Ok(ForceSample {
                t_ns,
                ft_seq: self.seq_epoch + seq as u64,
                wrench: Wrench {
                    fx_n: a[0] as f64 * n,
                    tx_nmm: a[1] as f64 * t,
                    fy_n: a[2] as f64 * n,
                    ty_nmm: a[3] as f64 * t,
                    fz_n: b[0] as f64 * n,
                    tz_nmm: b[1] as f64 * t,
                },
                // Any status bit means the reading is not trustworthy (out of range,
                // gauge fault): flagged like a saturated sample.
                status: if status != 0 {
                    status | STATUS_SATURATED
                } else {
                    0
                },
            });
        }
        Err(RigError::Timeout {
            device: format!("{} (no complete reply)", self.name()),
            timeout_ms: self.s.timeout.as_millis() as u64,
        })
    }
}
