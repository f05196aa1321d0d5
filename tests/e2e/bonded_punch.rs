//! The simulated gel's flat punches against an independent solution of the same problem:
//! an axisymmetric finite-element model of the bonded layer (`tests/peers/bonded_punch_fe.py`,
//! Taylor–Hood elements in (r, z), scikit-fem), which shares no code, table or method with
//! the simulator's Fourier-space surface solver. Frictionless, it gives the layer stiffening
//! κ(a/h, ν); stuck (u_r = 0 under the face), the pressed-with-friction force and field
//! (at μ = 0.6 the whole face sticks: the oracle's |q|/p stays below 0.51).
//!
//! Needs `python3` with `scikit-fem` (`.ci/run` installs it). Where it is missing the test
//! prints a visible skip line — unless `GELRIG_REQUIRE_PEERS=1` (set by CI).

use std::process::Command;

use mechanics::contact::Contact;
use mechanics::geometry::presets;
use mechanics::response::{ContactModel, ModelSpec, Quality, State};
use mechanics::{Indenter, Layer, Material};

use crate::support::{python_peer, root};

/// The oracle's summary for a punch of radius `a_mm` on a layer `h_mm` thick (`extra`: more
/// arguments, e.g. a finite pad's), or `None` (with the skip line) where it cannot run.
fn oracle(a_mm: f64, h_mm: f64, nu: f64, extra: &[&str]) -> Option<serde_json::Value> {
    if !python_peer(
        "import skfem, scipy",
        "python3 with scikit-fem",
        "pip install scikit-fem",
    ) {
        return None;
    }
    let out = Command::new("python3")
        .arg(root().join("tests/peers/bonded_punch_fe.py"))
        .args(["--a", &a_mm.to_string(), "--h", &h_mm.to_string()])
        .args(["--nu", &nu.to_string(), "--levels", "2"])
        .args(extra)
        .output()
        .expect("python3");
    assert!(
        out.status.success(),
        "the oracle failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("the oracle's JSON");
    Some(v)
}

fn model(layer: Layer, material: Material, d_mm: f64, mu: f64, view_mm: f64) -> ContactModel {
    model_at(layer, material, d_mm, mu, view_mm, Quality::default())
}

fn model_at(
    layer: Layer,
    mut material: Material,
    d_mm: f64,
    mu: f64,
    view_mm: f64,
    quality: Quality,
) -> ContactModel {
    material.friction = mu;
    ContactModel::build(ModelSpec {
        contact: Contact {
            layer,
            material,
            indenter: Indenter::FlatCircle { diameter_mm: d_mm },
        },
        max_depth_mm: 0.2 * layer.thickness_mm,
        shear: false,
        twist: false,
        field_view_mm: (view_mm > 0.0).then_some((view_mm, view_mm)),
        pressing_friction: true,
        quality,
    })
    .expect("builds")
}

#[test]
fn the_pressed_flat_punches_match_an_independent_finite_element_solution() {
    let cases = [
        (
            "box 9.5 mm",
            presets::BOX_LAYER,
            presets::box_material(),
            9.5,
        ),
        (
            "box 12.68 mm",
            presets::BOX_LAYER,
            presets::box_material(),
            12.68,
        ),
        (
            "portable 12.5 mm",
            presets::PORTABLE_LAYER,
            presets::portable_material(),
            12.5,
        ),
    ];
    println!(
        "punch              κ free (FE / sim)    κ stuck (FE / sim)   u_r stuck at 1.25a, 1.5a, 2a (FE / sim)"
    );
    for (name, layer, material, d_mm) in cases {
        let (a, h, nu) = (d_mm / 2.0, layer.thickness_mm, material.poisson_ratio);
        let Some(fe) = oracle(a, h, nu, &[]) else {
            return;
        };
        let s = &fe["summary"];
        let num = |v: &serde_json::Value| v.as_f64().expect("a number");
        let (k_free, k_stuck) = (num(&s["kappa_frictionless"]), num(&s["kappa_stuck"]));
        let unit = 2.0 * material.contact_modulus_mpa() * a;
        // Frictionless: the simulator's exact κ.
        let free = model(layer, material.clone(), d_mm, 0.0, 0.0).normal_force_n(1.0) / unit;
        assert!(
            (free / k_free - 1.0).abs() < 0.001,
            "{name}: frictionless κ {free} against the oracle's {k_free}"
        );
        // μ = 0.6: stuck over the whole face; the target is 2 %.
        let mut stuck_model = model(layer, material.clone(), d_mm, 0.6, 2.5 * d_mm);
        let stuck = stuck_model.normal_force_n(1.0) / unit;
        assert!(
            (stuck / k_stuck - 1.0).abs() < 0.004,
            "{name}: stuck κ {stuck} against the oracle's {k_stuck}"
        );
        // The published figure: the stuck/frictionless ratio within 0.3 % of the FE ratio.
        let ratio = (stuck / free) / (k_stuck / k_free) - 1.0;
        println!(
            "{name}: stuck/frictionless ratio {:+.3} % from the FE ratio",
            100.0 * ratio
        );
        assert!(ratio.abs() < 0.003, "{name}: ratio {:+.3} %", 100.0 * ratio);
        // Every fidelity level against the oracle (docs/benchmarks/simulator.md, "Fidelity
        // levels"): the stuck/frictionless ratio, each level's own. A circle's frictionless
        // force is the exact κ at every level; the stuck one is the grid's.
        for (level, quality, allowed) in [
            ("fast", Quality::fast(), 0.01),
            ("reference", Quality::reference(), 0.003),
        ] {
            let at = |mu: f64| {
                model_at(layer, material.clone(), d_mm, mu, 0.0, quality).normal_force_n(1.0) / unit
            };
            let r = (at(0.6) / at(0.0)) / (k_stuck / k_free) - 1.0;
            println!(
                "{name}: at fidelity {level}, stuck/frictionless {:+.3} % from the FE ratio",
                100.0 * r
            );
            assert!(r.abs() < allowed, "{name} at {level}: {:+.3} %", 100.0 * r);
        }
        // μ between: never below frictionless, never above stuck.
        let partial = model(layer, material.clone(), d_mm, 0.2, 0.0).normal_force_n(1.0) / unit;
        assert!(
            partial > free && partial <= stuck * (1.0 + 1e-9),
            "{name}: {partial}"
        );
        // The in-plane field outside the face, per mm of depth.
        let field = stuck_model
            .field(State {
                depth_mm: 1.0,
                shear_n: 0.0,
                torque_nmm: 0.0,
            })
            .expect("a field");
        let radii = fe["ur_points_r_over_a"].as_array().expect("radii");
        let ur_fe = s["ur_over_delta_stuck"].as_array().expect("u_r");
        let mut line = String::new();
        for (r, u) in radii.iter().zip(ur_fe).filter(|(r, _)| {
            let r = num(r);
            (1.2..=2.5).contains(&r)
        }) {
            let (r, u) = (num(r), num(u));
            let sim = field.grid.sample(&field.ux, r * a, 0.0);
            line += &format!("  {u:.4} / {sim:.4}");
            assert!(
                (sim - u).abs() < 0.011 * u.abs().max(0.1),
                "{name}: u_r/δ at {r}a is {sim}, the oracle's {u}"
            );
        }
        println!("{name:<18} {k_free:.4} / {free:.4}    {k_stuck:.4} / {stuck:.4}  {line}");
    }
}

/// The simulated gel is an infinite layer; the portable pad (22.6 × 23.4 × 2 mm) has free
/// sides 5.05 and 5.45 mm (2.5 h and 2.7 h) from its 12.5 mm punch. The oracle bounds a
/// square pad between two discs with free sides: the inscribed one (radius 11.3 mm, every
/// side as near as the nearest) overstates the edges' effect, the circumscribed one (16.27
/// mm, as far as the corners) understates it. The infinite layer's force is 0.05–2.1 %
/// (frictionless) and 0.02–0.85 % (stuck) above the pad's (a free side softens it); the field
/// near the sides is not bounded tightly (docs/explanation/simulated-bench.md, "Finite pads").
#[test]
fn the_portable_pads_free_sides_soften_its_punch_as_the_fe_pads_do() {
    let (layer, material, d_mm) = (presets::PORTABLE_LAYER, presets::portable_material(), 12.5);
    let (a, h, nu) = (d_mm / 2.0, layer.thickness_mm, material.poisson_ratio);
    let unit = 2.0 * material.contact_modulus_mpa() * a;
    let free = model(layer, material.clone(), d_mm, 0.0, 0.0).normal_force_n(1.0) / unit;
    let stuck = model(layer, material.clone(), d_mm, 0.6, 0.0).normal_force_n(1.0) / unit;
    // (pad radius, the infinite layer's excess over the pad, frictionless and stuck, as the
    // oracle converges it: BENCHMARKS.md "Finite pads")
    for (r_out, over_free, over_stuck) in [(11.3, 0.0206, 0.0085), (16.27, 0.0005, 0.0002)] {
        let Some(fe) = oracle(
            a,
            h,
            nu,
            &["--outer", "free", "--r-out", &r_out.to_string()],
        ) else {
            return;
        };
        let s = &fe["summary"];
        let num = |v: &serde_json::Value| v.as_f64().expect("a number");
        let (k_free, k_stuck) = (num(&s["kappa_frictionless"]), num(&s["kappa_stuck"]));
        println!(
            "pad radius {r_out} mm: κ free {k_free:.4} (infinite layer {free:.4}, {:+.2} %), \
             stuck {k_stuck:.4} ({stuck:.4}, {:+.2} %)",
            100.0 * (free / k_free - 1.0),
            100.0 * (stuck / k_stuck - 1.0)
        );
        // Within the simulator's own error against the infinite layer's oracle (the test
        // above: 0.1 % frictionless, 0.4 % stuck) of the pad's softening.
        for (name, sim, pad, over, tol) in [
            ("frictionless", free, k_free, over_free, 0.001),
            ("stuck", stuck, k_stuck, over_stuck, 0.004),
        ] {
            let excess = sim / pad - 1.0;
            assert!(
                (excess - over).abs() < tol,
                "{name}, pad radius {r_out} mm: the infinite layer's κ {sim} against the \
                 pad's {pad} ({:+.2} %)",
                100.0 * excess
            );
        }
    }
}
