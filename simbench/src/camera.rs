//! A simulated camera: frames exposed on the camera's own clock, delivered late, stamped as
//! a careful driver would ([`FrameTiming`]), rendered from the plant at their true exposure.

use std::sync::{Arc, Mutex};

use async_trait::async_trait;

use mechanics::response::ContactModel;

use super::frame_timing::FrameTiming;
use super::plant::Plant;
use super::render::{Renderer, SurfaceView};
use super::surface_truth::surface_truth;
use rig::device::{Camera, CameraInfo, DeviceTiming, Frame};
use rig::{Clock, RigError, lock};

/// Delivers frames at `fps` on the run's clock, showing the markers displaced by the plant.
pub(crate) struct SimCamera {
    info: CameraInfo,
    plant: Arc<Mutex<Plant>>,
    clock: Clock,
    timing: FrameTiming,
    renderer: Renderer,
    /// The camera's own copy of the contact model: fields are computed outside the plant's
    /// lock, so rendering never holds up the force sensor.
    model: ContactModel,
    /// Mixed into the frame number for the sensor noise: each seed sees its own noise.
    noise_key: u64,
    /// Frame pixels per cell of the traction maps handed with each frame; `None`: no maps
    /// (only a dataset run asks for them).
    maps_px_per_cell: Option<u32>,
}

impl SimCamera {
    pub(crate) fn new(
        info: CameraInfo,
        timing: FrameTiming,
        plant: Arc<Mutex<Plant>>,
        clock: Clock,
        seed: u64,
        maps_px_per_cell: Option<u32>,
    ) -> Self {
        let (renderer, model) = {
            let p = lock(&plant);
            (
                Renderer::new(p.spec(), info.width, info.height),
                p.field_model(),
            )
        };
        Self {
            info,
            plant,
            clock,
            timing,
            renderer,
            model,
            noise_key: seed.wrapping_mul(0xD1B5_4A32_D192_ED03),
            maps_px_per_cell,
        }
    }
}

#[async_trait]
impl Camera for SimCamera {
    fn info(&self) -> &CameraInfo {
        &self.info
    }

    fn timing(&self) -> Option<DeviceTiming> {
        Some(self.timing.report())
    }

    async fn capture(&mut self) -> Result<Frame, RigError> {
        let times = self.timing.next_after(self.clock.now_ns());
        // The picture is the gel as it is at the exposure's midpoint; the host has it only
        // when it arrives.
        self.clock.sleep_until_ns(times.exposure_mid_ns).await;
        let pose = lock(&self.plant).surface_pose(times.exposure_mid_ns);
        let (surface, tractions) = match self.maps_px_per_cell {
            Some(_) => match self.model.field_and_tractions(pose.state) {
                Some((f, t)) => (Some(f), Some(t)),
                None => (None, None),
            },
            None => (self.model.field(pose.state), None),
        };
        let surface = surface.map(|field| SurfaceView {
            field,
            centre_mm: pose.centre_mm,
            rotation_rad: pose.rotation_rad,
        });
        let (rgb, truth) = self
            .renderer
            .render(surface.as_ref(), times.seq ^ self.noise_key);
        let truth_surface = match (&surface, &tractions, self.maps_px_per_cell) {
            (Some(view), Some(t), Some(k)) => {
                let mut maps = surface_truth(&self.renderer, view, t, k);
                maps.depth_mm = pose.state.depth_mm;
                maps.shear_n = pose.state.shear_n;
                maps.torque_nmm = pose.state.torque_nmm;
                Some(Box::new(maps))
            }
            _ => None,
        };
        // Stamped at its arrival, as the kernel stamps a buffer: not when this task wakes
        // (a timer tick later on a real clock).
        self.clock.sleep_until_ns(times.arrival_ns).await;
        let t_ns = self.timing.stamp(times.seq, times.arrival_ns);
        Ok(Frame {
            t_ns,
            seq: times.seq,
            width: self.info.width,
            height: self.info.height,
            rgb,
            truth_px: Some(truth),
            truth_t_ns: Some(times.exposure_mid_ns),
            truth_surface,
        })
    }
}
