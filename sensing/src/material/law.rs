//! A pressing run's elastic force law at unit modulus: its indenter and layer as the
//! mechanics models them, built at any Poisson's ratio (`fit-material` fits E∞ against it,
//! and ν where two flat punch sizes' forces tell it).

use mechanics::response::{ContactModel, ModelSpec};

/// How a run's elastic force at unit modulus (1 MPa) against depth is built: the run's
/// indenter and layer, pressed as its rig presses.
pub(super) struct ForceLaw {
    /// The model's spec at 1 MPa.
    pub(super) spec: ModelSpec,
    /// The rig presses at finite strain (`contact:` or `sim: {finite_strain: true}`).
    pub(super) finite_strain: bool,
}

impl ForceLaw {
    /// The radius of a flat circular punch over the layer's thickness, a/h: the one
    /// indenter whose law only scales with ν, through the layer's κ(a/h, ν) solved exactly
    /// (other flat shapes come from a grid whose residual's dependence on ν is unchecked).
    pub(super) fn flat_circle_a_over_h(&self) -> Option<f64> {
        match self.spec.contact.indenter {
            mechanics::Indenter::FlatCircle { diameter_mm } => {
                Some(0.5 * diameter_mm / self.spec.contact.layer.thickness_mm)
            }
            _ => None,
        }
    }

    /// The force at 1 MPa against depth at Poisson's ratio `nu` (a depth table, linearly
    /// interpolated); `None` where the mechanics has no model for it.
    pub(super) fn table(&self, nu: f64) -> Option<(Vec<f64>, Vec<f64>)> {
        let mut spec = self.spec.clone();
        spec.contact.material.poisson_ratio = nu;
        let h = spec.contact.layer.thickness_mm;
        let depths: Vec<f64> = (0..=200)
            .map(|i| spec.max_depth_mm * i as f64 / 200.0)
            .collect();
        let m = ContactModel::build(spec).ok()?;
        // The bench's own force law: at finite strain where its rig presses so.
        let f: Vec<f64> = depths
            .iter()
            .map(|&d| {
                let s = if self.finite_strain && m.is_flat() {
                    let a = m.contact_radius_mm(d);
                    mechanics::finite_strain::flat_punch_stiffening(d / h, a / h)
                } else {
                    1.0
                };
                m.normal_force_n(d) * s
            })
            .collect();
        Some((depths, f))
    }
}

/// The least-squares scale from force table `base` to table `other` over (0, `deepest_mm`]
/// (50 depths): how a run's force law moves with ν, one number per run. `None` where the
/// base law carries no force there.
pub(super) fn law_scale(
    base: &(Vec<f64>, Vec<f64>),
    other: &(Vec<f64>, Vec<f64>),
    deepest_mm: f64,
) -> Option<f64> {
    let (mut num, mut den) = (0.0, 0.0);
    for i in 1..=50 {
        let d = deepest_mm * i as f64 / 50.0;
        let f0 = interp(base, d);
        num += interp(other, d) * f0;
        den += f0 * f0;
    }
    (den > 0.0 && num > 0.0).then(|| num / den)
}

/// Linear interpolation in a depth table, zero out of contact, extended linearly past its
/// end.
pub(super) fn interp((d, f): &(Vec<f64>, Vec<f64>), x: f64) -> f64 {
    if x <= 0.0 || d.len() < 2 {
        return 0.0;
    }
    let i = d.partition_point(|v| *v < x).clamp(1, d.len() - 1);
    let w = (x - d[i - 1]) / (d[i] - d[i - 1]).max(1e-300);
    f[i - 1] + w * (f[i] - f[i - 1])
}
