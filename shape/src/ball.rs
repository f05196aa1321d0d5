//! The ball's geometry, which is the calibration's truth: inside the contact circle the gel
//! has the ball's shape, so its slope and its depth below the circle's edge are known. The
//! same definitions score a reconstruction, in the calibration's leave-one-out figures, the
//! tests and BENCHMARKS alike.

use nalgebra::{Matrix4, Vector4};
use serde::{Deserialize, Serialize};

/// A press's contact circle in pixels (x right, y down).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Circle {
    /// Centre, px.
    pub x_px: f64,
    /// Centre, px.
    pub y_px: f64,
    /// Contact radius, px.
    pub radius_px: f64,
}

/// The depth slope `(∂d/∂x, ∂d/∂y)` of a ball of radius `ball_px` centred over `c` at pixel
/// `(x, y)`: the depth of the gel surface (positive into the gel) follows the sphere,
/// `d = √(R² − r²) − √(R² − a²)`.
pub fn slope(c: &Circle, ball_px: f64, x: f64, y: f64) -> [f64; 2] {
    let (dx, dy) = (x - c.x_px, y - c.y_px);
    let s = (ball_px * ball_px - dx * dx - dy * dy).max(1e-9).sqrt();
    [-dx / s, -dy / s]
}

/// The cap's depth at its centre below the circle's edge, in the units of `ball` and `a`.
pub fn cap_height(ball: f64, a: f64) -> f64 {
    ball - (ball * ball - a * a).max(0.0).sqrt()
}

/// How a depth map reads a ball press.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BallScore {
    /// The depth of the circle's centre below its edge, read against the ball's, % (signed).
    pub height_error_pct: f64,
    /// The radius of the sphere fitted to the reconstructed cap against the ball's, % (signed).
    pub radius_error_pct: f64,
    /// Root-mean-square angle between the read and the ball's surface normals inside the
    /// circle, degrees.
    pub slope_rms_deg: f64,
    /// The largest height beyond 2.5 contact radii (after its median is taken away), as a
    /// share of the cap's height: a spurious deep region outside the contact reads near 1.
    pub spurious: f64,
}

/// Scores a depth map (`depth_px`, positive into the gel, in pixels) and its slopes against
/// the ball of radius `ball_px` on `circle`; `mm_per_px` only to state the fit in mm.
pub fn score(
    depth_px: &[f32],
    slopes: (&[f32], &[f32]),
    size: (usize, usize),
    circle: &Circle,
    ball_px: f64,
) -> BallScore {
    let (w, h) = size;
    let a = circle.radius_px;
    let sample = |x: f64, y: f64| -> f64 {
        let (x0, y0) = (
            x.floor().clamp(0.0, (w - 2) as f64),
            y.floor().clamp(0.0, (h - 2) as f64),
        );
        let (fx, fy) = (x - x0, y - y0);
        let (i, j) = (x0 as usize, y0 as usize);
        let at = |i: usize, j: usize| depth_px[j * w + i] as f64;
        (1.0 - fy) * ((1.0 - fx) * at(i, j) + fx * at(i + 1, j))
            + fy * ((1.0 - fx) * at(i, j + 1) + fx * at(i + 1, j + 1))
    };
    // The centre's depth below the mean of the circle's edge (the part inside the frame).
    let mut edge = (0.0, 0usize);
    for k in 0..360 {
        let t = (k as f64).to_radians();
        let (x, y) = (circle.x_px + a * t.cos(), circle.y_px + a * t.sin());
        if x >= 0.0 && y >= 0.0 && x <= (w - 1) as f64 && y <= (h - 1) as f64 {
            edge.0 += sample(x, y);
            edge.1 += 1;
        }
    }
    let truth = cap_height(ball_px, a);
    let read = sample(circle.x_px, circle.y_px) - edge.0 / edge.1.max(1) as f64;
    // Algebraic sphere fit x² + y² + z² + Dx + Ey + Fz + G = 0 to the cap (Pratt 1987), and
    // the normals' angles, over the pixels inside the circle.
    let (mut ata, mut atb) = (Matrix4::<f64>::zeros(), Vector4::<f64>::zeros());
    let (mut ang2, mut n) = (0.0, 0usize);
    let mut far = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let (xf, yf) = (x as f64, y as f64);
            let r2 = (xf - circle.x_px).powi(2) + (yf - circle.y_px).powi(2);
            let i = y * w + x;
            if r2 < a * a {
                let z = depth_px[i] as f64;
                let v = Vector4::new(xf, yf, z, 1.0);
                ata += v * v.transpose();
                atb -= v * (xf * xf + yf * yf + z * z);
                let t = slope(circle, ball_px, xf, yf);
                let (g, u) = ([slopes.0[i] as f64, slopes.1[i] as f64], t);
                let dot = (g[0] * u[0] + g[1] * u[1] + 1.0)
                    / ((g[0] * g[0] + g[1] * g[1] + 1.0).sqrt()
                        * (u[0] * u[0] + u[1] * u[1] + 1.0).sqrt());
                ang2 += dot.clamp(-1.0, 1.0).acos().to_degrees().powi(2);
                n += 1;
            } else if r2 > 6.25 * a * a {
                far.push(depth_px[i] as f64);
            }
        }
    }
    let fitted = ata.lu().solve(&atb).map_or(f64::NAN, |s| {
        let c = [-s[0] / 2.0, -s[1] / 2.0, -s[2] / 2.0];
        (c[0] * c[0] + c[1] * c[1] + c[2] * c[2] - s[3])
            .max(0.0)
            .sqrt()
    });
    let spurious = if far.is_empty() {
        0.0
    } else {
        far.sort_by(f64::total_cmp);
        let median = far[far.len() / 2];
        far.iter().map(|v| (v - median).abs()).fold(0.0, f64::max) / truth
    };
    BallScore {
        height_error_pct: 100.0 * (read - truth) / truth,
        radius_error_pct: 100.0 * (fitted - ball_px) / ball_px,
        slope_rms_deg: (ang2 / n.max(1) as f64).sqrt(),
        spurious,
    }
}
