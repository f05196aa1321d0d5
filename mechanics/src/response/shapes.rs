//! Indenter shapes on the solver's grid: a curved indenter's profile, a flat punch's face,
//! and the cell size at which the discretised face has the face's true area.

use std::f64::consts::PI;

use crate::Indenter;
use crate::operator::Grid;

/// Profile of a curved indenter (mm above its lowest point) at (x, y); large outside it.
pub(super) fn profile(ind: &Indenter, layer_width: f64, x: f64, y: f64) -> f64 {
    const AWAY: f64 = 1e3;
    match *ind {
        Indenter::Sphere { diameter_mm } => {
            let r = diameter_mm / 2.0;
            let r2 = x * x + y * y;
            if r2 < r * r {
                r - (r * r - r2).sqrt()
            } else {
                AWAY
            }
        }
        Indenter::Cylinder {
            diameter_mm,
            length_mm,
        } => {
            let r = diameter_mm / 2.0;
            // Axis along x, the direction the tangential solver loads: a can's weight pulls
            // along its own axis (thesis §6.3), so the grasp's shear runs along the strip.
            let half = length_mm.min(layer_width) / 2.0;
            if x.abs() <= half && y.abs() < r {
                r - (r * r - y * y).sqrt()
            } else {
                AWAY
            }
        }
        _ => 0.0,
    }
}

/// Face of a flat punch centred at the origin.
pub(super) fn inside_face(ind: &Indenter, x: f64, y: f64) -> bool {
    match *ind {
        Indenter::FlatCircle { diameter_mm } => x * x + y * y <= (diameter_mm / 2.0).powi(2),
        Indenter::FlatEllipse { major_mm, minor_mm } => {
            (x / (major_mm / 2.0)).powi(2) + (y / (minor_mm / 2.0)).powi(2) <= 1.0
        }
        Indenter::FlatRectangle {
            width_mm,
            length_mm,
        } => x.abs() <= width_mm / 2.0 && y.abs() <= length_mm / 2.0,
        Indenter::FlatTriangle { side_mm } => {
            let rc = side_mm / 3f64.sqrt();
            let v: Vec<(f64, f64)> = (0..3)
                .map(|k| {
                    let a = -PI / 2.0 + k as f64 * 2.0 * PI / 3.0;
                    (rc * a.cos(), rc * a.sin())
                })
                .collect();
            (0..3).all(|k| {
                let (ax, ay) = v[k];
                let (bx, by) = v[(k + 1) % 3];
                (bx - ax) * (y - ay) - (by - ay) * (x - ax) >= 0.0
            })
        }
        _ => false,
    }
}

/// A cell size near `dx` (within +12 %) at which the discretised face of a flat punch has
/// the face's true area: the face's area sets its effective radius, and an area error of
/// one edge cell moves the whole outside field (it made a 256² field 2 % off at its worst
/// marker; matched, 0.6 %).
pub(super) fn matched_dx(ind: &Indenter, n: usize, dx: f64) -> f64 {
    let Some(area) = ind.flat_area_mm2() else {
        return dx;
    };
    let mismatch = |dx: f64| {
        let g = Grid { n, dx };
        let cells = (0..g.len())
            .filter(|i| {
                let (x, y) = g.xy(*i);
                inside_face(ind, x, y)
            })
            .count();
        (cells as f64 * dx * dx - area).abs()
    };
    (0..=48)
        .map(|k| dx * (1.0 + 0.0025 * k as f64))
        .min_by(|a, b| mismatch(*a).total_cmp(&mismatch(*b)))
        .unwrap_or(dx)
}

/// The cells of `grid` under a flat punch's face.
pub(super) fn face_mask(ind: &Indenter, grid: Grid) -> Vec<bool> {
    (0..grid.len())
        .map(|i| {
            let (x, y) = grid.xy(i);
            inside_face(ind, x, y)
        })
        .collect()
}
