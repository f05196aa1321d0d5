//! A curved indenter pressed with friction and backed off along the same depths: how far its
//! unloading force departs from its loading path's, for the shipped contacts (the box sphere
//! to 2 mm on the 4.2 mm gel, the lifting can across the portable pad to 0.4 mm), on grids
//! sized as the contact model's tables are (16 cells across 2.4 contact radii, 8h beyond),
//! 16 increments each way (even in √δ, as the model presses).
//!
//! The simulated bench gives a retracting curved contact its loading path's state at each
//! depth; this measures what that leaves out. A point caught without slipping keeps its
//! displacement from capture on, so a path that never slips retraces itself exactly on the
//! way back; only slip (on loading or unloading) opens a loop.
//!
//! `cargo run --release -p mechanics --example unloading_friction`

use std::time::Instant;

use mechanics::operator::{Grid, LayerOperator, fast_size};
use mechanics::pressing::curved::{CurvedPath, path_depths};
use mechanics::solve::Tolerance;

/// Height above the lowest point beyond the indenter, mm: never touched.
const AWAY: f64 = 1e3;

struct Case {
    name: &'static str,
    h_mm: f64,
    e_mpa: f64,
    depth_mm: f64,
    /// Contact radius (mm) at the deepest point, for the grid: √(A/π) from the model's
    /// table (`tilt_arms` example).
    a_mm: f64,
    /// Strip length along x for a cylinder (its axis), none for a sphere.
    strip_mm: Option<f64>,
    radius_mm: f64,
}

fn profile(c: &Case, g: Grid) -> Vec<f64> {
    let r = c.radius_mm;
    (0..g.len())
        .map(|i| {
            let (x, y) = g.xy(i);
            let (inside, s2) = match c.strip_mm {
                Some(len) => (x.abs() <= len / 2.0 && y.abs() < r, y * y),
                None => (x * x + y * y < r * r, x * x + y * y),
            };
            if inside {
                r - (r * r - s2).sqrt()
            } else {
                AWAY
            }
        })
        .collect()
}

fn main() {
    let cases = [
        Case {
            name: "box sphere 12.68 mm to 2 mm",
            h_mm: 4.2,
            e_mpa: 0.25,
            depth_mm: 2.0,
            a_mm: 4.49,
            strip_mm: None,
            radius_mm: 6.34,
        },
        Case {
            name: "can across the pad to 0.4 mm",
            h_mm: 2.0,
            e_mpa: 0.15,
            depth_mm: 0.4,
            a_mm: 9.0,
            strip_mm: Some(22.6),
            radius_mm: 28.6,
        },
    ];
    let tol = Tolerance {
        rel: 1e-7,
        max_iter: 4000,
    };
    for c in &cases {
        let dx = 2.4 * c.a_mm / 16.0;
        let span = (2.4 * c.a_mm).max(c.strip_mm.unwrap_or(0.0) * 1.1) + 8.0 * c.h_mm;
        let grid = Grid {
            n: fast_size((span / dx).ceil() as usize),
            dx,
        };
        let nu = 0.49;
        let op = LayerOperator::new(grid, c.h_mm, c.e_mpa / (2.0 * (1.0 + nu)), nu);
        let prof = profile(c, grid);
        let depths = path_depths(c.depth_mm, 16);
        println!("{} ({}² cells, dx {:.3} mm)", c.name, grid.n, dx);
        println!(
            "  mu    depth_mm  loading_N   unloading_N  unloading/loading-1  stick(load/unload)"
        );
        for mu in [0.0, 0.6, 2.0] {
            let t0 = Instant::now();
            let mut path = CurvedPath::new(&op, &prof, mu, tol);
            let mut up = Vec::new();
            for d in &depths {
                let s = path.press_to(*d).expect("a finite depth");
                up.push((s.force_n, s.t.stick_fraction(&s.p)));
            }
            let mut down = Vec::new();
            for d in depths.iter().rev().skip(1) {
                let s = path.press_to(*d).expect("a finite depth");
                down.push((*d, s.force_n, s.t.stick_fraction(&s.p)));
            }
            let ms = t0.elapsed().as_secs_f64() * 1e3;
            let mut worst: f64 = 0.0;
            for (k, (d, f, st)) in down.iter().enumerate() {
                let (fu, su) = up[depths.len() - 2 - k];
                let gap = f / fu - 1.0;
                worst = worst.max(gap.abs());
                if k % 3 == 0 {
                    println!(
                        "  {mu:<4}  {d:>8.4}  {fu:>9.5}  {f:>11.5}  {gap:>+19.2e}  {su:>8.3}/{st:<8.3}"
                    );
                }
            }
            println!(
                "  {mu:<4}  worst |unloading/loading − 1| {worst:.2e}, path there and back {ms:.0} ms"
            );
        }
    }
}
