//! Grasp trials, one by one (thesis §6.3.2, Fig. 6-20 to 6-23): how hard the grip
//! squeezed, what it carried, how close it came to slipping, when the markers felt slip
//! coming against when the force sensor (and, on a dry run, the simulator) saw the can go,
//! and how each trial ended.
//!
//! Definitions (docs/explanation/grasp.md):
//! - a trial is the rows of one `trial` number; its *carrying* part runs from the end of its
//!   first step that raises the lift axis to the start of the next lift move (lowering);
//! - squeeze: the window-mean Fz of the lift step; lift load: |Fy| of the first hold (or the
//!   lift step) — the sponge side's share, which the thesis's jig reads as equal to the gel's;
//! - force-based slip onset: the first carrying sample from which |Fy| stays more than 25 %
//!   away from the lift load for 0.2 s, outside disturbance steps (a sliding can loads the
//!   sponge side with kinetic friction and its damping, then lands); μ̂ = lift load / Fz
//!   there, the grasp's ratio at slip (the thesis's μ = F_t/F_n at slip, §6.3.2);
//! - slip margin: 1 − lift load / (μ̂ · squeeze), with the run's median μ̂ over trials that
//!   slipped (none without one);
//! - tactile onset: the first carrying frame of `tactile.csv` not in `stick`;
//! - true onset (dry runs): the first carrying frame where the simulator's can slides;
//! - lead: (true onset, else force onset) − tactile onset;
//! - outcome: `dropped` when the can came down to the table while carried (truth), or |Fy|
//!   stayed below a fifth of the lift load to the end of carrying (force); `slipped` when
//!   it slid but was caught; `held` otherwise;
//! - false alarms: frames not in `stick` during the holds and disturbances of trials that
//!   held (a loosening that stops on `incipient` is the warning doing its job).

use serde_json::{Value, json};

use super::RunData;
use super::plots::{Chart, Series};
use sensing::run_data::TactileCsvRow;

/// One trial's results.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct TrialResult {
    pub trial: u32,
    pub squeeze_n: f64,
    pub lift_load_n: f64,
    pub mu_hat: Option<f64>,
    pub margin: Option<f64>,
    pub tactile_onset_s: Option<f64>,
    pub force_onset_s: Option<f64>,
    pub true_onset_s: Option<f64>,
    pub lead_s: Option<f64>,
    pub outcome: &'static str,
    pub false_alarm_frames: usize,
    /// Largest |Tz| the Nano17 read in the trial's disturbances, N·mm.
    pub peak_twist_nmm: Option<f64>,
    pub carrying_s: (f64, f64),
}

/// The trials of a grasp run; empty unless the run lifts (a `lift` axis step in a trial).
pub(crate) fn analyse(data: &RunData, tactile: &[TactileCsvRow]) -> Vec<TrialResult> {
    let mut trials: Vec<u32> = data.steps.iter().map(|s| s.trial).collect();
    trials.sort_unstable();
    trials.dedup();
    let mut out = Vec::new();
    for trial in trials.into_iter().filter(|t| *t > 0) {
        let steps: Vec<_> = data.steps.iter().filter(|s| s.trial == trial).collect();
        let Some(lift_k) = steps
            .iter()
            .position(|s| s.axis == "lift" && s.position.is_some_and(|p| p > 0.0))
        else {
            continue;
        };
        let lift = steps[lift_k];
        let from_ns = lift.t_end_ns.max(lift.settle_end_ns);
        let to_ns = steps[lift_k + 1..]
            .iter()
            .find(|s| s.axis == "lift")
            .map(|s| s.t_start_ns)
            .unwrap_or(u64::MAX);
        let squeeze = lift.fz_n.abs();
        let load = steps[lift_k + 1..]
            .iter()
            .find(|s| s.phase == "hold")
            .map(|s| s.fy_n.abs())
            .unwrap_or(lift.fy_n.abs());
        let carrying: Vec<&super::ForceRow> = data
            .force
            .iter()
            .filter(|r| r.t_ns >= from_ns && r.t_ns < to_ns)
            .collect();
        let quiet: Vec<u32> = steps
            .iter()
            .filter(|s| s.phase == "hold" || s.phase == "disturb")
            .map(|s| s.step)
            .collect();
        let disturbing: Vec<u32> = steps
            .iter()
            .filter(|s| s.phase == "disturb")
            .map(|s| s.step)
            .collect();
        let onset = force_onset(&carrying, load, &disturbing);
        let peak_twist_nmm = carrying
            .iter()
            .filter(|r| disturbing.contains(&r.step))
            .map(|r| r.tz_nmm.abs())
            .reduce(f64::max);
        let force_onset_ns = onset.map(|k| carrying[k].t_ns);
        let mu_hat = onset
            .map(|k| carrying[k].fz_n)
            .filter(|fz| *fz > 0.0)
            .map(|fz| load / fz);
        let frames: Vec<&TactileCsvRow> = tactile
            .iter()
            .filter(|r| r.trial == trial && r.gripping && r.t_ns >= from_ns && r.t_ns < to_ns)
            .collect();
        let tactile_onset_ns = frames.iter().find(|r| r.state != "stick").map(|r| r.t_ns);
        let true_onset_ns = frames
            .iter()
            .find(|r| r.true_sliding == Some(true))
            .map(|r| r.t_ns);
        let has_truth = frames.iter().any(|r| r.true_sliding.is_some());
        let outcome = if has_truth {
            let dropped = true_onset_ns.is_some_and(|t0| {
                frames
                    .iter()
                    .any(|r| r.t_ns >= t0 && r.true_height_mm.is_some_and(|h| h <= 0.5))
            });
            match (true_onset_ns, dropped) {
                (_, true) => "dropped",
                (Some(_), false) => "slipped",
                (None, _) => "held",
            }
        } else {
            match onset {
                Some(_) if carrying.last().is_some_and(|r| r.fy_n.abs() < 0.5 * load) => "dropped",
                Some(_) => "slipped",
                None => "held",
            }
        };
        let gone = true_onset_ns.or(force_onset_ns);
        let s = |t: u64| t as f64 * 1e-9;
        out.push(TrialResult {
            trial,
            squeeze_n: squeeze,
            lift_load_n: load,
            mu_hat,
            margin: None,
            tactile_onset_s: tactile_onset_ns.map(s),
            force_onset_s: force_onset_ns.map(s),
            true_onset_s: true_onset_ns.map(s),
            lead_s: match (gone, tactile_onset_ns) {
                (Some(g), Some(t)) => Some((g as f64 - t as f64) * 1e-9),
                _ => None,
            },
            outcome,
            peak_twist_nmm,
            false_alarm_frames: if outcome == "held" {
                frames
                    .iter()
                    .filter(|r| r.state != "stick" && quiet.contains(&r.step))
                    .count()
            } else {
                0
            },
            carrying_s: (
                s(from_ns),
                if to_ns == u64::MAX {
                    f64::NAN
                } else {
                    s(to_ns)
                },
            ),
        });
    }
    // The margin needs μ: the median of the run's own slips.
    let mut mus: Vec<f64> = out.iter().filter_map(|t| t.mu_hat).collect();
    mus.sort_by(f64::total_cmp);
    if let Some(&mu) = mus.get(mus.len() / 2) {
        for t in &mut out {
            if t.squeeze_n > 0.0 && mu > 0.0 {
                t.margin = Some(1.0 - t.lift_load_n / (mu * t.squeeze_n));
            }
        }
    }
    out
}

/// Index of the first sample from which |Fy| stays > 25 % off `load` for 0.2 s, outside
/// the `disturbing` steps.
fn force_onset(carrying: &[&super::ForceRow], load: f64, disturbing: &[u32]) -> Option<usize> {
    const HOLD_NS: u64 = 200_000_000;
    let mut start: Option<usize> = None;
    for (k, r) in carrying.iter().enumerate() {
        let off = !disturbing.contains(&r.step) && (r.fy_n.abs() - load).abs() > 0.25 * load;
        match (off, start) {
            (true, None) => start = Some(k),
            (true, Some(s)) if r.t_ns >= carrying[s].t_ns + HOLD_NS => return Some(s),
            (false, _) => start = None,
            _ => {}
        }
    }
    None
}

fn opt(v: Option<f64>, digits: usize) -> String {
    v.filter(|v| v.is_finite())
        .map(|v| format!("{v:.digits$}"))
        .unwrap_or_else(|| "—".into())
}

/// The section's title, markdown, `summary.json` entries and per-trial charts.
pub(super) type TrialSection = (String, String, Value, Vec<(String, Chart)>);

/// The section: title, markdown, `summary.json` entries and per-trial charts.
pub(super) fn section(
    data: &RunData,
    results: &[TrialResult],
    tactile: &[TactileCsvRow],
) -> Option<TrialSection> {
    if results.is_empty() {
        return None;
    }
    let truth = results.iter().any(|t| t.true_onset_s.is_some())
        || tactile.iter().any(|r| r.true_sliding.is_some());
    let mut text = String::from(
        "Each trial's squeeze and load (Nano17, behind the sponge), slip margin \
         1 − |Fy|/(μ̂·Fz) with μ̂ from the run's own slips, and when slip was felt: by the \
         GelSight's markers (tactile.csv, the first frame not in `stick`), by the force \
         sensor (|Fy| halving)",
    );
    text.push_str(if truth {
        ", and by the simulator (the can sliding). Lead = when the can went − the tactile warning.\n\n"
    } else {
        ". Lead = force onset − tactile warning.\n\n"
    });
    text.push_str(
        "| trial | squeeze (N) | lift load (N) | μ̂ | slip margin (%) | tactile onset (s) | force onset (s) |",
    );
    text.push_str(if truth { " true onset (s) |" } else { "" });
    text.push_str(
        " lead (s) | outcome | peak twist Tz (N·mm) | false alarms (frames) |\n|---|---|---|---|---|---|---|",
    );
    text.push_str(if truth { "---|" } else { "" });
    text.push_str("---|---|---|---|\n");
    let mut rows = Vec::new();
    for t in results {
        text.push_str(&format!(
            "| {} | {:.3} | {:.3} | {} | {} | {} | {} |{} {} | {} | {} | {} |\n",
            t.trial,
            t.squeeze_n,
            t.lift_load_n,
            opt(t.mu_hat, 3),
            opt(t.margin.map(|m| m * 100.0), 0),
            opt(t.tactile_onset_s, 2),
            opt(t.force_onset_s, 2),
            if truth {
                format!(" {} |", opt(t.true_onset_s, 2))
            } else {
                String::new()
            },
            opt(t.lead_s, 2),
            t.outcome,
            opt(t.peak_twist_nmm, 1),
            t.false_alarm_frames
        ));
        rows.push(json!({
            "trial": t.trial, "squeeze_n": t.squeeze_n, "lift_load_n": t.lift_load_n,
            "mu_hat": t.mu_hat, "slip_margin": t.margin,
            "tactile_onset_s": t.tactile_onset_s, "force_onset_s": t.force_onset_s,
            "true_onset_s": t.true_onset_s, "lead_s": t.lead_s, "outcome": t.outcome,
            "false_alarm_frames": t.false_alarm_frames, "peak_twist_nmm": t.peak_twist_nmm,
        }));
    }
    let count = |o: &str| results.iter().filter(|t| t.outcome == o).count();
    let slipped: Vec<&TrialResult> = results.iter().filter(|t| t.outcome != "held").collect();
    let warned = slipped
        .iter()
        .filter(|t| t.lead_s.is_some_and(|l| l > 0.0))
        .count();
    let mut leads: Vec<f64> = slipped.iter().filter_map(|t| t.lead_s).collect();
    leads.sort_by(f64::total_cmp);
    let median_lead = leads.get(leads.len() / 2).copied();
    text.push_str(&format!(
        "\n{} trials: {} held, {} slipped, {} dropped. The tactile warning came before the \
         can went in {} of {} trials that slipped (median lead {} s); {} false-alarm frames \
         in trials that held. The slip margin is along the load only: a twist carried \
         near the contact's torsional capacity slips at the contact's ends too, and the \
         markers report it (see the peak twist).\n",
        results.len(),
        count("held"),
        count("slipped"),
        count("dropped"),
        warned,
        slipped.len(),
        opt(median_lead, 2),
        results.iter().map(|t| t.false_alarm_frames).sum::<usize>()
    ));
    let stats = json!({
        "trials": results.len(), "held": count("held"), "slipped": count("slipped"),
        "dropped": count("dropped"), "warned_before_slip": warned,
        "median_lead_s": median_lead,
        "false_alarm_frames": results.iter().map(|t| t.false_alarm_frames).sum::<usize>(),
    });
    let charts = results
        .iter()
        .map(|t| (format!("trial_{:03}", t.trial), chart(data, t)))
        .collect();
    Some((
        "Grasp trials".into(),
        text,
        json!({"trials": rows, "trial_stats": stats}),
        charts,
    ))
}

/// Forces of one trial against time, its steps shaded, slip events marked.
fn chart(data: &RunData, t: &TrialResult) -> Chart {
    let rows: Vec<&super::ForceRow> = data.force.iter().filter(|r| r.trial == t.trial).collect();
    let k = (rows.len() / 3000).max(1);
    let pts = |g: &dyn Fn(&super::ForceRow) -> f64| -> Vec<(f64, f64)> {
        rows.iter()
            .step_by(k)
            .map(|r| (r.t_ns as f64 * 1e-9, g(r)))
            .collect()
    };
    let mut markers = Vec::new();
    for (v, name) in [
        (t.tactile_onset_s, "tactile warning"),
        (t.force_onset_s, "force onset"),
        (t.true_onset_s, "true slip"),
    ] {
        if let Some(v) = v {
            markers.push((v, name.to_string()));
        }
    }
    Chart {
        title: format!("Trial {}: {} (shaded: steps)", t.trial, t.outcome),
        x_label: "time (s)".into(),
        y_label: "force (N), torque (N·mm)".into(),
        series: vec![
            Series::line("Fz (squeeze)", pts(&|r| r.fz_n), 0),
            Series::line("Fy (load)", pts(&|r| r.fy_n), 2),
            Series::line("Tz", pts(&|r| r.tz_nmm), 3),
        ],
        bands: data
            .steps
            .iter()
            .filter(|s| s.trial == t.trial)
            .map(|s| (s.t_start_ns as f64 * 1e-9, s.t_end_ns as f64 * 1e-9))
            .collect(),
        markers,
        legend_upper_right: true,
        ..Default::default()
    }
}
