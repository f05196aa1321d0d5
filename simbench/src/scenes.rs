//! Synthetic marker sequences with exact ground truth, for scoring trackers.
//!
//! A tracker is only as trustworthy as the hardest motion it was scored on. The bench's own
//! frames move the markers locally and slowly; these scenes make the motions that break
//! identity — a uniform pan with markers leaving and entering the view, jumps from rest, a
//! twist inside the contact, whole-view rotation, a return to rest — and the imaging that
//! breaks detection — exposure, contrast, defocus, noise — with the same drawing as the
//! simulated camera ([`Renderer`]). The gel can be larger than the view (`overscan`), so
//! markers leave and enter at the borders as they do on a real sensor.
//!
//! Every frame comes with the exact centre of every printed marker, in the tracker's pixel
//! convention (pixel (i, j) centred at (i, j)).

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rand_distr::StandardNormal;

use super::plant::MarkerLayout;
use super::render::{Renderer, marker_reference_positions_mm};

/// A sensor's marker layout seen by a camera, with markers printed beyond the view.
pub struct Scene {
    renderer: Renderer,
    rest_px: Vec<[f64; 2]>,
    spacing_px: f64,
    radius_px: f64,
}

impl Scene {
    /// `layout` seen over `view_mm` at `size` px; `overscan` more rows and columns of
    /// markers (in spacings) printed on each side beyond the sensor's own layout (0: the
    /// layout as the sensor has it, whose edges may be in view).
    pub fn new(
        layout: &MarkerLayout,
        view_mm: (f64, f64),
        size: (u32, u32),
        overscan: u32,
    ) -> Self {
        let renderer =
            Renderer::for_view(layout, view_mm.0, view_mm.1, size.0, size.1).without_noise();
        let mm = renderer.mm_per_px();
        let (spacing_mm, radius_mm, printed) = match *layout {
            MarkerLayout::Grid {
                columns,
                rows,
                spacing_mm,
                diameter_mm,
            } => {
                let wider = MarkerLayout::Grid {
                    columns: columns + 2 * overscan,
                    rows: rows + 2 * overscan,
                    spacing_mm,
                    diameter_mm,
                };
                (
                    spacing_mm,
                    diameter_mm / 2.0,
                    marker_reference_positions_mm(&wider, view_mm.0, view_mm.1),
                )
            }
            MarkerLayout::Random {
                spacing_mm,
                size_mm,
            } => {
                let extra = 2.0 * overscan as f64 * spacing_mm;
                (
                    spacing_mm,
                    size_mm / 3f64.sqrt(),
                    marker_reference_positions_mm(layout, view_mm.0 + extra, view_mm.1 + extra),
                )
            }
        };
        let rest_px = printed.iter().map(|&(x, y)| renderer.to_px(x, y)).collect();
        Self {
            renderer,
            rest_px,
            spacing_px: spacing_mm / mm,
            radius_px: radius_mm / mm,
        }
    }

    /// Frame size, px.
    pub fn size(&self) -> (u32, u32) {
        self.renderer.size()
    }

    /// Every printed marker at rest, px (some may lie outside the view).
    pub fn rest_px(&self) -> &[[f64; 2]] {
        &self.rest_px
    }

    /// Marker spacing, px.
    pub fn spacing_px(&self) -> f64 {
        self.spacing_px
    }

    /// Marker radius (a dot's radius, a triangle's circumradius), px.
    pub fn radius_px(&self) -> f64 {
        self.radius_px
    }

    /// Frame `k` of `motion` under `look`: RGB8 pixels and every marker's exact centre.
    pub fn frame(&self, motion: &Motion, k: usize, look: &Look) -> (Vec<u8>, Vec<[f64; 2]>) {
        let placed: Vec<([f64; 2], f64)> =
            self.rest_px.iter().map(|&p| motion.place(p, k)).collect();
        let centres: Vec<[f64; 2]> = placed.iter().map(|p| p.0).collect();
        let background = self.renderer.background_layer(None);
        let mut img = background.clone();
        self.renderer
            .draw_markers(&mut img, &centres, |m| placed[m].1);
        if let Some(c) = look.contrast {
            let gain = (c / self.renderer.ink_darkness()) as f32;
            for (v, b) in img.iter_mut().zip(&background) {
                *v = b + (*v - b) * gain;
            }
        }
        let (w, h) = self.size();
        if look.defocus_px > 0.0 {
            defocus(&mut img, w as usize, h as usize, look.defocus_px);
        }
        let exposure = look.exposure as f32;
        let mut rng =
            StdRng::seed_from_u64(look.seed ^ (k as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15));
        let rgb = img
            .iter()
            .map(|&v| {
                let n: f64 = if look.noise_sigma > 0.0 {
                    look.noise_sigma * rng.sample::<f64, _>(StandardNormal)
                } else {
                    0.0
                };
                // Saturating casts round and clamp at once.
                (v * exposure + n as f32 + 0.5) as u8
            })
            .collect();
        (rgb, centres)
    }
}

/// How the camera sees the scene.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Look {
    /// Global exposure gain (0.6 = 40 % darker).
    pub exposure: f64,
    /// Marker contrast, as darkness `1 − max_c(I/B)` at a marker's centre (the renderer's
    /// ink gives about 0.8); `None` keeps the ink.
    pub contrast: Option<f64>,
    /// Radius of the defocus blur circle, px: a Gaussian with the circle's second moment
    /// (σ = radius / 2), by three box passes.
    pub defocus_px: f64,
    /// Sensor noise, grey levels (σ of a Gaussian per pixel and channel).
    pub noise_sigma: f64,
    /// Seed of the noise.
    pub seed: u64,
}

impl Default for Look {
    /// The renderer's own look: sharp, full contrast, noise σ 1.5.
    fn default() -> Self {
        Self {
            exposure: 1.0,
            contrast: None,
            defocus_px: 0.0,
            noise_sigma: 1.5,
            seed: 0x005C_E4E5,
        }
    }
}

/// How the gel moves, frame by frame; frame 0 is always at rest (the reference).
#[derive(Debug, Clone, PartialEq)]
pub enum Motion {
    /// Nothing moves.
    Rest {
        /// Frames.
        frames: usize,
    },
    /// The whole gel translates by `step_px` per frame for `frames` frames, then back at
    /// the same speed, ending exactly at rest.
    PanAndReturn {
        /// Translation per frame, px.
        step_px: [f64; 2],
        /// Frames out (as many back).
        frames: usize,
    },
    /// At rest, then translated by `by_px` in one frame, held for `hold` frames, then back
    /// to rest in one frame.
    Jump {
        /// The jump, px.
        by_px: [f64; 2],
        /// Frames held.
        hold: usize,
    },
    /// Inside a contact of radius `radius_px` around `centre_px`, the gel turns by
    /// `angle_rad` in one frame (stuck to a twisting indenter); outside, the turn decays as
    /// (a/r)³ (u_θ = θa³/r², the far field of a twisted punch, Johnson 1985 §7.3). Held for
    /// `hold` frames, then back to rest in one frame.
    Twist {
        /// Contact centre, px.
        centre_px: [f64; 2],
        /// Contact radius, px.
        radius_px: f64,
        /// Turn inside the contact, rad.
        angle_rad: f64,
        /// Frames held.
        hold: usize,
    },
    /// The whole gel translates along a path: frame `k` ≥ 1 is at `offsets_px[k − 1]` from
    /// rest (reversals mid-pan, accelerations, jumps of any size).
    Path {
        /// Offset from rest of frames 1, 2, …, px.
        offsets_px: Vec<[f64; 2]>,
    },
    /// The whole view turns by `rad_per_frame` about `centre_px` for `frames` frames, then
    /// back at the same speed.
    Rotate {
        /// Centre of rotation, px.
        centre_px: [f64; 2],
        /// Turn per frame, rad.
        rad_per_frame: f64,
        /// Frames out (as many back).
        frames: usize,
    },
}

impl Motion {
    /// Number of frames, the reference included.
    pub fn frames(&self) -> usize {
        match *self {
            Self::Rest { frames } => frames.max(1),
            Self::PanAndReturn { frames, .. } | Self::Rotate { frames, .. } => 2 * frames + 1,
            Self::Jump { hold, .. } | Self::Twist { hold, .. } => hold + 3,
            Self::Path { ref offsets_px } => offsets_px.len() + 1,
        }
    }

    /// A path of whole-gel translations from per-frame steps (frame 1 is one step from
    /// rest), in px.
    pub fn from_steps(steps_px: &[[f64; 2]]) -> Self {
        let mut at = [0.0; 2];
        Self::Path {
            offsets_px: steps_px
                .iter()
                .map(|s| {
                    at = [at[0] + s[0], at[1] + s[1]];
                    at
                })
                .collect(),
        }
    }

    /// How far along frame `k` is: 0 at rest, 1 at the full motion.
    fn progress(&self, k: usize) -> f64 {
        match *self {
            Self::Rest { .. } | Self::Path { .. } => 0.0,
            Self::PanAndReturn { frames, .. } | Self::Rotate { frames, .. } => {
                (if k <= frames {
                    k
                } else {
                    (2 * frames).saturating_sub(k)
                }) as f64
            }
            Self::Jump { hold, .. } | Self::Twist { hold, .. } => {
                if k == 0 || k > hold + 1 {
                    0.0
                } else {
                    1.0
                }
            }
        }
    }

    /// Where the marker at rest at `rest` is in frame `k`, and how far it has turned.
    pub fn place(&self, rest: [f64; 2], k: usize) -> ([f64; 2], f64) {
        let t = self.progress(k);
        match *self {
            Self::Rest { .. } => (rest, 0.0),
            Self::Path { ref offsets_px } => {
                let o = k
                    .checked_sub(1)
                    .and_then(|i| offsets_px.get(i))
                    .copied()
                    .unwrap_or([0.0; 2]);
                ([rest[0] + o[0], rest[1] + o[1]], 0.0)
            }
            Self::PanAndReturn { step_px, .. } => {
                ([rest[0] + t * step_px[0], rest[1] + t * step_px[1]], 0.0)
            }
            Self::Jump { by_px, .. } => ([rest[0] + t * by_px[0], rest[1] + t * by_px[1]], 0.0),
            Self::Twist {
                centre_px,
                radius_px,
                angle_rad,
                ..
            } => {
                let (dx, dy) = (rest[0] - centre_px[0], rest[1] - centre_px[1]);
                let r = dx.hypot(dy);
                let turn = if r <= radius_px {
                    angle_rad
                } else {
                    angle_rad * (radius_px / r).powi(3)
                } * t;
                (turn_about(rest, centre_px, turn), turn)
            }
            Self::Rotate {
                centre_px,
                rad_per_frame,
                ..
            } => {
                let turn = rad_per_frame * t;
                (turn_about(rest, centre_px, turn), turn)
            }
        }
    }
}

fn turn_about(p: [f64; 2], c: [f64; 2], angle: f64) -> [f64; 2] {
    let (s, co) = angle.sin_cos();
    let (dx, dy) = (p[0] - c[0], p[1] - c[1]);
    [c[0] + co * dx - s * dy, c[1] + s * dx + co * dy]
}

/// Gaussian blur with σ = `radius_px` / 2 (a defocus circle's second moment), by three
/// passes of a box filter in each direction (Wells 1986: three boxes approximate a
/// Gaussian within 3 %).
fn defocus(img: &mut [f32], w: usize, h: usize, radius_px: f64) {
    let sigma = radius_px / 2.0;
    // Box half-width whose three passes give variance σ²: 3·((2r+1)² − 1)/12 = σ².
    let r = (((4.0 * sigma * sigma + 1.0).sqrt() - 1.0) / 2.0)
        .round()
        .max(1.0) as usize;
    let mut line = Vec::new();
    for _ in 0..3 {
        for c in 0..3 {
            for y in 0..h {
                line.clear();
                line.extend((0..w).map(|x| img[(y * w + x) * 3 + c]));
                box_line(&line, r, |x, v| img[(y * w + x) * 3 + c] = v);
            }
            for x in 0..w {
                line.clear();
                line.extend((0..h).map(|y| img[(y * w + x) * 3 + c]));
                box_line(&line, r, |y, v| img[(y * w + x) * 3 + c] = v);
            }
        }
    }
}

/// A running box mean of half-width `r` over `src`, the edge value repeated beyond it.
fn box_line(src: &[f32], r: usize, mut put: impl FnMut(usize, f32)) {
    let n = src.len();
    let at = |i: isize| src[i.clamp(0, n as isize - 1) as usize];
    let mut sum: f32 = (-(r as isize)..=r as isize).map(at).sum();
    let k = (2 * r + 1) as f32;
    for i in 0..n {
        put(i, sum / k);
        sum += at(i as isize + r as isize + 1) - at(i as isize - r as isize);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid() -> MarkerLayout {
        MarkerLayout::Grid {
            columns: 18,
            rows: 16,
            spacing_mm: 2.52,
            diameter_mm: 1.4,
        }
    }

    #[test]
    fn a_pan_returns_exactly_to_rest() {
        let m = Motion::PanAndReturn {
            step_px: [3.5, -1.25],
            frames: 4,
        };
        assert_eq!(m.frames(), 9);
        let p = [100.0, 50.0];
        assert_eq!(m.place(p, 4).0, [114.0, 45.0]);
        assert_eq!(m.place(p, 8).0, p);
    }

    #[test]
    fn a_path_sums_its_steps() {
        let m = Motion::from_steps(&[[1.0, 0.0], [2.0, 1.0], [-3.0, -1.0]]);
        assert_eq!(m.frames(), 4);
        let p = [10.0, 20.0];
        assert_eq!(m.place(p, 0).0, p);
        assert_eq!(m.place(p, 2).0, [13.0, 21.0]);
        assert_eq!(m.place(p, 3).0, p);
    }

    #[test]
    fn a_twist_turns_the_contact_rigidly_and_decays_outside() {
        let m = Motion::Twist {
            centre_px: [0.0, 0.0],
            radius_px: 10.0,
            angle_rad: 0.2,
            hold: 1,
        };
        let (inside, turn) = m.place([5.0, 0.0], 1);
        assert!((turn - 0.2).abs() < 1e-12);
        assert!((inside[1] - 5.0 * 0.2f64.sin()).abs() < 1e-12);
        let (_, far) = m.place([20.0, 0.0], 1);
        assert!((far - 0.2 / 8.0).abs() < 1e-12);
        assert_eq!(m.place([5.0, 0.0], 3).0, [5.0, 0.0]);
    }

    #[test]
    fn overscan_prints_markers_beyond_the_view() {
        let s = Scene::new(&grid(), (45.36, 40.32), (640, 480), 3);
        assert_eq!(s.rest_px().len(), 24 * 22);
        assert!(s.rest_px().iter().any(|p| p[0] < 0.0));
        assert!((s.spacing_px() - 2.52 / (40.32 / 480.0)).abs() < 1e-9);
    }

    #[test]
    fn the_look_changes_exposure_and_contrast() {
        let s = Scene::new(&grid(), (45.36, 40.32), (160, 120), 0);
        let still = Motion::Rest { frames: 1 };
        let quiet = Look {
            noise_sigma: 0.0,
            ..Look::default()
        };
        let (a, _) = s.frame(&still, 0, &quiet);
        let (b, _) = s.frame(
            &still,
            0,
            &Look {
                exposure: 0.5,
                ..quiet
            },
        );
        let mean = |v: &[u8]| v.iter().map(|&x| x as f64).sum::<f64>() / v.len() as f64;
        assert!((mean(&b) / mean(&a) - 0.5).abs() < 0.01);
        let (c, _) = s.frame(
            &still,
            0,
            &Look {
                contrast: Some(0.07),
                ..quiet
            },
        );
        let darkest = |v: &[u8]| {
            v.chunks(3)
                .map(|p| p[0] as u32 + p[1] as u32 + p[2] as u32)
                .min()
        };
        assert!(darkest(&c) > darkest(&a).map(|d| d + 200));
        let (d, _) = s.frame(
            &still,
            0,
            &Look {
                defocus_px: 6.0,
                ..quiet
            },
        );
        assert!(darkest(&d) > darkest(&a));
    }
}
