//! Loading against unloading (thesis Fig. 6-5, 6-8): how far the unloading branch lies
//! from the loading one, and what is left when the load is gone.

/// Hysteresis of one load–unload cycle.
#[derive(Debug, Clone, PartialEq)]
pub struct Hysteresis {
    /// Area enclosed by the loading and unloading branches (x unit × y unit).
    pub loop_area: f64,
    /// Largest |loading − unloading| at the unloading points' x, y units.
    pub max_gap: f64,
    /// Where `max_gap` occurs (x).
    pub max_gap_at: f64,
    /// y at the end of unloading minus the loading branch at the same x (extrapolated
    /// linearly from its first two points when unloading goes below where loading began).
    pub residual_at_zero: f64,
}

/// Compares a loading branch with the unloading branch that follows it. Points are
/// (x, y) in recording order. `None` unless each branch has two points and the unloading
/// x values fall inside the loading range.
pub fn hysteresis(load: &[(f64, f64)], unload: &[(f64, f64)]) -> Option<Hysteresis> {
    if load.len() < 2 || unload.len() < 2 {
        return None;
    }
    let mut up = load.to_vec();
    up.sort_by(|a, b| a.0.total_cmp(&b.0));
    let interp = |x: f64| -> Option<f64> {
        let w = up
            .windows(2)
            .find(|w| x >= w[0].0 - 1e-12 && x <= w[1].0 + 1e-12)?;
        let dx = w[1].0 - w[0].0;
        Some(if dx.abs() < 1e-300 {
            w[0].1
        } else {
            w[0].1 + (x - w[0].0) / dx * (w[1].1 - w[0].1)
        })
    };
    let (mut max_gap, mut max_gap_at) = (0.0f64, f64::NAN);
    for &(x, y) in unload {
        if let Some(yl) = interp(x) {
            let g = yl - y;
            if g.abs() > max_gap.abs() || max_gap_at.is_nan() {
                max_gap = g;
                max_gap_at = x;
            }
        }
    }
    if max_gap_at.is_nan() {
        return None;
    }
    // The closed polygon: loading in order, then unloading in order (shoelace formula).
    let poly: Vec<(f64, f64)> = load.iter().chain(unload).copied().collect();
    let twice: f64 = (0..poly.len())
        .map(|i| {
            let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
            a.0 * b.1 - b.0 * a.1
        })
        .sum();
    let (xe, ye) = unload[unload.len() - 1];
    let on_load = interp(xe).unwrap_or_else(|| {
        let (a, b) = if xe < up[0].0 {
            (up[0], up[1])
        } else {
            (up[up.len() - 2], up[up.len() - 1])
        };
        let dx = b.0 - a.0;
        if dx.abs() < 1e-300 {
            a.1
        } else {
            a.1 + (xe - a.0) / dx * (b.1 - a.1)
        }
    });
    Some(Hysteresis {
        loop_area: 0.5 * twice.abs(),
        max_gap: max_gap.abs(),
        max_gap_at,
        residual_at_zero: ye - on_load,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_known_loop() {
        // Loading y = x², unloading y = x on [0, 1]: area 1/2 − 1/3 with trapezoids.
        let xs: Vec<f64> = (0..=100).map(|i| i as f64 / 100.0).collect();
        let load: Vec<(f64, f64)> = xs.iter().map(|&x| (x, x * x)).collect();
        let unload: Vec<(f64, f64)> = xs.iter().rev().map(|&x| (x, x)).collect();
        let h = hysteresis(&load, &unload).expect("loop");
        assert!((h.loop_area - 1.0 / 6.0).abs() < 1e-3, "{}", h.loop_area);
        assert!((h.max_gap - 0.25).abs() < 1e-3 && (h.max_gap_at - 0.5).abs() < 0.011);
        assert!(h.residual_at_zero.abs() < 1e-12);
        // A residual when unloading ends higher; extrapolated when it ends below the start.
        let back: Vec<(f64, f64)> = load
            .iter()
            .rev()
            .map(|&(x, y)| (x, y + 0.1 * (1.0 - x)))
            .collect();
        let h = hysteresis(&load, &back).expect("loop");
        assert!((h.residual_at_zero - 0.1).abs() < 1e-12);
        let line: Vec<(f64, f64)> = (1..=5).map(|i| (i as f64, 2.0 * i as f64)).collect();
        let down = [(4.0, 8.5), (0.0, 0.3)];
        let h = hysteresis(&line, &down).expect("loop");
        assert!(
            (h.residual_at_zero - 0.3).abs() < 1e-12,
            "{}",
            h.residual_at_zero
        );
        assert!(hysteresis(&load[..1], &back).is_none());
    }
}
