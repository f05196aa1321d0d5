//! Adaptive settling against the simulator's truth: `box-normal-flat` (relaxation times
//! 1.5 / 15 / 60 s) with `settle: {adaptive: …}` instead of its fixed three minutes, and the
//! same with a much slower relaxation added, where the rule must wait and say so.

use rundir::write::Status;

use crate::support::{col, csv_rows, load_text, run_virtual, shipped_text};

const ADAPTIVE: &str = "settle: {adaptive: {tolerance: 1 %, min: 20 s, max: 300 s}}";

fn adaptive_box(extra: &str) -> String {
    let text = shipped_text("box-normal-flat").replace("settle: {fixed: 180 s}", ADAPTIVE);
    assert!(text.contains("adaptive"), "the shipped protocol changed");
    text.replace("sensor: {kind: box}", extra)
}

/// Per step: |F∞ − the simulator's equilibrium|, the reported σ, the settle time, the verdict.
fn steps_against_truth(dir: &std::path::Path) -> Vec<(f64, f64, f64, f64, String)> {
    let steps = csv_rows(&dir.join("steps.csv"));
    let sim = csv_rows(&dir.join("sim_steps.csv"));
    assert_eq!(steps.len(), sim.len());
    let eq = col(&sim, "fz_eq_n");
    steps
        .iter()
        .zip(eq)
        .map(|(r, truth)| {
            let f: f64 = r["f_inf"].parse().expect("f_inf");
            let sd: f64 = r["f_inf_sigma"].parse().expect("f_inf_sigma");
            let settle: f64 = r["settle_s"].parse().expect("settle_s");
            let fz: f64 = r["fz_n"].parse().expect("fz_n");
            assert_eq!(f, fz, "the step's quasistatic Fz is F∞");
            assert!(
                r["window_mean"].parse::<f64>().is_ok(),
                "the window mean stays"
            );
            (
                (f - truth).abs(),
                sd,
                settle,
                truth,
                r["settle_verdict"].clone(),
            )
        })
        .collect()
}

#[test]
fn adaptive_settling_finds_each_steps_equilibrium_within_a_percent_in_a_fraction_of_the_time() {
    let tmp = tempfile::tempdir().unwrap();
    let loaded = load_text(tmp.path(), &adaptive_box("sensor: {kind: box}")).unwrap();
    // The rule's thresholds were set watching seeds 1–3 (BENCHMARKS.md, "Settle rules": mean
    // settle 42.1 s against the target's 45 s, 56 of 57 steps within 1 %); it is tested on
    // seeds 4–6, which nothing was tuned on (`settle_study from 4`: 41.8 s, 57 of 57).
    let (mut settles, mut within, mut in_contact) = (Vec::new(), 0, 0);
    for seed in 4..=6 {
        let (o, _) = run_virtual(&loaded, &tmp.path().join(seed.to_string()), seed, None);
        assert_eq!(o.status, Status::Completed, "{:?}", o.message);
        let rows = steps_against_truth(&o.dir);
        let steps = csv_rows(&o.dir.join("steps.csv"));
        let mut beyond_3sd = Vec::new();
        for (k, ((err, sd, settle, truth, verdict), row)) in rows.iter().zip(&steps).enumerate() {
            settles.push(*settle);
            // Unloaded to the contact origin the punch leaves the sunk gel, which recovers
            // into it later: no record of the step shows that (docs/reference/protocol.md,
            // "Choosing a settle rule").
            if row["position"].parse::<f64>().unwrap() <= 0.0 {
                continue;
            }
            in_contact += 1;
            let step = k + 1;
            assert!(
                verdict == "converged" || k == 0,
                "seed {seed}, step {step}: {verdict} (only the first step may wait out its max)"
            );
            let pct = 100.0 * err / truth.abs();
            assert!(
                pct <= 1.2,
                "seed {seed}, step {step}: F∞ off by {pct:.2} % of {truth} N"
            );
            assert!(
                *err <= 4.0 * sd,
                "seed {seed}, step {step}: error {err} beyond 4σ ({sd})"
            );
            if *err > 3.0 * sd {
                beyond_3sd.push(step);
            }
            if pct <= 1.0 {
                within += 1;
            }
        }
        // The σ each step claims: at most one step of a run beyond 3σ, none beyond 4σ
        // (pressed with friction, seed 1's step 8 stops at 26.6 s, 1.1 % off at 3.3σ).
        assert!(
            beyond_3sd.len() <= 1,
            "seed {seed}: steps {beyond_3sd:?} beyond their 3σ"
        );
        // The run said which time constants later steps assumed.
        let journal = std::fs::read_to_string(o.dir.join("journal.jsonl")).unwrap();
        assert!(journal.contains("gel_time_constants"));
    }
    let mean = settles.iter().sum::<f64>() / settles.len() as f64;
    eprintln!(
        "adaptive settle, held-out seeds 4–6: mean {mean:.1} s; F∞ within 1 % on {within} of {in_contact} steps"
    );
    assert!(
        within + 1 >= in_contact,
        "F∞ within 1 % on {within} of {in_contact} steps"
    );
    assert!(
        mean <= 45.0,
        "mean settle {mean:.1} s (target 45 s; fixed: 180 s)"
    );
}

#[test]
fn a_relaxation_slower_than_the_settle_is_waited_for_not_claimed_at_first() {
    let tmp = tempfile::tempdir().unwrap();
    // The box gel (E∞ 0.25 MPa, 1.5 / 15 / 60 s) with a 600 s term added.
    let slow = "sensor:\n  kind: box\n  material:\n    youngs_modulus: 0.25 MPa\n    \
                poisson_ratio: 0.49\n    friction: 0.6\n    prony:\n      \
                - {weight: 0.25, tau: 1.5 s}\n      - {weight: 0.20, tau: 15 s}\n      \
                - {weight: 0.15, tau: 60 s}\n      - {weight: 0.15, tau: 600 s}";
    let loaded = load_text(tmp.path(), &adaptive_box(slow)).unwrap();
    // A held-out seed: the rule was set watching seeds 1–3.
    let (o, _) = run_virtual(&loaded, tmp.path(), 4, None);
    assert_eq!(o.status, Status::Completed, "{:?}", o.message);
    let rows = steps_against_truth(&o.dir);
    let steps = csv_rows(&o.dir.join("steps.csv"));
    // The first steps cannot pin F∞: they wait out their max and say so.
    for (k, (.., settle, _, verdict)) in rows.iter().take(2).enumerate() {
        assert_eq!(verdict, "timeout", "step {}", k + 1);
        assert_eq!(*settle, 300.0);
    }
    // No step claims 1 % it does not have, and the reported uncertainty covers the error:
    // BENCHMARKS.md measures 55 of 57 over seeds 1–3 and 56 of 57 over held-out seeds 4–6;
    // one seed's 19 steps, at least 17.
    let (mut covered, mut in_contact) = (0, 0);
    for (k, ((err, sd, _, truth, verdict), row)) in rows.iter().zip(&steps).enumerate() {
        if row["position"].parse::<f64>().unwrap() <= 0.0 {
            continue;
        }
        in_contact += 1;
        if *err <= 2.0 * sd {
            covered += 1;
        }
        assert!(
            verdict != "converged" || *err <= 0.01 * truth.abs(),
            "step {}: claimed 1 %, off by {:.2} %",
            k + 1,
            100.0 * err / truth.abs()
        );
    }
    assert!(
        covered + 2 >= in_contact,
        "2σ covers the error on {covered} of {in_contact} steps"
    );
    let warnings = crate::support::manifest(&o.dir).warnings;
    assert!(
        warnings
            .iter()
            .any(|w| w.contains("was not known within 1 %")),
        "{warnings:?}"
    );
}

#[test]
fn the_report_replays_each_settle_rule_on_the_runs_own_relaxation() {
    let run = crate::support::shared_dry_run("box-normal-flat");
    let tmp = tempfile::tempdir().unwrap();
    report::report_with_sensor(&run, Some(tmp.path()), None).unwrap();
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(tmp.path().join("summary.json")).unwrap())
            .unwrap();
    let rules = summary["settle"]["rules"].as_array().expect("rules");
    let get = |prefix: &str| {
        rules
            .iter()
            .find(|r| r["rule"].as_str().unwrap().starts_with(prefix))
            .unwrap_or_else(|| panic!("no {prefix} rule in {rules:?}"))
    };
    let (rate, adaptive) = (get("rate"), get("adaptive"));
    let num = |v: &serde_json::Value, k: &str| v[k].as_f64().unwrap();
    // On 180 s records of the 1.5 / 15 / 60 s gel: the rate rule stops early and wrong by
    // the relaxation still to come; the adaptive rule stops before the 180 s and right. (A
    // first record of 180 s, 3 τ_slow, teaches the time constants with a wide spread, so
    // later steps wait longer than in a run whose first step follows 300 s: 122 s median.)
    assert!(num(rate, "median_settle_s") < 60.0);
    assert!(num(adaptive, "median_settle_s") < 150.0, "{rules:?}");
    assert!(
        num(adaptive, "median_abs_error") * 5.0 < num(rate, "median_abs_error"),
        "{rules:?}"
    );
    // The fixed 180 s wait's error, at the curve's last point, is of the adaptive rule's size.
    let curve = summary["settle"]["median_abs_error_vs_truth"]
        .as_array()
        .unwrap();
    let at_180 = curve.last().unwrap().as_f64().unwrap();
    assert!(
        num(adaptive, "median_abs_error") < 2.0 * at_180,
        "{rules:?} vs {at_180}"
    );
    let md = std::fs::read_to_string(tmp.path().join("report.md")).unwrap();
    assert!(md.contains("replayed through the other settle rules"));
}

#[test]
fn on_a_sphere_the_steps_that_claim_their_equilibrium_are_covered_by_their_uncertainty() {
    // `box-normal-sphere` with the adaptive rule: the first step (0.16 N against 3 mN of
    // noise) teaches the gel's time constants alone and a later one refines them; the
    // slowest term's weight carried to later steps must be learned again with them. Learned
    // once from the first step, it put every step that carried it off by the same fraction
    // (seed 2: −0.52 to −0.75 %, seed 3: +0.16 to +0.35 %) at a claimed 2σ of ±0.25 % —
    // 13 of the 33 claims of these two seeds outside their 2σ.
    let tmp = tempfile::tempdir().unwrap();
    let text = shipped_text("box-normal-sphere").replace("settle: {fixed: 180 s}", ADAPTIVE);
    assert!(text.contains("adaptive"), "the shipped protocol changed");
    let loaded = load_text(tmp.path(), &text).unwrap();
    let (mut claimed, mut covered, mut worst_pct) = (0, 0, 0.0f64);
    // Held out: the carried weight was worked out on seeds 2 and 3 (above); tested on 4 and 5.
    for seed in [4, 5] {
        let (o, _) = run_virtual(&loaded, &tmp.path().join(seed.to_string()), seed, None);
        assert_eq!(o.status, Status::Completed, "{:?}", o.message);
        for (err, sd, _, truth, verdict) in steps_against_truth(&o.dir) {
            if verdict != "converged" {
                continue;
            }
            claimed += 1;
            worst_pct = worst_pct.max(100.0 * err / truth.abs());
            if err <= 2.0 * sd {
                covered += 1;
            }
        }
    }
    eprintln!("sphere: {covered} of {claimed} claims within their 2σ, worst {worst_pct:.2} %");
    assert!(
        claimed >= 20,
        "only {claimed} steps claimed their equilibrium"
    );
    // docs/reference/protocol.md: on the tuning seeds 2–3 every claim within 0.31 % and its
    // 2σ; on these held-out seeds every claim within 0.80 %, 35 of 36 within their 2σ. Held
    // to what a claim promises (its 1 %) and to one claim outside its 2σ at most.
    assert!(worst_pct <= 1.0, "a claim off by {worst_pct:.2} %");
    assert!(
        covered + 1 >= claimed,
        "{covered} of {claimed} claims within their 2σ"
    );
}
