//! The simulated elastomer behind the wire twins of `gelrig sim serve`.
//!
//! In a dry run the simulated stages move the [`plant`](super::plant) directly. Behind real
//! transports the stages are twins that keep their own motion (their controllers' state
//! machines, speeds and limits), so here the plant *follows* them: whenever the Net F/T
//! twin sends a record, it asks this plant for the wrench, and the plant first moves every
//! stage to where its twin says it is (linearly since the last record), then integrates
//! the same contact, Prony relaxation and friction as the in-process bench. The force a
//! driver reads over UDP is therefore the force the dry run would have read, to within the
//! sampling of the stage positions.

use std::collections::BTreeSet;

use super::PlantSpec;
use super::plant::{BenchGeometry, Plant, PlantNeeds};
use rig::RigError;
use rig::config::{AxisRole, RigConfig};
use rig::device::{ForceRange, SimTruth, Wrench};

/// A plant driven by externally reported stage positions.
#[derive(Debug)]
pub struct TwinPlant {
    plant: Plant,
    range: ForceRange,
}

impl TwinPlant {
    /// Builds the plant of `rig`'s `sim:` geometry for `spec`, with contact tables only
    /// for the tangential axes in `axes` (a normal-only protocol solves no shear).
    pub fn new(
        rig: &RigConfig,
        spec: PlantSpec,
        axes: &BTreeSet<AxisRole>,
        seed: u64,
    ) -> Result<Self, RigError> {
        let geometry = BenchGeometry::of(rig, "twin plant")?;
        let needs = PlantNeeds {
            shear: axes.contains(&AxisRole::Shear),
            twist: axes.contains(&AxisRole::Rotation),
            fields: false,
        };
        let range =
            rig.force
                .as_ref()
                .map(|f| f.model.range())
                .ok_or_else(|| RigError::Unsupported {
                    device: "twin plant".into(),
                    detail: format!("rig `{}` has no force sensor to read the plant", rig.name),
                })?;
        let spec = PlantSpec {
            quality: crate::quality_for(rig.fidelity()),
            ..spec
        };
        Ok(Self {
            plant: Plant::new(spec, geometry, needs, seed)?,
            range,
        })
    }

    /// Moves the stages to `positions` (mm, or deg for rotation) at `t_ns` and returns
    /// the sensor's reading then: bias, noise, resolution and clipping as in a dry run,
    /// with the saturation flag in the status.
    pub fn sense(&mut self, positions: &[(AxisRole, f64)], t_ns: u64) -> (Wrench, u32) {
        self.plant.follow(positions, t_ns, false);
        self.plant.sense(t_ns, &self.range)
    }

    /// Ground truth at `t_ns` (after the last [`Self::sense`]).
    pub fn truth(&mut self, t_ns: u64) -> SimTruth {
        self.plant.truth(t_ns)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rig::config::RigConfig;

    fn rig() -> RigConfig {
        serde_yaml::from_str(
            "name: t\naxes: {}\nforce: {driver: net_ft, address: 127.0.0.1}\n\
             sim: {normal_contact: 10 mm, noise: false}\n",
        )
        .expect("test rig")
    }

    fn spec() -> PlantSpec {
        PlantSpec {
            contact: mechanics::contact::Contact::new(
                mechanics::Layer {
                    width_mm: 40.0,
                    length_mm: 40.0,
                    thickness_mm: 4.2,
                },
                mechanics::Material {
                    youngs_modulus_mpa: 0.2,
                    poisson_ratio: 0.49,
                    prony: vec![mechanics::PronyTerm {
                        weight: 0.3,
                        tau_s: 10.0,
                    }],
                    friction: 0.6,
                },
                mechanics::Indenter::FlatCircle { diameter_mm: 9.5 },
            )
            .expect("test contact"),
            markers: super::super::MarkerLayout::Grid {
                columns: 4,
                rows: 4,
                spacing_mm: 2.5,
                diameter_mm: 1.0,
            },
            view_width_mm: 20.0,
            view_height_mm: 20.0,
            object_mass_g: None,
            max_depth_mm: 1.0,
            kinetic_friction: 0.54,
            quality: Default::default(),
        }
    }

    /// Following the stage reproduces a step's relaxation: force rises at the step, then
    /// relaxes by the Prony weight towards the long-term value.
    #[test]
    fn a_followed_step_relaxes_like_the_dry_run() {
        let axes = BTreeSet::from([AxisRole::Normal]);
        let mut p = TwinPlant::new(&rig(), spec(), &axes, 0).expect("plant");
        let s = 1_000_000_000u64;
        assert_eq!(p.sense(&[(AxisRole::Normal, 9.0)], 0).0.fz_n, 0.0);
        // 0.3 mm into the elastomer over 1 s.
        for k in 1..=100 {
            let x = 10.0 + 0.3 * k as f64 / 100.0;
            p.sense(&[(AxisRole::Normal, x)], 10 * s + k * s / 100);
        }
        let peak = p.sense(&[(AxisRole::Normal, 10.3)], 11 * s).0.fz_n;
        let later = p.sense(&[(AxisRole::Normal, 10.3)], 111 * s).0.fz_n;
        let eq = p.truth(111 * s).equilibrium.fz_n;
        assert!(peak > 0.5, "peak {peak}");
        assert!(later < peak && later > 0.6 * peak, "{peak} → {later}");
        // Within the Nano17 resolution it is quantised to.
        assert!((later - eq).abs() < 0.01, "{later} vs long-term {eq}");
        // Out of contact again: nothing.
        assert!(p.sense(&[(AxisRole::Normal, 5.0)], 200 * s).0.fz_n.abs() < 1e-9);
    }
}
