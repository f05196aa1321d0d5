//! Pressing a flat punch with friction (the coupled normal–tangential problem) on the
//! shipped punches: the force against the frictionless one, by friction coefficient and
//! grid, with the cost of each solve.
//!
//! `cargo run --release -p mechanics --example pressing_friction`

use std::time::Instant;

use mechanics::operator::{Compliance, Grid, LayerOperator};
use mechanics::pressing::{Pressing, pressing};
use mechanics::solve::{Tolerance, normal_known_area};

/// The shipped flat punches: name, radius (mm), layer thickness (mm), E∞ (MPa).
const PUNCHES: [(&str, f64, f64, f64); 3] = [
    ("box 9.5 mm (h 4.2)", 4.75, 4.2, 0.25),
    ("box 12.68 mm (h 4.2)", 6.34, 4.2, 0.25),
    ("portable 12.5 (h 2.0)", 6.25, 2.0, 0.15),
];

/// The layer operator (ν = 0.49) with `cells` across the punch, and the punch's face.
fn punch(a: f64, h: f64, e: f64, cells: usize) -> (LayerOperator, Vec<bool>) {
    let nu = 0.49;
    let dx = 2.0 * a / cells as f64;
    let n = LayerOperator::period_for(2.0 * a, h, dx);
    let op = LayerOperator::new(Grid { n, dx }, h, e / (2.0 * (1.0 + nu)), nu);
    let g = op.grid();
    let mask = (0..g.len())
        .map(|i| {
            let (x, y) = g.xy(i);
            x * x + y * y <= a * a
        })
        .collect();
    (op, mask)
}

fn main() {
    tilt_arms();
    let tol = Tolerance {
        rel: 1e-8,
        max_iter: 4000,
    };
    println!("punch                 cells  mu    F/F_free  stick   sweeps  ms");
    for (name, a, h, e) in PUNCHES {
        for cells in [16usize, 32, 48] {
            let (op, mask) = punch(a, h, e, cells);
            let g = op.grid();
            let uz = vec![1.0; g.len()];
            let zero = vec![0.0; g.len()];
            let free = normal_known_area(&op, &mask, &uz, tol).force_n;
            for mu in [0.3, 0.6, 1e3] {
                let t0 = Instant::now();
                let s = pressing(&Pressing {
                    op: &op,
                    mask: &mask,
                    uz: &uz,
                    target: (&zero, &zero),
                    mu,
                    tol,
                });
                let ms = t0.elapsed().as_secs_f64() * 1e3;
                println!(
                    "{name:<22}{cells:>5}  {mu:<5} {:>8.4}  {:>5.3}  {:>6}  {ms:>6.0}",
                    s.force_n / free,
                    s.t.stick_fraction(&s.p),
                    s.sweeps
                );
            }
        }
    }
}

/// The tilting moment a stuck punch's shear causes through the layer's coupling: the punch
/// held level, shifted 1 µm along x; M = ∫ x p dA against Fx.
fn tilt_arms() {
    let tol = Tolerance {
        rel: 1e-9,
        max_iter: 4000,
    };
    println!("punch                 cells  Fx_per_um_N  arm_mm (∫x p / Fx)");
    for (name, a, h, e) in PUNCHES {
        for cells in [16usize, 32] {
            let (op, mask) = punch(a, h, e, cells);
            let g = op.grid();
            let zero = vec![0.0; g.len()];
            let shift = vec![1e-3; g.len()];
            // Pressed 1 mm (so the face stays compressed), shifted 1 µm: by symmetry the
            // pressing alone has no moment and no net shear.
            let s = pressing(&Pressing {
                op: &op,
                mask: &mask,
                uz: &vec![1.0; g.len()],
                target: (&shift, &zero),
                mu: 1e9,
                tol,
            });
            let m: f64 = (0..g.len()).map(|i| g.xy(i).0 * s.p[i]).sum::<f64>() * g.area();
            println!(
                "{name:<22}{cells:>5}  {:>11.5}  {:>8.4}",
                s.t.fx_n,
                m / s.t.fx_n
            );
        }
    }
}
