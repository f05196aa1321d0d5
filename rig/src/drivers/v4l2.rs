//! A USB (UVC) camera through V4L2, behind the `v4l` feature (the `v4l` crate needs
//! libclang to build).
//!
//! A capture thread owns the device and its memory-mapped stream (neither needs to cross
//! threads) and hands each frame over a channel, converted from YUYV to RGB, with the
//! driver's buffer timestamp when it is CLOCK_MONOTONIC (flags & 0xE000 == 0x2000: the run's
//! timebase on a real bench, spec `devices.md` §4) and its `sequence`, whose gaps are
//! dropped frames. Otherwise the frame is stamped on arrival. The buffer timestamp is taken
//! at the start of the exposure (`V4L2_BUF_FLAG_TSTAMP_SRC_SOE`, what uvcvideo sets) or at
//! the end of the frame (`…_EOF`); [`exposure_midpoint_ns`] moves it to the exposure's
//! midpoint with the exposure the camera reports (`V4L2_CID_EXPOSURE_ABSOLUTE`, 100 µs
//! units), less a latency calibrated per setup.

use std::sync::mpsc;
use std::time::Duration;

use async_trait::async_trait;
use v4l::buffer::Type;
use v4l::io::mmap::Stream;
use v4l::io::traits::CaptureStream;
use v4l::video::Capture;
use v4l::{Device, FourCC};

use crate::device::{Camera, CameraInfo, Frame};
use crate::{Clock, RigError};

/// A V4L2 camera.
pub struct V4l2Camera {
    info: CameraInfo,
    frames: tokio::sync::mpsc::Receiver<Result<Frame, String>>,
    stop: std::sync::Arc<std::sync::atomic::AtomicBool>,
    /// Frames the driver dropped (gaps in `sequence`).
    pub dropped: u64,
    last_seq: Option<u64>,
}

/// `V4L2_BUF_FLAG_TIMESTAMP_MASK` and its CLOCK_MONOTONIC value.
const TIMESTAMP_MASK: u32 = 0xE000;
const TIMESTAMP_MONOTONIC: u32 = 0x2000;
/// `V4L2_BUF_FLAG_TSTAMP_SRC_MASK` and its start-of-exposure value (0 is end of frame).
const TSTAMP_SRC_MASK: u32 = 0x0007_0000;
const TSTAMP_SRC_SOE: u32 = 0x0001_0000;
/// `V4L2_CID_EXPOSURE_ABSOLUTE`, in 100 µs units.
const CID_EXPOSURE_ABSOLUTE: u32 = 0x009a_0902;

/// The exposure midpoint of a frame whose buffer carries `timestamp_ns` with `flags`, for an
/// exposure of `exposure_ns` (when known) and a calibrated `latency_ns`; `None` unless the
/// timestamp is CLOCK_MONOTONIC (the frame is then stamped on arrival).
pub fn exposure_midpoint_ns(
    timestamp_ns: u64,
    flags: u32,
    exposure_ns: Option<u64>,
    latency_ns: u64,
) -> Option<u64> {
    if flags & TIMESTAMP_MASK != TIMESTAMP_MONOTONIC {
        return None;
    }
    let half = exposure_ns.unwrap_or(0) / 2;
    let t = if flags & TSTAMP_SRC_MASK == TSTAMP_SRC_SOE {
        timestamp_ns + half
    } else {
        timestamp_ns.saturating_sub(half)
    };
    Some(t.saturating_sub(latency_ns))
}

/// YUYV (4:2:2) to RGB8, ITU-R BT.601.
pub fn yuyv_to_rgb(yuyv: &[u8], width: usize, height: usize) -> Vec<u8> {
    let mut rgb = Vec::with_capacity(width * height * 3);
    for px in yuyv.chunks_exact(4).take(width * height / 2) {
        let (y0, u, y1, v) = (
            px[0] as f32,
            px[1] as f32 - 128.0,
            px[2] as f32,
            px[3] as f32 - 128.0,
        );
        for y in [y0, y1] {
            let c = |x: f32| x.round().clamp(0.0, 255.0) as u8;
            rgb.extend([
                c(y + 1.402 * v),
                c(y - 0.344_136 * u - 0.714_136 * v),
                c(y + 1.772 * u),
            ]);
        }
    }
    rgb
}

impl V4l2Camera {
    /// Opens `path`, asks for YUYV at `width`×`height` and `fps`, and starts streaming.
    pub fn open(
        path: &str,
        width: u32,
        height: u32,
        fps: f64,
        latency_s: f64,
        clock: Clock,
    ) -> Result<Self, RigError> {
        let latency_ns = (latency_s.max(0.0) * 1e9) as u64;
        let device = format!("camera {path}");
        let (init_tx, init_rx) = mpsc::channel::<Result<(u32, u32, Option<u64>), String>>();
        let (tx, frames) = tokio::sync::mpsc::channel(4);
        let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        let (p, st) = (path.to_string(), stop.clone());
        std::thread::spawn(move || {
            let setup = || -> std::io::Result<(Device, u32, u32, Option<u64>)> {
                let dev = Device::with_path(&p)?;
                let mut fmt = dev.format()?;
                fmt.width = width;
                fmt.height = height;
                fmt.fourcc = FourCC::new(b"YUYV");
                let fmt = dev.set_format(&fmt)?;
                if fmt.fourcc != FourCC::new(b"YUYV") {
                    return Err(std::io::Error::other(format!(
                        "the camera offers {} instead of YUYV",
                        fmt.fourcc
                    )));
                }
                let _ = dev.set_params(&v4l::video::capture::Parameters::with_fps(
                    fps.round().max(1.0) as u32,
                ));
                // A camera without the control: frames are matched to the force within
                // half a frame period instead of inside the exposure.
                let exposure_ns = match dev.control(CID_EXPOSURE_ABSOLUTE) {
                    Ok(c) => match c.value {
                        v4l::control::Value::Integer(v) if v > 0 => Some(v as u64 * 100_000),
                        _ => None,
                    },
                    Err(_) => None,
                };
                Ok((dev, fmt.width, fmt.height, exposure_ns))
            };
            let (dev, w, h, exposure_ns) = match setup() {
                Ok(x) => x,
                Err(e) => {
                    let _ = init_tx.send(Err(e.to_string()));
                    return;
                }
            };
            let mut stream = match Stream::with_buffers(&dev, Type::VideoCapture, 4) {
                Ok(s) => s,
                Err(e) => {
                    let _ = init_tx.send(Err(e.to_string()));
                    return;
                }
            };
            let _ = init_tx.send(Ok((w, h, exposure_ns)));
            while !st.load(std::sync::atomic::Ordering::Relaxed) {
                let item = match stream.next() {
                    Ok((buf, meta)) => {
                        let stamp_ns = meta.timestamp.sec as u64 * 1_000_000_000
                            + meta.timestamp.usec as u64 * 1000;
                        let t_ns = exposure_midpoint_ns(
                            stamp_ns,
                            meta.flags.bits(),
                            exposure_ns,
                            latency_ns,
                        )
                        .unwrap_or_else(|| clock.now_ns().saturating_sub(latency_ns));
                        Ok(Frame {
                            t_ns,
                            seq: meta.sequence as u64,
                            width: w,
                            height: h,
                            rgb: yuyv_to_rgb(buf, w as usize, h as usize),
                            truth_px: None,
                            truth_t_ns: None,
                            truth_surface: None,
                        })
                    }
                    Err(e) => Err(e.to_string()),
                };
                let failed = item.is_err();
                if tx.blocking_send(item).is_err() || failed {
                    return;
                }
            }
        });
        let (w, h, exposure_ns) = init_rx
            .recv_timeout(Duration::from_secs(5))
            .map_err(|_| RigError::Timeout {
                device: device.clone(),
                timeout_ms: 5000,
            })?
            .map_err(|e| RigError::Io {
                device: device.clone(),
                source: std::io::Error::other(format!(
                    "{e}; fix: check the path and that no other program uses the camera"
                )),
            })?;
        Ok(Self {
            info: CameraInfo {
                width: w,
                height: h,
                fps,
                exposure_s: exposure_ns.map(|e| e as f64 * 1e-9),
                identity: format!("V4L2 {path} {w}×{h} YUYV"),
            },
            frames,
            stop,
            dropped: 0,
            last_seq: None,
        })
    }
}

impl Drop for V4l2Camera {
    fn drop(&mut self) {
        self.stop.store(true, std::sync::atomic::Ordering::Relaxed);
    }
}

#[async_trait]
impl Camera for V4l2Camera {
    fn info(&self) -> &CameraInfo {
        &self.info
    }

    async fn capture(&mut self) -> Result<Frame, RigError> {
        let device = self.info.identity.clone();
        let wait = Duration::from_secs_f64((10.0 / self.info.fps).max(1.0));
        let frame = tokio::time::timeout(wait, self.frames.recv())
            .await
            .map_err(|_| RigError::Timeout {
                device: device.clone(),
                timeout_ms: wait.as_millis() as u64,
            })?
            .ok_or_else(|| RigError::Io {
                device: device.clone(),
                source: std::io::Error::other("the capture thread stopped"),
            })?
            .map_err(|e| RigError::Io {
                device,
                source: std::io::Error::other(e),
            })?;
        if let Some(last) = self.last_seq {
            self.dropped += frame.seq.saturating_sub(last + 1);
        }
        self.last_seq = Some(frame.seq);
        Ok(frame)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn buffer_timestamps_move_to_the_exposure_midpoint() {
        let soe = TIMESTAMP_MONOTONIC | TSTAMP_SRC_SOE;
        // Start of exposure + half of 10 ms − 1 ms latency.
        assert_eq!(
            exposure_midpoint_ns(100_000_000, soe, Some(10_000_000), 1_000_000),
            Some(104_000_000)
        );
        // End of frame − half the exposure.
        assert_eq!(
            exposure_midpoint_ns(100_000_000, TIMESTAMP_MONOTONIC, Some(10_000_000), 0),
            Some(95_000_000)
        );
        // Unknown exposure: the timestamp as it is.
        assert_eq!(
            exposure_midpoint_ns(100_000_000, soe, None, 0),
            Some(100_000_000)
        );
        // Not CLOCK_MONOTONIC (0x4000: copied from the output): not usable.
        assert_eq!(exposure_midpoint_ns(100_000_000, 0x4000, None, 0), None);
    }

    #[test]
    fn yuyv_grey_and_red() {
        // Y=128, U=V=128 is mid grey; a saturated red is Y=81, U=90, V=240.
        let rgb = yuyv_to_rgb(&[128, 128, 128, 128, 81, 90, 81, 240], 4, 1);
        assert_eq!(&rgb[..6], &[128, 128, 128, 128, 128, 128]);
        assert!(
            rgb[6] > 230 && rgb[7] < 20 && rgb[8] < 20,
            "{:?}",
            &rgb[6..9]
        );
        // No device: a clear error naming the path.
        let e = V4l2Camera::open(
            "/dev/video-none",
            640,
            480,
            25.0,
            0.0,
            Clock::new(crate::ClockMode::Monotonic),
        )
        .err()
        .expect("no camera");
        assert!(e.to_string().contains("/dev/video-none"), "{e}");
    }
}
