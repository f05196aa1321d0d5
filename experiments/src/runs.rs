//! `gelrig runs`: what is in a runs directory, and which runs were cut short.

use std::path::{Path, PathBuf};

use rundir::write::{Status, is_locked, read_manifest};

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

/// Lists the runs in `root`, oldest first.
pub fn list(root: &Path) -> Result<Vec<RunSummary>, String> {
    let entries =
        std::fs::read_dir(root).map_err(|e| format!("cannot list {}: {e}", root.display()))?;
    let mut dirs: Vec<PathBuf> = entries
        .filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| p.join("run.yaml").is_file())
        .collect();
    dirs.sort();
    Ok(dirs
        .into_iter()
        .map(|dir| match read_manifest(&dir) {
            Ok(m) => {
                let simulated = !m.devices.is_empty()
                    && m.devices
                        .iter()
                        .all(|d| d.identity.starts_with("simulated"));
                let at = |s: &str| s.parse::<jiff::Timestamp>().ok();
                let duration_s = m
                    .ended_utc
                    .as_deref()
                    .and_then(at)
                    .zip(at(&m.started_utc))
                    .map(|(end, start)| {
                        (end.as_nanosecond() - start.as_nanosecond()) as f64 * 1e-9
                    });
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
