//! Force from the displacement field (thesis §4.3–4.4): the measured field is a scaled copy
//! of a reference field of the same contact, and the scale is proportional to the load.
//!
//! Per frame, a weighted least-squares scale `s` (and, for normal load, the thesis's
//! additive term, which absorbs the outward spreading that a no-slip model lacks, §4.3)
//! fits the measured component to the reference component at every measured marker. The
//! weights are the thesis's reliability weights (Fig. 4-7(b), §4.4): small inside the
//! contact and on its border (imprint shading and partial slip disturb the markers there),
//! largest just outside the contact, fading far away (small displacements, large relative
//! error). A linear map from scale to force is then calibrated on some steps and used to
//! predict the others (Fig. 4-8, 4-15).

use mechanics::response::Field;

use tracking::field::MarkerField;

/// Which component of the field is fitted.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Component {
    /// Radial from the contact centre (normal load), with an additive term.
    Radial,
    /// Along a unit direction in the image (shear direction), no additive term.
    Along([f64; 2]),
}

/// The thesis's reliability weight at distance `r` from the contact centre, for contact
/// radius `a` (both px): 0.1 inside 0.85a, 0.05 on the border (0.85a–1.15a), 1 out to 2a,
/// then fading as e^{−(r−2a)/a} (a piecewise reading of Fig. 4-7(b)).
pub fn reliability_weight(r: f64, a: f64) -> f64 {
    let a = a.max(1e-9);
    if r < 0.85 * a {
        0.1
    } else if r < 1.15 * a {
        0.05
    } else if r <= 2.0 * a {
        1.0
    } else {
        (-(r - 2.0 * a) / a).exp()
    }
}

/// In-plane displacement of a mechanics field at (x, y) mm from its centre, bilinear;
/// zero outside the grid.
pub fn sample(field: &Field, x_mm: f64, y_mm: f64) -> [f64; 2] {
    let g = field.grid;
    let n = g.n;
    let fx = x_mm / g.dx + (n / 2) as f64 - 0.5;
    let fy = y_mm / g.dx + (n / 2) as f64 - 0.5;
    if !(fx >= 0.0 && fy >= 0.0 && fx < (n - 1) as f64 && fy < (n - 1) as f64) {
        return [0.0, 0.0];
    }
    let (i, j) = (fx.floor() as usize, fy.floor() as usize);
    let (tx, ty) = (fx - i as f64, fy - j as f64);
    let at = |v: &[f64]| {
        let k = j * n + i;
        (1.0 - ty) * ((1.0 - tx) * v[k] + tx * v[k + 1])
            + ty * ((1.0 - tx) * v[k + n] + tx * v[k + n + 1])
    };
    [at(&field.ux), at(&field.uy)]
}

/// The reference field at every marker of `reference_px`, in px, for a contact centred at
/// `centre_px`, `mm_per_px` on the gel; `rotation_rad` turns the field's x axis into the
/// image (a shear along image direction θ uses a field sheared along x, turned by θ).
pub fn reference_at_markers(
    field: &Field,
    reference_px: &[[f64; 2]],
    centre_px: [f64; 2],
    mm_per_px: f64,
    rotation_rad: f64,
) -> Vec<[f64; 2]> {
    let (c, s) = (rotation_rad.cos(), rotation_rad.sin());
    reference_px
        .iter()
        .map(|p| {
            let (dx, dy) = (
                (p[0] - centre_px[0]) * mm_per_px,
                (p[1] - centre_px[1]) * mm_per_px,
            );
            // Into the field's frame, sample, back to the image frame, mm → px.
            let (fx, fy) = (c * dx + s * dy, -s * dx + c * dy);
            let u = sample(field, fx, fy);
            [
                (c * u[0] - s * u[1]) / mm_per_px,
                (s * u[0] + c * u[1]) / mm_per_px,
            ]
        })
        .collect()
}

/// One frame's fit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScaleFit {
    /// Measured ≈ scale × reference (+ offset).
    pub scale: f64,
    /// Additive term, px (0 for [`Component::Along`]).
    pub offset_px: f64,
    /// Weighted rms of the misfit, px.
    pub rms_px: f64,
    /// Markers used.
    pub markers: usize,
}

/// Fits `measured ≈ scale·reference (+ offset)` on the chosen component. `None` with
/// fewer than three usable markers or a reference without signal.
pub fn fit_scale(
    measured: &MarkerField,
    reference: &[[f64; 2]],
    centre_px: [f64; 2],
    contact_radius_px: f64,
    component: Component,
) -> Option<ScaleFit> {
    let additive = matches!(component, Component::Radial);
    let (mut sw, mut swr, mut swm, mut swrr, mut swrm) = (0.0, 0.0, 0.0, 0.0, 0.0);
    let mut rows = Vec::new();
    for i in measured.measured_ids() {
        let Some(rf) = reference.get(i) else { continue };
        let p = measured.reference_px[i];
        let (dx, dy) = (p[0] - centre_px[0], p[1] - centre_px[1]);
        let r = dx.hypot(dy);
        let dir = match component {
            Component::Radial if r > 1e-9 => [dx / r, dy / r],
            Component::Radial => continue,
            Component::Along(d) => d,
        };
        let u = measured.displacement_px[i];
        let (m, f) = (
            u[0] * dir[0] + u[1] * dir[1],
            rf[0] * dir[0] + rf[1] * dir[1],
        );
        let w = reliability_weight(r, contact_radius_px);
        sw += w;
        swr += w * f;
        swm += w * m;
        swrr += w * f * f;
        swrm += w * f * m;
        rows.push((w, f, m));
    }
    if rows.len() < 3 || swrr <= 1e-300 {
        return None;
    }
    let (scale, offset) = if additive {
        let det = sw * swrr - swr * swr;
        if det.abs() <= 1e-300 {
            return None;
        }
        (
            (sw * swrm - swr * swm) / det,
            (swrr * swm - swr * swrm) / det,
        )
    } else {
        (swrm / swrr, 0.0)
    };
    let rss: f64 = rows
        .iter()
        .map(|(w, f, m)| w * (m - scale * f - offset).powi(2))
        .sum();
    Some(ScaleFit {
        scale,
        offset_px: offset,
        rms_px: (rss / sw).sqrt(),
        markers: rows.len(),
    })
}

/// How scale maps to force.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Map {
    /// force = gain·scale + bias (flat punches: the field is proportional to the load).
    Linear,
    /// Piecewise linear through the calibration points sorted by scale, extended by the
    /// end segments (curved indenters: the field's shape changes with depth, so one
    /// reference field's scale grows slower than the force, but monotonically).
    Piecewise,
}

/// Scale-to-force calibration and its prediction error.
#[derive(Debug, Clone, PartialEq)]
pub struct Prediction {
    /// The map used.
    pub map: Map,
    /// Linear map: force per unit scale (piecewise: the overall slope).
    pub gain: f64,
    /// Linear map: force at zero scale.
    pub bias: f64,
    /// Predicted force per step (all steps).
    pub predicted: Vec<f64>,
    /// Whether each step was used to calibrate.
    pub calibration: Vec<bool>,
    /// Rms prediction error over the steps not used to calibrate, force units.
    pub rmse: f64,
    /// `rmse` as a percentage of the rms recorded force on those steps.
    pub rmse_pct: f64,
}

/// Calibrates on the steps where `calibrate[i]` and predicts the rest. `None` with fewer
/// than two calibration steps or no step left to predict.
pub fn calibrate_and_predict(
    scales: &[f64],
    forces: &[f64],
    calibrate: &[bool],
    map: Map,
) -> Option<Prediction> {
    let n = scales.len().min(forces.len()).min(calibrate.len());
    let pick = |want: bool| -> Vec<(f64, f64)> {
        (0..n)
            .filter(|&i| calibrate[i] == want && scales[i].is_finite() && forces[i].is_finite())
            .map(|i| (scales[i], forces[i]))
            .collect()
    };
    let mut cal = pick(true);
    let test = pick(false);
    if cal.len() < 2 || test.is_empty() {
        return None;
    }
    let (cs, cf): (Vec<f64>, Vec<f64>) = cal.iter().copied().unzip();
    let line = crate::linearity::fit_line(&cs, &cf, true)?;
    cal.sort_by(|a, b| a.0.total_cmp(&b.0));
    cal.dedup_by(|a, b| (a.0 - b.0).abs() < 1e-12);
    let piecewise = |s: f64| -> f64 {
        let k = cal.partition_point(|p| p.0 < s).clamp(1, cal.len() - 1);
        let (a, b) = (cal[k - 1], cal[k]);
        a.1 + (s - a.0) / (b.0 - a.0) * (b.1 - a.1)
    };
    let predict = |s: f64| match map {
        Map::Linear => line.slope * s + line.intercept,
        Map::Piecewise if cal.len() >= 2 => piecewise(s),
        Map::Piecewise => line.slope * s + line.intercept,
    };
    let mse = test
        .iter()
        .map(|(s, f)| (predict(*s) - f).powi(2))
        .sum::<f64>()
        / test.len() as f64;
    let ms = test.iter().map(|(_, f)| f * f).sum::<f64>() / test.len() as f64;
    Some(Prediction {
        map,
        gain: line.slope,
        bias: line.intercept,
        predicted: scales[..n].iter().map(|&s| predict(s)).collect(),
        calibration: calibrate[..n].to_vec(),
        rmse: mse.sqrt(),
        rmse_pct: 100.0 * (mse / ms.max(1e-300)).sqrt(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use mechanics::operator::Grid;

    fn radial_field(amp: f64) -> Field {
        // u_r = amp·r·e^{−r²/8} mm (a radiating bump), on a 64² grid of 0.25 mm.
        let grid = Grid { n: 64, dx: 0.25 };
        let (mut ux, mut uy) = (vec![0.0; 64 * 64], vec![0.0; 64 * 64]);
        for k in 0..64 * 64 {
            let (x, y) = grid.xy(k);
            let g = amp * (-(x * x + y * y) / 8.0).exp();
            ux[k] = g * x;
            uy[k] = g * y;
        }
        Field {
            grid,
            ux: ux.clone(),
            uy,
            uz: vec![0.0; 64 * 64],
        }
    }

    #[test]
    fn scale_of_a_scaled_field_and_force_prediction() {
        let field = radial_field(0.01);
        let refs: Vec<[f64; 2]> = (0..15)
            .flat_map(|j| (0..15).map(move |i| [10.0 + 20.0 * i as f64, 10.0 + 20.0 * j as f64]))
            .collect();
        let centre = [150.0, 150.0];
        let mm_per_px = 0.05;
        let reference = reference_at_markers(&field, &refs, centre, mm_per_px, 0.0);
        // Spot check: 1 mm (20 px) right of the centre, u = 0.01·1·e^{−1/8} mm.
        let k = refs
            .iter()
            .position(|p| *p == [170.0, 150.0])
            .expect("marker");
        assert!(
            (reference[k][0] - 0.01 * (-1.0f64 / 8.0).exp() / mm_per_px).abs() < 2e-3,
            "{:?}",
            reference[k]
        );
        let mut scales = Vec::new();
        let forces: Vec<f64> = (1..=8).map(|i| 0.9 * i as f64).collect();
        for (i, _) in forces.iter().enumerate() {
            let s = (i + 1) as f64 * 0.5;
            let measured = MarkerField {
                reference_px: refs.clone(),
                displacement_px: reference.iter().map(|u| [s * u[0], s * u[1]]).collect(),
                measured: vec![true; refs.len()],
            };
            let fit =
                fit_scale(&measured, &reference, centre, 30.0, Component::Radial).expect("fit");
            assert!((fit.scale - s).abs() < 1e-9 && fit.offset_px.abs() < 1e-9);
            scales.push(fit.scale);
        }
        let calibrate: Vec<bool> = (0..8).map(|i| i % 2 == 0).collect();
        let p =
            calibrate_and_predict(&scales, &forces, &calibrate, Map::Linear).expect("prediction");
        assert!(p.rmse < 1e-9 && (p.gain - 1.8).abs() < 1e-9);
        assert!(calibrate_and_predict(&scales, &forces, &[true; 8], Map::Linear).is_none());
        // A force growing faster than the scale: the piecewise map follows it.
        let curved: Vec<f64> = scales.iter().map(|s| 0.5 * s + 0.3 * s * s).collect();
        let lin = calibrate_and_predict(&scales, &curved, &calibrate, Map::Linear).expect("line");
        let pw =
            calibrate_and_predict(&scales, &curved, &calibrate, Map::Piecewise).expect("piecewise");
        assert!(
            pw.rmse_pct < 0.5 * lin.rmse_pct && pw.rmse_pct < 5.0,
            "{} {}",
            pw.rmse_pct,
            lin.rmse_pct
        );
    }

    #[test]
    fn weights_follow_the_thesis_shape() {
        let a = 50.0;
        assert!(reliability_weight(10.0, a) < reliability_weight(70.0, a));
        assert!(reliability_weight(50.0, a) < reliability_weight(10.0, a));
        assert!(reliability_weight(200.0, a) < reliability_weight(90.0, a));
    }
}
