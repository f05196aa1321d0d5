//! Weighted Lucas–Kanade on darkness maps (thesis §3.4, eq. 3.9–3.11).
//!
//! Each marker's patch in the reference darkness map is the template T; the displacement u
//! minimises Σ w (I(x + u) − T(x))² with the thesis's weight w = T_x² + T_y² (eq. 3.9),
//! which puts the weight on the marker's rim, where the signal is, not on its flat inside
//! or the background, where only noise changes. (Eq. 3.8 and 3.11 print Σ I_x I_t in both
//! rows of b; the second row is Σ I_y I_t.)
//!
//! The solve is inverse compositional (Baker & Matthews 2004): the gradients and the 2×2
//! weighted Hessian Ã (eq. 3.11) come from the template, once per marker and pyramid level,
//! so each iteration only samples the current frame. Working on darkness rather than grey
//! levels keeps the coloured contact shading out of the flow, which the thesis names as
//! LK's main interference. Coarse-to-fine over a 2×2-mean pyramid extends the capture range
//! beyond the half-marker limit the thesis found for a single level.
//!
//! Used two ways: on its own, started from each marker's previous displacement with the
//! full pyramid; and as a refinement of the centroids, started from them at full
//! resolution only.

/// Settings of the LK solve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LkParams {
    /// Half-width of the square patch at every level, px.
    pub half_window: usize,
    /// Pyramid levels (1 = full resolution only).
    pub levels: usize,
    /// Iterations per level at most.
    pub iterations: usize,
    /// Stop when an update is smaller than this, px.
    pub epsilon_px: f64,
}

impl LkParams {
    /// A patch of the marker plus its rim: half-width radius + 3 px.
    pub fn for_radius(radius_px: f64, levels: usize) -> Self {
        Self {
            half_window: (radius_px + 3.0).ceil() as usize,
            levels: levels.max(1),
            iterations: 12,
            epsilon_px: 0.005,
        }
    }
}

/// A float image.
#[derive(Debug, Clone)]
struct Plane {
    w: usize,
    h: usize,
    v: Vec<f32>,
}

impl Plane {
    fn from_u8(w: usize, h: usize, v: &[u8]) -> Self {
        Self {
            w,
            h,
            v: v.iter().map(|&x| x as f32).collect(),
        }
    }

    /// 2×2 mean; pixel centres map as x_coarse = (x_fine + 0.5)/2 − 0.5.
    fn half(&self) -> Self {
        let (w, h) = ((self.w / 2).max(1), (self.h / 2).max(1));
        let mut v = vec![0.0; w * h];
        for y in 0..h {
            for x in 0..w {
                let (x0, y0) = ((2 * x).min(self.w - 1), (2 * y).min(self.h - 1));
                let (x1, y1) = ((2 * x + 1).min(self.w - 1), (2 * y + 1).min(self.h - 1));
                v[y * w + x] = 0.25
                    * (self.v[y0 * self.w + x0]
                        + self.v[y0 * self.w + x1]
                        + self.v[y1 * self.w + x0]
                        + self.v[y1 * self.w + x1]);
            }
        }
        Self { w, h, v }
    }

    /// Bilinear sample with edge clamping.
    fn sample(&self, x: f64, y: f64) -> f32 {
        let xc = x.clamp(0.0, (self.w - 1) as f64);
        let yc = y.clamp(0.0, (self.h - 1) as f64);
        let (x0, y0) = (xc.floor() as usize, yc.floor() as usize);
        let (x1, y1) = ((x0 + 1).min(self.w - 1), (y0 + 1).min(self.h - 1));
        let (fx, fy) = ((xc - x0 as f64) as f32, (yc - y0 as f64) as f32);
        let a =
            self.v[y0 * self.w + x0] + fx * (self.v[y0 * self.w + x1] - self.v[y0 * self.w + x0]);
        let b =
            self.v[y1 * self.w + x0] + fx * (self.v[y1 * self.w + x1] - self.v[y1 * self.w + x0]);
        a + fy * (b - a)
    }
}

/// Σ w·T_x·e, Σ w·T_y·e and Σ e² over the patch of half-width `hw` centred at (x, y),
/// with e = I(x + d) − T(d).
///
/// Every sample of a translated patch shares the same fractional offset, so the bilinear
/// weights are computed once and each row is a fixed 2×2 blend of two image rows; only a
/// patch that touches the border takes the clamped path.
fn residual_products(
    plane: &Plane,
    tpl: &Template,
    x: f64,
    y: f64,
    hw: isize,
) -> (f64, f64, f64, usize) {
    let (xf, yf) = (x.floor(), y.floor());
    let (fx, fy) = ((x - xf) as f32, (y - yf) as f32);
    let (x0, y0) = (xf as isize - hw, yf as isize - hw);
    let side = (2 * hw + 1) as usize;
    let inside = x0 >= 0
        && y0 >= 0
        && x0 + (side as isize) < plane.w as isize
        && y0 + (side as isize) < plane.h as isize;
    let (mut bx, mut by, mut sse) = (0.0f64, 0.0f64, 0.0f64);
    if inside {
        let w00 = (1.0 - fx) * (1.0 - fy);
        let w10 = fx * (1.0 - fy);
        let w01 = (1.0 - fx) * fy;
        let w11 = fx * fy;
        for row in 0..side {
            let top = (y0 as usize + row) * plane.w + x0 as usize;
            let a = &plane.v[top..top + side + 1];
            let b = &plane.v[top + plane.w..top + plane.w + side + 1];
            let t = &tpl.t[row * side..][..side];
            let gx = &tpl.wgx[row * side..][..side];
            let gy = &tpl.wgy[row * side..][..side];
            let (mut rx, mut ry, mut re) = (0.0f32, 0.0f32, 0.0f32);
            for c in 0..side {
                let v = w00 * a[c] + w10 * a[c + 1] + w01 * b[c] + w11 * b[c + 1];
                let e = v - t[c];
                rx += gx[c] * e;
                ry += gy[c] * e;
                re += e * e;
            }
            bx += rx as f64;
            by += ry as f64;
            sse += re as f64;
        }
    } else {
        let mut k = 0;
        for dy in -hw..=hw {
            for dx in -hw..=hw {
                let e = plane.sample(x + dx as f64, y + dy as f64) - tpl.t[k];
                bx += (tpl.wgx[k] * e) as f64;
                by += (tpl.wgy[k] * e) as f64;
                sse += (e * e) as f64;
                k += 1;
            }
        }
    }
    (bx, by, sse, side * side)
}

/// A darkness pyramid of one frame.
#[derive(Debug, Clone)]
pub struct Pyramid {
    levels: Vec<Plane>,
}

impl Pyramid {
    /// Builds `levels` levels from a smoothed darkness map (see [`super::Detector::smoothed`]).
    pub fn new(width: usize, height: usize, darkness: &[u8], levels: usize) -> Self {
        let mut out = vec![Plane::from_u8(width, height, darkness)];
        for _ in 1..levels.max(1) {
            let next = out[out.len() - 1].half();
            out.push(next);
        }
        Self { levels: out }
    }

    fn levels(&self) -> usize {
        self.levels.len()
    }
}

/// One marker's template at one level: values, weighted gradients, inverse Hessian.
#[derive(Debug, Clone)]
struct Template {
    t: Vec<f32>,
    /// w·T_x and w·T_y per pixel.
    wgx: Vec<f32>,
    wgy: Vec<f32>,
    /// Ã⁻¹ (eq. 3.10–3.11), row-major 2×2; `None` when the patch has no texture.
    inv: Option<[f64; 4]>,
}

/// Templates of every reference marker at every level.
#[derive(Debug, Clone)]
pub struct LkTracker {
    params: LkParams,
    /// [marker][level].
    templates: Vec<Vec<Template>>,
    reference_px: Vec<[f64; 2]>,
}

fn to_level(p: f64, level: usize) -> f64 {
    (p + 0.5) / (1u32 << level) as f64 - 0.5
}

impl LkTracker {
    /// Prepares the templates from the reference darkness pyramid.
    pub fn new(reference: &Pyramid, reference_px: &[[f64; 2]], params: LkParams) -> Self {
        let levels = params.levels.min(reference.levels());
        let hw = params.half_window as isize;
        let side = (2 * hw + 1) as usize;
        let templates = reference_px
            .iter()
            .map(|p| {
                (0..levels)
                    .map(|l| {
                        let plane = &reference.levels[l];
                        let (cx, cy) = (to_level(p[0], l), to_level(p[1], l));
                        let mut t = Vec::with_capacity(side * side);
                        let mut wgx = Vec::with_capacity(side * side);
                        let mut wgy = Vec::with_capacity(side * side);
                        let (mut a, mut b, mut c) = (0.0f64, 0.0f64, 0.0f64);
                        for dy in -hw..=hw {
                            for dx in -hw..=hw {
                                let (x, y) = (cx + dx as f64, cy + dy as f64);
                                let gx =
                                    0.5 * (plane.sample(x + 1.0, y) - plane.sample(x - 1.0, y));
                                let gy =
                                    0.5 * (plane.sample(x, y + 1.0) - plane.sample(x, y - 1.0));
                                let w = gx * gx + gy * gy; // eq. 3.9
                                t.push(plane.sample(x, y));
                                wgx.push(w * gx);
                                wgy.push(w * gy);
                                a += (w * gx * gx) as f64;
                                b += (w * gx * gy) as f64;
                                c += (w * gy * gy) as f64;
                            }
                        }
                        let det = a * c - b * b;
                        let inv = (det > 1e-9 * (a + c).powi(2) && a + c > 0.0)
                            .then(|| [c / det, -b / det, -b / det, a / det]);
                        Template { t, wgx, wgy, inv }
                    })
                    .collect()
            })
            .collect();
        Self {
            params: LkParams { levels, ..params },
            templates,
            reference_px: reference_px.to_vec(),
        }
    }

    /// Number of pyramid levels the templates have.
    pub fn levels(&self) -> usize {
        self.params.levels
    }

    /// Displacement of marker `id` from the reference in `frame`, started from `init_px`,
    /// over levels `levels − 1 … 0`. Returns the displacement and the rms residual of
    /// the patch (darkness levels), or `None` if the patch has no texture or the solve
    /// leaves the frame.
    pub fn track(
        &self,
        frame: &Pyramid,
        id: usize,
        init_px: [f64; 2],
        levels: usize,
    ) -> Option<([f64; 2], f64)> {
        let levels = levels.clamp(1, self.params.levels.min(frame.levels()));
        let p = self.reference_px.get(id)?;
        let hw = self.params.half_window as isize;
        let scale = (1u32 << (levels - 1)) as f64;
        let mut u = [init_px[0] / scale, init_px[1] / scale];
        let mut rms = f64::NAN;
        for l in (0..levels).rev() {
            let tpl = &self.templates[id][l];
            let inv = tpl.inv?;
            let plane = &frame.levels[l];
            let (cx, cy) = (to_level(p[0], l), to_level(p[1], l));
            for _ in 0..self.params.iterations {
                let (bx, by, sse, k) = residual_products(plane, tpl, cx + u[0], cy + u[1], hw);
                rms = (sse / k as f64).sqrt();
                let du = [inv[0] * bx + inv[1] * by, inv[2] * bx + inv[3] * by];
                u = [u[0] - du[0], u[1] - du[1]];
                if !(u[0].is_finite() && u[1].is_finite()) {
                    return None;
                }
                if du[0].hypot(du[1]) < self.params.epsilon_px / (1u32 << l) as f64 {
                    break;
                }
            }
            if l > 0 {
                u = [2.0 * u[0], 2.0 * u[1]];
            }
        }
        let (x, y) = (p[0] + u[0], p[1] + u[1]);
        let inside = |v: f64, n: usize| v >= -0.5 && v <= n as f64 - 0.5;
        (inside(x, frame.levels[0].w) && inside(y, frame.levels[0].h)).then_some((u, rms))
    }
}
