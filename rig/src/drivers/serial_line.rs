//! Line-oriented serial devices (Zaber ASCII, SMC100): opening a port by path and the
//! write-a-command, read-lines-until-the-answer loop both drivers share.

use std::io::{BufRead, BufReader, Write};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use crate::{RigError, lock};

/// An open port with a line reader.
pub(crate) type LinePort = Arc<Mutex<BufReader<Box<dyn serialport::SerialPort>>>>;

/// Opens `path` at `baud` (XON/XOFF when `software_flow`), with a short read timeout so
/// the reply loop can watch its own deadline.
pub(crate) fn open(
    path: &str,
    baud: u32,
    software_flow: bool,
    device: &str,
) -> Result<LinePort, RigError> {
    let flow = if software_flow {
        serialport::FlowControl::Software
    } else {
        serialport::FlowControl::None
    };
    let port = serialport::new(path, baud)
        .flow_control(flow)
        .timeout(Duration::from_millis(20))
        .open()
        .map_err(|e| RigError::Io {
            device: device.to_string(),
            source: std::io::Error::other(format!(
                "{e}; fix: check the `port:` path in the rig file"
            )),
        })?;
    Ok(Arc::new(Mutex::new(BufReader::new(port))))
}

/// A second, write-only handle on an open port: a stop line goes out through it while an
/// exchange on the first handle holds the reader waiting for its reply. A tty serialises
/// whole `write` calls, so the two lines never interleave byte-wise.
pub(crate) type LineWriter = Arc<Mutex<Box<dyn serialport::SerialPort>>>;

/// Clones `port`'s file descriptor into a [`LineWriter`].
pub(crate) fn writer(port: &LinePort, device: &str) -> Result<LineWriter, RigError> {
    let clone = lock(port).get_ref().try_clone().map_err(|e| RigError::Io {
        device: device.to_string(),
        source: std::io::Error::other(format!("cannot open a second handle for stops: {e}")),
    })?;
    Ok(Arc::new(Mutex::new(clone)))
}

/// A stop that writes one line to a serial controller without waiting for its reply (the
/// watchdog's path: SMC100 `1ST`, Zaber `/1 1 stop`), on the writer the axis keeps for it.
pub(crate) struct LineStopper {
    /// The stop command, line ending included.
    pub(crate) line: String,
    pub(crate) writer: LineWriter,
    /// The device, for errors.
    pub(crate) name: String,
}

#[async_trait::async_trait]
impl crate::device::AxisStopper for LineStopper {
    async fn stop_now(&self) -> Result<(), RigError> {
        send_only(&self.writer, self.line.clone(), &self.name).await
    }
}

/// Writes `line` through `w` on the blocking pool, without reading any reply.
pub(crate) async fn send_only(w: &LineWriter, line: String, device: &str) -> Result<(), RigError> {
    let w = w.clone();
    tokio::task::spawn_blocking(move || {
        let mut p = lock(&w);
        p.write_all(line.as_bytes()).and_then(|()| p.flush())
    })
    .await
    .map_err(|e| std::io::Error::other(e.to_string()))
    .and_then(|r| r)
    .map_err(|e| RigError::Io {
        device: device.to_string(),
        source: disconnected(e),
    })
}

/// What a reply loop saw.
pub(crate) enum Outcome<T> {
    /// The answer.
    Answer(T),
    /// Nothing usable before the deadline; the last unreadable line, if any.
    Nothing(Option<String>),
}

/// Longest reply line kept, bytes: every reply of the supported devices fits in a few
/// dozen; a longer one is noise (a wrong baud rate, another device) and is discarded up to
/// its end instead of being buffered whole.
const MAX_LINE: usize = 4096;

/// Writes `line`, then hands every complete, non-empty line read before `timeout` to
/// `judge`: `Ok(Some(answer))` ends the exchange, `Ok(None)` skips the line (not ours),
/// `Err(why)` records it as garbled and keeps reading. Lines are read as bytes (invalid
/// UTF-8 is garbled, not a disconnect) and bounded by [`MAX_LINE`]. I/O errors end it at
/// once.
pub(crate) fn exchange<T>(
    port: &Mutex<BufReader<Box<dyn serialport::SerialPort>>>,
    line: &str,
    timeout: Duration,
    mut judge: impl FnMut(&str) -> Result<Option<T>, String>,
) -> std::io::Result<Outcome<T>> {
    use std::io::ErrorKind::{TimedOut, WouldBlock};
    let mut p = lock(port);
    p.get_mut()
        .write_all(line.as_bytes())
        .and_then(|()| p.get_mut().flush())
        .map_err(disconnected)?;
    let deadline = Instant::now() + timeout;
    let mut buf: Vec<u8> = Vec::new();
    let mut dropped = 0usize;
    let mut garbled = None;
    while Instant::now() < deadline {
        let available = match p.fill_buf() {
            Ok([]) => {
                return Err(std::io::Error::other(
                    "the port closed; fix: check the cable",
                ));
            }
            Ok(b) => b,
            Err(e) if matches!(e.kind(), TimedOut | WouldBlock) => continue,
            Err(e) => return Err(disconnected(e)),
        };
        let (chunk, complete) = match available.iter().position(|&b| b == b'\n') {
            Some(i) => (&available[..=i], true),
            None => (available, false),
        };
        let room = MAX_LINE.saturating_sub(buf.len()).min(chunk.len());
        buf.extend_from_slice(&chunk[..room]);
        dropped += chunk.len() - room;
        let used = chunk.len();
        p.consume(used);
        if !complete {
            continue;
        }
        let bytes = std::mem::take(&mut buf);
        if std::mem::take(&mut dropped) > 0 {
            garbled = Some(format!(
                "a reply line longer than {MAX_LINE} bytes (`{}`)",
                crate::quote(&String::from_utf8_lossy(&bytes))
            ));
            continue;
        }
        let Ok(text) = std::str::from_utf8(&bytes) else {
            garbled = Some(format!(
                "a reply that is not text (`{}`)",
                crate::quote(&String::from_utf8_lossy(&bytes))
            ));
            continue;
        };
        let l = text.trim();
        if l.is_empty() {
            continue;
        }
        match judge(l) {
            Ok(Some(answer)) => return Ok(Outcome::Answer(answer)),
            Ok(None) => {}
            Err(why) => garbled = Some(why),
        }
    }
    Ok(Outcome::Nothing(garbled))
}

/// A write or read that fails outright (EPIPE, EIO: the USB adapter unplugged, or the
/// twin behind a pseudo-terminal stopped) says so and how to recover.
fn disconnected(e: std::io::Error) -> std::io::Error {
    std::io::Error::new(
        e.kind(),
        format!(
            "{e}: the device disconnected; fix: check its cable or USB adapter, then run `gelrig probe`"
        ),
    )
}
