//! What the plant's sensors read: the true wrench on the gel (with the tilting moments a
//! sheared contact carries), the ground truth a report is checked against, and the Nano17's
//! reading with its offset, noise, quantisation and clipping.

use std::f64::consts::PI;

use mechanics::response::{tilt_arms_at, tilting_moments_nmm};
use rand::Rng;
use rand::rngs::StdRng;
use rand_distr::StandardNormal;

use super::{Channel, Curve, Plant};
use rig::device::{ForceRange, STATUS_SATURATED, SimTruth, Wrench};

impl Plant {
    /// The contact's tilting-moment arms (mm) where a tangential force last acted: zero
    /// before one has and without a shear channel. The full-stick arms, the one along the
    /// shear stage's axis moved toward its full-slip value as far as the shear's elastic
    /// force has gone along its backbone (`tilt_arms_at`).
    fn tilt_arms_mm(&self) -> (f64, f64) {
        let Some(c) = self.shear.as_ref() else {
            return (0.0, 0.0);
        };
        let Some(tilt) = c.tilt.as_ref() else {
            return (0.0, 0.0);
        };
        // Partial slip moves the arm along x as far as the shear's elastic force has gone
        // along its backbone, from that backbone's own full-stick arm (a disturbance alone
        // may have moved `tilt` to another depth since; the force still follows the
        // backbone of the depth the stage last moved at).
        match c.curve.as_ref().and_then(|curve| {
            curve
                .slip_tilt
                .as_ref()
                .map(|(stuck_x, slip)| (&curve.backbone, *stuck_x, slip))
        }) {
            Some((backbone, stuck_x, slip)) => tilt_arms_at(
                (stuck_x, tilt.arms_mm.1),
                backbone,
                slip,
                c.element.force(),
                c.element.sliding(),
            ),
            _ => tilt.arms_mm,
        }
    }

    /// The true wrench at the plant's current time, before sensor effects.
    pub(crate) fn true_wrench(&self) -> Wrench {
        if self.grasp.is_some() {
            // Behind the sponge, the Nano17 feels the squeeze and the sponge side's share.
            let l = self.grasp_loads().unwrap_or_default();
            return Wrench {
                fx_n: 0.0,
                fy_n: l.sponge_n,
                fz_n: self.normal_n,
                tx_nmm: 0.0,
                ty_nmm: 0.0,
                tz_nmm: l.sponge_nmm,
            };
        }
        let mut fy = 0.0;
        let mut tz = self.twist.as_ref().map(|c| c.state.value()).unwrap_or(0.0);
        if let Some(d) = self.disturbance
            && self.t_ns >= d.t0_ns
            && self.t_ns < d.t1_ns
            && self.in_contact
        {
            let phase = 2.0 * PI * d.frequency_hz * (self.t_ns - d.t0_ns) as f64 * 1e-9;
            fy += d.force_y_n * phase.sin();
            tz += d.torque_z_nmm * phase.sin();
        }
        let fx = self.shear.as_ref().map(|c| c.state.value()).unwrap_or(0.0);
        // A stuck contact's shear tilts its pressure through the layer's coupling.
        let (tx, ty) = tilting_moments_nmm(self.tilt_arms_mm(), fx, fy);
        Wrench {
            fx_n: fx,
            fy_n: fy,
            fz_n: self.normal_n,
            tx_nmm: tx,
            ty_nmm: ty,
            tz_nmm: tz,
        }
    }

    /// Ground truth at `t_ns`: depth, the wrench without sensor effects, the long-term
    /// (equilibrium) wrench of the present state, and the contact's slip state.
    pub(crate) fn truth(&mut self, t_ns: u64) -> SimTruth {
        self.advance_to(t_ns);
        let d = self.depth_at(t_ns);
        let stick = |c: &Option<Channel>| -> Option<f64> {
            let c = c.as_ref()?;
            let Curve {
                backbone: b,
                stick: s,
                ..
            } = c.curve.as_ref()?;
            let x = b.displacement_at(c.element.force());
            let n = b.x.len();
            if n == 0 {
                return None;
            }
            let xa = x.abs();
            if xa >= b.x[n - 1] || c.element.sliding() {
                return Some(0.0);
            }
            let i = b.x.partition_point(|v| *v <= xa).clamp(1, n - 1);
            let t = (xa - b.x[i - 1]) / (b.x[i] - b.x[i - 1]);
            Some(s[i - 1] * (1.0 - t) + s[i] * t)
        };
        let h = self.spec.contact.layer.thickness_mm;
        let fx_eq = self
            .shear
            .as_ref()
            .map(|c| c.element.force())
            .unwrap_or(0.0);
        let (tx_eq, ty_eq) = if self.grasp.is_some() {
            (0.0, 0.0)
        } else {
            tilting_moments_nmm(self.tilt_arms_mm(), fx_eq, 0.0)
        };
        SimTruth {
            depth_mm: d,
            wrench: self.true_wrench(),
            equilibrium: Wrench {
                fx_n: fx_eq,
                fy_n: self.grasp_loads().map(|l| l.sponge_n).unwrap_or(0.0),
                fz_n: self.equilibrium_normal_n(t_ns),
                tx_nmm: tx_eq,
                ty_nmm: ty_eq,
                tz_nmm: self
                    .twist
                    .as_ref()
                    .map(|c| c.element.force())
                    .unwrap_or(0.0),
            },
            contact_radius_mm: if d > 0.0 {
                self.model.contact_radius_mm(d.min(0.95 * h))
            } else {
                0.0
            },
            shear_stick_fraction: stick(&self.shear),
            twist_stick_fraction: stick(&self.twist),
            shear_sliding: self.shear.as_ref().is_some_and(|c| c.element.sliding()),
            twist_sliding: self.twist.as_ref().is_some_and(|c| c.element.sliding()),
            shear_slips: self.shear.as_ref().map(|c| c.element.slips()).unwrap_or(0),
            twist_slips: self.twist.as_ref().map(|c| c.element.slips()).unwrap_or(0),
            object_slips: self.grasp.as_ref().map(|g| g.state().slips).unwrap_or(0),
            grasp: self.grasp_truth(),
        }
    }

    /// Reads the simulated sensor at `t_ns`: true wrench plus bias, noise at the sensor's
    /// resolution, quantisation to it, and clipping with the saturation flag.
    pub(crate) fn sense(&mut self, t_ns: u64, range: &ForceRange) -> (Wrench, u32) {
        self.advance_to(t_ns);
        let truth = self.true_wrench();
        let mut status = 0;
        let noise = self.geometry.noise;
        let mut channel = |v: f64, bias: f64, res: f64, lim: f64, rng: &mut StdRng| -> f64 {
            let z: f64 = if noise {
                rng.sample(StandardNormal)
            } else {
                0.0
            };
            let raw = ((v + bias + z * res) / res).round() * res;
            if raw.abs() > lim {
                status |= STATUS_SATURATED;
                raw.signum() * lim
            } else {
                raw
            }
        };
        let (fr, tr) = (range.force_resolution_n, range.torque_resolution_nmm);
        let b = self.bias;
        let rng = &mut self.rng;
        let w = Wrench {
            fx_n: channel(truth.fx_n, b.fx_n, fr, range.fxy_n, rng),
            fy_n: channel(truth.fy_n, b.fy_n, fr, range.fxy_n, rng),
            fz_n: channel(truth.fz_n, b.fz_n, fr, range.fz_n, rng),
            tx_nmm: channel(truth.tx_nmm, b.tx_nmm, tr, range.torque_nmm, rng),
            ty_nmm: channel(truth.ty_nmm, b.ty_nmm, tr, range.torque_nmm, rng),
            tz_nmm: channel(truth.tz_nmm, b.tz_nmm, tr, range.torque_nmm, rng),
        };
        (w, status)
    }
}
