//! A sphere's viscoelastic unloading against an independent solution: a brute-force
//! axisymmetric surface-traction solver on a viscoelastic half-space
//! (`tests/peers/viscoelastic_sphere_unloading.py`: rings with the exact half-space kernel,
//! the creep function's hereditary integral, a contact problem solved at every step), which
//! shares no method with the simulator's foundation ([`mechanics::unloading`], Ting's
//! treatment by the method of dimensionality reduction). Hertz's law at unit modulus on a
//! unit sphere, a standard linear solid unloaded at three speeds and the simulated gel's
//! three-term relaxation held and let go.
//!
//! Needs `python3` with `numpy` and `scipy` (`.ci/run` installs them). Where they are missing
//! the test prints a visible skip line — unless `GELRIG_REQUIRE_PEERS=1` (set by CI).

use mechanics::unloading::TingContact;
use mechanics::{Prony, PronyTerm};

use crate::support::{peer_json, python_peer};

/// The oracle's cases, or `None` (with the skip line) where it cannot run.
fn oracle() -> Option<serde_json::Value> {
    if !python_peer(
        "import numpy, scipy",
        "python3 with numpy and scipy",
        "pip install scipy",
    ) {
        return None;
    }
    Some(peer_json(
        "tests/peers/viscoelastic_sphere_unloading.py",
        &["--quick"],
        "--out",
    ))
}

fn floats(v: &serde_json::Value) -> Vec<f64> {
    v.as_array()
        .expect("an array")
        .iter()
        .map(|x| x.as_f64().unwrap_or(f64::NAN))
        .collect()
}

/// Loading, unloading and letting go, each case: the foundation's force within 0.001 % of
/// the peak of the oracle's at every output time — through the part of the unloading where
/// Lee–Radok's integral pulls and the oracle's force is small or zero — and separating
/// within two output intervals of the oracle.
#[test]
fn a_sphere_unloaded_from_a_viscoelastic_gel_pushes_as_tings_solution_does() {
    let Some(v) = oracle() else {
        return;
    };
    let cases = v["cases"].as_object().expect("cases");
    assert!(cases.len() >= 4, "{:?}", cases.keys());
    for (name, c) in cases {
        let (w, tau) = (floats(&c["G"]["w"]), floats(&c["G"]["tau"]));
        let prony = Prony::new(
            w.iter()
                .zip(&tau)
                .map(|(&weight, &tau_s)| PronyTerm { weight, tau_s })
                .collect(),
        )
        .expect("prony");
        let hertz = |d: f64| 4.0 / 3.0 * d.max(0.0).powf(1.5);
        let (t, delta, f_ref, f_lr) = (
            floats(&c["t"]),
            floats(&c["delta"]),
            floats(&c["F_ting"]),
            floats(&c["F_lee_radok"]),
        );
        let d_max = delta.iter().copied().fold(0.0, f64::max);
        let peak = c["F_peak"].as_f64().expect("peak");
        let mut ting = TingContact::new(hertz, d_max, &prony).expect("foundation");
        let mut worst = 0.0f64;
        let mut separated_at = None;
        let mut pulled = false;
        for k in 1..t.len() {
            // The depth is piecewise linear between the output times; 200 steps each.
            let sub = 200;
            let dt = (t[k] - t[k - 1]) / sub as f64;
            let mut f = 0.0;
            for j in 1..=sub {
                let d = delta[k - 1] + (delta[k] - delta[k - 1]) * j as f64 / sub as f64;
                f = ting.step(d, dt);
            }
            worst = worst.max((f - f_ref[k]).abs() / peak);
            pulled |= f_lr[k] < 0.0;
            if separated_at.is_none() && t[k] > c["t_F_peak"].as_f64().unwrap_or(0.0) && f == 0.0 {
                separated_at = Some(t[k]);
            }
        }
        println!(
            "{name}: worst |F − oracle| {:.5} % of the peak",
            100.0 * worst
        );
        // The published figure: within 0.001 % of the peak.
        assert!(worst < 1e-5, "{name}: {:.5} % of the peak", 100.0 * worst);
        assert!(pulled, "{name}: Lee–Radok should pull somewhere");
        let want = c["separation_time"].as_f64().expect("separates");
        let got = separated_at.expect("separates");
        // The output grid is coarser than the separation: within two of its intervals.
        let grid = t[1] - t[0];
        assert!(
            (got - want).abs() <= 2.0 * grid + 0.02 * want,
            "{name}: {got} vs {want}"
        );
    }
}
