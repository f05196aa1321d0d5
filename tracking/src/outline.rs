//! Geometry of a closed outline (a contact region's polygon): its area, centroid and second
//! moments, by the shoelace sums over its edges (Steger 1996, "On the calculation of
//! arbitrary moments of polygons").

/// Area (px²) and centroid (px) of the closed polygon `p`, either orientation; zero area
/// and a NaN centroid for a degenerate one.
pub(crate) fn area_centroid(p: &[[f64; 2]]) -> (f64, [f64; 2]) {
    let (mut a, mut cx, mut cy) = (0.0, 0.0, 0.0);
    for k in 0..p.len() {
        let (q, r) = (p[k], p[(k + 1) % p.len()]);
        let cross = q[0] * r[1] - r[0] * q[1];
        a += cross;
        cx += (q[0] + r[0]) * cross;
        cy += (q[1] + r[1]) * cross;
    }
    if a.abs() < 1e-12 {
        return (0.0, [f64::NAN; 2]);
    }
    (a.abs() / 2.0, [cx / (3.0 * a), cy / (3.0 * a)])
}

/// Central second moments per unit area of the closed polygon `p` about its centroid:
/// [σxx, σyy, σxy], px². A uniform disc of radius a has σxx = σyy = a²/4, σxy = 0; a
/// region's moment-equivalent ellipse has semi-axes 2√λ for the eigenvalues λ of
/// [[σxx, σxy], [σxy, σyy]]. `None` for a degenerate polygon.
pub(crate) fn second_moments(p: &[[f64; 2]]) -> Option<[f64; 3]> {
    let (area, c) = area_centroid(p);
    if area <= 0.0 || !c[0].is_finite() || !c[1].is_finite() {
        return None;
    }
    // Shoelace sums about the centroid, so the moments need no large cancellation.
    let (mut sxx, mut syy, mut sxy, mut signed) = (0.0, 0.0, 0.0, 0.0);
    for k in 0..p.len() {
        let (q, r) = (p[k], p[(k + 1) % p.len()]);
        let (x0, y0, x1, y1) = (q[0] - c[0], q[1] - c[1], r[0] - c[0], r[1] - c[1]);
        let cross = x0 * y1 - x1 * y0;
        signed += cross;
        sxx += (x0 * x0 + x0 * x1 + x1 * x1) * cross;
        syy += (y0 * y0 + y0 * y1 + y1 * y1) * cross;
        sxy += (x0 * y1 + 2.0 * x0 * y0 + 2.0 * x1 * y1 + x1 * y0) * cross;
    }
    // ∫x² dA = Σ/12, ∫xy dA = Σ/24, with the polygon's orientation's sign; area = signed/2.
    let a = signed / 2.0;
    Some([sxx / 12.0 / a, syy / 12.0 / a, sxy / 24.0 / a])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_square_has_its_area_and_centre() {
        let sq = [[0.0, 0.0], [4.0, 0.0], [4.0, 4.0], [0.0, 4.0]];
        let (a, c) = area_centroid(&sq);
        assert!((a - 16.0).abs() < 1e-12);
        assert!((c[0] - 2.0).abs() < 1e-12 && (c[1] - 2.0).abs() < 1e-12);
        let reversed: Vec<_> = sq.iter().rev().copied().collect();
        let (a2, c2) = area_centroid(&reversed);
        assert!((a2 - 16.0).abs() < 1e-12 && (c2[0] - 2.0).abs() < 1e-12);
    }

    /// A w × h rectangle has σxx = w²/12, σyy = h²/12 whichever way it is walked and
    /// wherever it sits; turned by 30°, its moments turn as a tensor; a fine polygon of a
    /// disc gives a²/4.
    #[test]
    fn second_moments_of_known_shapes() {
        let (w, h) = (6.0, 2.0);
        let rect = [
            [10.0, 5.0],
            [10.0 + w, 5.0],
            [10.0 + w, 5.0 + h],
            [10.0, 5.0 + h],
        ];
        let m = second_moments(&rect).expect("rectangle");
        assert!((m[0] - w * w / 12.0).abs() < 1e-12, "{m:?}");
        assert!((m[1] - h * h / 12.0).abs() < 1e-12, "{m:?}");
        assert!(m[2].abs() < 1e-12, "{m:?}");
        let rev: Vec<_> = rect.iter().rev().copied().collect();
        assert_eq!(second_moments(&rev), Some(m));
        let t = 30f64.to_radians();
        let (c, s) = (t.cos(), t.sin());
        let turned: Vec<[f64; 2]> = rect
            .iter()
            .map(|p| [c * p[0] - s * p[1], s * p[0] + c * p[1]])
            .collect();
        let q = second_moments(&turned).expect("turned");
        let (a, b) = (w * w / 12.0, h * h / 12.0);
        assert!((q[0] - (a * c * c + b * s * s)).abs() < 1e-9, "{q:?}");
        assert!((q[1] - (a * s * s + b * c * c)).abs() < 1e-9, "{q:?}");
        assert!((q[2] - (a - b) * s * c).abs() < 1e-9, "{q:?}");
        let disc: Vec<[f64; 2]> = (0..720)
            .map(|k| {
                let t = std::f64::consts::TAU * k as f64 / 720.0;
                [3.0 + 5.0 * t.cos(), -2.0 + 5.0 * t.sin()]
            })
            .collect();
        let d = second_moments(&disc).expect("disc");
        assert!((d[0] - 6.25).abs() < 1e-3 && (d[1] - 6.25).abs() < 1e-3 && d[2].abs() < 1e-9);
        assert_eq!(second_moments(&[[0.0, 0.0], [1.0, 1.0]]), None);
    }
}
