//! Modbus RTU framing for the twin: requests cut by their function code's length, or by
//! the silence after them; CRC-16/MODBUS checked; answered through the same service as TCP.

use std::sync::atomic::{AtomicBool, Ordering};

use tokio_modbus::{Request, Response};

use super::Service;
use crate::lock;

const RTU_CRC: crc::Crc<u16> = crc::Crc::<u16>::new(&crc::CRC_16_MODBUS);

/// Appends the CRC, low byte first (Modbus serial line spec §2.5.1.2).
fn with_crc(mut frame: Vec<u8>) -> Vec<u8> {
    let c = RTU_CRC.checksum(&frame);
    frame.extend_from_slice(&c.to_le_bytes());
    frame
}

/// Length of the request starting `buf` (slave id, function code, …, CRC), if it can be
/// told yet; `Some(None)` for a function whose length the spec does not fix (its frame
/// ends at the silence after it). Functions the drive does not implement (FC1, 2, 4, 5, 15,
/// …) are still framed, so they get their Illegal Function answer as over TCP.
fn request_len(buf: &[u8]) -> Option<Option<usize>> {
    let fc = *buf.get(1)?;
    Some(match fc {
        0x01..=0x06 => Some(8),
        0x0F | 0x10 => Some(9 + *buf.get(6)? as usize),
        _ => None,
    })
}

fn be(b: &[u8], i: usize) -> u16 {
    u16::from_be_bytes([b[i], b[i + 1]])
}

/// The reply frame (CRC included) to one CRC-checked request frame, if any.
fn rtu_reply(svc: &Service, frame: &[u8]) -> Option<Vec<u8>> {
    let (slave, fc) = (frame[0], frame[1]);
    let request = match fc {
        0x03 => Request::ReadHoldingRegisters(be(frame, 2), be(frame, 4)),
        0x06 => Request::WriteSingleRegister(be(frame, 2), be(frame, 4)),
        0x10 => {
            let n = frame[6] as usize / 2;
            let words: Vec<u16> = (0..n).map(|k| be(frame, 7 + 2 * k)).collect();
            Request::WriteMultipleRegisters(be(frame, 2), words.into())
        }
        _ => Request::Custom(fc, Vec::new().into()),
    };
    let mut out = vec![slave];
    let delay = svc.reply_delay();
    if !delay.is_zero() {
        std::thread::sleep(delay);
    }
    match svc.handle(slave, request)? {
        Ok(Response::ReadHoldingRegisters(words)) => {
            out.extend([fc, (2 * words.len()) as u8]);
            words.iter().for_each(|w| out.extend(w.to_be_bytes()));
        }
        Ok(Response::WriteSingleRegister(a, w)) => {
            out.push(fc);
            out.extend(a.to_be_bytes());
            out.extend(w.to_be_bytes());
        }
        Ok(Response::WriteMultipleRegisters(a, n)) => {
            out.push(fc);
            out.extend(a.to_be_bytes());
            out.extend(n.to_be_bytes());
        }
        Ok(_) => return None,
        Err(code) => out.extend([fc | 0x80, u8::from(code)]),
    }
    Some(with_crc(out))
}

pub(super) fn serve(master: &mut serialport::TTYPort, svc: &Service, stop: &AtomicBool) {
    use std::io::Read;
    let mut pending: Vec<u8> = Vec::new();
    let mut buf = [0u8; 256];
    while !stop.load(Ordering::Relaxed) {
        match master.read(&mut buf) {
            Ok(n) => pending.extend_from_slice(&buf[..n]),
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::TimedOut | std::io::ErrorKind::WouldBlock
                ) =>
            {
                // Silence ends a frame (t3.5): a whole frame of a function with no fixed
                // length is answered; anything else pending is noise.
                let whole = pending.len() >= 4
                    && RTU_CRC
                        .checksum(&pending[..pending.len() - 2])
                        .to_le_bytes()
                        == pending[pending.len() - 2..];
                if whole && let Some(reply) = rtu_reply(svc, &pending) {
                    respond(master, svc, reply);
                }
                pending.clear();
                continue;
            }
            // EIO while no driver holds the slave side open: wait for the next one.
            Err(_) => {
                pending.clear();
                std::thread::sleep(std::time::Duration::from_millis(10));
                continue;
            }
        }
        while let Some(Some(len)) = request_len(&pending) {
            if pending.len() < len {
                break;
            }
            let frame: Vec<u8> = pending.drain(..len).collect();
            if RTU_CRC.checksum(&frame[..len - 2]).to_le_bytes() != frame[len - 2..] {
                // A slave ignores a frame with a bad CRC; resynchronise on the next one.
                pending.clear();
                break;
            }
            if let Some(reply) = rtu_reply(svc, &frame) {
                respond(master, svc, reply);
            }
        }
    }
}

/// Sends a reply, garbled if the fault asks.
fn respond(master: &mut serialport::TTYPort, svc: &Service, mut reply: Vec<u8>) {
    use std::io::Write;
    {
        let mut f = lock(&svc.faults);
        if f.garble_next > 0 {
            f.garble_next -= 1;
            let last = reply.len() - 1;
            reply[last] ^= 0x5A;
        }
    }
    let _ = master.write_all(&reply);
}
