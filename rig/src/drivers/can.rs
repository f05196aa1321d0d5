//! CAN transport behind a trait: the ATI framing code never sees the bus implementation.
//! [`MemBus`] is an in-memory hub (tests and twins; this machine has no vcan), and
//! `SocketCanBus` (feature `socketcan`) is a Linux SocketCAN interface.

use std::sync::Arc;
use std::sync::atomic::{AtomicU32, AtomicU64, Ordering};

use async_trait::async_trait;
use tokio::sync::broadcast;

use crate::RigError;

/// A classic CAN frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RawFrame {
    /// Identifier (11 or 29 bits).
    pub id: u32,
    /// Extended (29-bit) identifier.
    pub ext: bool,
    /// Data length, 0–8.
    pub len: u8,
    /// Payload (first `len` bytes).
    pub data: [u8; 8],
}

impl RawFrame {
    /// A standard data frame.
    pub fn new(id: u32, payload: &[u8]) -> Self {
        let mut data = [0u8; 8];
        let len = payload.len().min(8);
        data[..len].copy_from_slice(&payload[..len]);
        Self {
            id,
            ext: false,
            len: len as u8,
            data,
        }
    }
}

/// A CAN bus endpoint.
#[async_trait]
pub trait CanBus: Send + Sync {
    /// Sends a frame.
    async fn send(&self, f: RawFrame) -> Result<(), RigError>;
    /// Waits for the next frame from another node.
    async fn recv(&self) -> Result<RawFrame, RigError>;
}

/// An in-memory bus: every frame sent by one endpoint reaches all others.
#[derive(Debug, Clone)]
pub struct MemBus {
    tx: broadcast::Sender<(u64, RawFrame)>,
    next: Arc<AtomicU64>,
    /// Drop every Nth frame on the bus (0: none), to test loss.
    pub drop_every: Arc<AtomicU32>,
    sent: Arc<AtomicU32>,
}

impl Default for MemBus {
    fn default() -> Self {
        Self::new()
    }
}

impl MemBus {
    /// A new, empty bus.
    pub fn new() -> Self {
        let (tx, _) = broadcast::channel(1024);
        Self {
            tx,
            next: Arc::new(AtomicU64::new(1)),
            drop_every: Arc::new(AtomicU32::new(0)),
            sent: Arc::new(AtomicU32::new(0)),
        }
    }

    /// A new node on the bus.
    pub fn endpoint(&self) -> MemEndpoint {
        MemEndpoint {
            bus: self.clone(),
            me: self.next.fetch_add(1, Ordering::Relaxed),
            rx: tokio::sync::Mutex::new(self.tx.subscribe()),
        }
    }
}

/// One node of a [`MemBus`].
#[derive(Debug)]
pub struct MemEndpoint {
    bus: MemBus,
    me: u64,
    rx: tokio::sync::Mutex<broadcast::Receiver<(u64, RawFrame)>>,
}

#[async_trait]
impl CanBus for MemEndpoint {
    async fn send(&self, f: RawFrame) -> Result<(), RigError> {
        let k = self.bus.sent.fetch_add(1, Ordering::Relaxed) + 1;
        let every = self.bus.drop_every.load(Ordering::Relaxed);
        if every > 0 && k.is_multiple_of(every) {
            return Ok(());
        }
        // No receiver yet is not an error on a real bus either (nobody acknowledges).
        let _ = self.bus.tx.send((self.me, f));
        Ok(())
    }

    async fn recv(&self) -> Result<RawFrame, RigError> {
        let mut rx = self.rx.lock().await;
        loop {
            match rx.recv().await {
                Ok((from, f)) if from != self.me => return Ok(f),
                Ok(_) | Err(broadcast::error::RecvError::Lagged(_)) => continue,
                Err(broadcast::error::RecvError::Closed) => {
                    return Err(RigError::Io {
                        device: "in-memory CAN bus".into(),
                        source: std::io::Error::other("the bus closed"),
                    });
                }
            }
        }
    }
}

/// A SocketCAN interface (`can0`); the bus adapter must be up (`ip link set can0 up type
/// can bitrate 1000000`).
#[cfg(feature = "socketcan")]
pub struct SocketCanBus {
    sock: socketcan::tokio::CanSocket,
    name: String,
}

#[cfg(feature = "socketcan")]
impl SocketCanBus {
    /// Opens interface `name`.
    pub fn open(name: &str) -> Result<Self, RigError> {
        let sock = socketcan::tokio::CanSocket::open(name).map_err(|e| RigError::Io {
            device: format!("CAN interface {name}"),
            source: std::io::Error::other(format!("{e}; fix: check `ip link show {name}`")),
        })?;
        Ok(Self {
            sock,
            name: name.to_string(),
        })
    }
}

#[cfg(feature = "socketcan")]
#[async_trait]
impl CanBus for SocketCanBus {
    async fn send(&self, f: RawFrame) -> Result<(), RigError> {
        use socketcan::{EmbeddedFrame, StandardId};
        let id = StandardId::new(f.id as u16).ok_or_else(|| RigError::Unsupported {
            device: self.name.clone(),
            detail: format!("id {:#x} is not 11-bit", f.id),
        })?;
        let frame = socketcan::CanFrame::new(id, &f.data[..f.len as usize]).ok_or_else(|| {
            RigError::Unsupported {
                device: self.name.clone(),
                detail: "frame longer than 8 bytes".into(),
            }
        })?;
        self.sock
            .write_frame(frame)
            .await
            .map_err(|source| RigError::Io {
                device: self.name.clone(),
                source,
            })
    }

    async fn recv(&self) -> Result<RawFrame, RigError> {
        use socketcan::{EmbeddedFrame, Frame};
        let f = self
            .sock
            .read_frame()
            .await
            .map_err(|source| RigError::Io {
                device: self.name.clone(),
                source,
            })?;
        Ok(RawFrame {
            ext: f.is_extended(),
            ..RawFrame::new(f.raw_id(), f.data())
        })
    }
}
