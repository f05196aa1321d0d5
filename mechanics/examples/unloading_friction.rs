//! A curved indenter pressed with friction and backed off along the normal, through the same
//! depths: how far its unloading state departs from its loading path's at each depth, for
//! the shipped contacts (the box sphere to 2 mm on the 4.2 mm gel, the lifting can across
//! the portable pad to 0.4 mm), on one grid sized as the model's table at the deepest depth
//! is (16 cells across 2.4 contact radii, 4h each side beyond), 16 increments each way
//! (even in √δ, as the model presses), at the model's path tolerance (its sweeps stop at a
//! force change of 3.2e-5).
//!
//! The simulated bench gives a retracting curved contact its loading path's state at each
//! depth; this measures what that leaves out. A point caught without slipping keeps its
//! displacement from capture on, so a path that never slips retraces itself to the
//! solver's tolerance; slip (a thin rim of the contact, on loading or unloading) opens a
//! loop. Printed: the force gap, the largest pressure and tangential-traction differences
//! over their peaks, and the least stick fraction on the way there and back (over contacts
//! of 20 cells or more), and at μ = 0.6 each loading increment's contact cells and stick
//! fraction. μ = 1000 sticks everywhere: its gap is the solver's floor.
//!
//! `cargo run --release -p mechanics --example unloading_friction`

use std::time::Instant;

use mechanics::operator::{Grid, LayerOperator, fast_size};
use mechanics::pressing::PressingSolution;
use mechanics::pressing::curved::{CurvedPath, path_depths};
use mechanics::solve::Tolerance;

/// Height above the lowest point beyond the indenter, mm: never touched.
const AWAY: f64 = 1e3;

struct Case {
    name: &'static str,
    h_mm: f64,
    e_mpa: f64,
    depth_mm: f64,
    /// Contact radius (mm) at the deepest point, for the grid: √(A/π) of the model's table
    /// (the sphere's at 2 mm from the `tilt_arms` example; the can's at 0.4 mm extrapolated
    /// from its 0.1 and 0.3 mm there).
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
            a_mm: 8.8,
            strip_mm: Some(22.6),
            radius_mm: 28.6,
        },
    ];
    // The model's path tolerance (`response::pressed::path_tol`).
    let tol = Tolerance {
        rel: 1e-9,
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
            "  mu     worst force gap  worst Δp/max p  worst Δq/max q  least stick (load/unload)  ms"
        );
        let mut loading_rim = String::new();
        for mu in [0.0, 0.6, 2.0, 1000.0] {
            let t0 = Instant::now();
            let mut path = CurvedPath::new(&op, &prof, mu, tol);
            let up: Vec<_> = depths
                .iter()
                .map(|d| path.press_to(*d).expect("a finite depth"))
                .collect();
            let down: Vec<_> = depths
                .iter()
                .rev()
                .skip(1)
                .map(|d| path.press_to(*d).expect("a finite depth"))
                .collect();
            let ms = t0.elapsed().as_secs_f64() * 1e3;
            let peak = |v: &[f64]| v.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
            let diff = |a: &[f64], b: &[f64]| {
                a.iter()
                    .zip(b)
                    .fold(0.0_f64, |m, (x, y)| m.max((x - y).abs()))
            };
            let (mut gap, mut dp, mut dq): (f64, f64, f64) = (0.0, 0.0, 0.0);
            for (k, back) in down.iter().enumerate() {
                let there = &up[depths.len() - 2 - k];
                gap = gap.max((back.force_n / there.force_n - 1.0).abs());
                dp = dp.max(diff(&back.p, &there.p) / peak(&there.p).max(1e-300));
                let q = peak(&there.t.qx).max(peak(&there.t.qy));
                if q > 0.0 {
                    let d = diff(&back.t.qx, &there.t.qx).max(diff(&back.t.qy, &there.t.qy));
                    dq = dq.max(d / q);
                }
            }
            // Over the states whose contact spans at least 20 cells (at first touch a
            // contact of a cell or two has no stuck interior to speak of).
            let least = |v: &[PressingSolution]| {
                v.iter()
                    .filter(|s| s.p.iter().filter(|p| **p > 0.0).count() >= 20)
                    .map(|s| s.t.stick_fraction(&s.p))
                    .fold(1.0_f64, f64::min)
            };
            if mu == 0.6 {
                let each: Vec<String> = up
                    .iter()
                    .map(|s| {
                        format!(
                            "{}:{:.2}",
                            s.p.iter().filter(|p| **p > 0.0).count(),
                            s.t.stick_fraction(&s.p)
                        )
                    })
                    .collect();
                loading_rim = format!(
                    "  μ 0.6 on the way there, contact cells:stick fraction per increment: {}",
                    each.join(" ")
                );
            }
            let stick = if mu > 0.0 {
                format!("{:.3}/{:.3}", least(&up), least(&down))
            } else {
                "–".to_string()
            };
            println!("  {mu:<6} {gap:>15.2e}  {dp:>14.2e}  {dq:>14.2e}  {stick:>25}  {ms:.0}");
        }
        println!("{loading_rim}");
    }
}
