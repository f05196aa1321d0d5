//! Finite strain on the bonded layer: how much stiffer a nearly incompressible neo-Hookean
//! gel presses than the small-strain model that every solver here assumes.
//!
//! The reference is an axisymmetric finite-element solution of the same layer at finite
//! strain (`tests/peers/layer_finite_strain_fe.py`: total Lagrangian, nearly incompressible
//! neo-Hookean in mixed Taylor–Hood form, ν = 0.49, Newton on depth increments; its small
//! strain part reproduces the linear oracle's κ to 4e-6; two nested meshes, which agree to
//! 4e-3). A stuck flat punch on a thin layer stiffens at first order in δ/h — the layer
//! under the face thins, and a bonded incompressible layer's stiffness grows steeply as it
//! does: the portable punch (a/h = 3.1) presses 6.9 % harder at 5 % strain, 29 % at 20 %,
//! 45 % at 30 %; the box's 9.5 mm punch (a/h = 1.1) 4.5 % at 5 %, 21 % at 20 %. A sphere
//! does not: within 1 % to 2 mm on the box gel (the contact grows outward instead), so curved
//! indenters get no correction.
//!
//! [`flat_punch_stiffening`] interpolates the reference's force ratio linearly in strain
//! (from 1 at zero) and in a/h between its two punches, holding a/h at the nearer end
//! outside [1.13, 3.13] and extending the last strain segment's slope beyond the reference's
//! deepest strain (30 % portable, 20 % box). It is the stuck punch's ratio: at μ = 0.6 a
//! pressed punch sticks (issue 19's coupled solution), and the frictionless finite-strain
//! problem is ill-posed at the punch's edge (the reference's Newton stops near 11–15 %; where
//! it converged its ratio was 2–5 % higher).
//!
//! Whether a real gel follows: the thesis measured the box sensor's small flat punch "in a
//! good linear relation within a fairly large range" (§4.3, Fig. 4-5), which a neo-Hookean gel
//! would not be, so the simulator applies this only when asked (`sim: {finite_strain: true}`).

/// The reference's stuck flat punches: (a/h, [(δ/h, F_finite/F_linear)]), the finer mesh.
const FLAT_STUCK: [(f64, &[(f64, f64)]); 2] = [
    (
        4.75 / 4.2,
        &[
            (0.05, 1.045_409),
            (0.10, 1.098_774),
            (0.15, 1.155_269),
            (0.20, 1.213_456),
        ],
    ),
    (
        6.25 / 2.0,
        &[
            (0.05, 1.069_216),
            (0.10, 1.140_689),
            (0.15, 1.212_979),
            (0.20, 1.287_252),
            (0.25, 1.365_625),
            (0.30, 1.447_954),
        ],
    ),
];

/// The reference's points, for checks against its file.
pub fn flat_punch_reference() -> Vec<(f64, Vec<(f64, f64)>)> {
    FLAT_STUCK
        .iter()
        .map(|(ah, pts)| (*ah, pts.to_vec()))
        .collect()
}

/// The finite-strain force of a flat punch over the small-strain one at `strain` = δ/h, for
/// a face of equivalent radius a = `a_over_h`·h (1 at zero strain and for strain ≤ 0).
pub fn flat_punch_stiffening(strain: f64, a_over_h: f64) -> f64 {
    if strain.is_nan() || strain <= 0.0 {
        return 1.0;
    }
    let along = |pts: &[(f64, f64)]| -> f64 {
        let mut prev = (0.0, 1.0);
        for &p in pts {
            if strain <= p.0 {
                return prev.1 + (p.1 - prev.1) * (strain - prev.0) / (p.0 - prev.0);
            }
            prev = p;
        }
        let n = pts.len();
        let (a, b) = (pts[n.saturating_sub(2)], pts[n - 1]);
        b.1 + (b.1 - a.1) / (b.0 - a.0) * (strain - b.0)
    };
    let (lo, hi) = (FLAT_STUCK[0], FLAT_STUCK[1]);
    let t = ((a_over_h - lo.0) / (hi.0 - lo.0)).clamp(0.0, 1.0);
    let t = if t.is_nan() { 0.0 } else { t };
    (1.0 - t) * along(lo.1) + t * along(hi.1)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The table's own points come back; zero strain is 1; between punches it lies between
    /// them; beyond the table it keeps rising with the last slope.
    #[test]
    fn the_stiffening_interpolates_the_reference() {
        for (ah, pts) in flat_punch_reference() {
            for (e, r) in pts {
                assert!((flat_punch_stiffening(e, ah) - r).abs() < 1e-12);
            }
        }
        assert_eq!(flat_punch_stiffening(0.0, 2.0), 1.0);
        assert_eq!(flat_punch_stiffening(-0.1, 2.0), 1.0);
        let mid = flat_punch_stiffening(0.1, 2.0);
        assert!(mid > 1.098_774 && mid < 1.140_689, "{mid}");
        assert!((flat_punch_stiffening(0.025, 3.125) - (1.0 + 0.5 * 0.069_216)).abs() < 1e-9);
        assert!(flat_punch_stiffening(0.4, 3.125) > 1.447_954);
        assert!((flat_punch_stiffening(0.1, 10.0) - 1.140_689).abs() < 1e-12);
        assert!(flat_punch_stiffening(f64::NAN, 2.0) == 1.0);
    }
}
