//! Two-dimensional real FFT of square grids: real-to-complex along rows (realfft), then
//! complex along columns (rustfft). The spectrum of an n×n real field holds n·(n/2+1)
//! coefficients, row-major in (ky, kx), kx = 0..n/2.

use std::sync::Arc;

use realfft::{ComplexToReal, RealFftPlanner, RealToComplex};
use rustfft::num_complex::Complex;
use rustfft::{Fft, FftPlanner};

/// A complex number.
pub type C64 = Complex<f64>;

/// Plans for one grid size.
#[derive(Clone)]
pub struct Fft2 {
    n: usize,
    r2c: Arc<dyn RealToComplex<f64>>,
    c2r: Arc<dyn ComplexToReal<f64>>,
    col_fwd: Arc<dyn Fft<f64>>,
    col_inv: Arc<dyn Fft<f64>>,
}

impl std::fmt::Debug for Fft2 {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Fft2({}×{})", self.n, self.n)
    }
}

impl Fft2 {
    /// Plans transforms of n×n fields (n even).
    pub fn new(n: usize) -> Self {
        let mut real = RealFftPlanner::<f64>::new();
        let mut cplx = FftPlanner::<f64>::new();
        Self {
            n,
            r2c: real.plan_fft_forward(n),
            c2r: real.plan_fft_inverse(n),
            col_fwd: cplx.plan_fft_forward(n),
            col_inv: cplx.plan_fft_inverse(n),
        }
    }

    /// Side length.
    pub fn n(&self) -> usize {
        self.n
    }

    /// Number of spectrum coefficients, n·(n/2+1).
    pub fn spectrum_len(&self) -> usize {
        self.n * (self.n / 2 + 1)
    }

    /// Forward transform (unnormalised, e^{−ik·x}) of `input` (n² values) into `out`.
    pub fn forward(&self, input: &[f64], out: &mut [C64]) {
        let (n, h) = (self.n, self.n / 2 + 1);
        let mut row = vec![0.0; n];
        let mut scratch = self.r2c.make_scratch_vec();
        for iy in 0..n {
            row.copy_from_slice(&input[iy * n..(iy + 1) * n]);
            // Lengths are fixed by construction; an error here would be a programming bug.
            let _ = self.r2c.process_with_scratch(
                &mut row,
                &mut out[iy * h..(iy + 1) * h],
                &mut scratch,
            );
        }
        self.columns(out, true);
    }

    /// Inverse transform, normalised by 1/n², of `spec` (overwritten) into `out`.
    pub fn inverse(&self, spec: &mut [C64], out: &mut [f64]) {
        let (n, h) = (self.n, self.n / 2 + 1);
        self.columns(spec, false);
        let norm = 1.0 / (n * n) as f64;
        let mut scratch = self.c2r.make_scratch_vec();
        for iy in 0..n {
            let row_spec = &mut spec[iy * h..(iy + 1) * h];
            // The imaginary parts of the kx = 0 and Nyquist terms must be zero for a real
            // result; they are, up to rounding, and realfft insists on exactly zero.
            row_spec[0].im = 0.0;
            row_spec[h - 1].im = 0.0;
            let _ = self.c2r.process_with_scratch(
                row_spec,
                &mut out[iy * n..(iy + 1) * n],
                &mut scratch,
            );
        }
        for v in out.iter_mut() {
            *v *= norm;
        }
    }

    fn columns(&self, data: &mut [C64], forward: bool) {
        let (n, h) = (self.n, self.n / 2 + 1);
        let plan = if forward {
            &self.col_fwd
        } else {
            &self.col_inv
        };
        let mut col = vec![C64::new(0.0, 0.0); n];
        let mut scratch = vec![C64::new(0.0, 0.0); plan.get_inplace_scratch_len()];
        for ix in 0..h {
            for iy in 0..n {
                col[iy] = data[iy * h + ix];
            }
            plan.process_with_scratch(&mut col, &mut scratch);
            for iy in 0..n {
                data[iy * h + ix] = col[iy];
            }
        }
    }

    /// Wavenumbers (kx, ky) in rad/mm of spectrum index `idx` for cell size `dx`.
    pub fn wavevector(&self, idx: usize, dx: f64) -> (f64, f64) {
        let (n, h) = (self.n, self.n / 2 + 1);
        let (iy, ix) = (idx / h, idx % h);
        let f = |i: usize| -> f64 {
            let i = if i <= n / 2 {
                i as f64
            } else {
                i as f64 - n as f64
            };
            2.0 * std::f64::consts::PI * i / (n as f64 * dx)
        };
        (f(ix), f(iy))
    }

    /// True if the spectrum index sits on a Nyquist row or column, where an odd (imaginary)
    /// kernel must vanish for the result to stay real and the operator symmetric.
    pub fn is_nyquist(&self, idx: usize) -> (bool, bool) {
        let (n, h) = (self.n, self.n / 2 + 1);
        let (iy, ix) = (idx / h, idx % h);
        (ix == n / 2, iy == n / 2)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_parseval() {
        let n = 16;
        let f = Fft2::new(n);
        let input: Vec<f64> = (0..n * n)
            .map(|i| ((i * 7919) % 101) as f64 / 101.0 - 0.5)
            .collect();
        let mut spec = vec![C64::new(0.0, 0.0); f.spectrum_len()];
        f.forward(&input, &mut spec);
        // DC term is the sum.
        assert!((spec[0].re - input.iter().sum::<f64>()).abs() < 1e-12);
        let mut back = vec![0.0; n * n];
        f.inverse(&mut spec, &mut back);
        for (a, b) in input.iter().zip(&back) {
            assert!((a - b).abs() < 1e-13);
        }
    }
}
