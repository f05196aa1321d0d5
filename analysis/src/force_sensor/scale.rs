//! The thesis's scale fit (§4.3–4.4), generalised to combined loads by superposition.
//!
//! The thesis fits one reference field of the contact to the measured field and reads the
//! load from the scale. A linear layer superposes its responses, so a frame under pressing,
//! shear and twist together is fitted by all the reference fields at once:
//! u ≈ s_n U_n + s_x U_x + s_y U_y + s_θ U_θ + c r̂, with U the fields of a normal, an x
//! shear, a y shear and a twisting load on the calibration's contact (from the layer model in
//! `mechanics`) and c r̂ the thesis's additive radial term (the outward spread a no-slip model
//! lacks, §4.3). Weighted least squares with the thesis's reliability weights (Fig. 4-7b);
//! the five coefficients are the features the per-channel ridge maps to the wrench.

use nalgebra::{DMatrix, DVector};

use crate::field_force::reliability_weight;

/// Names of the scale fit's coefficients, the features of the `scale-fit` method.
pub const SCALE_FEATURES: [&str; 5] = [
    "scale_normal",
    "scale_shear_x",
    "scale_shear_y",
    "scale_twist",
    "radial_offset_mm",
];

/// The reference fields at a layout's markers, ready to fit frames.
#[derive(Debug, Clone)]
pub struct ScaleBasis {
    /// Per basis field, its displacement at each marker, mm.
    fields: Vec<Vec<[f64; 2]>>,
    /// Each marker's reliability weight.
    weights: Vec<f64>,
    /// (Bᵀ W B)⁻¹.
    gram_inv: DMatrix<f64>,
}

impl ScaleBasis {
    /// The basis of the four load fields `loads` (normal, shear x, shear y, twist; mm at each
    /// of the markers `markers_mm`, positions from the contact's centre) and the radial
    /// term, weighted for a contact of radius `contact_radius_mm`. `None` when the fields
    /// do not determine the coefficients (a singular fit).
    pub fn new(
        loads: [Vec<[f64; 2]>; 4],
        markers_mm: &[[f64; 2]],
        contact_radius_mm: f64,
    ) -> Option<Self> {
        let n = markers_mm.len();
        if loads.iter().any(|f| f.len() != n) || n < SCALE_FEATURES.len() + 1 {
            return None;
        }
        let radial: Vec<[f64; 2]> = markers_mm
            .iter()
            .map(|p| {
                let r = p[0].hypot(p[1]);
                if r > 1e-9 {
                    [p[0] / r, p[1] / r]
                } else {
                    [0.0, 0.0]
                }
            })
            .collect();
        let weights: Vec<f64> = markers_mm
            .iter()
            .map(|p| reliability_weight(p[0].hypot(p[1]), contact_radius_mm))
            .collect();
        let mut fields: Vec<Vec<[f64; 2]>> = loads.into_iter().collect();
        fields.push(radial);
        let k = fields.len();
        let gram = DMatrix::from_fn(k, k, |a, b| {
            (0..n)
                .map(|i| {
                    weights[i]
                        * (fields[a][i][0] * fields[b][i][0] + fields[a][i][1] * fields[b][i][1])
                })
                .sum::<f64>()
        });
        // Each field's scale differs by orders of magnitude (mm per N, per N·mm, unit
        // vectors): judge singularity on the correlation, not on raw values.
        let d: Vec<f64> = (0..k).map(|a| gram[(a, a)].max(1e-300).sqrt()).collect();
        let corr = DMatrix::from_fn(k, k, |a, b| gram[(a, b)] / (d[a] * d[b]));
        // Bounded and only on finite input: nalgebra's plain `svd` may never return.
        if !corr.iter().all(|v| v.is_finite()) {
            return None;
        }
        let svd = corr.clone().try_svd(false, false, f64::EPSILON, 1000)?;
        let (smax, smin) = svd
            .singular_values
            .iter()
            .fold((0.0f64, f64::INFINITY), |(hi, lo), s| {
                (hi.max(*s), lo.min(*s))
            });
        // NaN (a non-finite field) fails the comparison and is refused too.
        if smin.partial_cmp(&(1e-10 * smax)) != Some(std::cmp::Ordering::Greater) {
            return None;
        }
        let corr_inv = corr.try_inverse()?;
        let gram_inv = DMatrix::from_fn(k, k, |a, b| corr_inv[(a, b)] / (d[a] * d[b]));
        Some(Self {
            fields,
            weights,
            gram_inv,
        })
    }

    /// The coefficients ([`SCALE_FEATURES`]) of displacements `u_mm` at the markers.
    pub fn features(&self, u_mm: &[[f64; 2]]) -> Vec<f64> {
        let k = self.fields.len();
        let rhs = DVector::from_fn(k, |a, _| {
            self.fields[a]
                .iter()
                .zip(u_mm)
                .zip(&self.weights)
                .map(|((f, u), w)| w * (f[0] * u[0] + f[1] * u[1]))
                .sum::<f64>()
        });
        (&self.gram_inv * rhs).iter().copied().collect()
    }

    /// The basis fields, mm at each marker (the four loads, then the radial term).
    pub fn fields(&self) -> &[Vec<[f64; 2]>] {
        &self.fields
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn markers() -> Vec<[f64; 2]> {
        (0..15)
            .flat_map(|i| (0..12).map(move |j| [i as f64 * 1.5 - 10.5, j as f64 * 1.5 - 8.25]))
            .collect()
    }

    /// Smooth, unlike fields: a radial bump, two shears, a swirl.
    fn loads(m: &[[f64; 2]]) -> [Vec<[f64; 2]>; 4] {
        let bump = |p: &[f64; 2]| (-(p[0] * p[0] + p[1] * p[1]) / 30.0).exp();
        [
            m.iter()
                .map(|p| [0.01 * p[0] * bump(p), 0.01 * p[1] * bump(p)])
                .collect(),
            m.iter().map(|p| [0.05 * bump(p), 0.0]).collect(),
            m.iter().map(|p| [0.0, 0.05 * bump(p)]).collect(),
            m.iter()
                .map(|p| [-0.002 * p[1] * bump(p), 0.002 * p[0] * bump(p)])
                .collect(),
        ]
    }

    #[test]
    fn a_superposed_field_gives_back_its_scales() {
        let m = markers();
        let basis = ScaleBasis::new(loads(&m), &m, 4.0).expect("basis");
        let want = [3.0, -0.7, 1.2, 2.5, 0.004];
        let u: Vec<[f64; 2]> = (0..m.len())
            .map(|i| {
                let mut v = [0.0; 2];
                for (k, s) in want.iter().enumerate() {
                    v[0] += s * basis.fields()[k][i][0];
                    v[1] += s * basis.fields()[k][i][1];
                }
                v
            })
            .collect();
        let got = basis.features(&u);
        for (g, w) in got.iter().zip(want) {
            assert!(
                (g - w).abs() < 1e-9 * w.abs().max(1.0),
                "{got:?} vs {want:?}"
            );
        }
    }

    #[test]
    fn fields_that_cannot_be_told_apart_are_refused() {
        let m = markers();
        let mut l = loads(&m);
        l[2] = l[1].clone();
        assert!(ScaleBasis::new(l, &m, 4.0).is_none());
    }
}
