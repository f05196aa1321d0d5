//! The stiff and extreme variants at every fidelity level: relaxation times from 1 ms to
//! 10⁴ s, ν to 0.49999, depths to 95 % of the layer, μ from 0.01 to 5. Each builds (a
//! solver that cannot converge is an error, announced), and a press, hold, release — with a
//! shear beyond slip where μ is the extreme — gives finite forces, a hold that only relaxes
//! (a step that adds energy would raise it), a load–unload loop that dissipates, and a
//! shear force the friction law bounds.

use super::*;
use mechanics::{Layer, Material};
use rig::config::Fidelity;

const S: u64 = 1_000_000_000;
const MS: u64 = 1_000_000;

/// One extreme variant.
struct Case {
    name: &'static str,
    indenter: Indenter,
    layer: Layer,
    nu: f64,
    mu: f64,
    prony: Vec<PronyTerm>,
    /// Deepest press, share of the layer.
    depth_share: f64,
    shear: bool,
}

fn cases() -> Vec<Case> {
    let portable = Layer {
        width_mm: 25.0,
        length_mm: 25.0,
        thickness_mm: 2.0,
    };
    let relax = |tau_s: f64| vec![PronyTerm { weight: 0.5, tau_s }];
    let punch = Indenter::FlatCircle { diameter_mm: 6.0 };
    let base = |name, indenter, depth_share| Case {
        name,
        indenter,
        layer: portable,
        nu: 0.49,
        mu: 0.6,
        prony: relax(1.0),
        depth_share,
        shear: false,
    };
    vec![
        Case {
            prony: relax(1e-3),
            ..base("tau 1 ms", punch, 0.2)
        },
        Case {
            prony: relax(1e4),
            ..base("tau 1e4 s", punch, 0.2)
        },
        Case {
            nu: 0.49999,
            ..base("nu 0.49999", punch, 0.2)
        },
        base("punch to 95 % of the layer", punch, 0.95),
        base(
            "sphere to 95 % of the layer",
            Indenter::Sphere { diameter_mm: 12.0 },
            0.95,
        ),
        Case {
            mu: 0.01,
            shear: true,
            ..base("mu 0.01, sheared", punch, 0.1)
        },
        Case {
            mu: 5.0,
            shear: true,
            ..base("mu 5, sheared", punch, 0.1)
        },
    ]
}

fn plant(case: &Case, fidelity: Fidelity) -> Result<Plant, RigError> {
    let contact = Contact::new(
        case.layer,
        Material {
            youngs_modulus_mpa: 0.15,
            poisson_ratio: case.nu,
            prony: case.prony.clone(),
            friction: case.mu,
        },
        case.indenter,
    )
    .expect("a valid contact");
    let spec = PlantSpec {
        contact,
        markers: MarkerLayout::Grid {
            columns: 8,
            rows: 6,
            spacing_mm: 2.5,
            diameter_mm: 0.8,
        },
        view_width_mm: 20.0,
        view_height_mm: 15.0,
        object_mass_g: None,
        max_depth_mm: case.depth_share * case.layer.thickness_mm,
        kinetic_friction: 0.9 * case.mu,
        quality: crate::quality_for(fidelity),
    };
    let geometry = BenchGeometry {
        normal_contact_mm: 10.0,
        grip_contact_mm: 10.0,
        force_bias_n: 0.0,
        noise: false,
        pressing_friction: true,
        finite_strain: false,
    };
    let needs = PlantNeeds {
        shear: case.shear,
        ..PlantNeeds::default()
    };
    Plant::new(spec, geometry, needs, 1)
}

/// Normal force (N) against the normal stage's depth (mm), every 10 ms from `t0` to `t1`.
fn sample(p: &mut Plant, t0: u64, t1: u64) -> Vec<(f64, f64)> {
    (t0 / (10 * MS)..=t1 / (10 * MS))
        .map(|k| {
            let t = k * 10 * MS;
            p.advance_to(t);
            let depth = p
                .axis(AxisRole::Normal)
                .map_or(f64::NAN, |a| a.motion.position(t) - 10.0);
            (depth, p.true_wrench().fz_n)
        })
        .collect()
}

fn check(case: &Case, fidelity: Fidelity) {
    let at = format!("{} at fidelity {}", case.name, fidelity.as_str());
    let mut p = plant(case, fidelity).unwrap_or_else(|e| panic!("{at}: does not build: {e}"));
    let depth = case.depth_share * case.layer.thickness_mm;
    p.add_axis(AxisRole::Normal, 10.0);
    // Press in 1 s, hold 2 s, back out in 1 s.
    p.start_move(AxisRole::Normal, 10.0 + depth, depth, 0, false);
    let loading = sample(&mut p, 0, S);
    let hold = sample(&mut p, S, 3 * S);
    let mut shear_forces = Vec::new();
    if case.shear {
        p.add_axis(AxisRole::Shear, 0.0);
        // Far past slip at either μ: 2 mm of shear on a 6 mm punch.
        p.start_move(AxisRole::Shear, 2.0, 2.0, 3 * S, false);
        for k in 1..=100 {
            p.advance_to(3 * S + k * 10 * MS);
            let w = p.true_wrench();
            shear_forces.push((w.fx_n, w.fz_n));
        }
        p.start_move(AxisRole::Shear, 0.0, 2.0, 4 * S, false);
        p.advance_to(5 * S);
    }
    let t_back = if case.shear { 5 * S } else { 3 * S };
    p.start_move(AxisRole::Normal, 10.0, depth, t_back, false);
    let unloading = sample(&mut p, t_back, t_back + S);
    for (d, f) in loading.iter().chain(&hold).chain(&unloading) {
        assert!(d.is_finite() && f.is_finite(), "{at}: {f} N at {d} mm");
        assert!(*f >= -1e-9, "{at}: the gel pulls ({f} N at {d} mm)");
    }
    let peak = loading.last().map_or(0.0, |s| s.1);
    assert!(peak > 0.0, "{at}: no force at {depth} mm");
    // The hold only relaxes (to within rounding of the peak).
    for w in hold.windows(2) {
        assert!(
            w[1].1 <= w[0].1 + 1e-9 * peak,
            "{at}: the held force rose from {} to {} N",
            w[0].1,
            w[1].1
        );
    }
    // The loop dissipates: the work put in pressing is at least what comes back.
    let work = |s: &[(f64, f64)]| {
        s.windows(2)
            .map(|w| 0.5 * (w[0].1 + w[1].1) * (w[1].0 - w[0].0))
            .sum::<f64>()
    };
    let (w_in, w_out) = (work(&loading), -work(&unloading));
    assert!(
        w_out <= w_in * (1.0 + 1e-6) + 1e-12,
        "{at}: the loop returns {w_out} N·mm for {w_in} N·mm put in"
    );
    let shear_max = shear_forces.iter().map(|s| s.0.abs()).fold(0.0, f64::max);
    eprintln!(
        "{at}: peak {peak:.4} N, held to {:.4} N, loop {w_in:.5} in / {w_out:.5} N·mm out, \
         shear up to {shear_max:.4} N",
        hold.last().map_or(0.0, |s| s.1)
    );
    // Friction bounds the shear: never past μ·Fz (static).
    for (fx, fz) in &shear_forces {
        assert!(
            fx.is_finite() && fx.abs() <= case.mu * fz * (1.0 + 1e-6) + 1e-9,
            "{at}: shear {fx} N over μ·Fz = {} N",
            case.mu * fz
        );
    }
}

#[test]
fn extreme_variants_stay_stable_at_every_fidelity() {
    for fidelity in Fidelity::ALL {
        for case in cases() {
            check(&case, fidelity);
        }
    }
}
