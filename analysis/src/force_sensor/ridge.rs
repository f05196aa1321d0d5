//! Ridge regression of each wrench channel on the field moments, the regularisation chosen
//! by generalised cross-validation (Golub, Heath & Wahba 1979, *Technometrics* 21:215): for
//! the standardised, centred design X = U S Vᵀ, a ridge λ keeps the filter factors
//! φᵢ = sᵢ²/(sᵢ² + λ), and GCV(λ) = n‖(I − A)y‖² / (n − 1 − Σφᵢ)² is minimised over a
//! logarithmic grid (the 1 is the intercept's degree of freedom). Each channel keeps its
//! residual scale σ and (XᵀX + λI)⁻¹, so a prediction carries σ·√(1 + 1/n + xᵀ(XᵀX + λI)⁻¹x):
//! a field unlike anything in the calibration reads with a wider uncertainty.

use nalgebra::{DMatrix, DVector};

use super::SensorError;

/// One channel's fit.
#[derive(Debug, Clone, PartialEq)]
pub struct ChannelFit {
    /// Weights on the standardised features.
    pub weights: Vec<f64>,
    /// Intercept (the channel's mean over the calibration).
    pub bias: f64,
    /// Ridge parameter chosen by GCV (on the standardised features).
    pub lambda: f64,
    /// Residual scale, in the channel's unit.
    pub sigma: f64,
    /// (XᵀX + λI)⁻¹, row-major, p × p.
    pub inv_gram: Vec<f64>,
    /// Effective degrees of freedom, Σφᵢ.
    pub dof: f64,
}

/// A linear model of every channel on the same features.
#[derive(Debug, Clone, PartialEq)]
pub struct LinearModel {
    /// Feature means over the calibration.
    pub mean: Vec<f64>,
    /// Feature standard deviations (1 for a constant feature).
    pub scale: Vec<f64>,
    /// Samples fitted.
    pub samples: usize,
    /// One fit per channel.
    pub channels: Vec<ChannelFit>,
}

/// Points of the λ grid, from 1e-10 to 1e3 times the largest squared singular value.
const LAMBDA_GRID: usize = 80;

/// One channel's ridge on the standardised design `xs`, or `None` when its SVD fails.
fn fit_channel(xs: &DMatrix<f64>, yc: &[f64]) -> Option<ChannelFit> {
    let (n, p) = xs.shape();
    // Bounded and only on finite input: nalgebra's plain `svd` may never return.
    if !xs.iter().all(|v| v.is_finite()) {
        return None;
    }
    let svd = xs.clone().try_svd(true, true, f64::EPSILON, 1000)?;
    let (u, vt, s) = (svd.u?, svd.v_t?, svd.singular_values);
    let smax2 = s.iter().fold(0.0f64, |a, v| a.max(v * v)).max(1e-300);
    let bias = yc.iter().sum::<f64>() / n as f64;
    let yv = DVector::from_iterator(n, yc.iter().map(|v| v - bias));
    let uty = u.transpose() * &yv;
    let yy = yv.norm_squared();
    let uty2 = uty.norm_squared();
    let score = |lambda: f64| {
        let mut resid = yy - uty2;
        let mut dof = 0.0;
        for (i, si) in s.iter().enumerate() {
            let phi = si * si / (si * si + lambda);
            resid += ((1.0 - phi) * uty[i]).powi(2);
            dof += phi;
        }
        let denom = n as f64 - 1.0 - dof;
        (
            n as f64 * resid.max(0.0) / (denom * denom).max(1e-300),
            resid.max(0.0),
            dof,
        )
    };
    let (mut best, mut best_l) = (f64::INFINITY, smax2);
    for k in 0..LAMBDA_GRID {
        let l = smax2 * 10f64.powf(-10.0 + 13.0 * k as f64 / (LAMBDA_GRID - 1) as f64);
        let (g, _, _) = score(l);
        if g < best {
            best = g;
            best_l = l;
        }
    }
    let (_, resid, dof) = score(best_l);
    let mut w = DVector::zeros(p);
    let mut inv = DMatrix::zeros(p, p);
    for (i, si) in s.iter().enumerate() {
        let v = vt.row(i).transpose();
        w += &v * (si / (si * si + best_l) * uty[i]);
        inv += &v * v.transpose() / (si * si + best_l);
    }
    // Directions of the feature space with no singular value (p > rank) get the pure
    // ridge 1/λ.
    let rank = s.len();
    if rank < p {
        let vv = vt.transpose() * &vt;
        let eye = DMatrix::<f64>::identity(p, p);
        inv += (eye - vv) / best_l;
    }
    let sigma = (resid / (n as f64 - 1.0 - dof).max(1.0)).sqrt();
    Some(ChannelFit {
        weights: w.iter().copied().collect(),
        bias,
        lambda: best_l,
        sigma,
        inv_gram: inv.transpose().iter().copied().collect(),
        dof,
    })
}

impl LinearModel {
    /// Fits every channel of `y` (rows: samples) on features `x` (rows: samples).
    pub fn fit(x: &[Vec<f64>], y: &[Vec<f64>]) -> Result<Self, SensorError> {
        Self::fit_masked(x, y, None)
    }

    /// As [`Self::fit`], channel `c` seeing only the features `masks[c]` marks (a channel
    /// without a mask, and a feature past the end of one, is seen).
    pub fn fit_masked(
        x: &[Vec<f64>],
        y: &[Vec<f64>],
        masks: Option<&[Vec<bool>]>,
    ) -> Result<Self, SensorError> {
        let n = x.len();
        let p = x.first().map_or(0, Vec::len);
        if n < p + 2 || y.len() != n {
            return Err(SensorError::TooFewSamples {
                samples: n,
                features: p,
            });
        }
        let mean: Vec<f64> = (0..p)
            .map(|j| x.iter().map(|r| r[j]).sum::<f64>() / n as f64)
            .collect();
        let scale: Vec<f64> = (0..p)
            .map(|j| {
                let v = x.iter().map(|r| (r[j] - mean[j]).powi(2)).sum::<f64>() / n as f64;
                if v > 0.0 { v.sqrt() } else { 1.0 }
            })
            .collect();
        let xs = DMatrix::from_fn(n, p, |i, j| (x[i][j] - mean[j]) / scale[j]);
        let nc = y.first().map_or(0, Vec::len);
        let mut channels = Vec::with_capacity(nc);
        for c in 0..nc {
            let keep: Vec<usize> = (0..p)
                .filter(|&j| {
                    masks.is_none_or(|m| {
                        m.get(c).is_none_or(|mc| mc.get(j).copied().unwrap_or(true))
                    })
                })
                .collect();
            let yc: Vec<f64> = y.iter().map(|r| r[c]).collect();
            if keep.is_empty() {
                // Nothing to see: the channel is its calibration mean.
                let bias = yc.iter().sum::<f64>() / n as f64;
                let resid = yc.iter().map(|v| (v - bias).powi(2)).sum::<f64>();
                channels.push(ChannelFit {
                    weights: vec![0.0; p],
                    bias,
                    lambda: 0.0,
                    sigma: (resid / (n as f64 - 1.0).max(1.0)).sqrt(),
                    inv_gram: vec![0.0; p * p],
                    dof: 0.0,
                });
                continue;
            }
            let sub = DMatrix::from_fn(n, keep.len(), |i, j| xs[(i, keep[j])]);
            let fit = fit_channel(&sub, &yc).ok_or(SensorError::TooFewSamples {
                samples: n,
                features: p,
            })?;
            // Scattered back to every feature: an excluded one has no weight and no
            // variance.
            let q = keep.len();
            let mut weights = vec![0.0; p];
            let mut inv_gram = vec![0.0; p * p];
            for (a, &ja) in keep.iter().enumerate() {
                weights[ja] = fit.weights[a];
                for (b, &jb) in keep.iter().enumerate() {
                    inv_gram[ja * p + jb] = fit.inv_gram[a * q + b];
                }
            }
            channels.push(ChannelFit {
                weights,
                inv_gram,
                ..fit
            });
        }
        Ok(Self {
            mean,
            scale,
            samples: n,
            channels,
        })
    }

    /// Each channel's value and its standard uncertainty at features `f`.
    pub fn predict(&self, f: &[f64]) -> (Vec<f64>, Vec<f64>) {
        let p = self.mean.len();
        let z: Vec<f64> = (0..p)
            .map(|j| (f.get(j).copied().unwrap_or(0.0) - self.mean[j]) / self.scale[j])
            .collect();
        let mut value = Vec::with_capacity(self.channels.len());
        let mut sd = Vec::with_capacity(self.channels.len());
        for c in &self.channels {
            value.push(c.bias + c.weights.iter().zip(&z).map(|(w, v)| w * v).sum::<f64>());
            let mut lev = 0.0;
            for i in 0..p {
                for j in 0..p {
                    lev += z[i] * c.inv_gram.get(i * p + j).copied().unwrap_or(0.0) * z[j];
                }
            }
            sd.push(c.sigma * (1.0 + 1.0 / self.samples.max(1) as f64 + lev.max(0.0)).sqrt());
        }
        (value, sd)
    }
}
