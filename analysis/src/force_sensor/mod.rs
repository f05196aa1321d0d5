//! The GelSight as a force sensor (thesis ch. 4, §6.2): the wrench (Fx, Fy, Fz, Tz) read from
//! the marker field, once calibrated against a force sensor.
//!
//! The method here is a regularised linear model on **moments of the displacement field**,
//! chosen because linear elasticity ties them to the wrench whatever the contact's shape. For
//! a layer of thickness h and shear modulus μ bonded to a rigid base, the surface compliance
//! Ĝ(k) relating traction to displacement (û = Ĝ t̂, [`mechanics::greens::layer`]) is even in k
//! with Ĝ_LL(0) = Ĝ_TT(0) = h/μ, and its normal–tangential coupling is odd, Ĉ(k) ≈ c₁k with
//! c₁ = h²[1 − (1−2ν)(3−4ν)] / (μ(8 − 16ν + 8ν²)) (h²/2μ at ν = ½). Moments of u are
//! derivatives of û at k = 0, so for *any* traction distribution:
//!
//! - ∫ u dA = (h/μ) (Fx, Fy): the mean displacement reads the shear force;
//! - ∫ r·u dA = 2c₁ Fz + (h/μ) ∫ r·t_∥ dA: the outward spread reads the normal force (the
//!   bonded layer pushes the surface outward, thesis Fig. 4-2);
//! - ∫ r×u dA = (h/μ) Tz: the curl moment reads the torque.
//!
//! A real gel's μ, the view's finite extent, its free edges and the markers' sampling make
//! the constants unknown, so they are fitted ([`ridge`]) on calibration runs, with the
//! regularisation chosen per channel by generalised cross-validation. Second moments are
//! offered to the fit as well (they carry what truncation at the view's edge loses).
//!
//! Markers that are not measured in a frame are filled from their measured neighbours
//! (inverse-distance weights over the reference layout), so a marker lost at the contact's
//! edge does not take its cell of the integral with it.

pub mod memory;
pub mod ridge;
pub mod scale;
pub mod traction;

use tracking::field::MarkerField;

/// The wrench channels, in the order of every array here.
pub const CHANNELS: [&str; 4] = ["fx_n", "fy_n", "fz_n", "tz_nmm"];

/// Names of the field moments, in the order of [`Layout::features`].
pub const FEATURES: [&str; 8] = [
    "int_ux",
    "int_uy",
    "int_r_dot_u",
    "int_r_cross_u",
    "int_x_ux_minus_y_uy",
    "int_x_uy_plus_y_ux",
    "int_r2_r_dot_u",
    "int_r2_r_cross_u",
];

/// Names of the traction map's integrals (at the nominal modulus), the features of the
/// `traction-map` method, and the normal integral times the contact's elongation
/// ([`traction::elongation`]). The first four are every traction sensor's; the fifth is read
/// only by a sensor calibrated on an elongated contact (sensor files from before it, and
/// calibrations on round contacts only, have the four).
///
/// Why the fifth: calibrated on a punch and a sphere, the map reads a strip's normal force (a
/// dowel, a can's side) high: the can's hold 17–24 % over ten trials, 0–5 % with the fifth
/// (docs/explanation/force-sensing.md, "The can's strip"). Under a curved
/// contact the gel's surface is caught as the contact grows and carries a frictional radial
/// shear (Spence 1975, "The Hertz contact problem with finite friction", J. Elasticity 5);
/// the map, which sees the pressure only through the layer's weak normal–tangential
/// coupling, takes part of that shear for pressure, in a share set by the contact's
/// plane-strain or axisymmetric shape. One scale cannot serve both, and the elongation,
/// scale-free and unchanged by turns, tells them apart. The figures behind it:
/// docs/explanation/force-sensing.md, "The can's strip: the elongation term".
pub const TRACTION_FEATURES: [&str; 5] = [
    "traction_fx",
    "traction_fy",
    "traction_fz",
    "traction_tz",
    ELONGATION_FEATURE,
];

/// The traction features of sensor files without the elongation term.
pub const TRACTION_FEATURES_ROUND: [&str; 4] =
    ["traction_fx", "traction_fy", "traction_fz", "traction_tz"];

/// The traction map's normal integral times the contact's elongation.
pub const ELONGATION_FEATURE: &str = "traction_fz_elongation";

/// How a feature changes when the whole load is turned or mirrored about the view's centre.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Symmetry {
    /// The x component of a vector (a shear force along x).
    VectorX,
    /// The y component of a vector.
    VectorY,
    /// Unchanged by turns and mirrors (a normal force, a radial spread).
    Scalar,
    /// Unchanged by turns, negated by a mirror (a torque, a curl).
    Pseudo,
    /// A rank-2 part (a pure shear of the field): turns at twice the angle; no channel is
    /// of this kind.
    Rank2,
}

fn symmetry(feature: &str) -> Option<Symmetry> {
    Some(match feature {
        "int_ux" | "scale_shear_x" | "traction_fx" => Symmetry::VectorX,
        "int_uy" | "scale_shear_y" | "traction_fy" => Symmetry::VectorY,
        "int_r_dot_u" | "int_r2_r_dot_u" | "scale_normal" | "radial_offset_mm" | "traction_fz"
        | ELONGATION_FEATURE => Symmetry::Scalar,
        "int_r_cross_u" | "int_r2_r_cross_u" | "scale_twist" | "traction_tz" => Symmetry::Pseudo,
        "int_x_ux_minus_y_uy" | "int_x_uy_plus_y_ux" => Symmetry::Rank2,
        _ => return None,
    })
}

/// Which of `features` each channel ([`CHANNELS`]) is fitted on when the calibration asks
/// for symmetry (`gelrig calibrate --symmetric`): those that turn as the channel does. The
/// layer is isotropic, so a load turned about the view's centre turns its field with it: Fx
/// and Fy are a vector's components, Fz a scalar and Tz a pseudo-scalar, and a linear
/// reading of them may use only features of the same kind (Fx ← ∫ux; Fz ← ∫r·u, ∫r²r·u;
/// Tz ← ∫r×u, ∫r²r×u). Tz also sees the shear features: the force sensor's axis is not the
/// view's centre, and its torque carries that offset times the shear force. A feature of
/// another kind reaches a channel only through a coincidence of the calibration's loads
/// (round contacts only, a twist never combined with an elongated one), and a load without
/// the coincidence then leaks in: fitted on every feature, a lifting can's twist read 0–36 N
/// of Fz under a steady 5 N squeeze, and punch shapes the calibration never saw read Fz
/// 2–7 % of span off. It assumes the force sensor's axes are the view's: in a grasp jig
/// whose Nano17 is turned against the camera, Fy is the view's x, and a symmetric fit
/// cannot map it. An unknown feature name is offered to every channel.
pub fn channel_features(features: &[&str]) -> Vec<Vec<bool>> {
    CHANNELS
        .iter()
        .map(|c| {
            features
                .iter()
                .map(|f| match (symmetry(f), *c) {
                    (None, _) => true,
                    (Some(s), "fx_n") => s == Symmetry::VectorX,
                    (Some(s), "fy_n") => s == Symmetry::VectorY,
                    (Some(s), "fz_n") => s == Symmetry::Scalar,
                    (Some(s), _) => {
                        matches!(s, Symmetry::Pseudo | Symmetry::VectorX | Symmetry::VectorY)
                    }
                })
                .collect()
        })
        .collect()
}

/// Why a field cannot be read with a layout.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum SensorError {
    /// The frame's markers do not match the layout the sensor was calibrated on.
    #[error(
        "only {matched} of the sensor's {expected} markers are within {tolerance_px:.1} px of this \
         recording's reference markers ({found} found): the sensor was calibrated on another \
         gel, view or camera; calibrate one for this setup"
    )]
    LayoutMismatch {
        /// Markers of the layout matched.
        matched: usize,
        /// Markers in the layout.
        expected: usize,
        /// Markers in the recording's reference.
        found: usize,
        /// Match tolerance, px.
        tolerance_px: f64,
    },
    /// Too few calibration samples for the model.
    #[error("{samples} calibration frames for {features} field moments: record more steps")]
    TooFewSamples {
        /// Frames given.
        samples: usize,
        /// Moments fitted.
        features: usize,
    },
}

/// The calibrated marker layout: where each marker sits on the untouched gel, the image
/// scale, and what each marker's cell of the integrals is.
#[derive(Debug, Clone, PartialEq)]
pub struct Layout {
    /// Reference marker centres, px.
    pub reference_px: Vec<[f64; 2]>,
    /// Image scale on the gel, mm per px.
    pub mm_per_px: f64,
    /// Origin of the moments, px (the view's centre).
    pub centre_px: [f64; 2],
    /// Each marker's share of the view, mm² (its cell: the view's area over the markers,
    /// the same for all on an even pattern).
    cell_mm2: f64,
    /// For each marker, its nearest neighbours (for filling unmeasured markers).
    neighbours: Vec<Vec<usize>>,
    /// Median nearest-neighbour distance, px.
    spacing_px: f64,
}

/// Neighbours used to fill an unmeasured marker.
const FILL_NEIGHBOURS: usize = 6;

/// Fewest of the layout's markers a recording must match, as a fraction.
const MIN_MATCHED: f64 = 0.8;

impl Layout {
    /// The layout of a reference field, `mm_per_px` on the gel, moments about `centre_px`.
    pub fn new(reference_px: Vec<[f64; 2]>, mm_per_px: f64, centre_px: [f64; 2]) -> Self {
        let n = reference_px.len();
        let neighbours: Vec<Vec<usize>> = (0..n)
            .map(|i| {
                let mut d: Vec<(f64, usize)> = (0..n)
                    .filter(|&j| j != i)
                    .map(|j| {
                        let (a, b) = (reference_px[i], reference_px[j]);
                        ((a[0] - b[0]).hypot(a[1] - b[1]), j)
                    })
                    .collect();
                d.sort_by(|x, y| x.0.total_cmp(&y.0));
                d.into_iter()
                    .take(FILL_NEIGHBOURS)
                    .map(|(_, j)| j)
                    .collect()
            })
            .collect();
        let mut nearest: Vec<f64> = neighbours
            .iter()
            .enumerate()
            .filter_map(|(i, nb)| {
                let j = *nb.first()?;
                let (a, b) = (reference_px[i], reference_px[j]);
                Some((a[0] - b[0]).hypot(a[1] - b[1]))
            })
            .collect();
        nearest.sort_by(f64::total_cmp);
        let spacing_px = nearest.get(nearest.len() / 2).copied().unwrap_or(0.0);
        // The markers' hull, grown by half a spacing each side, shared evenly.
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for p in &reference_px {
            for a in 0..2 {
                lo[a] = lo[a].min(p[a]);
                hi[a] = hi[a].max(p[a]);
            }
        }
        let cell_mm2 = if n > 1 {
            (hi[0] - lo[0] + spacing_px) * (hi[1] - lo[1] + spacing_px) / n as f64
                * mm_per_px
                * mm_per_px
        } else {
            0.0
        };
        Self {
            reference_px,
            mm_per_px,
            centre_px,
            cell_mm2,
            neighbours,
            spacing_px,
        }
    }

    /// Markers in the layout.
    pub fn len(&self) -> usize {
        self.reference_px.len()
    }

    /// Whether the layout has no markers.
    pub fn is_empty(&self) -> bool {
        self.reference_px.is_empty()
    }

    /// Typical marker spacing, px (median nearest-neighbour distance).
    pub fn spacing_px(&self) -> f64 {
        self.spacing_px
    }

    /// For each of this layout's markers, the index of the recording's marker at the same
    /// reference position (within a third of the spacing), or `None`; an error when fewer
    /// than 80 % match.
    pub fn match_markers(
        &self,
        reference_px: &[[f64; 2]],
    ) -> Result<Vec<Option<usize>>, SensorError> {
        let tol = self.spacing_px() / 3.0;
        // A coarse bucket grid keeps this linear in the markers.
        let cell = tol.max(1.0);
        let mut buckets: std::collections::HashMap<(i64, i64), Vec<usize>> =
            std::collections::HashMap::new();
        for (j, p) in reference_px.iter().enumerate() {
            let key = ((p[0] / cell).floor() as i64, (p[1] / cell).floor() as i64);
            buckets.entry(key).or_default().push(j);
        }
        let map: Vec<Option<usize>> = self
            .reference_px
            .iter()
            .map(|p| {
                let (bx, by) = ((p[0] / cell).floor() as i64, (p[1] / cell).floor() as i64);
                let mut best: Option<(f64, usize)> = None;
                for dx in -1..=1 {
                    for dy in -1..=1 {
                        for &j in buckets.get(&(bx + dx, by + dy)).into_iter().flatten() {
                            let q = reference_px[j];
                            let d = (p[0] - q[0]).hypot(p[1] - q[1]);
                            if d <= tol && best.is_none_or(|(b, _)| d < b) {
                                best = Some((d, j));
                            }
                        }
                    }
                }
                best.map(|(_, j)| j)
            })
            .collect();
        let matched = map.iter().filter(|m| m.is_some()).count();
        if (matched as f64) < MIN_MATCHED * self.len() as f64 || self.is_empty() {
            return Err(SensorError::LayoutMismatch {
                matched,
                expected: self.len(),
                found: reference_px.len(),
                tolerance_px: tol,
            });
        }
        Ok(map)
    }

    /// The field's displacement at each of the layout's markers, mm: measured where the
    /// recording measured the matched marker, else filled from measured neighbours
    /// (inverse-distance weights), else zero. Also the share of markers measured.
    pub fn displacements_mm(
        &self,
        field: &MarkerField,
        map: &[Option<usize>],
    ) -> (Vec<[f64; 2]>, f64) {
        let s = self.mm_per_px;
        let got: Vec<Option<[f64; 2]>> = map
            .iter()
            .map(|m| {
                let j = (*m)?;
                (field.measured.get(j).copied().unwrap_or(false))
                    .then(|| field.displacement_px.get(j).map(|d| [d[0] * s, d[1] * s]))
                    .flatten()
                    .filter(|d| d[0].is_finite() && d[1].is_finite())
            })
            .collect();
        let measured = got.iter().filter(|g| g.is_some()).count();
        let out = (0..self.len())
            .map(|i| {
                if let Some(d) = got[i] {
                    return d;
                }
                let (mut acc, mut wsum) = ([0.0; 2], 0.0);
                for &j in &self.neighbours[i] {
                    if let Some(d) = got[j] {
                        let (a, b) = (self.reference_px[i], self.reference_px[j]);
                        let w = 1.0 / (a[0] - b[0]).hypot(a[1] - b[1]).max(1e-6);
                        acc[0] += w * d[0];
                        acc[1] += w * d[1];
                        wsum += w;
                    }
                }
                if wsum > 0.0 {
                    [acc[0] / wsum, acc[1] / wsum]
                } else {
                    [0.0; 2]
                }
            })
            .collect();
        (out, measured as f64 / self.len().max(1) as f64)
    }

    /// The field moments ([`FEATURES`]) of displacements `u_mm` at the layout's markers:
    /// integrals over the view in mm³ (first moments) and mm⁵ (second), with r about
    /// [`Self::centre_px`] in mm.
    pub fn features(&self, u_mm: &[[f64; 2]]) -> [f64; 8] {
        let s = self.mm_per_px;
        let w = self.cell_mm2;
        let mut f = [0.0; 8];
        for (p, u) in self.reference_px.iter().zip(u_mm) {
            let (x, y) = (
                (p[0] - self.centre_px[0]) * s,
                (p[1] - self.centre_px[1]) * s,
            );
            let dot = x * u[0] + y * u[1];
            let cross = x * u[1] - y * u[0];
            let r2 = x * x + y * y;
            f[0] += w * u[0];
            f[1] += w * u[1];
            f[2] += w * dot;
            f[3] += w * cross;
            f[4] += w * (x * u[0] - y * u[1]);
            f[5] += w * (x * u[1] + y * u[0]);
            f[6] += w * r2 * dot;
            f[7] += w * r2 * cross;
        }
        f
    }
}

#[cfg(test)]
mod tests;
