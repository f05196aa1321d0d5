//! The thesis's representatives of a displacement field.
//!
//! - Normal load (§4.3, Fig. 4-4): the field radiates from the contact centre; its radial
//!   component against distance, u_r(r), is what the force is fitted to.
//! - Shear (§4.4, Fig. 4-12, 4-13): the direction of the mean displacement, the component
//!   of every marker along it, and that component along the central line through the
//!   contact centre — flat over a stuck contact, peaked at the centre under partial slip.
//! - Torsion (ch. 6, Fig. 6-15): a rotation about the contact centre.
//! - Superposition (§4.4): the field of a sheared contact minus the field of the same
//!   contact pressed only is the pure shear field.
//!
//! Only measured markers enter (see [`MarkerField::measured`]).

use super::MarkerField;
use crate::median;

/// The point the field radiates from, px: the weighted least-squares intersection of the
/// lines through each marker along its displacement (weight |u|², so markers that moved
/// little and point nowhere in particular count little). `None` when fewer than two markers
/// moved or all move parallel.
pub fn radiating_centre(field: &MarkerField) -> Option<[f64; 2]> {
    // Minimise Σ w |(I − d̂d̂ᵀ)(c − p)|²  ⇒  (Σ w P) c = Σ w P p,  P = I − d̂d̂ᵀ.
    let (mut a, mut b, mut c, mut rx, mut ry) = (0.0, 0.0, 0.0, 0.0, 0.0);
    let mut used = 0;
    for i in field.measured_ids() {
        let u = field.displacement_px[i];
        let m2 = u[0] * u[0] + u[1] * u[1];
        if m2 < 1e-6 {
            continue;
        }
        let (dx, dy) = (u[0] / m2.sqrt(), u[1] / m2.sqrt());
        let (pxx, pxy, pyy) = (1.0 - dx * dx, -dx * dy, 1.0 - dy * dy);
        let p = field.reference_px[i];
        a += m2 * pxx;
        b += m2 * pxy;
        c += m2 * pyy;
        rx += m2 * (pxx * p[0] + pxy * p[1]);
        ry += m2 * (pxy * p[0] + pyy * p[1]);
        used += 1;
    }
    let det = a * c - b * b;
    if used < 2 || det <= 1e-9 * (a + c) * (a + c) {
        return None;
    }
    Some([(c * rx - b * ry) / det, (a * ry - b * rx) / det])
}

/// One bin of a profile.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProfileBin {
    /// Bin centre: distance from the centre (radial) or position along the line, px.
    pub at_px: f64,
    /// Mean displacement component, px.
    pub mean_px: f64,
    /// Standard deviation of the component in the bin, px.
    pub spread_px: f64,
    /// Markers in the bin.
    pub count: usize,
}

fn bins(samples: &mut [(f64, f64)], width_px: f64) -> Vec<ProfileBin> {
    samples.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut out: Vec<ProfileBin> = Vec::new();
    let mut k = 0;
    while k < samples.len() {
        let index = (samples[k].0 / width_px).floor();
        let mut e = k;
        while e < samples.len() && (samples[e].0 / width_px).floor() == index {
            e += 1;
        }
        let part = &samples[k..e];
        let n = part.len() as f64;
        let mean = part.iter().map(|s| s.1).sum::<f64>() / n;
        let var = part.iter().map(|s| (s.1 - mean).powi(2)).sum::<f64>() / n;
        out.push(ProfileBin {
            at_px: (index + 0.5) * width_px,
            mean_px: mean,
            spread_px: var.sqrt(),
            count: part.len(),
        });
        k = e;
    }
    out
}

/// Radial component u_r against distance r from `centre_px`, in bins `bin_px` wide
/// (half a marker spacing keeps about one ring of markers per bin).
pub fn radial_profile(field: &MarkerField, centre_px: [f64; 2], bin_px: f64) -> Vec<ProfileBin> {
    let mut samples: Vec<(f64, f64)> = field
        .measured_ids()
        .filter_map(|i| {
            let p = field.reference_px[i];
            let (dx, dy) = (p[0] - centre_px[0], p[1] - centre_px[1]);
            let r = dx.hypot(dy);
            (r > 1e-9).then(|| {
                let u = field.displacement_px[i];
                (r, (u[0] * dx + u[1] * dy) / r)
            })
        })
        .collect();
    bins(&mut samples, bin_px.max(1e-6))
}

/// The shear representatives of a field.
#[derive(Debug, Clone, PartialEq)]
pub struct Shear {
    /// Direction of the shear, rad (image axes: x right, y down).
    pub direction_rad: f64,
    /// Mean displacement of the measured markers, px.
    pub mean_px: [f64; 2],
    /// Centre the central line passes through, px.
    pub centre_px: [f64; 2],
    /// Every marker's displacement component along the shear direction, px (unmeasured:
    /// NaN).
    pub component_px: Vec<f64>,
    /// The component along the central line against the position on it (0 at the centre,
    /// positive along the shear), in bins.
    pub central_line: Vec<ProfileBin>,
}

/// The shear direction (of the |u|-weighted mean displacement), each marker's component
/// along it, and the central-line profile through `centre_px` (default: the |u|²-weighted
/// centroid of the markers, where the contact drags the gel most), with markers within
/// `half_width_px` of the line, binned `bin_px` wide. `None` when nothing moved.
pub fn shear(
    field: &MarkerField,
    centre_px: Option<[f64; 2]>,
    half_width_px: f64,
    bin_px: f64,
) -> Option<Shear> {
    let (mut sx, mut sy, mut sw, mut n) = (0.0, 0.0, 0.0, 0.0);
    let (mut mx, mut my) = (0.0, 0.0);
    let (mut cx, mut cy, mut cw) = (0.0, 0.0, 0.0);
    for i in field.measured_ids() {
        let u = field.displacement_px[i];
        let m = u[0].hypot(u[1]);
        sx += m * u[0];
        sy += m * u[1];
        sw += m;
        mx += u[0];
        my += u[1];
        n += 1.0;
        let p = field.reference_px[i];
        cx += m * m * p[0];
        cy += m * m * p[1];
        cw += m * m;
    }
    if sw <= 1e-9 || n == 0.0 {
        return None;
    }
    let direction_rad = sy.atan2(sx);
    let (dx, dy) = (direction_rad.cos(), direction_rad.sin());
    let centre_px = centre_px.unwrap_or([cx / cw, cy / cw]);
    let component_px = (0..field.len())
        .map(|i| {
            if field.measured[i] {
                let u = field.displacement_px[i];
                u[0] * dx + u[1] * dy
            } else {
                f64::NAN
            }
        })
        .collect::<Vec<_>>();
    let mut line: Vec<(f64, f64)> = field
        .measured_ids()
        .filter_map(|i| {
            let p = field.reference_px[i];
            let (rx, ry) = (p[0] - centre_px[0], p[1] - centre_px[1]);
            let along = rx * dx + ry * dy;
            let across = -rx * dy + ry * dx;
            (across.abs() <= half_width_px).then_some((along, component_px[i]))
        })
        .collect();
    // Bins centred on the centre: shift by half a bin so 0 is a bin centre.
    for s in line.iter_mut() {
        s.0 += 0.5 * bin_px;
    }
    let mut central_line = bins(&mut line, bin_px.max(1e-6));
    for b in central_line.iter_mut() {
        b.at_px -= 0.5 * bin_px;
    }
    Some(Shear {
        direction_rad,
        mean_px: [mx / n, my / n],
        centre_px,
        component_px,
        central_line,
    })
}

/// A rigid rotation fitted to the field.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rotation {
    /// Angle, rad, positive from +x towards +y (clockwise on screen, y down).
    pub angle_rad: f64,
    /// Fixed point of the fitted motion, px; `None` when the angle is too small to place it
    /// or the point falls beyond twice the weighted radius of gyration of the markers used.
    pub centre_px: Option<[f64; 2]>,
    /// Weighted rms of what the rigid motion does not explain, px.
    pub residual_px: f64,
}

/// The weighted rigid motion (2-D Procrustes; Umeyama 1991) from the reference to the
/// displaced markers. Weights |u|² make the rotating contact region dominate over the still
/// surroundings; markers farther than `radius_px` from `around_px` (if given) are left out.
pub fn rotation(
    field: &MarkerField,
    around_px: Option<[f64; 2]>,
    radius_px: f64,
) -> Option<Rotation> {
    let pick: Vec<(usize, f64)> = field
        .measured_ids()
        .filter(|&i| {
            around_px.is_none_or(|c| {
                let p = field.reference_px[i];
                (p[0] - c[0]).hypot(p[1] - c[1]) <= radius_px
            })
        })
        .map(|i| {
            let u = field.displacement_px[i];
            (i, u[0] * u[0] + u[1] * u[1] + 1e-6)
        })
        .collect();
    let wsum: f64 = pick.iter().map(|p| p.1).sum();
    if pick.len() < 3 || wsum <= 0.0 {
        return None;
    }
    let mut pbar = [0.0; 2];
    let mut qbar = [0.0; 2];
    for &(i, w) in &pick {
        let p = field.reference_px[i];
        let u = field.displacement_px[i];
        for k in 0..2 {
            pbar[k] += w * p[k] / wsum;
            qbar[k] += w * (p[k] + u[k]) / wsum;
        }
    }
    // Cross-covariance H = Σ w (p − p̄)(q − q̄)ᵀ; the angle maximising tr(RH).
    let (mut sxx, mut sxy, mut syx, mut syy) = (0.0, 0.0, 0.0, 0.0);
    for &(i, w) in &pick {
        let p = field.reference_px[i];
        let u = field.displacement_px[i];
        let (px, py) = (p[0] - pbar[0], p[1] - pbar[1]);
        let (qx, qy) = (p[0] + u[0] - qbar[0], p[1] + u[1] - qbar[1]);
        sxx += w * px * qx;
        sxy += w * px * qy;
        syx += w * py * qx;
        syy += w * py * qy;
    }
    let angle = (sxy - syx).atan2(sxx + syy);
    let (c, s) = (angle.cos(), angle.sin());
    // Translation t = q̄ − R p̄; fixed point c solves (I − R) c = t.
    let t = [
        qbar[0] - (c * pbar[0] - s * pbar[1]),
        qbar[1] - (s * pbar[0] + c * pbar[1]),
    ];
    let (a11, a12, a21, a22) = (1.0 - c, s, -s, 1.0 - c);
    let det = a11 * a22 - a12 * a21;
    // A fixed point far outside the markers used means the motion is a translation with a
    // small twist, not a rotation about a point in view: report no centre then.
    let gyration = (pick
        .iter()
        .map(|&(i, w)| {
            let p = field.reference_px[i];
            w * ((p[0] - pbar[0]).powi(2) + (p[1] - pbar[1]).powi(2))
        })
        .sum::<f64>()
        / wsum)
        .sqrt();
    let centre_px = (angle.abs() > 1e-4 && det.abs() > 1e-12)
        .then(|| {
            [
                (a22 * t[0] - a12 * t[1]) / det,
                (a11 * t[1] - a21 * t[0]) / det,
            ]
        })
        .filter(|c| (c[0] - pbar[0]).hypot(c[1] - pbar[1]) <= 2.0 * gyration.max(1.0));
    let mut rss = 0.0;
    for &(i, w) in &pick {
        let p = field.reference_px[i];
        let u = field.displacement_px[i];
        let fit = [c * p[0] - s * p[1] + t[0], s * p[0] + c * p[1] + t[1]];
        rss += w * ((p[0] + u[0] - fit[0]).powi(2) + (p[1] + u[1] - fit[1]).powi(2));
    }
    Some(Rotation {
        angle_rad: angle,
        centre_px,
        residual_px: (rss / wsum).sqrt(),
    })
}

/// The pure shear field: `total` minus `pressing` (the same contact under normal load
/// only), marker by marker; measured only where both are.
pub fn subtract(total: &MarkerField, pressing: &MarkerField) -> MarkerField {
    let n = total.len().min(pressing.len());
    MarkerField {
        reference_px: total.reference_px[..n].to_vec(),
        displacement_px: (0..n)
            .map(|i| {
                let (a, b) = (total.displacement_px[i], pressing.displacement_px[i]);
                [a[0] - b[0], a[1] - b[1]]
            })
            .collect(),
        measured: (0..n)
            .map(|i| total.measured[i] && pressing.measured[i])
            .collect(),
    }
}

/// Median displacement magnitude of the measured markers, px (a robust size of the field).
pub fn median_magnitude(field: &MarkerField) -> Option<f64> {
    let mut m: Vec<f64> = field
        .measured_ids()
        .map(|i| field.displacement_px[i][0].hypot(field.displacement_px[i][1]))
        .collect();
    median(&mut m)
}

/// Mean displacement component along `dir` of the measured markers within `radius_px` of
/// `centre_px` (the gel under the contact centre, slip cue (c)). `None` if none.
pub fn mean_along_within(
    field: &MarkerField,
    centre_px: [f64; 2],
    dir: [f64; 2],
    radius_px: f64,
) -> Option<f64> {
    let v: Vec<f64> = field
        .measured_ids()
        .filter(|&i| {
            let p = field.reference_px[i];
            (p[0] - centre_px[0]).hypot(p[1] - centre_px[1]) <= radius_px
        })
        .map(|i| {
            let u = field.displacement_px[i];
            u[0] * dir[0] + u[1] * dir[1]
        })
        .collect();
    (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
}

/// Central-line displacement along `dir` near the contact centre (|s| < 0.4a) over that
/// near the contact edge (0.7a < |s| < 1.0a), using markers within `half_width_px` of the
/// line through `centre_px` along `dir` (slip cue (b), thesis Fig. 4-13). `None` when
/// either part has no marker or the edge barely moved.
pub fn centre_over_edge(
    field: &MarkerField,
    centre_px: [f64; 2],
    dir: [f64; 2],
    contact_radius_px: f64,
    half_width_px: f64,
) -> Option<f64> {
    let a = contact_radius_px;
    let (mut centre, mut edge) = (Vec::new(), Vec::new());
    for i in field.measured_ids() {
        let p = field.reference_px[i];
        let (dx, dy) = (p[0] - centre_px[0], p[1] - centre_px[1]);
        let along = dx * dir[0] + dy * dir[1];
        let across = -dx * dir[1] + dy * dir[0];
        if across.abs() > half_width_px {
            continue;
        }
        let u = field.displacement_px[i];
        let m = u[0] * dir[0] + u[1] * dir[1];
        if along.abs() < 0.4 * a {
            centre.push(m);
        } else if along.abs() > 0.7 * a && along.abs() < a {
            edge.push(m);
        }
    }
    if centre.is_empty() || edge.is_empty() {
        return None;
    }
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let e = mean(&edge);
    (e.abs() > 1e-3).then(|| mean(&centre) / e)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid_field(f: impl Fn([f64; 2]) -> [f64; 2]) -> MarkerField {
        let reference_px: Vec<[f64; 2]> = (0..15 * 12)
            .map(|k| [15.0 + (k % 15) as f64 * 20.0, 12.0 + (k / 15) as f64 * 20.0])
            .collect();
        MarkerField {
            displacement_px: reference_px.iter().map(|p| f(*p)).collect(),
            measured: vec![true; reference_px.len()],
            reference_px,
        }
    }

    #[test]
    fn radiating_centre_and_radial_profile_of_a_press() {
        let c = [151.3, 118.7];
        let field = grid_field(|p| {
            let (dx, dy) = (p[0] - c[0], p[1] - c[1]);
            let r = dx.hypot(dy);
            // Outward, peaking at r = 40 px, as a bonded layer under a punch.
            let ur = 3.0
                * (r / 40.0)
                * (1.0 - (r / 40.0).powi(2) / 3.0)
                    .max(0.0)
                    .max((-r / 40.0).exp());
            [ur * dx / r.max(1e-9), ur * dy / r.max(1e-9)]
        });
        let got = radiating_centre(&field).expect("a centre");
        assert!(
            (got[0] - c[0]).abs() < 1e-6 && (got[1] - c[1]).abs() < 1e-6,
            "{got:?}"
        );
        let profile = radial_profile(&field, got, 10.0);
        // Every marker's radial component equals the law at its radius (spread 0 in thin
        // bins) and the first bins grow with r.
        assert!(profile.len() > 10);
        assert!(profile[1].mean_px > profile[0].mean_px);
        let total: usize = profile.iter().map(|b| b.count).sum();
        assert_eq!(total, field.len());
    }

    #[test]
    fn shear_direction_component_and_central_line() {
        let (c, a) = ([150.0, 120.0], 30f64.to_radians());
        let field = grid_field(|p| {
            let r2 = (p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2);
            let m = 4.0 * (-r2 / (2.0 * 50.0f64.powi(2))).exp();
            [m * a.cos(), m * a.sin()]
        });
        let s = shear(&field, Some(c), 10.0, 10.0).expect("moved");
        assert!((s.direction_rad - a).abs() < 1e-9);
        // The component is the magnitude here, and the central line peaks at the centre.
        let peak = s
            .central_line
            .iter()
            .max_by(|x, y| x.mean_px.total_cmp(&y.mean_px))
            .expect("bins");
        assert!(peak.at_px.abs() <= 10.0, "peak at {}", peak.at_px);
        assert!(s.component_px.iter().all(|v| *v >= 0.0));
        // Without a given centre, the |u|²-weighted centroid finds it.
        let auto = shear(&field, None, 10.0, 10.0).expect("moved");
        assert!((auto.centre_px[0] - c[0]).abs() < 2.0 && (auto.centre_px[1] - c[1]).abs() < 2.0);
    }

    #[test]
    fn rotation_angle_and_centre_of_a_spin() {
        let (c, th) = ([140.0, 115.0], 2.5f64.to_radians());
        let field = grid_field(|p| {
            let (dx, dy) = (p[0] - c[0], p[1] - c[1]);
            [
                dx * th.cos() - dy * th.sin() - dx,
                dx * th.sin() + dy * th.cos() - dy,
            ]
        });
        let r = rotation(&field, None, 0.0).expect("fit");
        assert!((r.angle_rad - th).abs() < 1e-9, "{}", r.angle_rad);
        let got = r.centre_px.expect("placed");
        assert!((got[0] - c[0]).abs() < 1e-6 && (got[1] - c[1]).abs() < 1e-6);
        assert!(r.residual_px < 1e-9);
    }

    #[test]
    fn a_shift_with_a_slight_twist_has_no_rotation_centre_in_view() {
        // 6 px of shear with a 0.3° twist: the fixed point would be ~1100 px away.
        let th = 0.3f64.to_radians();
        let field = grid_field(|p| {
            let (dx, dy) = (p[0] - 150.0, p[1] - 120.0);
            [6.0 - th * dy, th * dx]
        });
        let r = rotation(&field, None, 0.0).expect("fit");
        assert!((r.angle_rad - th).abs() < 1e-3, "{}", r.angle_rad);
        assert_eq!(r.centre_px, None);
    }

    #[test]
    fn pure_shear_is_total_minus_pressing() {
        let press = grid_field(|p| [0.01 * (p[0] - 150.0), 0.01 * (p[1] - 120.0)]);
        let mut total = grid_field(|p| [0.01 * (p[0] - 150.0) + 2.0, 0.01 * (p[1] - 120.0)]);
        total.measured[5] = false;
        let pure = subtract(&total, &press);
        assert!(
            pure.measured_ids()
                .all(|i| (pure.displacement_px[i][0] - 2.0).abs() < 1e-12)
        );
        assert!(!pure.measured[5]);
        assert_eq!(median_magnitude(&pure), Some(2.0));
    }

    #[test]
    fn slip_cues_from_a_stuck_and_a_slipping_contact() {
        let c = [150.0, 120.0];
        // Stuck: everything within 60 px moves 3 px along x, decaying outside.
        let stuck = grid_field(|p| {
            let r = (p[0] - c[0]).hypot(p[1] - c[1]);
            [if r <= 60.0 { 3.0 } else { 3.0 * 60.0 / r }, 0.0]
        });
        let m = mean_along_within(&stuck, c, [1.0, 0.0], 30.0).expect("markers");
        assert!((m - 3.0).abs() < 1e-12);
        let r = centre_over_edge(&stuck, c, [1.0, 0.0], 60.0, 12.0).expect("ratio");
        assert!((r - 1.0).abs() < 1e-12, "{r}");
        // Partial slip: the edge lags the centre.
        let slipping = grid_field(|p| {
            let r = (p[0] - c[0]).hypot(p[1] - c[1]);
            [3.0 * (1.0 - 0.4 * (r / 60.0).min(1.0).powi(2)), 0.0]
        });
        let r = centre_over_edge(&slipping, c, [1.0, 0.0], 60.0, 12.0).expect("ratio");
        assert!(r > 1.1, "{r}");
    }
}
