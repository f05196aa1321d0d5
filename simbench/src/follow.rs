//! A real axis whose reported positions move the simulated elastomer.
//!
//! A rig may mix real stages with simulated devices: the `sim-wire` rig's stages are
//! production drivers talking to twins while its camera is rendered in-process (V4L2 has
//! no wire protocol a twin could speak without a kernel module). For the rendered markers
//! to show what the real stages did, every position the driver reads back is handed to
//! the plant ([`Plant::follow`]), which moves its stage there linearly since its last time
//! and integrates the contact as a dry run would.

use std::sync::{Arc, Mutex};

use async_trait::async_trait;

use super::plant::Plant;
use rig::config::AxisRole;
use rig::device::{Axis, AxisInfo, AxisStatus, AxisStopper};
use rig::{Clock, RigError, lock};

/// Wraps a driver; behaves exactly like it.
pub(crate) struct FollowedAxis {
    role: AxisRole,
    inner: Box<dyn Axis>,
    plant: Arc<Mutex<Plant>>,
    clock: Clock,
}

impl FollowedAxis {
    pub(crate) fn new(
        role: AxisRole,
        inner: Box<dyn Axis>,
        plant: Arc<Mutex<Plant>>,
        clock: Clock,
    ) -> Self {
        Self {
            role,
            inner,
            plant,
            clock,
        }
    }
}

#[async_trait]
impl Axis for FollowedAxis {
    fn info(&self) -> &AxisInfo {
        self.inner.info()
    }

    fn stopper(&self) -> Arc<dyn AxisStopper> {
        self.inner.stopper()
    }

    async fn home(&mut self) -> Result<(), RigError> {
        self.inner.home().await
    }

    async fn move_to(&mut self, target: f64, speed: f64) -> Result<(), RigError> {
        self.inner.move_to(target, speed).await
    }

    async fn status(&mut self) -> Result<AxisStatus, RigError> {
        let s = self.inner.status().await?;
        let t_ns = self.clock.now_ns();
        lock(&self.plant).follow(&[(self.role, s.position)], t_ns, !s.moving);
        Ok(s)
    }

    async fn stop(&mut self) -> Result<(), RigError> {
        self.inner.stop().await
    }
}
