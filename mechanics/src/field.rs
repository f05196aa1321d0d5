//! In-plane surface displacement fields of the elastomer under normal, shear and torsional
//! load, as closed forms.
//!
//! The thesis found the fields superpose (Fig. 4-4, §6.3.2), so a combined load is the sum
//! of the three below. Sources:
//! - **normal**: the frictionless radial profile u_r(r)/d of a flat punch on the bonded,
//!   incompressible layer, tabulated in spec §1.9 at a/h = 1.131 and 1.51 (the thesis's two
//!   box-sensor punches), interpolated in a/h and continued beyond r = 3a with the layer
//!   kernel's decay e^{−0.739 r/h} (spec §1.8). It points outward and peaks just outside the
//!   contact, as thesis Fig. 4-2 and 4-7. Other indenters use their effective radius; the
//!   layer solver of the physics issue gives their exact fields.
//! - **shear**: Mindlin's full-stick field of a tangentially loaded circular contact on a
//!   half-space (spec §1.3): uniform under the contact, the transverse "8" outside.
//! - **torsion**: the Reissner–Sagoci / Lubkin rotation field (spec §1.6): rigid spin βr
//!   inside, (2β/π)[r·asin(a/r) − a√(1−a²/r²)] outside.

use std::f64::consts::PI;

/// r/a nodes of the tabulated radial profile.
const UR_R: [f64; 8] = [0.0, 0.5, 0.9, 1.05, 1.2, 1.5, 2.0, 3.0];
/// u_r/d at a/h = 1.131 (spec §1.9 table).
const UR_1131: [f64; 8] = [0.0, 0.320, 0.474, 0.496, 0.498, 0.453, 0.312, 0.109];
/// u_r/d at a/h = 1.51 (spec §1.9 table).
const UR_151: [f64; 8] = [0.0, 0.498, 0.728, 0.743, 0.719, 0.585, 0.320, 0.081];

/// Radial surface displacement (mm, outward positive) at distance `r_mm` from the centre of
/// a normal contact of radius `a_mm` and depth `depth_mm` on a layer of thickness
/// `thickness_mm`.
pub fn normal_radial_mm(a_mm: f64, depth_mm: f64, thickness_mm: f64, r_mm: f64) -> f64 {
    if depth_mm <= 0.0 || a_mm <= 0.0 {
        return 0.0;
    }
    let t = ((a_mm / thickness_mm - 1.131) / (1.51 - 1.131)).clamp(0.0, 1.0);
    let profile = |s: f64| -> f64 {
        let i = UR_R.partition_point(|&n| n <= s).clamp(1, UR_R.len() - 1);
        let (s0, s1) = (UR_R[i - 1], UR_R[i]);
        let w = ((s - s0) / (s1 - s0)).clamp(0.0, 1.0);
        let lo = UR_1131[i - 1] * (1.0 - w) + UR_1131[i] * w;
        let hi = UR_151[i - 1] * (1.0 - w) + UR_151[i] * w;
        lo * (1.0 - t) + hi * t
    };
    let s = r_mm / a_mm;
    let u = if s <= 3.0 {
        profile(s)
    } else {
        profile(3.0) * (-0.739 * (r_mm - 3.0 * a_mm) / thickness_mm).exp()
    };
    u * depth_mm
}

/// Mindlin full-stick field (u_x, u_y) in units of Q/(2πGa)·a/… : returns the displacement in
/// mm at (x, y) for tangential force `q_n` along +x on a circle of radius `a_mm`, shear
/// modulus `g_mpa`, Poisson ratio `nu` (spec §1.3, oracle O9).
pub fn mindlin_shear_mm(
    q_n: f64,
    g_mpa: f64,
    nu: f64,
    a_mm: f64,
    x_mm: f64,
    y_mm: f64,
) -> (f64, f64) {
    if a_mm <= 0.0 || g_mpa <= 0.0 {
        return (0.0, 0.0);
    }
    let c = q_n / (2.0 * PI * g_mpa * a_mm);
    let r = x_mm.hypot(y_mm);
    let (f0, f2) = if r <= a_mm {
        (PI / 2.0, 0.0)
    } else {
        let s = a_mm / r;
        (s.asin(), s * (1.0 - s * s).sqrt())
    };
    let theta = y_mm.atan2(x_mm);
    let ux = c * ((1.0 - nu / 2.0) * f0 + nu / 2.0 * (2.0 * theta).cos() * f2);
    let uy = c * (nu / 2.0) * (2.0 * theta).sin() * f2;
    (ux, uy)
}

/// Rigid tangential displacement δ of a stuck circular contact under force Q (spec §1.3):
/// δ = (2−ν)Q/(8Ga). Inverts [`mindlin_shear_mm`]'s scale for a given stage offset.
pub fn mindlin_force_for_offset_n(offset_mm: f64, g_mpa: f64, nu: f64, a_mm: f64) -> f64 {
    offset_mm * 8.0 * g_mpa * a_mm / (2.0 - nu)
}

/// Azimuthal displacement (mm) at radius `r_mm` for a twist `beta_rad` of a stuck circular
/// contact of radius `a_mm` (spec §1.6, oracle O14).
pub fn torsion_azimuthal_mm(beta_rad: f64, a_mm: f64, r_mm: f64) -> f64 {
    if r_mm <= a_mm {
        beta_rad * r_mm
    } else {
        let s = a_mm / r_mm;
        2.0 * beta_rad / PI * (r_mm * s.asin() - a_mm * (1.0 - s * s).sqrt())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn radial_profile_matches_table_and_points_outward_o16() {
        let (a, h, d) = (4.75, 4.2, 0.1);
        let at = |s: f64| normal_radial_mm(a, d, h, s * a) / d;
        assert!((at(0.5) - 0.3198).abs() < 0.003);
        assert!((at(1.5) - 0.453).abs() < 0.003);
        assert!((at(2.0) - 0.312).abs() < 0.003);
        // Outward everywhere, peak just outside the contact, decaying far away.
        let peak = (0..400)
            .map(|i| i as f64 * 0.01)
            .max_by(|p, q| at(*p).total_cmp(&at(*q)))
            .expect("non-empty");
        assert!(peak > 1.0 && peak < 1.3, "peak at {peak}a");
        assert!(at(6.0) > 0.0 && at(6.0) < 0.01);
    }

    #[test]
    fn mindlin_field_o9() {
        let (ux, uy) = mindlin_shear_mm(1.0, 1.0, 0.3, 1.0, 0.2, 0.1);
        assert!((ux - 0.2125).abs() < 1e-8 && uy.abs() < 1e-12);
        let (ux, _) = mindlin_shear_mm(1.0, 1.0, 0.3, 1.0, 1.5, 0.0);
        assert!((ux - 0.110582).abs() < 1e-6);
        let (ux, _) = mindlin_shear_mm(1.0, 1.0, 0.3, 1.0, 0.0, 1.5);
        assert!((ux - 0.086856).abs() < 1e-6);
        let (ux, uy) = mindlin_shear_mm(1.0, 1.0, 0.3, 1.0, 1.2, 0.9);
        assert!((ux - 0.102040).abs() < 1e-6 && (uy - 0.011388).abs() < 1e-6);
    }

    #[test]
    fn torsion_field_o14() {
        assert!((torsion_azimuthal_mm(1.0, 1.0, 1.5) - 0.222330).abs() < 1e-6);
        assert!((torsion_azimuthal_mm(1.0, 1.0, 3.0) - 0.048830).abs() < 1e-6);
        assert!((torsion_azimuthal_mm(1.0, 1.0, 0.5) - 0.5).abs() < 1e-15);
    }
}
