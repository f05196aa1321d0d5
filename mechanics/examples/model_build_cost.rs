//! What a dry run pays once for its flat punch — building the contact model for the run's
//! needs and its first field — and what the model gives: Fz per mm of depth, the slip
//! limit over Fz, and the radial field outside the face. Medians of three builds.
//!
//! `cargo run --release -p mechanics --example model_build_cost`

use std::time::Instant;

use mechanics::contact::Contact;
use mechanics::geometry::presets;
use mechanics::response::{ContactModel, ModelSpec, Quality, State};
use mechanics::{Indenter, Layer, Material};

struct Case {
    name: &'static str,
    layer: Layer,
    material: Material,
    diameter_mm: f64,
    shear: bool,
    twist: bool,
    view_mm: f64,
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

fn main() {
    let bx = || (presets::BOX_LAYER, presets::box_material());
    let pt = || (presets::PORTABLE_LAYER, presets::portable_material());
    let case = |name, (layer, material): (Layer, Material), d, shear, twist, view| Case {
        name,
        layer,
        material,
        diameter_mm: d,
        shear,
        twist,
        view_mm: view,
    };
    let cases = [
        case("box-normal-flat", bx(), 9.5, false, false, 30.0),
        case("box-shear-flat", bx(), 12.68, true, false, 30.0),
        case("portable-normal", pt(), 12.5, false, false, 22.0),
        case("portable-rotation", pt(), 12.5, false, true, 22.0),
    ];
    println!(
        "case               pressing     build_ms  first_field_ms  Fz_per_mm_N  Qmax/Fz  My/Fx_mm  ur(1.5a)/d"
    );
    for (c, coupled) in cases.iter().flat_map(|c| [(c, false), (c, true)]) {
        let spec = ModelSpec {
            contact: Contact {
                layer: c.layer,
                material: c.material.clone(),
                indenter: Indenter::FlatCircle {
                    diameter_mm: c.diameter_mm,
                },
            },
            max_depth_mm: 0.2 * c.layer.thickness_mm,
            shear: c.shear,
            twist: c.twist,
            field_view_mm: Some((c.view_mm, c.view_mm)),
            pressing_friction: coupled,
            quality: Quality::default(),
        };
        let (mut builds, mut fields) = (Vec::new(), Vec::new());
        let mut last = None;
        for _ in 0..3 {
            let t0 = Instant::now();
            let mut m = match ContactModel::build(spec.clone()) {
                Ok(m) => m,
                Err(e) => {
                    eprintln!("{}: {e}", c.name);
                    return;
                }
            };
            builds.push(t0.elapsed().as_secs_f64() * 1e3);
            let t1 = Instant::now();
            let f = m.field(State {
                depth_mm: 1.0,
                shear_n: 0.0,
                torque_nmm: 0.0,
            });
            fields.push(t1.elapsed().as_secs_f64() * 1e3);
            last = Some((m, f));
        }
        let Some((mut m, f)) = last else { return };
        let fz = m.normal_force_n(1.0);
        let qmax = m
            .shear_curve(1.0)
            .and_then(|(b, _)| b.f.last().copied())
            .map_or(f64::NAN, |q| q / fz);
        let arm = m.tilt_arms_mm(1.0).0;
        let ur = f.map_or(f64::NAN, |f| {
            f.grid.sample(&f.ux, 0.75 * c.diameter_mm, 0.0)
        });
        println!(
            "{:<18} {:<11} {:>8.0}  {:>14.0}  {fz:>11.4}  {qmax:>7.4}  {arm:>8.3}  {ur:>10.4}",
            c.name,
            if coupled { "friction" } else { "frictionless" },
            median(builds),
            median(fields)
        );
    }
}
