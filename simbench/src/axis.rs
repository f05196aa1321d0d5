//! A simulated stage axis: travel, speed, resolution and a reference state, moving the
//! plant's kinematics.

use std::sync::{Arc, Mutex};

use async_trait::async_trait;

use super::plant::Plant;
use rig::config::AxisRole;
use rig::device::{Axis, AxisInfo, AxisStatus, AxisStopper};
use rig::{Clock, RigError, lock};

/// A stage that behaves like the thesis's micrometer stages seen through a controller:
/// unreferenced at power-up, refuses moves outside travel or above its speed, rounds targets
/// to its resolution, moves at constant speed.
pub(crate) struct SimAxis {
    role: AxisRole,
    info: AxisInfo,
    plant: Arc<Mutex<Plant>>,
    clock: Clock,
}

impl SimAxis {
    pub(crate) fn new(
        role: AxisRole,
        info: AxisInfo,
        plant: Arc<Mutex<Plant>>,
        clock: Clock,
    ) -> Self {
        lock(&plant).add_axis(role, 0.0_f64.max(info.travel_min).min(info.travel_max));
        Self {
            role,
            info,
            plant,
            clock,
        }
    }
}

/// Stops a simulated stage through the shared plant.
struct SimStopper {
    role: AxisRole,
    resolution: f64,
    plant: Arc<Mutex<Plant>>,
    clock: Clock,
}

#[async_trait]
impl AxisStopper for SimStopper {
    async fn stop_now(&self) -> Result<(), RigError> {
        let now = self.clock.now_ns();
        lock(&self.plant).stop(self.role, now, self.resolution);
        Ok(())
    }
}

#[async_trait]
impl Axis for SimAxis {
    fn info(&self) -> &AxisInfo {
        &self.info
    }

    fn stopper(&self) -> Arc<dyn AxisStopper> {
        Arc::new(SimStopper {
            role: self.role,
            resolution: self.info.resolution,
            plant: self.plant.clone(),
            clock: self.clock.clone(),
        })
    }

    async fn home(&mut self) -> Result<(), RigError> {
        let home = 0.0_f64.max(self.info.travel_min).min(self.info.travel_max);
        let now = self.clock.now_ns();
        lock(&self.plant).start_move(self.role, home, self.info.max_speed, now, true);
        Ok(())
    }

    async fn move_to(&mut self, target: f64, speed: f64) -> Result<(), RigError> {
        let info = &self.info;
        let referenced = lock(&self.plant)
            .axis(self.role)
            .is_some_and(|a| a.referenced);
        if !referenced {
            return Err(RigError::NotReferenced {
                axis: self.role.to_string(),
            });
        }
        if !(speed > 0.0 && speed <= info.max_speed * (1.0 + 1e-9)) {
            return Err(RigError::BadSpeed {
                axis: self.role.to_string(),
                speed,
                max: info.max_speed,
                unit: info.unit,
            });
        }
        let quantised = (target / info.resolution).round() * info.resolution;
        let tol = info.resolution * 1e-6;
        if !(quantised >= info.travel_min - tol && quantised <= info.travel_max + tol) {
            return Err(RigError::OutOfTravel {
                axis: self.role.to_string(),
                target,
                min: info.travel_min,
                max: info.travel_max,
                unit: info.unit,
            });
        }
        let now = self.clock.now_ns();
        lock(&self.plant).start_move(self.role, quantised, speed, now, false);
        Ok(())
    }

    async fn status(&mut self) -> Result<AxisStatus, RigError> {
        let now = self.clock.now_ns();
        let (position, moving, referenced) = lock(&self.plant)
            .axis_status(self.role, now)
            .ok_or_else(|| RigError::Plant(format!("{} axis was never added", self.role)))?;
        Ok(AxisStatus {
            position,
            moving,
            referenced,
            in_position: None,
        })
    }

    async fn stop(&mut self) -> Result<(), RigError> {
        let now = self.clock.now_ns();
        lock(&self.plant).stop(self.role, now, self.info.resolution);
        Ok(())
    }
}
