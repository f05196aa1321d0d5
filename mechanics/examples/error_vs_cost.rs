//! Error against cost of the layer field solver (issue 3, "error against run time").
//!
//! Run: `cargo run --release -p mechanics --example error_vs_cost`
//!
//! 1. Flat punch on the bonded layer (a/h = 1.131, ν = ½, frictionless): force against the
//!    exact semi-analytic κ and the radial field u_r/d against a converged 256-cell grid,
//!    for 16–128 cells across the contact, with the time of each solve.
//! 2. The surface field of the box sensor's flat punch (20 % depth, with friction) on the
//!    256×256 field grid against a 512×512 reference, and its evaluation time. (The
//!    reference was 1024² until a flat punch's field pressure came to be solved on a grid
//!    twice as fine as the field's: 2048² is beyond the model's 1024-cell cap, so the
//!    reference is the finest field grid the model builds.)
//! 3. The sphere on the layer (spec O18) against cells across the contact.

use std::time::Instant;

use mechanics::operator::{Compliance, Grid, LayerOperator, fast_size};
use mechanics::solve::{Tolerance, normal_known_area, normal_unknown_area};

fn median_ms(mut f: impl FnMut(), reps: usize) -> f64 {
    let mut t: Vec<f64> = (0..reps)
        .map(|_| {
            let s = Instant::now();
            f();
            s.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    t.sort_by(|a, b| a.total_cmp(b));
    t[reps / 2]
}

fn flat_punch(cells: usize) -> (f64, f64, f64, f64, Grid) {
    let (h, a, mu, nu) = (1.0, 1.131, 1.0, 0.5);
    let dx = 2.0 * a / cells as f64;
    let g = Grid {
        n: LayerOperator::period_for(2.0 * a, h, dx),
        dx,
    };
    let t = Instant::now();
    let op = LayerOperator::new(g, h, mu, nu);
    let mask: Vec<bool> = (0..g.len())
        .map(|i| {
            let (x, y) = g.xy(i);
            x * x + y * y <= a * a
        })
        .collect();
    let s = normal_known_area(
        &op,
        &mask,
        &vec![1.0; g.len()],
        Tolerance {
            rel: 1e-9,
            max_iter: 5000,
        },
    );
    let zero = vec![0.0; g.len()];
    let [ux, _, _] = op.full(&zero, &zero, &s.p);
    let ms = t.elapsed().as_secs_f64() * 1e3;
    let kappa = s.force_n / (2.0 * 4.0 * a);
    (
        kappa,
        g.sample(&ux, 1.5 * a, 0.0),
        g.sample(&ux, 0.5 * a, 0.0),
        ms,
        g,
    )
}

fn main() {
    punch_table();
    field_table();
    model_build_table();
    sphere_table();
}

/// 1. The flat punch on the layer against the exact semi-analytic κ and a converged field.
fn punch_table() {
    let exact = mechanics::punch::layer_kappa(1.131, 0.5, 64);
    let (_, ur15_ref, ur05_ref, _, _) = flat_punch(256);
    println!("## Flat punch on the layer, a/h = 1.131, ν = ½ (exact κ = {exact:.5})\n");
    println!(
        "| cells across 2a | grid | κ error | u_r(1.5a)/d error vs 256 cells | u_r(0.5a)/d error | solve + field, ms |"
    );
    println!("|---|---|---|---|---|---|");
    for cells in [16, 32, 64, 128] {
        let (k, ur15, ur05, ms, g) = flat_punch(cells);
        println!(
            "| {cells} | {}² | {:+.2} % | {:+.4} | {:+.4} | {ms:.0} |",
            g.n,
            (k / exact - 1.0) * 100.0,
            ur15 - ur15_ref,
            ur05 - ur05_ref
        );
    }
}

/// 2. The field the camera sees: box sensor, 9.5 mm punch, 20 % depth, friction.
fn field_table() {
    println!(
        "\n## Surface field of the box sensor (9.5 mm punch, 0.84 mm), field grid vs 512² reference (the finest the model builds)\n"
    );
    let field = |n: usize| {
        use mechanics::Indenter;
        use mechanics::contact::Contact;
        use mechanics::response::{ContactModel, ModelSpec, Quality, State};
        let mut m = ContactModel::build(ModelSpec {
            contact: Contact::new(
                mechanics::geometry::presets::BOX_LAYER,
                mechanics::geometry::presets::box_material(),
                Indenter::FlatCircle { diameter_mm: 9.5 },
            )
            .expect("valid"),
            max_depth_mm: 0.84,
            shear: false,
            twist: false,
            field_view_mm: Some((45.36, 40.32)),
            pressing_friction: false,
            quality: Quality {
                field_cells: n,
                ..Quality::default()
            },
        })
        .expect("builds");
        let state = State {
            depth_mm: 0.84,
            shear_n: 0.0,
            torque_nmm: 0.0,
        };
        let f = m.field(state).expect("field");
        let ms = median_ms(
            || {
                let _ = m.field(state);
            },
            7,
        );
        (f, ms)
    };
    let (reference, _) = field(512);
    let probe: Vec<(f64, f64)> = (0..18 * 16)
        .map(|k| {
            (
                ((k % 18) as f64 - 8.5) * 2.52,
                ((k / 18) as f64 - 7.5) * 2.52,
            )
        })
        .collect();
    let ref_vals: Vec<f64> = probe
        .iter()
        .map(|(x, y)| {
            reference
                .grid
                .sample(&reference.ux, *x, *y)
                .hypot(reference.grid.sample(&reference.uy, *x, *y))
        })
        .collect();
    let peak = ref_vals.iter().cloned().fold(0.0, f64::max);
    let rms_ref = (ref_vals.iter().map(|v| v * v).sum::<f64>() / ref_vals.len() as f64).sqrt();
    println!(
        "| field grid | RMS error at the 288 markers, % of RMS | worst marker, % of the peak (where) | evaluation, ms (median of 7) |"
    );
    println!("|---|---|---|---|");
    for n in [128, 192, 256, 384] {
        let (f, ms) = field(n);
        let errs: Vec<(f64, f64, f64)> = probe
            .iter()
            .zip(&ref_vals)
            .map(|((x, y), r)| {
                (
                    (f.grid
                        .sample(&f.ux, *x, *y)
                        .hypot(f.grid.sample(&f.uy, *x, *y))
                        - r)
                        .abs(),
                    *x,
                    *y,
                )
            })
            .collect();
        let rms = (errs.iter().map(|e| e.0 * e.0).sum::<f64>() / errs.len() as f64).sqrt();
        let worst = errs
            .iter()
            .cloned()
            .fold((0.0, 0.0, 0.0), |b, e| if e.0 > b.0 { e } else { b });
        println!(
            "| {n}² | {:.2} % | {:.2} % (r = {:.1} mm) | {ms:.1} |",
            rms / rms_ref * 100.0,
            worst.0 / peak * 100.0,
            worst.1.hypot(worst.2)
        );
    }
}

/// 3. What a dry run pays up front: building the contact model of each thesis case.
fn model_build_table() {
    println!("\n## Contact model build per shipped protocol (what each dry run pays once)\n");
    println!(
        "| case | build, ms | tables at the run's depth, ms | first field, ms | force at max depth, N |"
    );
    println!("|---|---|---|---|---|");
    {
        use mechanics::contact::Contact;
        use mechanics::response::{ContactModel, ModelSpec, Quality, State};
        use mechanics::{Indenter, Layer, Material};
        let c = |ind: Indenter, w: f64, l: f64, h: f64, e: f64| {
            Contact::new(
                Layer {
                    width_mm: w,
                    length_mm: l,
                    thickness_mm: h,
                },
                Material {
                    youngs_modulus_mpa: e,
                    poisson_ratio: 0.49,
                    prony: vec![],
                    friction: 0.6,
                },
                ind,
            )
            .expect("valid")
        };
        let box_view = Some((45.36, 40.32));
        let portable_view = Some((20.0, 15.0));
        let cases = [
            (
                "box-normal-flat",
                c(
                    Indenter::FlatCircle { diameter_mm: 9.5 },
                    125.0,
                    70.0,
                    4.2,
                    0.25,
                ),
                0.84,
                false,
                false,
                box_view,
            ),
            (
                "box-shear-flat",
                c(
                    Indenter::FlatCircle { diameter_mm: 12.68 },
                    125.0,
                    70.0,
                    4.2,
                    0.25,
                ),
                0.21,
                true,
                false,
                box_view,
            ),
            (
                "box-normal-sphere",
                c(
                    Indenter::Sphere { diameter_mm: 12.68 },
                    125.0,
                    70.0,
                    4.2,
                    0.25,
                ),
                2.0,
                false,
                false,
                box_view,
            ),
            (
                "box-shear-sphere",
                c(
                    Indenter::Sphere { diameter_mm: 12.68 },
                    125.0,
                    70.0,
                    4.2,
                    0.25,
                ),
                1.0,
                true,
                false,
                box_view,
            ),
            (
                "portable-rotation",
                c(
                    Indenter::FlatCircle { diameter_mm: 12.5 },
                    22.6,
                    23.4,
                    2.0,
                    0.15,
                ),
                0.03,
                false,
                true,
                portable_view,
            ),
            (
                "lifting-can",
                c(
                    Indenter::Cylinder {
                        diameter_mm: 57.2,
                        length_mm: 100.0,
                    },
                    22.6,
                    23.4,
                    2.0,
                    0.15,
                ),
                1.0,
                false,
                false,
                None,
            ),
        ];
        for (name, contact, depth, shear, twist, view) in cases {
            let t = Instant::now();
            let mut m = ContactModel::build(ModelSpec {
                contact,
                max_depth_mm: depth,
                shear,
                twist,
                field_view_mm: view,
                pressing_friction: false,
                quality: Quality::default(),
            })
            .expect("builds");
            let build = t.elapsed().as_secs_f64() * 1e3;
            let t = Instant::now();
            let _ = m.shear_curve(depth);
            let _ = m.twist_curve(depth);
            let tables = t.elapsed().as_secs_f64() * 1e3;
            let t = Instant::now();
            let _ = m.field(State {
                depth_mm: depth,
                shear_n: 0.0,
                torque_nmm: 0.0,
            });
            let first = t.elapsed().as_secs_f64() * 1e3;
            println!(
                "| {name} | {build:.0} | {tables:.0} | {first:.0} | {:.2} |",
                m.normal_force_n(depth)
            );
        }
    }
}

/// 4. The sphere on the layer (spec O18) against cells across the contact.
fn sphere_table() {
    println!(
        "\n## Sphere on the layer (R/h = 1.51, ν = ½, paraboloid), P/P_Hertz at d/h = 0.2 (spec: 2.360)\n"
    );
    println!("| cells across 1.2·2a_H | grid | P/P_Hertz | solve, ms |");
    println!("|---|---|---|---|");
    let (r, h, d): (f64, f64, f64) = (6.34, 4.2, 0.84);
    let a_h = (r * d).sqrt();
    for cells in [8.0, 12.0, 16.0, 27.0, 54.0] {
        let dx = 2.4 * a_h / cells;
        let g = Grid {
            n: fast_size(((2.4 * a_h + 8.0 * h) / dx).ceil() as usize),
            dx,
        };
        let t = Instant::now();
        let op = LayerOperator::new(g, h, 1.0, 0.5);
        let prof: Vec<f64> = (0..g.len())
            .map(|i| {
                let (x, y) = g.xy(i);
                (x * x + y * y) / (2.0 * r)
            })
            .collect();
        let s = normal_unknown_area(
            &op,
            &prof,
            d,
            None,
            Tolerance {
                rel: 1e-8,
                max_iter: 3000,
            },
        );
        let ms = t.elapsed().as_secs_f64() * 1e3;
        let ph = 4.0 / 3.0 * 4.0 * r.sqrt() * d.powf(1.5);
        println!("| {cells} | {}² | {:.4} | {ms:.0} |", g.n, s.force_n / ph);
    }
}
