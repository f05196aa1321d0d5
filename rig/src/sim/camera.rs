//! A simulated camera: frames on a fixed grid of exposure times, rendered from the plant.

use std::sync::{Arc, Mutex};

use async_trait::async_trait;

use mechanics::response::ContactModel;

use super::plant::Plant;
use super::render::{Renderer, SurfaceView};
use crate::device::{Camera, CameraInfo, Frame};
use crate::{Clock, RigError, lock};

/// Delivers frames at `fps` on the run's clock, showing the markers displaced by the plant.
pub(crate) struct SimCamera {
    info: CameraInfo,
    plant: Arc<Mutex<Plant>>,
    clock: Clock,
    period_ns: u64,
    last_t_ns: Option<u64>,
    renderer: Renderer,
    /// The camera's own copy of the contact model: fields are computed outside the plant's
    /// lock, so rendering never holds up the force sensor.
    model: ContactModel,
    /// Mixed into the frame number for the sensor noise: each seed sees its own noise.
    noise_key: u64,
}

impl SimCamera {
    pub(crate) fn new(info: CameraInfo, plant: Arc<Mutex<Plant>>, clock: Clock, seed: u64) -> Self {
        let (renderer, model) = {
            let p = lock(&plant);
            (
                Renderer::new(p.spec(), info.width, info.height),
                p.field_model(),
            )
        };
        let period_ns = (1e9 / info.fps.max(1e-3)).round() as u64;
        Self {
            info,
            plant,
            clock,
            period_ns,
            last_t_ns: None,
            renderer,
            model,
            noise_key: seed.wrapping_mul(0xD1B5_4A32_D192_ED03),
        }
    }
}

#[async_trait]
impl Camera for SimCamera {
    fn info(&self) -> &CameraInfo {
        &self.info
    }

    async fn capture(&mut self) -> Result<Frame, RigError> {
        let now = self.clock.now_ns();
        let mut t = now.div_ceil(self.period_ns) * self.period_ns;
        if let Some(last) = self.last_t_ns
            && t <= last
        {
            t = last + self.period_ns;
        }
        self.clock.sleep_until_ns(t).await;
        self.last_t_ns = Some(t);
        let pose = lock(&self.plant).surface_pose(t);
        let surface = self.model.field(pose.state).map(|field| SurfaceView {
            field,
            centre_mm: pose.centre_mm,
            rotation_rad: pose.rotation_rad,
        });
        let seq = t / self.period_ns;
        let (rgb, truth) = self.renderer.render(surface.as_ref(), seq ^ self.noise_key);
        Ok(Frame {
            t_ns: t,
            seq,
            width: self.info.width,
            height: self.info.height,
            rgb,
            truth_px: Some(truth),
        })
    }
}
