//! A reference-free start: the undeformed marker lattice, inferred from a frame that already
//! shows contact, so a recording that begins mid-grasp can still be tracked.
//!
//! Grid markers are printed on a regular lattice, and a contact moves only the markers in
//! and around it; the periphery still sits where it was printed. So: the two lattice
//! directions are the peaks of the histogram of nearest-neighbour directions (modulo 180°),
//! the two steps the median neighbour distance along each; the origin is the detection whose
//! lattice explains the most others within a fifth of a spacing (a vote over candidates
//! spread across the frame); then origin and both steps are refitted by least squares on the
//! markers the lattice explains, three times with a tightening gate (three times the rms, at
//! most 0.15 spacing), then five times to the better half of those (least trimmed squares).
//! The fit is refused when fewer than 30 % of the detections (and 12)
//! fit, or they fit worse than 10 % of a spacing: random layouts, strongly distorted optics.
//!
//! A uniform shift of the whole gel cannot be seen this way (every shifted lattice is a
//! lattice); displacements are relative to the lattice that fits the periphery.

use super::TrackError;

/// The undeformed lattice: site (i, j) is at `origin + i·a + j·b`.
#[derive(Debug, Clone, PartialEq)]
pub struct Lattice {
    /// Site (0, 0), px.
    pub origin_px: [f64; 2],
    /// First step, px.
    pub a_px: [f64; 2],
    /// Second step, px.
    pub b_px: [f64; 2],
    /// Rms distance of the fitted markers from their sites, px.
    pub rms_px: f64,
    /// Markers the lattice explains.
    pub inliers: usize,
    /// Markers detected.
    pub detections: usize,
    /// Smallest and largest site indices (i, j) of the detections: the printed extent.
    pub extent: [[i64; 2]; 2],
}

impl Lattice {
    /// Where site (i, j) is.
    pub fn at(&self, i: f64, j: f64) -> [f64; 2] {
        [
            self.origin_px[0] + i * self.a_px[0] + j * self.b_px[0],
            self.origin_px[1] + i * self.a_px[1] + j * self.b_px[1],
        ]
    }

    /// Mean of the two steps, px.
    pub fn spacing_px(&self) -> f64 {
        0.5 * (self.a_px[0].hypot(self.a_px[1]) + self.b_px[0].hypot(self.b_px[1]))
    }

    /// Fractional lattice coordinates of `p`.
    fn coords(&self, p: [f64; 2]) -> [f64; 2] {
        let (a, b) = (self.a_px, self.b_px);
        let det = a[0] * b[1] - a[1] * b[0];
        let (dx, dy) = (p[0] - self.origin_px[0], p[1] - self.origin_px[1]);
        [(dx * b[1] - dy * b[0]) / det, (a[0] * dy - a[1] * dx) / det]
    }

    /// The sites of the printed extent whose centre lies in a `width × height` frame.
    pub fn sites_in(&self, width: usize, height: usize) -> Vec<[f64; 2]> {
        let (w, h) = (width as f64 - 1.0, height as f64 - 1.0);
        let corners = [[0.0, 0.0], [w, 0.0], [0.0, h], [w, h]].map(|c| self.coords(c));
        let lo = |k: usize| corners.iter().map(|c| c[k]).fold(f64::INFINITY, f64::min);
        let hi = |k: usize| {
            corners
                .iter()
                .map(|c| c[k])
                .fold(f64::NEG_INFINITY, f64::max)
        };
        let mut out = Vec::new();
        let [low, high] = self.extent;
        for j in (lo(1).floor() as i64).max(low[1])..=(hi(1).ceil() as i64).min(high[1]) {
            for i in (lo(0).floor() as i64).max(low[0])..=(hi(0).ceil() as i64).min(high[0]) {
                let p = self.at(i as f64, j as f64);
                if (0.0..=w).contains(&p[0]) && (0.0..=h).contains(&p[1]) {
                    out.push(p);
                }
            }
        }
        out
    }

    /// Residual of `p` from its nearest site.
    fn residual(&self, p: [f64; 2]) -> ([i64; 2], f64) {
        let c = self.coords(p);
        let (i, j) = (c[0].round(), c[1].round());
        let s = self.at(i, j);
        ([i as i64, j as i64], (p[0] - s[0]).hypot(p[1] - s[1]))
    }
}

/// Fits the undeformed lattice to `points` (detections of one frame); `spacing_px` is the
/// median nearest-neighbour distance among them.
pub fn fit(points: &[[f64; 2]], spacing_px: f64) -> Result<Lattice, TrackError> {
    let refuse = |rms_px: f64, inliers: usize| TrackError::NotALattice {
        inliers,
        detections: points.len(),
        rms_fraction: rms_px / spacing_px,
    };
    if points.len() < 12 || spacing_px <= 0.0 {
        return Err(refuse(f64::NAN, 0));
    }
    let (a, b) = directions(points, spacing_px).ok_or_else(|| refuse(f64::NAN, 0))?;
    let mut best: Option<(usize, Lattice)> = None;
    let stride = (points.len() / 40).max(1);
    for &origin in points.iter().step_by(stride) {
        let l = Lattice {
            origin_px: origin,
            a_px: a,
            b_px: b,
            rms_px: 0.0,
            inliers: 0,
            detections: points.len(),
            extent: [[i64::MIN; 2], [i64::MAX; 2]],
        };
        let n = points
            .iter()
            .filter(|p| l.residual(**p).1 < 0.2 * spacing_px)
            .count();
        if best.as_ref().is_none_or(|(m, _)| n > *m) {
            best = Some((n, l));
        }
    }
    let Some((_, mut lattice)) = best else {
        return Err(refuse(f64::NAN, 0));
    };
    let mut gate = 0.2 * spacing_px;
    for _ in 0..3 {
        let fitted = explained(&lattice, points, gate);
        let Some(refit) = least_squares(&fitted) else {
            return Err(refuse(f64::NAN, fitted.len()));
        };
        lattice = Lattice {
            rms_px: rms(&refit, &fitted),
            inliers: fitted.len(),
            ..refit
        };
        gate = (3.0 * lattice.rms_px).clamp(0.03 * spacing_px, 0.15 * spacing_px);
    }
    // Least trimmed squares: the contact's far field still moves the markers the gate lets
    // in (radially, which a plain fit takes for a larger spacing), so the lattice is refitted
    // to the half that fits it best, five times.
    let inliers = lattice.inliers;
    for _ in 0..5 {
        let mut fitted = explained(&lattice, points, gate);
        fitted.sort_by(|x, y| x.2.total_cmp(&y.2));
        fitted.truncate((fitted.len() / 2).max(12));
        let pairs: Vec<([i64; 2], [f64; 2], f64)> = fitted;
        let Some(refit) = least_squares(&pairs) else {
            break;
        };
        lattice = Lattice {
            rms_px: rms(&refit, &pairs),
            inliers,
            ..refit
        };
    }
    lattice.detections = points.len();
    let mut extent = [[i64::MAX; 2], [i64::MIN; 2]];
    for p in points {
        let (ij, _) = lattice.residual(*p);
        for k in 0..2 {
            extent[0][k] = extent[0][k].min(ij[k]);
            extent[1][k] = extent[1][k].max(ij[k]);
        }
    }
    lattice.extent = extent;
    if lattice.inliers < 12 || lattice.inliers * 10 < 3 * points.len() {
        return Err(refuse(lattice.rms_px, lattice.inliers));
    }
    if lattice.rms_px > 0.1 * spacing_px {
        return Err(refuse(lattice.rms_px, lattice.inliers));
    }
    Ok(lattice)
}

/// The two lattice steps: peaks of the nearest-neighbour direction histogram (mod 180°, 1°
/// bins smoothed over ±2°), the second at least 30° from the first; lengths the median
/// neighbour distance within 8° of each.
fn directions(points: &[[f64; 2]], spacing_px: f64) -> Option<([f64; 2], [f64; 2])> {
    let reach = 1.6 * spacing_px;
    let mut vectors: Vec<[f64; 2]> = Vec::new();
    for (i, p) in points.iter().enumerate() {
        let mut near: Vec<(f64, [f64; 2])> = points
            .iter()
            .enumerate()
            .filter(|&(j, _)| j != i)
            .map(|(_, q)| {
                let v = [q[0] - p[0], q[1] - p[1]];
                (v[0].hypot(v[1]), v)
            })
            .filter(|(d, _)| *d < reach)
            .collect();
        near.sort_by(|x, y| x.0.total_cmp(&y.0));
        vectors.extend(near.iter().take(4).map(|n| n.1));
    }
    let fold = |v: [f64; 2]| v[1].atan2(v[0]).rem_euclid(std::f64::consts::PI);
    let mut hist = [0.0f64; 180];
    for v in &vectors {
        hist[(fold(*v).to_degrees() as usize).min(179)] += 1.0;
    }
    let smooth: Vec<f64> = (0..180)
        .map(|k| {
            (-2i64..=2)
                .map(|d| hist[(k as i64 + d).rem_euclid(180) as usize])
                .sum()
        })
        .collect();
    let apart = |a: usize, b: usize| {
        let d = a.abs_diff(b);
        d.min(180 - d)
    };
    let first = (0..180).max_by(|&x, &y| smooth[x].total_cmp(&smooth[y]))?;
    let second = (0..180)
        .filter(|&k| apart(k, first) >= 30)
        .max_by(|&x, &y| smooth[x].total_cmp(&smooth[y]))?;
    let step = |peak: usize| -> Option<[f64; 2]> {
        let centre = (peak as f64 + 0.5).to_radians();
        let u = [centre.cos(), centre.sin()];
        // Vectors within 8° of the peak, turned to point along it.
        let mut along: Vec<[f64; 2]> = vectors
            .iter()
            .map(|v| {
                if v[0] * u[0] + v[1] * u[1] < 0.0 {
                    [-v[0], -v[1]]
                } else {
                    *v
                }
            })
            .filter(|v| {
                let c = (v[0] * u[0] + v[1] * u[1]) / v[0].hypot(v[1]);
                c > 8f64.to_radians().cos()
            })
            .collect();
        if along.len() < 3 {
            return None;
        }
        let angle = {
            let (sx, sy) = along
                .iter()
                .fold((0.0, 0.0), |(x, y), v| (x + v[0], y + v[1]));
            sy.atan2(sx)
        };
        let mut lengths: Vec<f64> = along.iter_mut().map(|v| v[0].hypot(v[1])).collect();
        let length = super::median(&mut lengths)?;
        Some([length * angle.cos(), length * angle.sin()])
    };
    Some((step(first)?, step(second)?))
}

/// The detections within `gate` of a site of `lattice`: (site, position, residual).
fn explained(lattice: &Lattice, points: &[[f64; 2]], gate: f64) -> Vec<([i64; 2], [f64; 2], f64)> {
    points
        .iter()
        .filter_map(|&p| {
            let (ij, r) = lattice.residual(p);
            (r < gate).then_some((ij, p, r))
        })
        .collect()
}

/// Rms distance of the pairs from their sites of `lattice`.
fn rms(lattice: &Lattice, pairs: &[([i64; 2], [f64; 2], f64)]) -> f64 {
    let sq: f64 = pairs
        .iter()
        .map(|(ij, p, _)| {
            let s = lattice.at(ij[0] as f64, ij[1] as f64);
            (p[0] - s[0]).powi(2) + (p[1] - s[1]).powi(2)
        })
        .sum();
    (sq / pairs.len().max(1) as f64).sqrt()
}

/// Least-squares origin and steps from (site index, position) pairs: x and y each fit
/// `o + i·a + j·b` (normal equations of a 3×3 system).
fn least_squares(pairs: &[([i64; 2], [f64; 2], f64)]) -> Option<Lattice> {
    if pairs.len() < 6 {
        return None;
    }
    let mut m = [[0.0f64; 3]; 3];
    let mut rhs = [[0.0f64; 3]; 2];
    for (ij, p, _) in pairs {
        let row = [1.0, ij[0] as f64, ij[1] as f64];
        for r in 0..3 {
            for c in 0..3 {
                m[r][c] += row[r] * row[c];
            }
            rhs[0][r] += row[r] * p[0];
            rhs[1][r] += row[r] * p[1];
        }
    }
    let sx = solve3(m, rhs[0])?;
    let sy = solve3(m, rhs[1])?;
    Some(Lattice {
        origin_px: [sx[0], sy[0]],
        a_px: [sx[1], sy[1]],
        b_px: [sx[2], sy[2]],
        rms_px: 0.0,
        inliers: pairs.len(),
        detections: pairs.len(),
        extent: [[i64::MIN; 2], [i64::MAX; 2]],
    })
}

/// Solves a 3×3 system by Cramer's rule (`None` when singular: sites on one line).
fn solve3(m: [[f64; 3]; 3], r: [f64; 3]) -> Option<[f64; 3]> {
    let det = |m: &[[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let d = det(&m);
    if d.abs() < 1e-9 {
        return None;
    }
    let mut out = [0.0; 3];
    for (k, o) in out.iter_mut().enumerate() {
        let mut mk = m;
        for row in 0..3 {
            mk[row][k] = r[row];
        }
        *o = det(&mk) / d;
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_turned_grid_with_a_pressed_centre_is_found_from_its_periphery() {
        let (a, b) = ([29.5, 3.1], [-3.1, 29.5]);
        let o = [17.0, 11.0];
        let mut pts = Vec::new();
        for j in 0..14 {
            for i in 0..18 {
                let mut p = [
                    o[0] + i as f64 * a[0] + j as f64 * b[0],
                    o[1] + i as f64 * a[1] + j as f64 * b[1],
                ];
                // A contact in the middle pushes markers outward by up to 0.4 spacing.
                let (cx, cy) = (270.0, 230.0);
                let r = (p[0] - cx).hypot(p[1] - cy);
                if r < 90.0 && r > 1.0 {
                    let push = 12.0 * (1.0 - r / 90.0);
                    p = [p[0] + push * (p[0] - cx) / r, p[1] + push * (p[1] - cy) / r];
                }
                pts.push(p);
            }
        }
        let l = fit(&pts, 29.66).expect("a lattice");
        let truth = |i: f64, j: f64| [o[0] + i * a[0] + j * b[0], o[1] + i * a[1] + j * b[1]];
        // The fitted sites are the printed ones (whatever the fit calls its origin).
        for site in l.sites_in(640, 480) {
            let nearest = (0..14)
                .flat_map(|j| (0..18).map(move |i| (i, j)))
                .map(|(i, j)| {
                    let t = truth(i as f64, j as f64);
                    (t[0] - site[0]).hypot(t[1] - site[1])
                })
                .fold(f64::INFINITY, f64::min);
            assert!(!(0.05..=5.0).contains(&nearest), "site off by {nearest} px");
        }
        assert!(l.rms_px < 0.3, "{l:?}");
        assert!(l.inliers > 150);
    }

    #[test]
    fn scattered_points_are_not_a_lattice() {
        let mut state = 7u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let pts: Vec<[f64; 2]> = (0..200).map(|_| [600.0 * next(), 450.0 * next()]).collect();
        assert!(matches!(
            fit(&pts, 25.0),
            Err(TrackError::NotALattice { .. })
        ));
    }
}
