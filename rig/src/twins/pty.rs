//! A line-oriented device on a pseudo-terminal: the twin holds the master side, the
//! production driver opens the slave by its `/dev/pts/N` path exactly as it opens a real
//! serial port. Lines end in CR, LF or CRLF; each goes to the device's handler, whose reply
//! (if any) is sent back with CRLF, subject to the injected [`Faults`].

use std::fs::OpenOptions;
use std::io::{Read, Write};
use std::os::unix::fs::OpenOptionsExt;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use nix::fcntl::OFlag;

use serialport::{SerialPort, TTYPort};

use crate::lock;

/// Faults to inject; change them at any time through [`PtyTwin::faults`].
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Faults {
    /// Drop every reply.
    pub no_reply: bool,
    /// Corrupt the next N replies (characters flipped, so checksum or grammar fails).
    pub garble_next: u32,
    /// Delay every reply by this long.
    pub delay: Duration,
    /// Close the port (the device was unplugged).
    pub disconnect: bool,
    /// Replace the next reply by this many bytes of noise on one line (a flood).
    pub flood_next: Option<usize>,
    /// The stage reports itself moving forever and goes nowhere (a jam, a stalled motor, a
    /// controller that never leaves BUSY); it still answers.
    pub stuck_busy: bool,
    /// The text of the position in every position reply instead of the real value (`NaN`,
    /// `1e308`: a controller's firmware fault).
    pub position_reply: Option<String>,
}

/// A running line device.
pub struct PtyTwin {
    path: String,
    faults: Arc<Mutex<Faults>>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
    transcript: Arc<Mutex<Vec<String>>>,
}

static PAIR: Mutex<()> = Mutex::new(());

impl PtyTwin {
    /// Opens a pseudo-terminal and serves `handler` on it until dropped; the handler sees
    /// the faults in force (for those only the device can act out). `garble` turns a reply
    /// into a corrupted one.
    pub fn spawn(
        mut handler: impl FnMut(&str, &Faults) -> Option<String> + Send + 'static,
        garble: fn(&str) -> String,
    ) -> std::io::Result<Self> {
        let (mut master, path) = open_pair()?;
        master
            .set_timeout(Duration::from_millis(10))
            .map_err(std::io::Error::other)?;
        let faults = Arc::new(Mutex::new(Faults::default()));
        let stop = Arc::new(AtomicBool::new(false));
        let transcript = Arc::new(Mutex::new(Vec::new()));
        let (f, s, t) = (faults.clone(), stop.clone(), transcript.clone());
        let thread =
            std::thread::spawn(move || serve(&mut master, &mut handler, garble, &f, &s, &t));
        Ok(Self {
            path,
            faults,
            stop,
            thread: Some(thread),
            transcript,
        })
    }

    /// The pseudo-terminal path the driver opens.
    pub fn path(&self) -> &str {
        &self.path
    }

    /// The fault switches.
    pub fn faults(&self) -> &Arc<Mutex<Faults>> {
        &self.faults
    }

    /// Every line received and sent (`> ` and `< `), for test diagnostics.
    pub fn transcript(&self) -> Vec<String> {
        lock(&self.transcript).clone()
    }

    /// A handle that reads the transcript from another thread.
    pub fn transcript_probe(&self) -> impl Fn() -> Vec<String> + Send + 'static {
        let t = self.transcript.clone();
        move || lock(&t).clone()
    }
}

/// A new pseudo-terminal: the master side a twin serves, and the slave's path that the
/// driver opens.
pub(crate) fn open_pair() -> std::io::Result<(TTYPort, String)> {
    let (master, slave) = {
        // `TTYPort::pair` is not thread-safe (serialport's own tests serialise it).
        let _g = lock(&PAIR);
        TTYPort::pair().map_err(std::io::Error::other)?
    };
    let path = slave
        .name()
        .ok_or_else(|| std::io::Error::other("pty without a name"))?;
    drop(slave);
    Ok((master, path))
}

impl Drop for PtyTwin {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        let Some(thread) = self.thread.take() else {
            return;
        };
        // A reply still being written when no driver reads the slave side any more (a
        // 4 MiB flood sent as the run gave up on the device) blocks the serving thread in
        // `write` once the terminal's buffer is full, and a join would wait forever (CI
        // hung there on 3 Dec): read the slave side empty until the thread has seen `stop`.
        // Past a few seconds the thread is left to end on its own rather than hang the
        // owner.
        let deadline = Instant::now() + Duration::from_secs(5);
        let mut drain: Option<std::fs::File> = None;
        let mut buf = [0u8; 4096];
        while !thread.is_finished() {
            if Instant::now() > deadline {
                return;
            }
            if drain.is_none() {
                drain = OpenOptions::new()
                    .read(true)
                    .custom_flags((OFlag::O_NOCTTY | OFlag::O_NONBLOCK).bits())
                    .open(&self.path)
                    .ok();
            }
            match drain.as_mut().map(|f| f.read(&mut buf)) {
                Some(Ok(n)) if n > 0 => {}
                _ => std::thread::sleep(Duration::from_millis(2)),
            }
        }
        let _ = thread.join();
    }
}

fn serve(
    master: &mut TTYPort,
    handler: &mut dyn FnMut(&str, &Faults) -> Option<String>,
    garble: fn(&str) -> String,
    faults: &Mutex<Faults>,
    stop: &AtomicBool,
    log: &Mutex<Vec<String>>,
) {
    let mut pending = Vec::new();
    let mut buf = [0u8; 256];
    while !stop.load(Ordering::Relaxed) {
        if lock(faults).disconnect {
            return;
        }
        let n = match master.read(&mut buf) {
            Ok(n) => n,
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::TimedOut | std::io::ErrorKind::WouldBlock
                ) =>
            {
                continue;
            }
            // EIO while no driver holds the slave side open (before the first open, between
            // probes): wait for the next one.
            Err(_) => {
                std::thread::sleep(Duration::from_millis(10));
                continue;
            }
        };
        pending.extend_from_slice(&buf[..n]);
        while let Some(k) = pending.iter().position(|b| *b == b'\n' || *b == b'\r') {
            let line: Vec<u8> = pending.drain(..=k).collect();
            let line = String::from_utf8_lossy(&line).trim().to_string();
            if line.is_empty() {
                continue;
            }
            lock(log).push(format!("> {line}"));
            let f = lock(faults).clone();
            let Some(mut reply) = handler(&line, &f) else {
                continue;
            };
            if f.no_reply {
                continue;
            }
            if let Some(n) = f.flood_next {
                lock(faults).flood_next = None;
                reply = "x".repeat(n);
            }
            if f.garble_next > 0 {
                lock(faults).garble_next -= 1;
                reply = garble(&reply);
            }
            if !f.delay.is_zero() {
                std::thread::sleep(f.delay);
            }
            lock(log).push(format!("< {}", crate::quote(&reply)));
            // A driver that went away mid-reply: drop the reply, keep serving.
            let _ = master.write_all(format!("{reply}\r\n").as_bytes());
        }
    }
}
