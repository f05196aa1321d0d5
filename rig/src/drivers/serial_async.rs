//! A serial port as a tokio byte stream, for `tokio-modbus`'s RTU client.
//!
//! `tokio-serial` would do this but pulls `serialport`'s default features (libudev, a
//! system library the default build must not need). The port is opened non-blocking by
//! path, set raw with nix's termios (baud, 8 data bits, parity; two stop bits without
//! parity, as the Modbus serial line spec §2.5.1 asks), and registered with tokio's
//! reactor through `AsyncFd`, so reads wait on readiness instead of a blocking thread.

use std::fs::{File, OpenOptions};
use std::io::{self, Read, Write};
use std::os::unix::fs::OpenOptionsExt;
use std::pin::Pin;
use std::task::{Context, Poll, ready};

use nix::fcntl::OFlag;
use nix::sys::termios::{self, BaudRate, ControlFlags, FlushArg, SetArg};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use tokio::io::unix::AsyncFd;
use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};

/// Parity of a serial line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema, Default)]
#[serde(rename_all = "snake_case")]
pub enum Parity {
    /// Even (the Modbus RTU default).
    #[default]
    Even,
    /// Odd.
    Odd,
    /// None (then two stop bits).
    None,
}

/// The rates Linux termios can set, by their number.
pub(crate) fn baud_rate(baud: u32) -> Option<BaudRate> {
    Some(match baud {
        1200 => BaudRate::B1200,
        2400 => BaudRate::B2400,
        4800 => BaudRate::B4800,
        9600 => BaudRate::B9600,
        19200 => BaudRate::B19200,
        38400 => BaudRate::B38400,
        57600 => BaudRate::B57600,
        115200 => BaudRate::B115200,
        230400 => BaudRate::B230400,
        _ => return None,
    })
}

fn ctx(e: nix::Error, what: &str) -> io::Error {
    io::Error::other(format!("{what}: {e}"))
}

/// Unix98 pseudo-terminal slaves have major numbers 136–143 (Linux
/// `Documentation/admin-guide/devices.txt`).
fn is_pseudo_terminal(file: &File) -> bool {
    use std::os::unix::fs::MetadataExt;
    file.metadata()
        .map(|m| (136..=143).contains(&nix::sys::stat::major(m.rdev())))
        .unwrap_or(false)
}

/// An open serial port.
#[derive(Debug)]
pub(crate) struct AsyncSerial {
    fd: AsyncFd<File>,
    /// The last thing done was a write: the next write continues the same request.
    writing: bool,
}

impl AsyncSerial {
    /// Opens `path` raw at `baud` with `parity`. Must run inside a tokio runtime.
    pub(crate) fn open(path: &str, baud: u32, parity: Parity) -> io::Result<Self> {
        let rate = baud_rate(baud).ok_or_else(|| {
            io::Error::new(
                io::ErrorKind::InvalidInput,
                format!("{baud} baud is not a standard rate (9600, 19200, 38400, 115200, …)"),
            )
        })?;
        let file = OpenOptions::new()
            .read(true)
            .write(true)
            .custom_flags((OFlag::O_NOCTTY | OFlag::O_NONBLOCK).bits())
            .open(path)?;
        let mut t = termios::tcgetattr(&file).map_err(|e| ctx(e, "reading its settings"))?;
        termios::cfmakeraw(&mut t);
        termios::cfsetspeed(&mut t, rate).map_err(|e| ctx(e, "setting the baud rate"))?;
        let c = &mut t.control_flags;
        c.insert(ControlFlags::CREAD | ControlFlags::CLOCAL | ControlFlags::CS8);
        c.remove(ControlFlags::PARENB | ControlFlags::PARODD | ControlFlags::CSTOPB);
        // A pseudo-terminal (a twin, or a serial-over-network bridge) has no line to
        // frame, and some kernels reject PARENB on one with EINVAL: framing bits are
        // only set on a real port.
        if !is_pseudo_terminal(&file) {
            match parity {
                Parity::Even => c.insert(ControlFlags::PARENB),
                Parity::Odd => c.insert(ControlFlags::PARENB | ControlFlags::PARODD),
                Parity::None => c.insert(ControlFlags::CSTOPB),
            }
        }
        termios::tcsetattr(&file, SetArg::TCSANOW, &t)
            .map_err(|e| ctx(e, "applying its settings (is it a serial port?)"))?;
        // `AsyncFd::new` is deprecated because a generic `AsRawFd` might hand out a
        // different or closed descriptor later; a `File` owns exactly one for its whole
        // life, which is the condition `register` asks callers to promise in `unsafe`
        // (forbidden in this workspace).
        #[allow(deprecated)]
        let fd = AsyncFd::new(file)?;
        Ok(Self { fd, writing: false })
    }
}

impl AsyncRead for AsyncSerial {
    fn poll_read(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<io::Result<()>> {
        self.writing = false;
        loop {
            let mut guard = ready!(self.fd.poll_read_ready(cx))?;
            let unfilled = buf.initialize_unfilled();
            match guard.try_io(|f| f.get_ref().read(unfilled)) {
                Ok(Ok(n)) => {
                    buf.advance(n);
                    return Poll::Ready(Ok(()));
                }
                // A pseudo-terminal whose other side closed reads EIO: end of stream.
                Ok(Err(e)) if e.raw_os_error() == Some(nix::libc::EIO) => {
                    return Poll::Ready(Ok(()));
                }
                Ok(Err(e)) => return Poll::Ready(Err(e)),
                Err(_would_block) => continue,
            }
        }
    }
}

impl AsyncWrite for AsyncSerial {
    fn poll_write(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        data: &[u8],
    ) -> Poll<io::Result<usize>> {
        // A new request: drop whatever waits in the input — a reply that came after its
        // request timed out would otherwise be read as the answer to this one, and every
        // answer after it would be one behind (what RTU masters do before each request).
        if !self.writing {
            termios::tcflush(self.fd.get_ref(), FlushArg::TCIFLUSH)
                .map_err(|e| ctx(e, "discarding stale input"))?;
            self.writing = true;
        }
        loop {
            let mut guard = ready!(self.fd.poll_write_ready(cx))?;
            match guard.try_io(|f| f.get_ref().write(data)) {
                Ok(r) => return Poll::Ready(r),
                Err(_would_block) => continue,
            }
        }
    }

    fn poll_flush(self: Pin<&mut Self>, _cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Poll::Ready(Ok(()))
    }

    fn poll_shutdown(self: Pin<&mut Self>, _cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Poll::Ready(Ok(()))
    }
}

#[cfg(test)]
mod tests {
    use std::io::{Read as _, Write as _};

    use tokio::io::{AsyncReadExt, AsyncWriteExt};

    use super::*;

    /// A reply that came after its request timed out waits in the input; the next request
    /// must not read it as its own answer.
    #[tokio::test]
    async fn a_new_request_drops_a_late_reply_waiting_in_the_input() {
        let (mut master, path) = crate::twins::pty::open_pair().expect("pty");
        let mut port = AsyncSerial::open(&path, 19200, Parity::Even).expect("open");
        // Request A; its reply comes only after the master gave up on it.
        port.write_all(b"A?").await.expect("write");
        let mut got = [0u8; 2];
        master.read_exact(&mut got).expect("read A");
        let mut late = [0u8; 1];
        let pending = tokio::time::timeout(
            std::time::Duration::from_millis(20),
            port.read_exact(&mut late),
        )
        .await;
        assert!(pending.is_err(), "nothing to read yet");
        master.write_all(b"late-A").expect("late reply");
        master.flush().expect("flush");
        std::thread::sleep(std::time::Duration::from_millis(50));
        // Request B, then its reply: only B's reply is read.
        port.write_all(b"B?").await.expect("write");
        master.read_exact(&mut got).expect("read B");
        assert_eq!(&got, b"B?");
        master.write_all(b"reply-B").expect("reply");
        let mut reply = [0u8; 7];
        port.read_exact(&mut reply).await.expect("read");
        assert_eq!(&reply, b"reply-B");
    }
}
