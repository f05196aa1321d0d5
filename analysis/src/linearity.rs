//! Quasistatic force against load displacement: straight-line fits, the linear range
//! (thesis Fig. 4-5, 4-10) and the power law of curved indenters (Fig. 5-1).

/// A least-squares straight line y = slope·x + intercept.
#[derive(Debug, Clone, PartialEq)]
pub struct LineFit {
    /// Slope, y units per x unit.
    pub slope: f64,
    /// Intercept (0 for a fit through the origin).
    pub intercept: f64,
    /// Coefficient of determination, 1 − RSS/TSS (TSS about the mean in both cases, so
    /// the two fits compare).
    pub r2: f64,
    /// y − fit, per point.
    pub residuals: Vec<f64>,
}

/// Fits a line to (x, y), through the origin when `intercept` is false. `None` with
/// fewer than two points or no spread in x.
pub fn fit_line(x: &[f64], y: &[f64], intercept: bool) -> Option<LineFit> {
    let n = x.len().min(y.len());
    if n < 2 {
        return None;
    }
    let (x, y) = (&x[..n], &y[..n]);
    let mean = |v: &[f64]| v.iter().sum::<f64>() / n as f64;
    let (mx, my) = if intercept {
        (mean(x), mean(y))
    } else {
        (0.0, 0.0)
    };
    let sxx: f64 = x.iter().map(|v| (v - mx).powi(2)).sum();
    if sxx <= 1e-300 {
        return None;
    }
    let sxy: f64 = x.iter().zip(y).map(|(a, b)| (a - mx) * (b - my)).sum();
    let slope = sxy / sxx;
    let intercept = my - slope * mx;
    let residuals: Vec<f64> = x
        .iter()
        .zip(y)
        .map(|(a, b)| b - slope * a - intercept)
        .collect();
    let rss: f64 = residuals.iter().map(|r| r * r).sum();
    let ym = mean(y);
    let tss: f64 = y.iter().map(|v| (v - ym).powi(2)).sum();
    Some(LineFit {
        slope,
        intercept,
        r2: if tss > 0.0 { 1.0 - rss / tss } else { f64::NAN },
        residuals,
    })
}

/// The linear range of a loading curve.
#[derive(Debug, Clone, PartialEq)]
pub struct LinearRange {
    /// Number of leading points inside the range.
    pub points: usize,
    /// The load at the last point inside the range.
    pub end_x: f64,
    /// Slope of the first three points (the "initial slope").
    pub initial_slope: f64,
    /// The tolerance used, as a fraction of the initial-line prediction.
    pub tolerance: f64,
}

/// The largest prefix of (x, y), in loading order, whose points stay within `tolerance`
/// (a fraction, e.g. 0.05) of the line through the first three points, measured relative
/// to that line's rise from the first point (thesis Fig. 4-10: the red line fitted to the
/// first few points). `noise_floor` absorbs measurement noise at small loads.
pub fn linear_range(x: &[f64], y: &[f64], tolerance: f64, noise_floor: f64) -> Option<LinearRange> {
    let n = x.len().min(y.len());
    if n < 3 {
        return None;
    }
    let first = fit_line(&x[..3], &y[..3], true)?;
    let mut points = 3;
    for i in 3..n {
        let pred = first.slope * x[i] + first.intercept;
        let rise = (first.slope * (x[i] - x[0])).abs();
        if (y[i] - pred).abs() > tolerance * rise + noise_floor {
            break;
        }
        points = i + 1;
    }
    Some(LinearRange {
        points,
        end_x: x[points - 1],
        initial_slope: first.slope,
        tolerance,
    })
}

/// F = k·(d + d0)ⁿ: a sphere's force against depth (thesis Fig. 5-1). `d0` absorbs the
/// depth the indenter had already reached when the approach detected contact.
#[derive(Debug, Clone, PartialEq)]
pub struct PowerLaw {
    /// Prefactor, force per depthⁿ.
    pub k: f64,
    /// Exponent (Hertz on a half-space: 1.5; a thin bonded layer stiffens it).
    pub n: f64,
    /// Depth offset, same unit as d.
    pub d0: f64,
    /// R² in linear space.
    pub r2: f64,
}

/// Fits a power law with a depth offset: for each candidate d0 a straight line in log–log
/// space, keeping the d0 with the smallest squared error in linear space. `None` with
/// fewer than four positive points.
pub fn fit_power_law(d: &[f64], f: &[f64]) -> Option<PowerLaw> {
    let pts: Vec<(f64, f64)> = d
        .iter()
        .zip(f)
        .filter(|(a, b)| a.is_finite() && **b > 0.0)
        .map(|(a, b)| (*a, *b))
        .collect();
    if pts.len() < 4 {
        return None;
    }
    let dmin = pts.iter().map(|p| p.0).fold(f64::INFINITY, f64::min);
    let dmax = pts.iter().map(|p| p.0).fold(f64::NEG_INFINITY, f64::max);
    let span = (dmax - dmin).max(1e-9);
    let ym = pts.iter().map(|p| p.1).sum::<f64>() / pts.len() as f64;
    let tss: f64 = pts.iter().map(|p| (p.1 - ym).powi(2)).sum();
    let mut best: Option<PowerLaw> = None;
    let mut best_rss = f64::INFINITY;
    for k in 0..=400 {
        // d0 from just above −dmin (all d + d0 > 0) to half the span.
        let d0 = -dmin + span * (1e-3 + 0.5 * k as f64 / 400.0);
        let lx: Vec<f64> = pts.iter().map(|p| (p.0 + d0).ln()).collect();
        let ly: Vec<f64> = pts.iter().map(|p| p.1.ln()).collect();
        let Some(line) = fit_line(&lx, &ly, true) else {
            continue;
        };
        let (kk, n) = (line.intercept.exp(), line.slope);
        let rss: f64 = pts
            .iter()
            .map(|p| (p.1 - kk * (p.0 + d0).powf(n)).powi(2))
            .sum();
        if rss < best_rss {
            best_rss = rss;
            best = Some(PowerLaw {
                k: kk,
                n,
                d0,
                r2: if tss > 0.0 { 1.0 - rss / tss } else { f64::NAN },
            });
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn line_fits_with_and_without_intercept() {
        let x = [0.1, 0.2, 0.3, 0.4];
        let y: Vec<f64> = x.iter().map(|v| 12.5 * v + 0.3).collect();
        let a = fit_line(&x, &y, true).expect("fit");
        assert!((a.slope - 12.5).abs() < 1e-12 && (a.intercept - 0.3).abs() < 1e-12);
        assert!((a.r2 - 1.0).abs() < 1e-12);
        let b = fit_line(&x, &y, false).expect("fit");
        assert!(b.slope > 12.5 && b.r2 < 1.0);
        assert!(fit_line(&[1.0, 1.0], &[1.0, 2.0], true).is_none());
    }

    #[test]
    fn linear_range_ends_where_the_curve_bends() {
        // Linear to x = 0.5, then saturating.
        let x: Vec<f64> = (1..=12).map(|i| 0.1 * i as f64).collect();
        let y: Vec<f64> = x
            .iter()
            .map(|&v| {
                if v <= 0.5 {
                    5.0 * v
                } else {
                    2.5 + 1.0 * (v - 0.5)
                }
            })
            .collect();
        let r = linear_range(&x, &y, 0.05, 0.0).expect("range");
        assert_eq!(r.points, 5);
        assert!((r.end_x - 0.5).abs() < 1e-12 && (r.initial_slope - 5.0).abs() < 1e-9);
    }

    #[test]
    fn power_law_with_an_unknown_offset() {
        let d: Vec<f64> = (1..=10).map(|i| 0.1 * i as f64).collect();
        let f: Vec<f64> = d.iter().map(|v| 3.0 * (v + 0.12f64).powf(1.4)).collect();
        let p = fit_power_law(&d, &f).expect("fit");
        assert!((p.n - 1.4).abs() < 0.02, "{p:?}");
        assert!((p.d0 - 0.12).abs() < 0.01, "{p:?}");
        assert!(p.r2 > 0.9999);
    }
}
