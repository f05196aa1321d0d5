//! An ATI Net F/T answering short-data requests on a CAN bus (spec `devices.md` §5,
//! "DAQ / CAN F/T"): little-endian i16 replies at base+5 and base+6 after about 1 ms;
//! `0x04` biases; a new request aborts the reply in progress. Faults: no reply, only the
//! first of the two frames, a status word.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use crate::device::Wrench;
use crate::drivers::ati_can::{REQ_BIAS, REQ_SHORT};
use crate::drivers::can::{CanBus, RawFrame};
use crate::lock;

/// Faults to inject.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Faults {
    /// Ignore requests.
    pub no_reply: bool,
    /// Send only the first frame of each reply.
    pub half_reply: bool,
    /// Status word to report (0: OK).
    pub status: u16,
}

/// The twin's handles.
pub struct AtiCanTwin {
    /// The load the box reads.
    pub load: Arc<Mutex<Wrench>>,
    /// Fault switches.
    pub faults: Arc<Mutex<Faults>>,
    task: tokio::task::JoinHandle<()>,
}

impl Drop for AtiCanTwin {
    fn drop(&mut self) {
        self.task.abort();
    }
}

impl AtiCanTwin {
    /// Serves on `bus` (a tokio task) with `counts_per_n` and `counts_per_nmm`.
    pub fn spawn(
        bus: Box<dyn CanBus>,
        base_id: u32,
        counts_per_n: f64,
        counts_per_nmm: f64,
    ) -> Self {
        let load = Arc::new(Mutex::new(Wrench::default()));
        let faults = Arc::new(Mutex::new(Faults::default()));
        let (l, f) = (load.clone(), faults.clone());
        let task = tokio::spawn(async move {
            let mut bias = Wrench::default();
            let mut sample: u16 = 0;
            while let Ok(req) = bus.recv().await {
                if req.id != base_id || req.len < 1 {
                    continue;
                }
                let faults = lock(&f).clone();
                match req.data[0] {
                    REQ_BIAS => bias = *lock(&l),
                    REQ_SHORT if !faults.no_reply => {
                        tokio::time::sleep(Duration::from_millis(1)).await;
                        let w = lock(&l).minus(&bias);
                        let c = |v: f64, per: f64| {
                            ((v * per).round().clamp(-32768.0, 32767.0) as i16).to_le_bytes()
                        };
                        let frame = |id: u32, v: [[u8; 2]; 4]| RawFrame::new(id, &v.concat());
                        sample = sample.wrapping_add(1);
                        let a = frame(
                            base_id + 5,
                            [
                                c(w.fx_n, counts_per_n),
                                c(w.tx_nmm, counts_per_nmm),
                                c(w.fy_n, counts_per_n),
                                c(w.ty_nmm, counts_per_nmm),
                            ],
                        );
                        let b = frame(
                            base_id + 6,
                            [
                                c(w.fz_n, counts_per_n),
                                c(w.tz_nmm, counts_per_nmm),
                                faults.status.to_le_bytes(),
                                sample.to_le_bytes(),
                            ],
                        );
                        if bus.send(a).await.is_err() {
                            return;
                        }
                        if !faults.half_reply && bus.send(b).await.is_err() {
                            return;
                        }
                    }
                    _ => {}
                }
            }
        });
        Self { load, faults, task }
    }
}
