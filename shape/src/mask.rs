//! Where the gel is touched: the colour change, blurred, above a few grey levels in any
//! channel, grown by a margin. Slopes outside it are set to zero before integration, so the
//! background's noise (σ ≈ 2–3 grey levels on a GelSight Mini) does not drift the height.

/// Grey levels of blurred colour change that mark a pixel touched. At 12 the mask missed
/// 12 % of the darkest corner press's circle and cost 17 points of its cap height
/// (docs/explanation/shape.md); 6 is about twice the background's noise after the blur.
pub(crate) const TOUCH_GREY: f32 = 6.0;
/// Pixels the touched region is grown by: the gel wraps around the ball beyond the circle.
pub(crate) const MARGIN_PX: usize = 8;
/// Pixels the far field starts beyond the grown region.
pub(crate) const FAR_PX: usize = 10;
/// The blur, at half resolution (each 2×2 block averaged): two passes of a box of radius 1
/// (3 half-pixels), σ ≈ 2.4 px of the frame. The region is coarse by nature (it is grown by
/// 8 px), and at half resolution finding it costs a quarter: at 640×480 it was a third of
/// the frame's time (docs/benchmarks/shape.md).
const BOX_R: usize = 1;

/// Buffers for [`Masker::touched`], kept between frames.
#[derive(Debug, Default)]
pub(crate) struct Masker {
    a: Vec<f32>,
    b: Vec<f32>,
    strength: Vec<f32>,
    row: Vec<u32>,
    half_touched: Vec<bool>,
    half_far: Vec<bool>,
}

impl Masker {
    /// Writes into `touched` the pixels of a colour change (`change`, 3 per pixel, in units
    /// of 64 grey levels) whose blur exceeds [`TOUCH_GREY`] in any channel, grown by
    /// [`MARGIN_PX`]; and into `far` those beyond a further [`FAR_PX`].
    pub(crate) fn touched(
        &mut self,
        change: &[f32],
        (w, h): (usize, usize),
        touched: &mut Vec<bool>,
        far: &mut Vec<bool>,
    ) {
        let (hw, hh) = (w.div_ceil(2), h.div_ceil(2));
        let n = hw * hh;
        self.a.resize(3 * n, 0.0);
        self.b.resize(3 * n, 0.0);
        self.strength.resize(n, 0.0);
        half(change, w, h, &mut self.a);
        for _ in 0..2 {
            box_rows(&self.a, &mut self.b, hw, hh);
            box_cols(&self.b, &mut self.a, hw, hh);
        }
        for (s, px) in self.strength.iter_mut().zip(self.a.chunks_exact(3)) {
            *s = px[0].abs().max(px[1].abs()).max(px[2].abs());
        }
        let limit = TOUCH_GREY * crate::frame::CHANGE_SCALE;
        let (ht, hf) = (&mut self.half_touched, &mut self.half_far);
        ht.clear();
        ht.extend(self.strength.iter().map(|s| *s > limit));
        grow(ht, hw, hh, MARGIN_PX / 2, &mut self.row);
        hf.clear();
        hf.extend_from_slice(ht);
        grow(hf, hw, hh, FAR_PX.div_ceil(2), &mut self.row);
        touched.resize(w * h, false);
        far.resize(w * h, false);
        for y in 0..h {
            let (t_row, f_row) = (
                &ht[(y / 2) * hw..(y / 2 + 1) * hw],
                &hf[(y / 2) * hw..(y / 2 + 1) * hw],
            );
            for x in 0..w {
                touched[y * w + x] = t_row[x / 2];
                far[y * w + x] = !f_row[x / 2];
            }
        }
    }
}

/// `out` ← each 2×2 block of interleaved RGB `src` (w × h) averaged (a partial block at an
/// odd border averages what it has).
fn half(src: &[f32], w: usize, h: usize, out: &mut [f32]) {
    let hw = w.div_ceil(2);
    for (hy, out_row) in out.chunks_exact_mut(3 * hw).enumerate() {
        let ys = [2 * hy, (2 * hy + 1).min(h - 1)];
        for hx in 0..hw {
            let xs = [2 * hx, (2 * hx + 1).min(w - 1)];
            for c in 0..3 {
                let mut s = 0.0;
                for y in ys {
                    for x in xs {
                        s += src[3 * (y * w + x) + c];
                    }
                }
                out_row[3 * hx + c] = 0.25 * s;
            }
        }
    }
}

/// A running box mean of radius [`BOX_R`] along rows of interleaved RGB (borders clamped:
/// the window shrinks).
fn box_rows(src: &[f32], dst: &mut [f32], w: usize, h: usize) {
    for y in 0..h {
        let row = &src[3 * y * w..3 * (y + 1) * w];
        let out = &mut dst[3 * y * w..3 * (y + 1) * w];
        let mut sum = [0f32; 3];
        let mut count = 0f32;
        for x in 0..BOX_R.min(w) {
            for c in 0..3 {
                sum[c] += row[3 * x + c];
            }
            count += 1.0;
        }
        for x in 0..w {
            let add = x + BOX_R;
            if add < w {
                for c in 0..3 {
                    sum[c] += row[3 * add + c];
                }
                count += 1.0;
            }
            if x > BOX_R {
                let sub = x - BOX_R - 1;
                for c in 0..3 {
                    sum[c] -= row[3 * sub + c];
                }
                count -= 1.0;
            }
            for c in 0..3 {
                out[3 * x + c] = sum[c] / count;
            }
        }
    }
}

/// A running box mean of radius [`BOX_R`] along columns of interleaved RGB, a row at a time.
fn box_cols(src: &[f32], dst: &mut [f32], w: usize, h: usize) {
    let stride = 3 * w;
    for y in 0..h {
        let (a, b) = (y.saturating_sub(BOX_R), (y + BOX_R).min(h - 1));
        let inv = 1.0 / (b - a + 1) as f32;
        let out = &mut dst[y * stride..(y + 1) * stride];
        out.copy_from_slice(&src[a * stride..(a + 1) * stride]);
        for yy in a + 1..=b {
            for (o, s) in out.iter_mut().zip(&src[yy * stride..(yy + 1) * stride]) {
                *o += s;
            }
        }
        for o in out.iter_mut() {
            *o *= inv;
        }
    }
}

/// Grows `mask` by `r` pixels in each direction (a square): along rows, then along columns,
/// each by the distance to the nearest set pixel before and after (two sweeps, no search).
pub(crate) fn grow(mask: &mut [bool], w: usize, h: usize, r: usize, scratch: &mut Vec<u32>) {
    const NONE: u32 = u32::MAX / 2;
    let r = r as u32;
    scratch.resize(w * h, 0);
    // Rows: distance to the nearest set pixel on the left, then the right.
    for y in 0..h {
        let row = &mut mask[y * w..(y + 1) * w];
        let dist = &mut scratch[y * w..(y + 1) * w];
        let mut d = NONE;
        for (m, o) in row.iter().zip(dist.iter_mut()) {
            d = if *m { 0 } else { d.saturating_add(1) };
            *o = d;
        }
        let mut d = NONE;
        for (m, o) in row.iter_mut().zip(dist.iter()).rev() {
            d = if *m { 0 } else { d.saturating_add(1) };
            *m = d.min(*o) <= r;
        }
    }
    // Columns, a row at a time: distance to the nearest grown pixel above, then below.
    let mut d = vec![NONE; w];
    for (m_row, s_row) in mask.chunks_exact(w).zip(scratch.chunks_exact_mut(w)) {
        for ((dx, m), s) in d.iter_mut().zip(m_row).zip(s_row) {
            *dx = if *m { 0 } else { dx.saturating_add(1) };
            *s = *dx;
        }
    }
    d.fill(NONE);
    for (m_row, s_row) in mask.chunks_exact_mut(w).zip(scratch.chunks_exact(w)).rev() {
        for ((dx, m), s) in d.iter_mut().zip(m_row.iter_mut()).zip(s_row) {
            *dx = if *m { 0 } else { dx.saturating_add(1) };
            *m = (*dx).min(*s) <= r;
        }
    }
}
