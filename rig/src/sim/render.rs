//! Marker frames of the simulated elastomer.
//!
//! The spine's renderer draws what tracking needs: the sensor's markers, anti-aliased, at
//! positions displaced by the closed-form surface fields of [`mechanics::field`] (radial
//! outward flow under normal load, Mindlin's uniform-then-"8" field under shear, spin under
//! torsion, superposed as the thesis found), on a smoothly lit background with sensor noise,
//! and returns the exact marker centres as ground truth. The GelSight shading of the contact
//! imprint and the layer-solver fields come with the physics issue.

use mechanics::field;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

use super::plant::{MarkerLayout, PlantSpec, SurfaceState};

/// Reference (undeformed) marker centres in mm relative to the view centre, x right, y down.
///
/// A grid is centred on the view. A random layout is a jittered lattice drawn once from a
/// fixed seed: the markers are printed on the elastomer, so every frame and every run of the
/// same sensor sees the same pattern.
pub fn marker_reference_positions_mm(
    layout: &MarkerLayout,
    view_w_mm: f64,
    view_h_mm: f64,
) -> Vec<(f64, f64)> {
    match *layout {
        MarkerLayout::Grid {
            columns,
            rows,
            spacing_mm,
            ..
        } => {
            let mut out = Vec::with_capacity((columns * rows) as usize);
            for j in 0..rows {
                for i in 0..columns {
                    out.push((
                        (i as f64 - (columns as f64 - 1.0) / 2.0) * spacing_mm,
                        (j as f64 - (rows as f64 - 1.0) / 2.0) * spacing_mm,
                    ));
                }
            }
            out
        }
        MarkerLayout::Random { spacing_mm, .. } => {
            let mut rng = StdRng::seed_from_u64(0x6E15_1647);
            let nx = (view_w_mm / spacing_mm).ceil() as i64 + 1;
            let ny = (view_h_mm / spacing_mm).ceil() as i64 + 1;
            let mut out = Vec::new();
            for j in -ny / 2..=ny / 2 {
                for i in -nx / 2..=nx / 2 {
                    let jx = (rng.random::<f64>() - 0.5) * 0.5 * spacing_mm;
                    let jy = (rng.random::<f64>() - 0.5) * 0.5 * spacing_mm;
                    let (x, y) = (i as f64 * spacing_mm + jx, j as f64 * spacing_mm + jy);
                    if x.abs() <= view_w_mm / 2.0 && y.abs() <= view_h_mm / 2.0 {
                        out.push((x, y));
                    }
                }
            }
            out
        }
    }
}

pub(crate) struct Renderer {
    width: u32,
    height: u32,
    mm_per_px: f64,
    background: Vec<u8>,
    markers_mm: Vec<(f64, f64)>,
    layout: MarkerLayout,
    thickness_mm: f64,
    poisson: f64,
}

impl Renderer {
    pub(crate) fn new(spec: &PlantSpec, width: u32, height: u32) -> Self {
        let mm_per_px =
            (spec.view_width_mm / width as f64).max(spec.view_height_mm / height as f64);
        let mut background = Vec::with_capacity((width * height * 3) as usize);
        for y in 0..height {
            for x in 0..width {
                let u = x as f64 / width as f64;
                let v = y as f64 / height as f64;
                background.push((150.0 + 45.0 * u) as u8);
                background.push((140.0 + 50.0 * v) as u8);
                background.push((165.0 - 35.0 * u) as u8);
            }
        }
        Self {
            width,
            height,
            mm_per_px,
            background,
            markers_mm: marker_reference_positions_mm(
                &spec.markers,
                spec.view_width_mm,
                spec.view_height_mm,
            ),
            layout: spec.markers.clone(),
            thickness_mm: spec.contact.layer.thickness_mm,
            poisson: spec.contact.material.poisson_ratio,
        }
    }

    /// Surface displacement (mm) of the marker at (x, y): sum of the three load fields.
    fn displacement_mm(&self, s: &SurfaceState, x: f64, y: f64) -> (f64, f64) {
        if s.depth_mm <= 0.0 || s.radius_mm <= 0.0 {
            return (0.0, 0.0);
        }
        let (rx, ry) = (x - s.centre_x_mm, y);
        let r = rx.hypot(ry);
        let (ex, ey) = if r > 1e-12 {
            (rx / r, ry / r)
        } else {
            (0.0, 0.0)
        };
        let ur = field::normal_radial_mm(s.radius_mm, s.depth_mm, self.thickness_mm, r);
        let (sx, sy) = field::mindlin_shear_mm(1.0, 1.0, self.poisson, s.radius_mm, rx, ry);
        let (s0, _) = field::mindlin_shear_mm(1.0, 1.0, self.poisson, s.radius_mm, 0.0, 0.0);
        let ut = field::torsion_azimuthal_mm(s.stick_twist_rad, s.radius_mm, r);
        (
            ur * ex + s.stick_x_mm * sx / s0 - ut * ey,
            ur * ey + s.stick_x_mm * sy / s0 + ut * ex,
        )
    }

    /// Renders one frame; returns RGB pixels and the exact marker centres in pixels.
    pub(crate) fn render(&self, s: &SurfaceState, seq: u64) -> (Vec<u8>, Vec<[f64; 2]>) {
        let mut img = self.background.clone();
        let (w, h) = (self.width as f64, self.height as f64);
        let mut truth = Vec::with_capacity(self.markers_mm.len());
        for &(x, y) in &self.markers_mm {
            let (ux, uy) = self.displacement_mm(s, x, y);
            let px = w / 2.0 + (x + ux) / self.mm_per_px;
            let py = h / 2.0 + (y + uy) / self.mm_per_px;
            truth.push([px, py]);
            match self.layout {
                MarkerLayout::Grid { diameter_mm, .. } => {
                    self.dot(&mut img, px, py, diameter_mm / 2.0 / self.mm_per_px)
                }
                MarkerLayout::Random { size_mm, .. } => {
                    self.triangle(&mut img, px, py, size_mm / self.mm_per_px)
                }
            }
        }
        // Sensor noise: σ ≈ 1.5 grey levels, a fresh pattern per frame.
        let mut rng = StdRng::seed_from_u64(seq.wrapping_mul(0x2545_F491_4F6C_DD1D));
        for p in img.chunks_exact_mut(3) {
            let n = (rng.random::<f64>() + rng.random::<f64>() - 1.0) * 3.7;
            for c in p {
                *c = (*c as f64 + n).round().clamp(0.0, 255.0) as u8;
            }
        }
        (img, truth)
    }

    fn blend(&self, img: &mut [u8], x: i64, y: i64, coverage: f64) {
        if coverage <= 0.0 || x < 0 || y < 0 || x >= self.width as i64 || y >= self.height as i64 {
            return;
        }
        const INK: [f64; 3] = [28.0, 26.0, 34.0];
        let i = ((y as u32 * self.width + x as u32) * 3) as usize;
        for (c, ink) in img[i..i + 3].iter_mut().zip(INK) {
            *c = (*c as f64 * (1.0 - coverage) + ink * coverage).round() as u8;
        }
    }

    /// An anti-aliased disc: coverage from the distance of each pixel centre to the edge.
    fn dot(&self, img: &mut [u8], cx: f64, cy: f64, r: f64) {
        let (x0, x1) = ((cx - r - 1.0).floor() as i64, (cx + r + 1.0).ceil() as i64);
        let (y0, y1) = ((cy - r - 1.0).floor() as i64, (cy + r + 1.0).ceil() as i64);
        for y in y0..=y1 {
            for x in x0..=x1 {
                let d = (x as f64 + 0.5 - cx).hypot(y as f64 + 0.5 - cy);
                self.blend(img, x, y, (r + 0.5 - d).clamp(0.0, 1.0));
            }
        }
    }

    /// An equilateral triangle of side `side`, centroid at (cx, cy), by 4×4 supersampling.
    fn triangle(&self, img: &mut [u8], cx: f64, cy: f64, side: f64) {
        let rc = side / 3f64.sqrt();
        let verts: Vec<(f64, f64)> = (0..3)
            .map(|k| {
                let a = -std::f64::consts::FRAC_PI_2 + k as f64 * 2.0 * std::f64::consts::PI / 3.0;
                (cx + rc * a.cos(), cy + rc * a.sin())
            })
            .collect();
        let inside = |px: f64, py: f64| {
            (0..3).all(|k| {
                let (ax, ay) = verts[k];
                let (bx, by) = verts[(k + 1) % 3];
                (bx - ax) * (py - ay) - (by - ay) * (px - ax) >= 0.0
            })
        };
        let (x0, x1) = (
            (cx - rc - 1.0).floor() as i64,
            (cx + rc + 1.0).ceil() as i64,
        );
        let (y0, y1) = (
            (cy - rc - 1.0).floor() as i64,
            (cy + rc + 1.0).ceil() as i64,
        );
        for y in y0..=y1 {
            for x in x0..=x1 {
                let mut hits = 0;
                for sy in 0..4 {
                    for sx in 0..4 {
                        if inside(
                            x as f64 + (sx as f64 + 0.5) / 4.0,
                            y as f64 + (sy as f64 + 0.5) / 4.0,
                        ) {
                            hits += 1;
                        }
                    }
                }
                self.blend(img, x, y, hits as f64 / 16.0);
            }
        }
    }
}
