//! Curved indenters pressed with friction (`mechanics::pressing::curved`): the shipped sphere
//! on the box gel and the can across the portable pad, followed along their loading path.
//! The force against the frictionless one at each depth, by friction coefficient, path
//! increments and grid, with the cost of the whole path.
//!
//! `cargo run --release -p mechanics --example curved_pressing`           # the path
//! `cargo run --release -p mechanics --example curved_pressing -- model`  # a dry run's cost

use std::time::Instant;

use mechanics::Indenter;
use mechanics::contact::Contact;
use mechanics::geometry::presets;
use mechanics::operator::{Compliance, Grid, LayerOperator};
use mechanics::pressing::curved::{CurvedPath, path_depths};
use mechanics::response::{ContactModel, ModelSpec, Quality, State};
use mechanics::solve::Tolerance;

/// A shipped curved contact: name, indenter radius (mm), strip length along x (mm; 0 for a
/// sphere), layer thickness (mm), E∞ (MPa), the deepest depth (mm). The force is reported at
/// a sixteenth, a quarter and all of the deepest depth (the contact a quarter, half and all
/// of its width).
struct Case {
    name: &'static str,
    radius_mm: f64,
    length_mm: f64,
    h_mm: f64,
    e_mpa: f64,
    max_depth_mm: f64,
}

const CASES: [Case; 2] = [
    Case {
        name: "box sphere 12.68 mm (h 4.2)",
        radius_mm: 6.34,
        length_mm: 0.0,
        h_mm: 4.2,
        e_mpa: 0.25,
        max_depth_mm: 2.0,
    },
    Case {
        name: "can 57.2 mm on portable (h 2.0)",
        radius_mm: 28.6,
        length_mm: 22.6,
        h_mm: 2.0,
        e_mpa: 0.15,
        max_depth_mm: 0.4,
    },
];

fn profile(c: &Case, g: Grid) -> Vec<f64> {
    let r = c.radius_mm;
    (0..g.len())
        .map(|i| {
            let (x, y) = g.xy(i);
            let r2 = if c.length_mm > 0.0 {
                if x.abs() > c.length_mm / 2.0 {
                    return 1e3;
                }
                y * y
            } else {
                x * x + y * y
            };
            if r2 < r * r {
                r - (r * r - r2).sqrt()
            } else {
                1e3
            }
        })
        .collect()
}

/// The layer (ν = 0.49) with `cells` across the deepest contact's width.
fn operator(c: &Case, cells: usize) -> LayerOperator {
    let nu = 0.49;
    let a = (2.0 * c.radius_mm * c.max_depth_mm).sqrt() * 0.8;
    let dx = 2.0 * a / cells as f64;
    let extent = (2.0 * a).max(c.length_mm * 1.1);
    let n = LayerOperator::period_for(extent, c.h_mm, dx);
    LayerOperator::new(Grid { n, dx }, c.h_mm, c.e_mpa / (2.0 * (1.0 + nu)), nu)
}

fn main() {
    if std::env::args().nth(1).as_deref() == Some("model") {
        model_cost();
        return;
    }
    let tol = Tolerance {
        rel: 1e-8,
        max_iter: 4000,
    };
    println!(
        "| contact | cells across | increments | μ | F/F_free at each depth | stick at the deepest | path, ms |"
    );
    println!("|---|---|---|---|---|---|---|");
    for c in &CASES {
        for cells in [16usize, 32] {
            let op = operator(c, cells);
            let prof = profile(c, op.grid());
            for steps in [8usize, 16, 32] {
                let depths = path_depths(c.max_depth_mm, steps);
                let run = |mu: f64| {
                    let mut path = CurvedPath::new(&op, &prof, mu, tol);
                    let t0 = Instant::now();
                    let mut out = Vec::new();
                    for (k, d) in depths.iter().enumerate() {
                        let s = path.press_to(*d).expect("forward");
                        if [steps / 4, steps / 2, steps].contains(&(k + 1)) {
                            out.push((*d, s));
                        }
                    }
                    (out, t0.elapsed().as_secs_f64() * 1e3)
                };
                let (free, _) = run(0.0);
                for mu in [0.6, 1e3] {
                    let (held, ms) = run(mu);
                    let ratios: Vec<String> = held
                        .iter()
                        .zip(&free)
                        .map(|((d, h), (_, f))| format!("{d} mm: {:.4}", h.force_n / f.force_n))
                        .collect();
                    let (_, last) = held.last().expect("a reported depth");
                    println!(
                        "| {} | {cells} | {steps} | {mu} | {} | {:.2} | {ms:.0} |",
                        c.name,
                        ratios.join(", "),
                        last.t.stick_fraction(&last.p),
                    );
                }
            }
        }
    }
}

/// What a dry run pays once, frictionless against with friction: the model build (the
/// normal table, and with friction its path), the first pressed field and a field one
/// depth bucket on (a new bucket's pressed state), medians of three; Fz at the depth.
fn model_cost() {
    let sphere = Indenter::Sphere { diameter_mm: 12.68 };
    let can = Indenter::Cylinder {
        diameter_mm: 57.2,
        length_mm: 100.0,
    };
    let cases = [
        (
            "box-normal-sphere",
            presets::BOX_LAYER,
            presets::box_material(),
            sphere,
            2.0,
            false,
            1.0,
            30.0,
        ),
        (
            "lifting-can",
            presets::PORTABLE_LAYER,
            presets::portable_material(),
            can,
            0.4,
            true,
            0.3,
            22.0,
        ),
    ];
    println!(
        "| case | pressing | build, ms | first field, ms | next bucket's field, ms | Fz at depth, N |"
    );
    println!("|---|---|---|---|---|---|");
    for (name, layer, material, indenter, max_depth_mm, shear, depth_mm, view_mm) in cases {
        for friction in [false, true] {
            let spec = ModelSpec {
                contact: Contact {
                    layer,
                    material: material.clone(),
                    indenter,
                },
                max_depth_mm,
                shear,
                twist: shear,
                field_view_mm: Some((view_mm, view_mm)),
                pressing_friction: friction,
                quality: Quality::default(),
            };
            let (mut builds, mut first, mut next) = (Vec::new(), Vec::new(), Vec::new());
            let mut fz = f64::NAN;
            for _ in 0..3 {
                let t0 = Instant::now();
                let Ok(mut m) = ContactModel::build(spec.clone()) else {
                    eprintln!("{name}: the model does not build");
                    return;
                };
                builds.push(t0.elapsed().as_secs_f64() * 1e3);
                let at = |d: f64| State {
                    depth_mm: d,
                    shear_n: 0.0,
                    torque_nmm: 0.0,
                };
                let t1 = Instant::now();
                let _ = m.field(at(depth_mm));
                first.push(t1.elapsed().as_secs_f64() * 1e3);
                let t2 = Instant::now();
                let _ = m.field(at(depth_mm + 0.01 * layer.thickness_mm));
                next.push(t2.elapsed().as_secs_f64() * 1e3);
                fz = m.normal_force_n(depth_mm);
            }
            let median = |mut v: Vec<f64>| {
                v.sort_by(f64::total_cmp);
                v[v.len() / 2]
            };
            println!(
                "| {name} ({depth_mm} mm) | {} | {:.0} | {:.0} | {:.0} | {fz:.3} |",
                if friction {
                    "with friction"
                } else {
                    "frictionless"
                },
                median(builds),
                median(first),
                median(next)
            );
        }
    }
}
