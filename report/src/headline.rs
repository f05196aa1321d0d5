//! The numbers a report leads with, for the terminal and for comparing runs.

/// The report's headline numbers as lines for the terminal: how the run ended, stiffness,
/// R² and linear range, μ and slip onset, force-from-field error, the relaxation's time
/// constants, the GelSight's force error — whichever the run has.
pub fn headline(summary: &serde_json::Value) -> Vec<String> {
    let num = |v: &serde_json::Value| v.as_f64();
    let mut out = Vec::new();
    let run = &summary["run"];
    if let Some(status) = run["status"].as_str() {
        let mut line = format!(
            "run: {status}, {} of {} steps",
            run["steps_completed"], run["steps_planned"]
        );
        if let Some(r) = run["reason"].as_str() {
            line.push_str(&format!(" ({r})"));
        }
        line.push_str(if run["simulated"] == true {
            ", simulated"
        } else {
            ", on devices"
        });
        out.push(line);
    }
    let (unit, force) = (
        summary["main_block"]["unit"].as_str().unwrap_or(""),
        summary["main_block"]["force_unit"].as_str().unwrap_or(""),
    );
    let lin = &summary["linearity"];
    if let (Some(slope), Some(r2)) = (num(&lin["slope"]), num(&lin["r2"])) {
        let mut line = format!("stiffness {slope:.4} {force}/{unit} (R² {r2:.4})");
        if let Some(range) = num(&lin["linear_range"]) {
            line.push_str(&format!(", linear to {range} {unit}"));
        }
        out.push(line);
    }
    let slip = &summary["slip"];
    if !slip.is_null() {
        let mut parts = Vec::new();
        if let Some(mu) = num(&slip["mu"]) {
            parts.push(format!("μ {mu:.3}"));
        }
        if let Some(s) = slip["incipient_step"].as_u64() {
            parts.push(format!("incipient slip at step {s}"));
        }
        if let Some(s) = slip["onset_step"].as_u64() {
            parts.push(format!("slip at step {s}"));
        }
        if !parts.is_empty() {
            out.push(format!("slip: {}", parts.join(", ")));
        }
    }
    let ff = &summary["force_from_field"];
    if let (Some(pct), Some(rmse)) = (num(&ff["rmse_pct"]), num(&ff["rmse_n"])) {
        out.push(format!(
            "force from field: {pct:.2} % RMSE ({rmse:.4} {force}) on the steps held out"
        ));
    }
    if let Some(taus) = summary["relaxation"]["shared_tau_s"].as_array() {
        let t: Vec<String> = taus
            .iter()
            .filter_map(|v| v.as_f64())
            .map(|v| format!("{v:.3}"))
            .collect();
        out.push(format!("relaxation: τ = {} s (pooled)", t.join(", ")));
    }
    if let Some(g) = summary["gelsight_force"].as_object() {
        let parts: Vec<String> = ["fx", "fy", "fz", "tz"]
            .iter()
            .filter_map(|c| num(&g.get(*c)?["pct_range"]).map(|p| format!("{c} {p:.2} %")))
            .collect();
        if !parts.is_empty() {
            out.push(format!(
                "GelSight force (RMSE, % of span): {}",
                parts.join(", ")
            ));
        }
    }
    out
}
