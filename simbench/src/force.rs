//! A simulated ATI Nano17 and a simulated disturbance source, both on the plant.

use std::sync::{Arc, Mutex};

use async_trait::async_trait;

use super::plant::Plant;
use rig::device::{Disturber, ForceInfo, ForceSample, ForceSensor, SimTruth};
use rig::{Clock, RigError, lock};

/// Reads the plant's wrench with the sensor's bias, noise, resolution and range.
pub(crate) struct SimForceSensor {
    info: ForceInfo,
    plant: Arc<Mutex<Plant>>,
    clock: Clock,
}

impl SimForceSensor {
    pub(crate) fn new(info: ForceInfo, plant: Arc<Mutex<Plant>>, clock: Clock) -> Self {
        Self { info, plant, clock }
    }
}

#[async_trait]
impl ForceSensor for SimForceSensor {
    fn info(&self) -> &ForceInfo {
        &self.info
    }

    async fn read(&mut self) -> Result<ForceSample, RigError> {
        let t_ns = self.clock.now_ns();
        let (wrench, status) = lock(&self.plant).sense(t_ns, &self.info.range);
        Ok(ForceSample {
            t_ns,
            ft_seq: (t_ns as f64 * 1e-9 * self.info.max_rate_hz) as u64,
            wrench,
            status,
        })
    }

    async fn truth(&mut self) -> Option<SimTruth> {
        let t_ns = self.clock.now_ns();
        Some(lock(&self.plant).truth(t_ns))
    }
}

/// Adds a sinusoidal load to the grasped object in the plant.
pub(crate) struct SimDisturber {
    plant: Arc<Mutex<Plant>>,
    clock: Clock,
}

impl SimDisturber {
    pub(crate) fn new(plant: Arc<Mutex<Plant>>, clock: Clock) -> Self {
        Self { plant, clock }
    }
}

#[async_trait]
impl Disturber for SimDisturber {
    async fn apply(
        &mut self,
        force_y_n: f64,
        torque_z_nmm: f64,
        frequency_hz: f64,
        duration_s: f64,
    ) -> Result<(), RigError> {
        let now = self.clock.now_ns();
        lock(&self.plant).disturb(now, force_y_n, torque_z_nmm, frequency_hz, duration_s);
        Ok(())
    }
}
