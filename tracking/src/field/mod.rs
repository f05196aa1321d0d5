//! Displacement fields: from tracked markers to a dense field, pictures, decomposition.
//!
//! The markers sample the elastomer's planar displacement at scattered points; the thesis
//! interpolates them over the view (§3.4) and reads its results off the field: the radial
//! profile under normal load (§4.3), the shear-direction component and its central line
//! under shear (§4.4), the spin under torsion (ch. 6). Here:
//!
//! - [`MarkerField`]: one frame's per-marker displacements and which were measured;
//! - [`Interpolator`]: barycentric interpolation over the Delaunay triangulation of the
//!   reference markers, precomputed once per reference so a frame costs three
//!   multiply-adds per grid point; markers not measured in a frame are filled first by
//!   harmonic inpainting over the triangulation (never zero-filled, which would pull the
//!   field towards zero where the contact is); grid points outside the markers' hull are
//!   flagged extrapolated;
//! - [`picture`]: the thesis's colour-vector image (hue = direction, value = magnitude)
//!   and quiver plots (SVG and RGB, via plotters);
//! - [`decompose`]: radiating centre and radial profile, shear direction and central line,
//!   rotation centre and angle, pure shear = total − pressing.
//!
//! Pixel coordinates as in [`crate`]: pixel (i, j) is centred at (i, j).

pub mod decompose;
pub mod picture;

use delaunator::{Point, triangulate};

use crate::{MarkerState, Tracker};

/// One frame's marker displacements.
#[derive(Debug, Clone, PartialEq)]
pub struct MarkerField {
    /// Reference (undeformed) marker positions, px; index = identity.
    pub reference_px: Vec<[f64; 2]>,
    /// Displacement from the reference, px.
    pub displacement_px: Vec<[f64; 2]>,
    /// Whether each displacement was measured this frame (not predicted or lost).
    pub measured: Vec<bool>,
}

impl MarkerField {
    /// The tracker's current field; only tracked, border and merged markers count as
    /// measured.
    pub fn from_tracker(tracker: &Tracker) -> Self {
        Self {
            reference_px: tracker.reference_px().to_vec(),
            displacement_px: (0..tracker.len())
                .map(|i| tracker.displacement_px(i))
                .collect(),
            measured: tracker.states().iter().map(|s| s.is_measured()).collect(),
        }
    }

    /// As [`Self::from_tracker`], but border markers (biased centroids) do not count.
    pub fn interior_from_tracker(tracker: &Tracker) -> Self {
        let mut f = Self::from_tracker(tracker);
        for (m, s) in f.measured.iter_mut().zip(tracker.states()) {
            *m = matches!(s, MarkerState::Tracked | MarkerState::Merged);
        }
        f
    }

    /// Number of markers.
    pub fn len(&self) -> usize {
        self.reference_px.len()
    }

    /// Whether there are no markers.
    pub fn is_empty(&self) -> bool {
        self.reference_px.is_empty()
    }

    /// Indices of the measured markers.
    pub fn measured_ids(&self) -> impl Iterator<Item = usize> + '_ {
        (0..self.len()).filter(|&i| self.measured[i])
    }
}

/// A regular grid of points over the view.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DenseGrid {
    /// Position of point (0, 0), px.
    pub origin_px: [f64; 2],
    /// Distance between points, px.
    pub step_px: f64,
    /// Points along x.
    pub nx: usize,
    /// Points along y.
    pub ny: usize,
}

impl DenseGrid {
    /// Points every `step_px` over a `width × height` frame, starting at pixel (0, 0).
    pub fn over_frame(width: usize, height: usize, step_px: f64) -> Self {
        let step_px = step_px.max(0.25);
        Self {
            origin_px: [0.0, 0.0],
            step_px,
            nx: ((width as f64 - 1.0) / step_px).floor() as usize + 1,
            ny: ((height as f64 - 1.0) / step_px).floor() as usize + 1,
        }
    }

    /// Position of point (i, j), px.
    pub fn point(&self, i: usize, j: usize) -> [f64; 2] {
        [
            self.origin_px[0] + i as f64 * self.step_px,
            self.origin_px[1] + j as f64 * self.step_px,
        ]
    }
}

/// How a dense-field value was obtained.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Support {
    /// Inside the markers' hull, from three measured markers.
    Measured,
    /// Inside the hull, but from at least one inpainted (unmeasured) marker.
    Inferred,
    /// Outside the markers' hull: the nearest marker's value.
    Extrapolated,
}

/// A dense displacement field on a grid.
#[derive(Debug, Clone, PartialEq)]
pub struct DenseField {
    /// The grid.
    pub grid: DenseGrid,
    /// Displacement at each point, px, row-major.
    pub displacement_px: Vec<[f32; 2]>,
    /// How each value was obtained.
    pub support: Vec<Support>,
}

impl DenseField {
    /// Largest displacement magnitude, px.
    pub fn max_magnitude_px(&self) -> f64 {
        self.displacement_px
            .iter()
            .map(|u| (u[0] as f64).hypot(u[1] as f64))
            .fold(0.0, f64::max)
    }
}

/// Barycentric interpolation weights over the reference triangulation, precomputed.
#[derive(Debug, Clone)]
pub struct Interpolator {
    grid: DenseGrid,
    /// Per grid point: three marker ids and their weights (outside the hull: the nearest
    /// marker with weight 1, twice more with weight 0).
    vertices: Vec<[u32; 3]>,
    weights: Vec<[f32; 3]>,
    outside: Vec<bool>,
    nbr_start: Vec<u32>,
    nbr: Vec<u32>,
    markers: usize,
}

impl Interpolator {
    /// Triangulates the reference markers and locates every grid point.
    pub fn new(reference_px: &[[f64; 2]], grid: DenseGrid) -> Self {
        let n = grid.nx * grid.ny;
        let mut vertices = vec![[0u32; 3]; n];
        let mut weights = vec![[0.0f32; 3]; n];
        let mut outside = vec![true; n];
        let pts: Vec<Point> = reference_px
            .iter()
            .map(|p| Point { x: p[0], y: p[1] })
            .collect();
        let tri = triangulate(&pts);
        let mut adj: Vec<Vec<u32>> = vec![Vec::new(); reference_px.len()];
        for t in tri.triangles.chunks_exact(3) {
            let (a, b, c) = (reference_px[t[0]], reference_px[t[1]], reference_px[t[2]]);
            for (x, y) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
                if !adj[x].contains(&(y as u32)) {
                    adj[x].push(y as u32);
                    adj[y].push(x as u32);
                }
            }
            let det = (b[1] - c[1]) * (a[0] - c[0]) + (c[0] - b[0]) * (a[1] - c[1]);
            if det.abs() < 1e-12 {
                continue;
            }
            let (lo_x, hi_x) = (a[0].min(b[0]).min(c[0]), a[0].max(b[0]).max(c[0]));
            let (lo_y, hi_y) = (a[1].min(b[1]).min(c[1]), a[1].max(b[1]).max(c[1]));
            let to_i = |v: f64, o: f64, lim: usize| ((v - o) / grid.step_px).clamp(0.0, lim as f64);
            let i0 = to_i(lo_x, grid.origin_px[0], grid.nx - 1).ceil() as usize;
            let i1 = to_i(hi_x, grid.origin_px[0], grid.nx - 1).floor() as usize;
            let j0 = to_i(lo_y, grid.origin_px[1], grid.ny - 1).ceil() as usize;
            let j1 = to_i(hi_y, grid.origin_px[1], grid.ny - 1).floor() as usize;
            for j in j0..=j1 {
                for i in i0..=i1 {
                    let p = grid.point(i, j);
                    let l1 = ((b[1] - c[1]) * (p[0] - c[0]) + (c[0] - b[0]) * (p[1] - c[1])) / det;
                    let l2 = ((c[1] - a[1]) * (p[0] - c[0]) + (a[0] - c[0]) * (p[1] - c[1])) / det;
                    let l3 = 1.0 - l1 - l2;
                    let eps = -1e-9;
                    if l1 >= eps && l2 >= eps && l3 >= eps {
                        let k = j * grid.nx + i;
                        vertices[k] = [t[0] as u32, t[1] as u32, t[2] as u32];
                        weights[k] = [l1 as f32, l2 as f32, l3 as f32];
                        outside[k] = false;
                    }
                }
            }
        }
        // Outside the hull: the nearest marker.
        for j in 0..grid.ny {
            for i in 0..grid.nx {
                let k = j * grid.nx + i;
                if !outside[k] {
                    continue;
                }
                let p = grid.point(i, j);
                let nearest = (0..reference_px.len())
                    .min_by(|&a, &b| {
                        let da = (reference_px[a][0] - p[0]).hypot(reference_px[a][1] - p[1]);
                        let db = (reference_px[b][0] - p[0]).hypot(reference_px[b][1] - p[1]);
                        da.total_cmp(&db)
                    })
                    .unwrap_or(0) as u32;
                vertices[k] = [nearest; 3];
                weights[k] = [1.0, 0.0, 0.0];
            }
        }
        let mut nbr_start = vec![0u32];
        let mut nbr = Vec::new();
        for list in adj {
            nbr.extend(list);
            nbr_start.push(nbr.len() as u32);
        }
        Self {
            grid,
            vertices,
            weights,
            outside,
            nbr_start,
            nbr,
            markers: reference_px.len(),
        }
    }

    /// The grid.
    pub fn grid(&self) -> DenseGrid {
        self.grid
    }

    /// Fills unmeasured markers from measured ones: harmonic inpainting on the
    /// triangulation (each unmeasured value is the mean of its neighbours; Gauss–Seidel
    /// until the largest change is below 10⁻³ px). With nothing measured, zeros.
    pub fn inpaint(&self, field: &MarkerField) -> Vec<[f64; 2]> {
        let mut u: Vec<[f64; 2]> = (0..self.markers)
            .map(|i| {
                if field.measured.get(i).copied().unwrap_or(false) {
                    field.displacement_px[i]
                } else {
                    [0.0; 2]
                }
            })
            .collect();
        if !field.measured.iter().any(|&m| m) {
            return u;
        }
        let free: Vec<usize> = (0..self.markers)
            .filter(|&i| !field.measured.get(i).copied().unwrap_or(false))
            .collect();
        for _ in 0..500 {
            let mut change = 0.0f64;
            for &i in &free {
                let nb = &self.nbr[self.nbr_start[i] as usize..self.nbr_start[i + 1] as usize];
                if nb.is_empty() {
                    continue;
                }
                let (mut sx, mut sy) = (0.0, 0.0);
                for &j in nb {
                    sx += u[j as usize][0];
                    sy += u[j as usize][1];
                }
                let new = [sx / nb.len() as f64, sy / nb.len() as f64];
                change = change.max((new[0] - u[i][0]).abs().max((new[1] - u[i][1]).abs()));
                u[i] = new;
            }
            if change < 1e-3 {
                break;
            }
        }
        u
    }

    /// The dense field of one frame.
    pub fn interpolate(&self, field: &MarkerField) -> DenseField {
        let u = self.inpaint(field);
        let measured = |i: u32| field.measured.get(i as usize).copied().unwrap_or(false);
        let n = self.vertices.len();
        let mut displacement_px = Vec::with_capacity(n);
        let mut support = Vec::with_capacity(n);
        for k in 0..n {
            let [a, b, c] = self.vertices[k];
            let [wa, wb, wc] = self.weights[k];
            let (ua, ub, uc) = (u[a as usize], u[b as usize], u[c as usize]);
            displacement_px.push([
                wa * ua[0] as f32 + wb * ub[0] as f32 + wc * uc[0] as f32,
                wa * ua[1] as f32 + wb * ub[1] as f32 + wc * uc[1] as f32,
            ]);
            support.push(if self.outside[k] {
                Support::Extrapolated
            } else if measured(a) && measured(b) && measured(c) {
                Support::Measured
            } else {
                Support::Inferred
            });
        }
        DenseField {
            grid: self.grid,
            displacement_px,
            support,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lattice(n: usize, spacing: f64) -> Vec<[f64; 2]> {
        (0..n * n)
            .map(|k| {
                [
                    10.0 + (k % n) as f64 * spacing,
                    10.0 + (k / n) as f64 * spacing,
                ]
            })
            .collect()
    }

    #[test]
    fn interpolation_reproduces_affine_fields_exactly() {
        let refs = lattice(8, 20.0);
        let affine = |p: [f64; 2]| [0.5 + 0.02 * p[0] - 0.01 * p[1], -1.0 + 0.03 * p[1]];
        let field = MarkerField {
            displacement_px: refs.iter().map(|p| affine(*p)).collect(),
            measured: vec![true; refs.len()],
            reference_px: refs.clone(),
        };
        let grid = DenseGrid::over_frame(170, 170, 3.0);
        let interp = Interpolator::new(&refs, grid);
        let dense = interp.interpolate(&field);
        let mut inside = 0;
        for j in 0..grid.ny {
            for i in 0..grid.nx {
                let k = j * grid.nx + i;
                if dense.support[k] != Support::Measured {
                    continue;
                }
                inside += 1;
                let want = affine(grid.point(i, j));
                let got = dense.displacement_px[k];
                assert!(
                    (got[0] as f64 - want[0]).abs() < 1e-4
                        && (got[1] as f64 - want[1]).abs() < 1e-4
                );
            }
        }
        assert!(inside > 1000, "{inside} points inside the hull");
        // Points left of the first column are outside the hull.
        assert_eq!(dense.support[0], Support::Extrapolated);
    }

    #[test]
    fn unmeasured_markers_are_inpainted_not_zeroed() {
        let refs = lattice(7, 20.0);
        let mut field = MarkerField {
            displacement_px: vec![[2.0, -1.0]; refs.len()],
            measured: vec![true; refs.len()],
            reference_px: refs.clone(),
        };
        // A hole in the middle, as a contact edge or a lost marker leaves.
        for k in [23, 24, 25, 17, 31] {
            field.measured[k] = false;
            field.displacement_px[k] = [0.0, 0.0];
        }
        let interp = Interpolator::new(&refs, DenseGrid::over_frame(150, 150, 5.0));
        let u = interp.inpaint(&field);
        for k in [23, 24, 25, 17, 31] {
            assert!(
                (u[k][0] - 2.0).abs() < 1e-2 && (u[k][1] + 1.0).abs() < 1e-2,
                "{:?}",
                u[k]
            );
        }
        let dense = interp.interpolate(&field);
        assert!(dense.support.contains(&Support::Inferred));
    }
}
