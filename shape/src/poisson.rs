//! Heights from slopes: the least-squares integration of a gradient field with free
//! (Neumann) borders, solved exactly by the discrete cosine transform.
//!
//! The gradient `(gx, gy)` is averaged onto the forward differences between neighbouring
//! pixels (trapezoid rule) and the height `z` minimising `‖Dz − v‖²` solves the normal
//! equations `DᵀD z = Dᵀv`. `DᵀD` is the grid Laplacian with Neumann borders, which the
//! DCT-II diagonalises with eigenvalues `(2 − 2cos(πk/W)) + (2 − 2cos(πl/H))` (Simchony,
//! Chellappa & Shao, "Direct analytical methods for solving Poisson equations in computer
//! vision problems", IEEE PAMI 12(5), 1990). Unlike the periodic Fourier solution
//! (Frankot & Chellappa 1988) it assumes nothing at the frame's border: a contact cut by the
//! border keeps its depth (15 % of the cap height lost on such a press with the periodic
//! one, docs/explanation/shape.md). The mean height is left at zero; callers set the datum.

use std::sync::Arc;

use rustdct::{DctPlanner, TransformType2And3};

/// A solver for one frame size, its transforms planned once.
pub struct Integrator {
    width: usize,
    height: usize,
    rows: Arc<dyn TransformType2And3<f32>>,
    cols: Arc<dyn TransformType2And3<f32>>,
    /// `1 / eigenvalue` per coefficient, with the DCT's scaling folded in; 0 at (0, 0);
    /// transposed (row `k` of the x-frequency holds the y-frequencies).
    inverse_eig: Vec<f32>,
    scratch: Vec<f32>,
    transposed: Vec<f32>,
}

impl std::fmt::Debug for Integrator {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Integrator({}×{})", self.width, self.height)
    }
}

impl Integrator {
    /// Plans the transforms for `width × height` frames (both at least 2).
    pub fn new(width: usize, height: usize) -> Self {
        let mut planner = DctPlanner::new();
        let rows = planner.plan_dct2(width);
        let cols = planner.plan_dct2(height);
        // rustdct's DCT-III after its DCT-II multiplies by N/2 in each direction.
        let scale = 4.0 / (width as f64 * height as f64);
        let mut inverse_eig = vec![0.0f32; width * height];
        for l in 0..height {
            let ey = 2.0 - 2.0 * (std::f64::consts::PI * l as f64 / height as f64).cos();
            for k in 0..width {
                let ex = 2.0 - 2.0 * (std::f64::consts::PI * k as f64 / width as f64).cos();
                let e = ex + ey;
                inverse_eig[k * height + l] = if e > 0.0 { (scale / e) as f32 } else { 0.0 };
            }
        }
        Self {
            scratch: vec![0.0; rows.get_scratch_len().max(cols.get_scratch_len())],
            width,
            height,
            rows,
            cols,
            inverse_eig,
            transposed: vec![0.0; width * height],
        }
    }

    /// The frame size planned for.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// Integrates row-major slopes `gx = ∂z/∂x`, `gy = ∂z/∂y` (per pixel) into `z` (same
    /// units as the slopes times pixels), mean zero. Slices must hold `width × height`.
    pub fn integrate(&mut self, gx: &[f32], gy: &[f32], z: &mut [f32]) {
        let (w, h) = (self.width, self.height);
        let n = w * h;
        assert!(
            gx.len() == n && gy.len() == n && z.len() == n,
            "slice sizes"
        );
        // z ← Dᵀv, v the trapezoid-averaged slopes on the forward differences.
        z.fill(0.0);
        for y in 0..h {
            let row = y * w;
            for x in 0..w - 1 {
                let v = 0.5 * (gx[row + x] + gx[row + x + 1]);
                z[row + x] -= v;
                z[row + x + 1] += v;
            }
        }
        for y in 0..h - 1 {
            let (a, b) = (y * w, (y + 1) * w);
            for x in 0..w {
                let v = 0.5 * (gy[a + x] + gy[b + x]);
                z[a + x] -= v;
                z[b + x] += v;
            }
        }
        // Rows, then columns as the rows of the transpose; the spectrum is divided there and
        // the inverse runs back the same way.
        let (rows, cols) = (&self.rows, &self.cols);
        let (t, scratch) = (&mut self.transposed, &mut self.scratch);
        for row in z.chunks_exact_mut(w) {
            rows.process_dct2_with_scratch(row, scratch);
        }
        transpose(z, t, w, h);
        for (col, k) in t.chunks_exact_mut(h).zip(self.inverse_eig.chunks_exact(h)) {
            cols.process_dct2_with_scratch(col, scratch);
            for (c, k) in col.iter_mut().zip(k) {
                *c *= k;
            }
            cols.process_dct3_with_scratch(col, scratch);
        }
        transpose(t, z, h, w);
        for row in z.chunks_exact_mut(w) {
            rows.process_dct3_with_scratch(row, scratch);
        }
    }
}

/// `dst` (w rows of h) ← the transpose of `src` (h rows of w), in tiles that stay in cache.
fn transpose(src: &[f32], dst: &mut [f32], w: usize, h: usize) {
    const TILE: usize = 32;
    for y0 in (0..h).step_by(TILE) {
        for x0 in (0..w).step_by(TILE) {
            for y in y0..(y0 + TILE).min(h) {
                for x in x0..(x0 + TILE).min(w) {
                    dst[x * h + y] = src[y * w + x];
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A smooth surface's exact slopes come back as the surface (up to its mean), with the
    /// border free: a bump cut by the frame's edge keeps its height.
    #[test]
    fn slopes_of_a_surface_integrate_back_to_it() {
        let (w, h) = (64, 48);
        let f = |x: f64, y: f64| {
            let (dx, dy) = (x - 60.0, y - 20.0);
            5.0 * (-(dx * dx + dy * dy) / 200.0).exp() + 0.01 * x
        };
        let (mut gx, mut gy, mut truth) = (vec![0f32; w * h], vec![0f32; w * h], vec![0f64; w * h]);
        for y in 0..h {
            for x in 0..w {
                let (xf, yf) = (x as f64, y as f64);
                let e = 1e-4;
                gx[y * w + x] = ((f(xf + e, yf) - f(xf - e, yf)) / (2.0 * e)) as f32;
                gy[y * w + x] = ((f(xf, yf + e) - f(xf, yf - e)) / (2.0 * e)) as f32;
                truth[y * w + x] = f(xf, yf);
            }
        }
        let mut z = vec![0f32; w * h];
        let mut integrator = Integrator::new(w, h);
        integrator.integrate(&gx, &gy, &mut z);
        let mean = truth.iter().sum::<f64>() / (w * h) as f64;
        let worst = z
            .iter()
            .zip(&truth)
            .map(|(a, t)| (*a as f64 - (t - mean)).abs())
            .fold(0.0, f64::max);
        // The trapezoid rule's own error on this bump is about 0.3 % of its height.
        assert!(worst < 0.03, "worst {worst} on a bump of 5");
    }
}
