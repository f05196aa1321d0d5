//! What is in a runs directory, and which runs were cut short (`gelrig runs`).

use std::path::{Path, PathBuf};

use crate::manifest::{Status, is_locked, read_manifest};

/// What `gelrig runs` shows for one run.
#[derive(Debug, Clone, PartialEq)]
pub struct RunSummary {
    /// Run directory.
    pub dir: PathBuf,
    /// Protocol name.
    pub protocol: String,
    /// completed, aborted, failed, running, interrupted, or unreadable.
    pub status: String,
    /// Start time.
    pub started: String,
    /// Steps done / planned.
    pub steps: String,
    /// Abort reason or error.
    pub note: String,
    /// Wall time from start to end, s (`None` while running or when unknown).
    pub duration_s: Option<f64>,
    /// The seed of its simulated devices.
    pub seed: Option<u64>,
    /// The rig: its name, and `simulated` when every device that ran was.
    pub rig: String,
}

/// The status a manifest and its lock imply: a `running` manifest whose lock no process
/// holds belongs to a run that was killed.
pub fn effective_status(dir: &Path, status: Status) -> &'static str {
    match status {
        Status::Running if !is_locked(dir) => "interrupted",
        s => s.name(),
    }
}

/// Wall time the run spent running, s: from start to end, less the time between a
/// segment's end and the resume that followed it (`None` while running or when unknown).
fn run_time_s(m: &crate::manifest::Manifest) -> Option<f64> {
    let at = |s: &str| s.parse::<jiff::Timestamp>().ok();
    let span = |start: &str, end: &str| -> Option<f64> {
        Some((at(end)?.as_nanosecond() - at(start)?.as_nanosecond()) as f64 / 1e9)
    };
    let mut total = 0.0;
    let mut start = m.started_utc.as_str();
    for seg in &m.resumed {
        // An old manifest without the segment's end counts the pause, as before.
        let end = seg
            .previous_ended_utc
            .as_deref()
            .unwrap_or(&seg.started_utc);
        total += span(start, end)?.max(0.0);
        start = &seg.started_utc;
    }
    Some(total + span(start, m.ended_utc.as_deref()?)?.max(0.0))
}

/// Lists the runs in `root`, oldest first.
pub fn list(root: &Path) -> Result<Vec<RunSummary>, String> {
    let entries =
        std::fs::read_dir(root).map_err(|e| format!("cannot list {}: {e}", root.display()))?;
    let mut dirs: Vec<PathBuf> = entries
        .filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| p.join(crate::names::MANIFEST).is_file())
        .collect();
    // A sweep's campaign keeps each point's runs in points/<point>/.
    if let Ok(points) = std::fs::read_dir(root.join("points")) {
        for point in points.filter_map(Result::ok) {
            if let Ok(runs) = std::fs::read_dir(point.path()) {
                dirs.extend(
                    runs.filter_map(Result::ok)
                        .map(|e| e.path())
                        .filter(|p| p.join(crate::names::MANIFEST).is_file()),
                );
            }
        }
    }
    dirs.sort();
    Ok(dirs
        .into_iter()
        .map(|dir| match read_manifest(&dir) {
            Ok(m) => {
                let simulated = !m.devices.is_empty()
                    && m.devices
                        .iter()
                        .all(|d| d.identity.starts_with("simulated"));
                let duration_s = run_time_s(&m);
                RunSummary {
                    status: effective_status(&dir, m.status).to_string(),
                    protocol: m.protocol,
                    started: m.started_utc,
                    steps: format!("{}/{}", m.steps_completed, m.steps_planned),
                    note: {
                        let why = m.reason.or(m.error).unwrap_or_default();
                        match m.resumed.len() {
                            0 => why,
                            n => format!(
                                "resumed {n}× (at step {}){}{why}",
                                m.resumed
                                    .iter()
                                    .map(|s| s.from_step.to_string())
                                    .collect::<Vec<_>>()
                                    .join(", "),
                                if why.is_empty() { "" } else { "; " }
                            ),
                        }
                    },
                    duration_s,
                    seed: Some(m.seed),
                    rig: if simulated {
                        format!("{} (simulated)", m.rig)
                    } else {
                        m.rig
                    },
                    dir,
                }
            }
            Err(e) => RunSummary {
                dir,
                protocol: String::new(),
                status: "unreadable".into(),
                started: String::new(),
                steps: String::new(),
                note: e,
                duration_s: None,
                seed: None,
                rig: String::new(),
            },
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::manifest::{Manifest, Segment};

    #[test]
    fn a_resumed_runs_duration_leaves_out_the_time_it_was_down() {
        let text = "status: completed\nprotocol: p\nprotocol_file: p.yaml\nrig: r\n\
                    rig_file: r.yaml\nstarted_utc: 2026-11-26T10:00:00Z\ngelrig_version: v\n\
                    seed: 0\nclock: monotonic\npid: 1\nsteps_planned: 4\nsteps_completed: 4\n\
                    eta_s: [1.0, 2.0]\nended_utc: 2026-11-26T11:05:00Z\n";
        let mut m: Manifest = serde_yaml::from_str(text).expect("a minimal manifest");
        assert_eq!(run_time_s(&m), Some(3900.0), "one segment: start to end");
        let segment = |started: &str, ended: Option<&str>| Segment {
            started_utc: started.into(),
            t_start_ns: 0,
            from_step: 2,
            pid: 2,
            previous_status: "interrupted".into(),
            previous_message: None,
            previous_ended_utc: ended.map(String::from),
        };
        // Killed at 10:10 (its last write), resumed at 11:00, ended at 11:05.
        m.resumed = vec![segment(
            "2026-11-26T11:00:00Z",
            Some("2026-11-26T10:10:00Z"),
        )];
        assert_eq!(run_time_s(&m), Some(900.0));
        // An older manifest without the end counts the pause.
        m.resumed = vec![segment("2026-11-26T11:00:00Z", None)];
        assert_eq!(run_time_s(&m), Some(3900.0));
        // Still running: unknown.
        m.ended_utc = None;
        assert_eq!(run_time_s(&m), None);
    }
}
