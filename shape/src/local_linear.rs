//! The local-linear model: a forward model of the colour change, `d = c + M·g` (3 channels,
//! the slope `g = (∂d/∂x, ∂d/∂y)`), fitted on each calibration press and interpolated over
//! the frame by a thin-plate spline, then inverted per pixel.
//!
//! Why forward and local: a GelSight Mini's lights vignette strongly (the colour change for
//! one slope varies about threefold between the centre and the right and bottom edges), so
//! one map from colour to slope for the whole frame reads border presses 25–40 % shallow; and
//! regressing the slope on a noisy colour change pulls the answer towards zero where the
//! signal is weak, which fitting the colour from the slope and inverting does not
//! (docs/explanation/shape.md). The thin-plate spline with a linear part is the smoothest
//! interpolant of scattered points (Duchon 1977; Bookstein 1989), with a little smoothing for
//! the presses' own noise.

use nalgebra::{DMatrix, DVector, Matrix3, Vector3};
use serde::{Deserialize, Serialize};

use crate::ball::{self, Circle};
use crate::frame::{Rgb, colour_change};

/// Share of the contact radius the per-press fit uses: the colour change blurs and the gel
/// wraps around the ball near the rim, where the ball's slope is not the gel's.
pub const RIM: f64 = 0.9;
/// The thin-plate spline's smoothing (on positions scaled to the frame, −0.5…0.5).
pub const SMOOTHING: f64 = 0.01;
/// Spacing of the nodes the spline is evaluated on, px (bilinear in between).
const NODE_PX: usize = 8;

/// One calibration press's response: where it was (scaled to the frame, −0.5…0.5) and its
/// `[c, ∂/∂gx, ∂/∂gy]` per channel (R, G, B), in units of 64 grey levels — of the
/// flat-fielded change (times 128 over the background's light there) where the model's
/// `flat_field` is set.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Response {
    /// Press centre, x / width − 0.5 and y / height − 0.5.
    pub at: [f64; 2],
    /// Per channel: offset, response to x-slope, response to y-slope.
    pub channels: [[f64; 3]; 3],
}

/// The fitted model: each press's response, and the spline through them.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LocalLinear {
    /// The calibration presses' responses.
    pub responses: Vec<Response>,
    /// Whether the responses are of the flat-fielded colour change (the change times
    /// [`crate::frame::flat_field`] of the background); files written before it was
    /// introduced hold responses of the raw change.
    #[serde(default)]
    pub flat_field: bool,
}

/// Fits one press's response on the pixels inside `RIM` of its circle, leaving out those
/// marked in `ink` (a gel's markers, in the frame or the background) where given; of the
/// colour change times `flat` (per pixel and channel) where given.
pub fn fit_response(
    frame: &Rgb<'_>,
    background: &Rgb<'_>,
    flat: Option<&[f32]>,
    ink: Option<&[bool]>,
    circle: &Circle,
    ball_px: f64,
) -> Option<Response> {
    let (w, h) = (frame.width, frame.height);
    let mut change = Vec::new();
    colour_change(frame, background, &mut change);
    if let Some(flat) = flat {
        for (c, f) in change.iter_mut().zip(flat) {
            *c *= f;
        }
    }
    let a = circle.radius_px * RIM;
    let (mut ata, mut atd) = (Matrix3::<f64>::zeros(), [Vector3::<f64>::zeros(); 3]);
    let mut n = 0;
    let (x0, x1) = (
        (circle.x_px - a).floor().max(0.0) as usize,
        ((circle.x_px + a).ceil() as usize).min(w - 1),
    );
    let (y0, y1) = (
        (circle.y_px - a).floor().max(0.0) as usize,
        ((circle.y_px + a).ceil() as usize).min(h - 1),
    );
    for y in y0..=y1 {
        for x in x0..=x1 {
            let (xf, yf) = (x as f64, y as f64);
            if (xf - circle.x_px).powi(2) + (yf - circle.y_px).powi(2) >= a * a
                || ink.is_some_and(|m| m[y * w + x])
            {
                continue;
            }
            let g = ball::slope(circle, ball_px, xf, yf);
            let t = Vector3::new(1.0, g[0], g[1]);
            ata += t * t.transpose();
            for (c, acc) in atd.iter_mut().enumerate() {
                *acc += t * change[3 * (y * w + x) + c] as f64;
            }
            n += 1;
        }
    }
    if n < 20 {
        return None;
    }
    let lu = ata.lu();
    let mut channels = [[0.0; 3]; 3];
    for (c, acc) in atd.iter().enumerate() {
        let s = lu.solve(acc)?;
        channels[c] = [s[0], s[1], s[2]];
    }
    Some(Response {
        at: [circle.x_px / w as f64 - 0.5, circle.y_px / h as f64 - 0.5],
        channels,
    })
}

/// The spline through the responses' 9 coefficients.
struct Spline {
    centres: Vec<[f64; 2]>,
    /// Per centre, its weight for each coefficient; then 3 rows of the linear part.
    weights: DMatrix<f64>,
}

fn kernel(r2: f64) -> f64 {
    if r2 <= 0.0 { 0.0 } else { 0.5 * r2 * r2.ln() }
}

impl Spline {
    fn fit(responses: &[Response]) -> Option<Self> {
        let n = responses.len();
        let m = n + 3;
        let mut a = DMatrix::<f64>::zeros(m, m);
        let mut b = DMatrix::<f64>::zeros(m, 9);
        for (i, ri) in responses.iter().enumerate() {
            for (j, rj) in responses.iter().enumerate() {
                let d2 = (ri.at[0] - rj.at[0]).powi(2) + (ri.at[1] - rj.at[1]).powi(2);
                a[(i, j)] = kernel(d2) + if i == j { SMOOTHING } else { 0.0 };
            }
            for (k, p) in [1.0, ri.at[0], ri.at[1]].iter().enumerate() {
                a[(i, n + k)] = *p;
                a[(n + k, i)] = *p;
            }
            for c in 0..3 {
                for t in 0..3 {
                    b[(i, 3 * c + t)] = ri.channels[c][t];
                }
            }
        }
        let weights = a.lu().solve(&b)?;
        Some(Self {
            centres: responses.iter().map(|r| r.at).collect(),
            weights,
        })
    }

    fn eval(&self, p: [f64; 2]) -> DVector<f64> {
        let n = self.centres.len();
        let mut basis = DVector::<f64>::zeros(n + 3);
        for (i, c) in self.centres.iter().enumerate() {
            basis[i] = kernel((p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2));
        }
        basis[n] = 1.0;
        basis[n + 1] = p[0];
        basis[n + 2] = p[1];
        self.weights.tr_mul(&basis)
    }
}

/// The model prepared for one frame size: per pixel the offset `c` (3) and the inverse
/// `K = (MᵀM + εI)⁻¹Mᵀ` (2 × 3), so a pixel's slope costs six multiply-adds.
#[derive(Debug, Clone)]
pub(crate) struct Prepared {
    /// Per pixel: c (3) then K row-major (6).
    pub(crate) per_pixel: Vec<[f32; 9]>,
    /// A flat-fielded model's forward coefficients per pixel, c (3) then M row-major
    /// (3 × 2), in flat-fielded units, until [`Prepared::light`] turns them into
    /// `per_pixel` for a background; `None` for a model of the raw change.
    forward: Option<Vec<[f32; 9]>>,
}

/// `c` and `K` of a pixel whose forward model is `c + M·g` with each channel's row scaled
/// by `lit` (the background's light over 128 there; 1 for a raw model).
///
/// Why invert after scaling rather than scale the change: the sensor's noise is the same
/// number of grey levels in every channel, so the least-squares slope weighs each channel by
/// its response in grey levels — a dim channel counts for less — which `(DM)ᵀ(DM)` does and
/// `MᵀM` on the flat-fielded change would not (on the 39 real presses, the worst cap height
/// 15.5 % the other way against 14.2 % this way).
fn invert(f: &[f32; 9], lit: [f32; 3]) -> [f32; 9] {
    let d = lit.map(f64::from);
    let v = |k: usize| f64::from(f[k]);
    let c = [v(0) * d[0], v(1) * d[1], v(2) * d[2]];
    let m = nalgebra::Matrix3x2::new(
        v(3) * d[0],
        v(4) * d[0],
        v(5) * d[1],
        v(6) * d[1],
        v(7) * d[2],
        v(8) * d[2],
    );
    let mtm = m.transpose() * m + nalgebra::Matrix2::identity() * 1e-6;
    let k = mtm
        .try_inverse()
        .map_or(nalgebra::Matrix2x3::zeros(), |inv| inv * m.transpose());
    [
        c[0] as f32,
        c[1] as f32,
        c[2] as f32,
        k[(0, 0)] as f32,
        k[(0, 1)] as f32,
        k[(0, 2)] as f32,
        k[(1, 0)] as f32,
        k[(1, 1)] as f32,
        k[(1, 2)] as f32,
    ]
}

impl LocalLinear {
    /// Prepares the per-pixel inverse for `width × height` frames; `None` with fewer than 3
    /// responses (the spline's linear part needs them) or a degenerate spread of presses.
    /// A flat-fielded model is inverted once [`Prepared::light`] gives it the background.
    pub(crate) fn prepare(&self, width: usize, height: usize) -> Option<Prepared> {
        if self.responses.len() < 3 {
            return None;
        }
        let spline = Spline::fit(&self.responses)?;
        let (nx, ny) = (
            (width - 1).div_ceil(NODE_PX) + 1,
            (height - 1).div_ceil(NODE_PX) + 1,
        );
        let node_xy = |i: usize, j: usize| {
            (
                ((i * NODE_PX).min(width - 1)) as f64,
                ((j * NODE_PX).min(height - 1)) as f64,
            )
        };
        let mut nodes = Vec::with_capacity(nx * ny);
        for j in 0..ny {
            for i in 0..nx {
                let (x, y) = node_xy(i, j);
                nodes.push(spline.eval([x / width as f64 - 0.5, y / height as f64 - 0.5]));
            }
        }
        let mut forward = Vec::with_capacity(width * height);
        for y in 0..height {
            let j = (y / NODE_PX).min(ny - 2);
            let (ya, yb) = (node_xy(0, j).1, node_xy(0, j + 1).1);
            let fy = if yb > ya {
                (y as f64 - ya) / (yb - ya)
            } else {
                0.0
            };
            for x in 0..width {
                let i = (x / NODE_PX).min(nx - 2);
                let (xa, xb) = (node_xy(i, 0).0, node_xy(i + 1, 0).0);
                let fx = if xb > xa {
                    (x as f64 - xa) / (xb - xa)
                } else {
                    0.0
                };
                let q = |k: usize| {
                    let v = |ii: usize, jj: usize| nodes[jj * nx + ii][k];
                    ((1.0 - fy) * ((1.0 - fx) * v(i, j) + fx * v(i + 1, j))
                        + fy * ((1.0 - fx) * v(i, j + 1) + fx * v(i + 1, j + 1)))
                        as f32
                };
                forward.push([q(0), q(3), q(6), q(1), q(2), q(4), q(5), q(7), q(8)]);
            }
        }
        if self.flat_field {
            return Some(Prepared {
                per_pixel: Vec::new(),
                forward: Some(forward),
            });
        }
        Some(Prepared {
            per_pixel: forward.iter().map(|f| invert(f, [1.0; 3])).collect(),
            forward: None,
        })
    }
}

impl Prepared {
    /// Inverts a flat-fielded model for the session's `background` (its light per pixel and
    /// channel, [`crate::frame::flat_field`]); nothing for a model of the raw change.
    pub(crate) fn light(&mut self, background: &Rgb<'_>) {
        let Some(forward) = self.forward.take() else {
            return;
        };
        let flat = crate::frame::flat_field(background);
        self.per_pixel = forward
            .iter()
            .zip(flat.chunks_exact(3))
            .map(|(f, l)| invert(f, [1.0 / l[0], 1.0 / l[1], 1.0 / l[2]]))
            .collect();
    }

    /// Slopes of the colour change `change` (3 per pixel) where `touched`, zero elsewhere.
    pub(crate) fn slopes(&self, change: &[f32], touched: &[bool], gx: &mut [f32], gy: &mut [f32]) {
        // A flat-fielded model has no inverse until it is lit ([`Prepared::light`]; `Depth`
        // lights every map it is given): reading it unlit would leave the slopes as they were.
        debug_assert_eq!(self.per_pixel.len(), touched.len(), "an unlit model");
        for (i, p) in self.per_pixel.iter().enumerate() {
            if !touched[i] {
                gx[i] = 0.0;
                gy[i] = 0.0;
                continue;
            }
            let d = [
                change[3 * i] - p[0],
                change[3 * i + 1] - p[1],
                change[3 * i + 2] - p[2],
            ];
            gx[i] = p[3] * d[0] + p[4] * d[1] + p[5] * d[2];
            gy[i] = p[6] * d[0] + p[7] * d[1] + p[8] * d[2];
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn model(flat_field: bool) -> LocalLinear {
        let responses = [[-0.3, -0.2], [0.3, -0.2], [0.0, 0.3], [0.2, 0.2]]
            .iter()
            .enumerate()
            .map(|(i, at)| Response {
                at: *at,
                channels: [
                    [0.01 * i as f64, 1.2 + 0.1 * i as f64, -0.3],
                    [-0.02, 0.4, 1.1 - 0.05 * i as f64],
                    [0.03, -0.9, -0.8 + 0.02 * i as f64],
                ],
            })
            .collect();
        LocalLinear {
            responses,
            flat_field,
        }
    }

    /// Under a background lit at 128 everywhere the flat field is 1: a flat-fielded model
    /// reads as the same model of the raw change does. Under a dimmer channel its response
    /// (offset and gains) is that much smaller in grey levels.
    #[test]
    fn a_flat_fielded_model_is_the_raw_one_under_even_light() {
        let (w, h) = (24, 20);
        let raw = model(false).prepare(w, h).unwrap();
        let mut flat = model(true).prepare(w, h).unwrap();
        assert!(flat.per_pixel.is_empty(), "inverted before it was lit");
        let even = vec![128u8; w * h * 3];
        flat.light(&Rgb::new(w, h, &even).unwrap());
        assert_eq!(flat.per_pixel.len(), raw.per_pixel.len());
        for (a, b) in flat.per_pixel.iter().zip(&raw.per_pixel) {
            for (x, y) in a.iter().zip(b) {
                assert!((x - y).abs() <= 1e-5 * (1.0 + y.abs()), "{a:?} vs {b:?}");
            }
        }
        // The red channel at half the light: its offset halves, and the slope read from a
        // change the model predicts is the slope that made it.
        let dim: Vec<u8> = (0..w * h * 3)
            .map(|i| if i % 3 == 0 { 64 } else { 128 })
            .collect();
        let mut lit = model(true).prepare(w, h).unwrap();
        lit.light(&Rgb::new(w, h, &dim).unwrap());
        let fwd = model(true).prepare(w, h).unwrap().forward.unwrap();
        let i = 7 * w + 11;
        let (f, p) = (fwd[i], lit.per_pixel[i]);
        assert!((p[0] - 0.5 * f[0]).abs() < 1e-6, "{p:?} {f:?}");
        let g = [0.25f32, -0.4];
        let d = [
            0.5 * (f[0] + f[3] * g[0] + f[4] * g[1]),
            f[1] + f[5] * g[0] + f[6] * g[1],
            f[2] + f[7] * g[0] + f[8] * g[1],
        ];
        let (mut gx, mut gy) = ([0.0f32; 1], [0.0f32; 1]);
        let one = Prepared {
            per_pixel: vec![p],
            forward: None,
        };
        one.slopes(&d, &[true], &mut gx, &mut gy);
        assert!((gx[0] - g[0]).abs() < 1e-4 && (gy[0] - g[1]).abs() < 1e-4);
    }
}
