//! The simulated gel's curved indenters pressed with friction against an independent
//! solution: an axisymmetric finite-element model of a rigid sphere pressed into the bonded
//! layer from first touch (`tests/peers/bonded_sphere_fe.py`, Taylor–Hood elements in
//! (r, z), scikit-fem; an active set on the surface nodes, each caught node's radial
//! displacement frozen where the sphere caught it), which shares no code, table or method
//! with the simulator's Fourier-space path (`mechanics::pressing::curved`): the force, and
//! the surface's radial displacement outside the contact. Its own checks
//! (Hertz on a thick layer, no friction effect at ν = 0.5, the stuck flat punch of
//! `bonded_punch_fe.py`) are in the script.
//!
//! Needs `python3` with `scikit-fem` (`.ci/run` installs it). Where it is missing the test
//! prints a visible skip line — unless `GELRIG_REQUIRE_PEERS=1` (set by CI).

use std::process::Command;

use mechanics::contact::Contact;
use mechanics::geometry::presets;
use mechanics::response::{ContactModel, ModelSpec, Quality, State};
use mechanics::{Indenter, Layer, Material};

use crate::support::{python_peer, root};

/// One reported depth of the oracle: the stuck-to-frictionless force ratio, the catch
/// interpolated to where each node's gap closes (its K → ∞ limit), and the surface's radial
/// displacement over the depth at the oracle's r/a (a = each solution's contact radius),
/// frictionless and stuck.
struct Fe {
    ratio: f64,
    r_over_a: Vec<f64>,
    a_free_mm: f64,
    ur_free: Vec<f64>,
    a_stuck_mm: f64,
    ur_stuck: Vec<f64>,
}

/// The oracle at each depth (`None` with the skip line where it cannot run).
fn oracle(r_mm: f64, h_mm: f64, nu: f64, depths_mm: &[f64]) -> Option<Vec<Fe>> {
    if !python_peer(
        "import skfem, scipy",
        "python3 with scikit-fem",
        "pip install scikit-fem",
    ) {
        return None;
    }
    let out_path = std::env::temp_dir().join(format!(
        "gelrig-sphere-fe-{}-{r_mm}-{h_mm}.json",
        std::process::id()
    ));
    let depths: Vec<String> = depths_mm.iter().map(f64::to_string).collect();
    let out = Command::new("python3")
        .arg(root().join("tests/peers/bonded_sphere_fe.py"))
        .args(["--R", &r_mm.to_string(), "--h", &h_mm.to_string()])
        .args(["--nu", &nu.to_string(), "--depths", &depths.join(",")])
        .args(["--levels", "2", "--K", "32", "--no-validation"])
        .arg("--out")
        .arg(&out_path)
        .output()
        .expect("python3");
    assert!(
        out.status.success(),
        "the oracle failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(&out_path).expect("the oracle's JSON");
    let _ = std::fs::remove_file(&out_path);
    let v: serde_json::Value = serde_json::from_str(&text).expect("the oracle's JSON");
    let case = v.get("cases").map_or(&v, |c| &c[0]);
    let num = |v: &serde_json::Value| v.as_f64().expect("a number");
    let nums = |v: &serde_json::Value| -> Vec<f64> {
        v.as_array().expect("numbers").iter().map(num).collect()
    };
    let results = case["results"].as_array().expect("results");
    Some(
        results
            .iter()
            .map(|r| {
                let s = &r["surface"];
                Fe {
                    ratio: num(&r["extrapolated"]["ratio_interp"]["extrapolated"]),
                    r_over_a: nums(&s["r_over_a"]),
                    a_free_mm: num(&s["a_edge_free"]["extrapolated"]),
                    ur_free: nums(&s["ur_free"]["extrapolated"]),
                    a_stuck_mm: num(&s["a_edge_stuck_interp"]["extrapolated"]),
                    ur_stuck: nums(&s["ur_stuck_interp"]["extrapolated"]),
                }
            })
            .collect(),
    )
}

fn model(
    layer: Layer,
    material: Material,
    r_mm: f64,
    max_mm: f64,
    mu: f64,
    friction: bool,
) -> ContactModel {
    model_at(
        layer,
        material,
        (r_mm, max_mm),
        mu,
        friction,
        Some((24.0, 24.0)),
        Quality::default(),
    )
}

/// A sphere of radius `r_mm` pressed up to `max_mm`, at `quality`, with fields over `view`.
fn model_at(
    layer: Layer,
    mut material: Material,
    (r_mm, max_mm): (f64, f64),
    mu: f64,
    friction: bool,
    view: Option<(f64, f64)>,
    quality: Quality,
) -> ContactModel {
    material.friction = mu;
    ContactModel::build(ModelSpec {
        contact: Contact {
            layer,
            material,
            indenter: Indenter::Sphere {
                diameter_mm: 2.0 * r_mm,
            },
        },
        max_depth_mm: max_mm,
        shear: false,
        twist: false,
        field_view_mm: view,
        pressing_friction: friction,
        quality,
    })
    .expect("builds")
}

#[test]
fn a_sphere_pressed_stuck_matches_an_independent_finite_element_solution() {
    // The shipped 12.68 mm sphere on the box gel to its protocol's 2 mm, and a 12 mm sphere
    // on a 2 mm layer (the portable pad's), where the layer's coupling is strong.
    let thin = Layer {
        thickness_mm: 2.0,
        ..presets::PORTABLE_LAYER
    };
    let cases = [
        (
            "box sphere",
            presets::BOX_LAYER,
            presets::box_material(),
            6.34,
            vec![0.5, 1.0, 2.0],
        ),
        (
            "12 mm sphere, h 2 mm",
            thin,
            presets::portable_material(),
            6.0,
            vec![0.075, 0.3],
        ),
    ];
    println!("sphere                  depth   stuck/frictionless (FE / sim)");
    for (name, layer, material, r_mm, depths) in cases {
        let nu = material.poisson_ratio;
        let Some(fe) = oracle(r_mm, layer.thickness_mm, nu, &depths) else {
            return;
        };
        let max = depths.iter().copied().fold(0.0, f64::max);
        let free = model(layer, material.clone(), r_mm, max, 1e3, false);
        let stuck = model(layer, material.clone(), r_mm, max, 1e3, true);
        let mut bare = model(layer, material.clone(), r_mm, max, 0.0, true);
        let mut held_fields = model(layer, material.clone(), r_mm, max, 1e3, true);
        assert_eq!(fe.len(), depths.len(), "the oracle answers every depth");
        for (d, fe) in depths.iter().zip(&fe) {
            let got = stuck.normal_force_n(*d) / free.normal_force_n(*d);
            println!("{name:<22} {d:>6}   {:.5} / {got:.5}", fe.ratio);
            // Target (issue 19): within 2 %; the simulator's path is within 0.1 % here.
            assert!(
                (got / fe.ratio - 1.0).abs() < 0.003,
                "{name} at {d} mm: {got} against the oracle's {}",
                fe.ratio
            );
            // The surface outside the contact, u_r/δ at 1.25, 1.5 and 2 contact radii:
            // frictionless (μ = 0) and stuck along the path.
            let pressed = State {
                depth_mm: *d,
                shear_n: 0.0,
                torque_nmm: 0.0,
            };
            let ur = |m: &mut ContactModel, a: f64, k: usize| {
                let f = m.field(pressed).expect("a field");
                f.grid.sample(&f.ux, fe.r_over_a[k] * a, 0.0) / d
            };
            let outside: Vec<usize> = (0..fe.r_over_a.len())
                .filter(|k| (1.2..=2.0).contains(&fe.r_over_a[*k]))
                .collect();
            assert!(outside.len() >= 3, "the oracle's radii: {:?}", fe.r_over_a);
            for k in outside {
                let (sim_free, sim_stuck) = (
                    ur(&mut bare, fe.a_free_mm, k),
                    ur(&mut held_fields, fe.a_stuck_mm, k),
                );
                let ra = fe.r_over_a[k];
                println!(
                    "    u_r/δ at {ra:.2} a: frictionless {:.4} / {sim_free:.4}, stuck {:.4} / {sim_stuck:.4}",
                    fe.ur_free[k], fe.ur_stuck[k]
                );
                // Frictionless within 0.2 % (measured); stuck, whose tractions come from
                // the tables' coarser grid and 16 increments, 0.9–2.5 % small at 1.25a and
                // within 1.2 % from 1.5a.
                assert!(
                    (sim_free / fe.ur_free[k] - 1.0).abs() < 0.005,
                    "{name} at {d} mm, {ra} a: frictionless u_r/δ {sim_free} against {}",
                    fe.ur_free[k]
                );
                let allowed = if ra < 1.4 { 0.03 } else { 0.015 };
                assert!(
                    (sim_stuck / fe.ur_stuck[k] - 1.0).abs() < allowed,
                    "{name} at {d} mm, {ra} a: stuck u_r/δ {sim_stuck} against {}",
                    fe.ur_stuck[k]
                );
            }
        }
        // Every fidelity level against the oracle at the deepest depth (docs/benchmarks/
        // simulator.md, "Fidelity levels"): each level's own stuck/frictionless ratio.
        let (deepest, fe_deepest) = (max, &fe[fe.len() - 1]);
        for (level, quality, allowed) in [
            ("fast", Quality::fast(), 0.02),
            ("reference", Quality::reference(), 0.003),
        ] {
            let force = |mu: f64, friction: bool| {
                model_at(
                    layer,
                    material.clone(),
                    (r_mm, max),
                    mu,
                    friction,
                    None,
                    quality,
                )
                .normal_force_n(deepest)
            };
            let r = force(1e3, true) / force(1e3, false) / fe_deepest.ratio - 1.0;
            println!(
                "{name} at {deepest} mm, fidelity {level}: stuck/frictionless {:+.3} % from the FE ratio",
                100.0 * r
            );
            assert!(r.abs() < allowed, "{name} at {level}: {:+.3} %", 100.0 * r);
        }
        // A real gel's μ = 0.6 sticks over most of the contact: no more than full stick,
        // and past the frictionless force.
        let held = model(layer, material, r_mm, max, 0.6, true);
        let d = max;
        let (f0, f1, f2) = (
            free.normal_force_n(d),
            held.normal_force_n(d),
            stuck.normal_force_n(d),
        );
        assert!(f1 > f0 && f1 <= f2 * (1.0 + 1e-3), "{f0} {f1} {f2}");
    }
}
