//! How the run ended, at the top of every report: what ran (protocol name and the hash of the
//! file as run), when, with which gelrig, on which rig (simulated or which devices), with
//! which seed, and whether it completed — a report of an aborted run must not read like one
//! of a completed run.

use serde_json::{Value, json};
use sha2::{Digest, Sha256};

use super::RunData;

/// The run's header: a markdown table for the report and its `summary.json` `run` object.
pub(super) fn header(data: &RunData) -> (String, Value) {
    let m = &data.manifest;
    let status = rundir::listing::effective_status(&data.dir, m.status);
    let reason = m.reason.clone().or_else(|| m.error.clone());
    let sha256 = std::fs::read(data.dir.join(rundir::names::PROTOCOL))
        .ok()
        .map(|bytes| hex(&Sha256::digest(&bytes)));
    // Simulated when every device that ran says so (a dry run, or `sim serve` twins bound
    // through a rig file say what they are): the rig that ran, not the files left behind.
    let simulated = !m.devices.is_empty()
        && m.devices
            .iter()
            .all(|d| d.identity.starts_with("simulated"));
    let rig = if simulated {
        format!("simulated ({})", m.rig)
    } else if m.devices.is_empty() {
        format!("{} (no device opened)", m.rig)
    } else {
        format!(
            "{}: {}",
            m.rig,
            m.devices
                .iter()
                .map(|d| format!("{} = {}", d.role, d.identity))
                .collect::<Vec<_>>()
                .join("; ")
        )
    };
    let status_text = match &reason {
        Some(r) => format!("**{status}**: {r}"),
        None => format!("**{status}**"),
    };
    let mut md = String::from("| | |\n|---|---|\n");
    let mut row = |k: &str, v: String| {
        md.push_str(&format!("| {k} | {} |\n", v.replace('|', "/")));
    };
    row(
        "protocol",
        format!(
            "`{}` (`{}`, sha256 {})",
            m.protocol,
            m.protocol_file,
            sha256
                .as_deref()
                .map_or("—".into(), |h| h[..12].to_string())
        ),
    );
    row("status", status_text);
    row(
        "steps",
        format!(
            "{} of {} planned completed",
            m.steps_completed, m.steps_planned
        ),
    );
    row(
        "date",
        format!(
            "{} → {}",
            m.started_utc,
            m.ended_utc.as_deref().unwrap_or("not ended")
        ),
    );
    row("rig", rig);
    row("seed", m.seed.to_string());
    row("clock", m.clock.clone());
    row("gelrig", m.gelrig_version.clone());
    if !m.safety_events.is_empty() {
        row("safety events", m.safety_events.join("; "));
    }
    if !m.resumed.is_empty() {
        // One run in segments: each step's data is the segment's that completed it.
        row(
            "resumed",
            m.resumed
                .iter()
                .map(|s| {
                    format!(
                        "at step {} on {} (the previous segment {}{})",
                        s.from_step,
                        s.started_utc,
                        s.previous_status,
                        s.previous_message
                            .as_deref()
                            .map_or(String::new(), |w| format!(": {w}"))
                    )
                })
                .collect::<Vec<_>>()
                .join("; "),
        );
    }
    let json = json!({
        "dir": data.dir.display().to_string(),
        "protocol": m.protocol,
        "protocol_file": m.protocol_file,
        "protocol_sha256": sha256,
        "status": status,
        "reason": reason,
        "steps_planned": m.steps_planned,
        "steps_completed": m.steps_completed,
        "resumed_at_steps": m.resumed.iter().map(|s| s.from_step).collect::<Vec<_>>(),
        "started_utc": m.started_utc,
        "ended_utc": m.ended_utc,
        "gelrig_version": m.gelrig_version,
        "rig": m.rig,
        "simulated": simulated,
        "devices": m.devices.iter().map(|d| json!({"role": d.role, "identity": d.identity})).collect::<Vec<_>>(),
        "seed": m.seed,
        "clock": m.clock,
        "steps": data.steps.len(),
        "frames": data.frames.len(),
    });
    (md, json)
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}
