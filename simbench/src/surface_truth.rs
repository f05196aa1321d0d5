//! The simulator's tractions under a rendered frame, as label maps on the frame's pixels:
//! what a dataset run records beside each frame (`record: {traction_maps: true}`).
//!
//! The contact model hands the tractions that make the rendered field
//! ([`ContactModel::field_and_tractions`](mechanics::response::ContactModel)) as cell means on
//! its field grid, centred on the contact. Each field cell is split into sub-cells no larger
//! than half a map cell, carried into the view as the renderer carries the surface (placed at
//! the contact's centre, turned by its slip), and its load added to the map cell it lands in:
//! the maps conserve the load (Σ pressure × cell area is the grid's normal force, within the
//! view), whatever the two grids' sizes. Tangential tractions turn with the contact, as the
//! marker displacements do in [`Renderer::render`].

use mechanics::response::Tractions;
use rig::device::SurfaceTruth;

use crate::render::{Renderer, SurfaceView};

/// The label maps of one frame: the tractions of `t` (the field of `view`) on cells of
/// `px_per_cell` × `px_per_cell` pixels of `renderer`'s frame.
pub fn surface_truth(
    renderer: &Renderer,
    view: &SurfaceView,
    t: &Tractions,
    px_per_cell: u32,
) -> SurfaceTruth {
    let k = px_per_cell.max(1);
    let (w_px, h_px) = renderer.size();
    let (w, h) = ((w_px / k) as usize, (h_px / k) as usize);
    let mm_per_px = renderer.mm_per_px();
    let cell_mm = f64::from(k) * mm_per_px;
    let g = t.grid;
    let (c, s) = (view.rotation_rad.cos(), view.rotation_rad.sin());
    // Pattern coordinates (mm, on the field grid) → view → map cell.
    let to_cell = |x: f64, y: f64| -> Option<usize> {
        let vx = view.centre_mm.0 + c * x - s * y;
        let vy = view.centre_mm.1 + s * x + c * y;
        let i = ((vx / mm_per_px + f64::from(w_px) / 2.0) / f64::from(k)).floor();
        let j = ((vy / mm_per_px + f64::from(h_px) / 2.0) / f64::from(k)).floor();
        (i >= 0.0 && j >= 0.0 && (i as usize) < w && (j as usize) < h)
            .then(|| j as usize * w + i as usize)
    };
    let sub = ((2.0 * g.dx / cell_mm).ceil() as usize).max(1);
    let sub_area = g.area() / (sub * sub) as f64;
    let (mut p, mut qx, mut qy) = (vec![0.0f64; w * h], vec![0.0f64; w * h], vec![0.0; w * h]);
    for idx in 0..g.len() {
        let (tp, tx, ty) = (t.pressure_mpa[idx], t.shear_x_mpa[idx], t.shear_y_mpa[idx]);
        if tp == 0.0 && tx == 0.0 && ty == 0.0 {
            continue;
        }
        // The traction turned into the view's axes.
        let (vx, vy) = (c * tx - s * ty, s * tx + c * ty);
        let (x0, y0) = g.xy(idx);
        for b in 0..sub {
            for a in 0..sub {
                let x = x0 + ((a as f64 + 0.5) / sub as f64 - 0.5) * g.dx;
                let y = y0 + ((b as f64 + 0.5) / sub as f64 - 0.5) * g.dx;
                if let Some(m) = to_cell(x, y) {
                    p[m] += tp * sub_area;
                    qx[m] += vx * sub_area;
                    qy[m] += vy * sub_area;
                }
            }
        }
    }
    // Load per cell (N) → mean traction (kPa).
    let kpa = 1000.0 / (cell_mm * cell_mm);
    let to_kpa = |v: Vec<f64>| -> Vec<f32> { v.into_iter().map(|x| (x * kpa) as f32).collect() };
    let contact = contact_mask(view, t, w, h, cell_mm, (w_px, h_px), mm_per_px);
    SurfaceTruth {
        width: w as u32,
        height: h as u32,
        px_per_cell: k,
        cell_mm,
        pressure_kpa: to_kpa(p),
        shear_x_kpa: to_kpa(qx),
        shear_y_kpa: to_kpa(qy),
        contact,
        depth_mm: 0.0,
        shear_n: 0.0,
        torque_nmm: 0.0,
        centre_mm: view.centre_mm,
        rotation_rad: view.rotation_rad,
    }
}

/// Pressures below this fraction of the frame's peak are not contact: the field's pressure,
/// solved on the camera's grid and blended between two depth tables, leaves a fringe of a
/// few cells below 0.1 % of the peak around a sphere's contact (13.0 mm² where the
/// simulator's contact is 10.4 mm²; 1 %: 10.2 mm², docs/reference/dataset.md).
const CONTACT_FRACTION: f64 = 0.01;

/// 1 where the map cell's centre falls on a field cell whose pressure is above
/// [`CONTACT_FRACTION`] of the peak.
fn contact_mask(
    view: &SurfaceView,
    t: &Tractions,
    w: usize,
    h: usize,
    cell_mm: f64,
    (w_px, h_px): (u32, u32),
    mm_per_px: f64,
) -> Vec<u8> {
    let g = t.grid;
    let (c, s) = (view.rotation_rad.cos(), view.rotation_rad.sin());
    let half = (g.n / 2) as f64;
    let peak = t.pressure_mpa.iter().copied().fold(0.0f64, f64::max);
    let floor = CONTACT_FRACTION * peak;
    let mut out = vec![0u8; w * h];
    if peak <= 0.0 {
        return out;
    }
    for j in 0..h {
        let vy = (j as f64 + 0.5) * cell_mm - f64::from(h_px) / 2.0 * mm_per_px;
        for i in 0..w {
            let vx = (i as f64 + 0.5) * cell_mm - f64::from(w_px) / 2.0 * mm_per_px;
            let (dx, dy) = (vx - view.centre_mm.0, vy - view.centre_mm.1);
            let (x, y) = (c * dx + s * dy, -s * dx + c * dy);
            let (fi, fj) = ((x / g.dx + half).floor(), (y / g.dx + half).floor());
            if fi < 0.0 || fj < 0.0 || fi >= g.n as f64 || fj >= g.n as f64 {
                continue;
            }
            let idx = fj as usize * g.n + fi as usize;
            out[j * w + i] = u8::from(t.pressure_mpa[idx] > floor);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use mechanics::operator::Grid;
    use mechanics::response::Field;

    fn view(centre_mm: (f64, f64), rotation_rad: f64, grid: Grid) -> SurfaceView {
        let z = vec![0.0; grid.len()];
        SurfaceView {
            field: Field {
                grid,
                ux: z.clone(),
                uy: z.clone(),
                uz: z,
            },
            centre_mm,
            rotation_rad,
        }
    }

    /// A disc of uniform pressure and a uniform shear along the pattern's x: the maps carry
    /// its load whole (inside the view), the mask covers its area, the shear turns with the
    /// contact, for field cells finer and coarser than a map cell.
    #[test]
    fn maps_conserve_the_load_and_turn_with_the_contact() {
        let r = Renderer::for_view(
            &crate::MarkerLayout::Grid {
                columns: 2,
                rows: 2,
                spacing_mm: 4.0,
                diameter_mm: 1.0,
            },
            16.0,
            12.0,
            320,
            240,
        );
        for dx in [0.02, 0.05, 0.4] {
            let n = ((12.0 / dx) as usize).next_multiple_of(2);
            let grid = Grid { n, dx };
            let radius = 2.5;
            let mut t = Tractions {
                grid,
                pressure_mpa: vec![0.0; grid.len()],
                shear_x_mpa: vec![0.0; grid.len()],
                shear_y_mpa: vec![0.0; grid.len()],
            };
            let (mut fz, mut fx, mut area) = (0.0, 0.0, 0.0);
            for i in 0..grid.len() {
                let (x, y) = grid.xy(i);
                if x * x + y * y < radius * radius {
                    t.pressure_mpa[i] = 0.1;
                    t.shear_x_mpa[i] = 0.03;
                    fz += 0.1 * grid.area();
                    fx += 0.03 * grid.area();
                    area += grid.area();
                }
            }
            let turn = 0.5f64;
            let m = surface_truth(&r, &view((1.5, -1.0), turn, grid), &t, 4);
            assert_eq!((m.width, m.height), (80, 60));
            let cell_mm2 = (4.0 * r.mm_per_px()).powi(2);
            let sum = |v: &[f32]| v.iter().map(|&x| f64::from(x)).sum::<f64>() * cell_mm2 / 1000.0;
            let (p, qx, qy) = (
                sum(&m.pressure_kpa),
                sum(&m.shear_x_kpa),
                sum(&m.shear_y_kpa),
            );
            assert!(
                (p - fz).abs() < 1e-9 * fz.max(1.0) + 1e-6,
                "dx {dx}: {p} vs {fz} N"
            );
            assert!((qx - fx * turn.cos()).abs() < 1e-6, "dx {dx}: qx {qx}");
            assert!((qy - fx * turn.sin()).abs() < 1e-6, "dx {dx}: qy {qy}");
            let mask_area = m.contact.iter().map(|&v| f64::from(v)).sum::<f64>() * cell_mm2;
            // The disc's edge through map cells of 0.2 mm: within 5 % of its area.
            assert!(
                (mask_area / area - 1.0).abs() < 0.05,
                "dx {dx}: mask {mask_area} vs {area}"
            );
            // The mask's centroid is where the contact is.
            let (mut cx, mut cy, mut k) = (0.0, 0.0, 0.0);
            for (idx, &v) in m.contact.iter().enumerate() {
                if v == 1 {
                    cx += ((idx % 80) as f64 + 0.5) * 4.0 * r.mm_per_px() - 8.0;
                    cy += ((idx / 80) as f64 + 0.5) * 4.0 * r.mm_per_px() - 6.0;
                    k += 1.0;
                }
            }
            assert!(
                (cx / k - 1.5).abs() < 0.1 && (cy / k + 1.0).abs() < 0.1,
                "dx {dx}: centroid"
            );
        }
    }
}
