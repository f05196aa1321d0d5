//! A camera that replays recorded frames from a folder (PNG files in name order, e.g.
//! `../shared/data/gelsight-mini-press`), paced at its frame rate on the run's clock: a
//! bench rehearsal with real GelSight images and no camera attached.

use std::path::{Path, PathBuf};

use async_trait::async_trait;

use crate::device::{Camera, CameraInfo, Frame};
use crate::{Clock, RigError};

/// The replaying camera.
pub struct ImageFolderCamera {
    info: CameraInfo,
    files: Vec<PathBuf>,
    next: usize,
    /// Loop back to the first frame after the last (otherwise capture fails at the end).
    pub repeat: bool,
    clock: Clock,
    last_ns: Option<u64>,
}

impl ImageFolderCamera {
    /// Lists the PNG files of `dir` and reads the first for the frame size.
    pub fn open(dir: &Path, fps: f64, clock: Clock) -> Result<Self, RigError> {
        let device = format!("image folder {}", dir.display());
        let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
            .map_err(|e| RigError::Io {
                device: device.clone(),
                source: e,
            })?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|x| x.eq_ignore_ascii_case("png")))
            .collect();
        files.sort();
        let first = files.first().ok_or_else(|| RigError::Unsupported {
            device: device.clone(),
            detail: "holds no .png frames; fix: point `path:` at a folder of PNG frames".into(),
        })?;
        let (width, height) = image::image_dimensions(first).map_err(|e| RigError::Garbled {
            device: device.clone(),
            detail: format!("{}: {e}", first.display()),
        })?;
        if fps.is_nan() || fps <= 0.0 {
            return Err(RigError::Unsupported {
                device,
                detail: "fps must be positive".into(),
            });
        }
        Ok(Self {
            info: CameraInfo {
                width,
                height,
                fps,
                exposure_s: None,
                identity: format!("{device} ({} frames)", files.len()),
            },
            files,
            next: 0,
            repeat: false,
            clock,
            last_ns: None,
        })
    }
}

#[async_trait]
impl Camera for ImageFolderCamera {
    fn info(&self) -> &CameraInfo {
        &self.info
    }

    async fn capture(&mut self) -> Result<Frame, RigError> {
        if self.next >= self.files.len() {
            if !self.repeat {
                return Err(RigError::Unsupported {
                    device: self.info.identity.clone(),
                    detail: "no frames left; fix: record fewer frames or set `repeat: true`".into(),
                });
            }
            self.next = 0;
        }
        let period_ns = (1e9 / self.info.fps) as u64;
        if let Some(last) = self.last_ns {
            self.clock.sleep_until_ns(last + period_ns).await;
        }
        let path = &self.files[self.next];
        let img = image::open(path)
            .map_err(|e| RigError::Garbled {
                device: self.info.identity.clone(),
                detail: format!("{}: {e}", path.display()),
            })?
            .to_rgb8();
        if (img.width(), img.height()) != (self.info.width, self.info.height) {
            return Err(RigError::Garbled {
                device: self.info.identity.clone(),
                detail: format!(
                    "{} is {}×{}, the folder's first frame {}×{}",
                    path.display(),
                    img.width(),
                    img.height(),
                    self.info.width,
                    self.info.height
                ),
            });
        }
        let t_ns = self.clock.now_ns();
        self.last_ns = Some(t_ns);
        let seq = self.next as u64;
        self.next += 1;
        Ok(Frame {
            t_ns,
            seq,
            width: img.width(),
            height: img.height(),
            rgb: img.into_raw(),
            truth_px: None,
            truth_t_ns: None,
            truth_surface: None,
        })
    }
}
