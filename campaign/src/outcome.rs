//! The campaign folder and each point's outcome.
//!
//! ```text
//! CAMPAIGN/sweep.yaml            the sweep file as run
//! CAMPAIGN/points.csv            every point: index, name, seed, its parameters
//! CAMPAIGN/points/NAME/          the point's run directory (<time>_NAME), log.txt, outcome.yaml
//! CAMPAIGN/campaign.csv          every point's outcome with its parameters as columns
//! ```
//!
//! `outcome.yaml` is written (atomically) when a point's run ends: a point whose outcome says
//! `completed` and whose run directory is there is never run again; a failed one is run again
//! on the next invocation, its old run directory left in place.

use std::fs;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::CampaignError;
use crate::point::Point;

/// How a point's run ended.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Outcome {
    /// The point's name.
    pub name: String,
    /// The point's parameters (as the sweep file gives them) and seed: what its run was.
    #[serde(default)]
    pub parameters: std::collections::BTreeMap<String, String>,
    /// `completed` or `failed`.
    pub status: String,
    /// The run's exit code (2: refused, 1: stopped or failed, a signal: none).
    pub exit_code: Option<i32>,
    /// Why it failed: the run's last line on stderr.
    #[serde(default)]
    pub message: String,
    /// Wall time, s.
    pub wall_s: f64,
    /// The run directory, relative to the campaign folder.
    pub run_dir: Option<String>,
}

/// A campaign folder.
#[derive(Debug, Clone)]
pub struct Campaign {
    /// The folder.
    pub dir: PathBuf,
}

fn io(path: &Path) -> impl Fn(std::io::Error) -> CampaignError + '_ {
    move |e| CampaignError::Write {
        path: path.to_path_buf(),
        detail: e.to_string(),
    }
}

/// Writes `bytes` to `path` through a temporary file and a rename, so a reader never sees
/// half a file (a job killed mid-write leaves the old one). The temporary file is this
/// process's own: shards of a job array write `campaign.csv` at the same time.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), CampaignError> {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = path.with_file_name(format!(".{name}.{}.tmp", std::process::id()));
    fs::write(&tmp, bytes).map_err(io(&tmp))?;
    fs::rename(&tmp, path).map_err(io(path))
}

impl Campaign {
    /// The point's folder.
    pub fn point_dir(&self, p: &Point) -> PathBuf {
        self.dir.join("points").join(&p.name)
    }

    /// Creates the folder, `sweep.yaml` (the file as run) and `points.csv`. A folder holding
    /// another sweep's points is refused: its runs would be taken for this one's.
    pub fn create(&self, sweep_text: &str, points: &[Point]) -> Result<(), CampaignError> {
        fs::create_dir_all(self.dir.join("points")).map_err(io(&self.dir))?;
        let copy = self.dir.join("sweep.yaml");
        if let Ok(old) = fs::read_to_string(&copy)
            && old != sweep_text
        {
            let listed = self.dir.join("points.csv");
            let same_points = fs::read_to_string(&listed).is_ok_and(|t| t == points_csv(points));
            if !same_points {
                return Err(CampaignError::Other(format!(
                    "{} holds a campaign of another sweep (its sweep.yaml differs and so do its \
                     points); fix: give another --out, or remove the folder",
                    self.dir.display()
                )));
            }
        }
        write_atomic(&copy, sweep_text.as_bytes())?;
        write_atomic(&self.dir.join("points.csv"), points_csv(points).as_bytes())
    }

    /// The point's outcome, if its run has ended.
    pub fn outcome(&self, p: &Point) -> Option<Outcome> {
        let text = fs::read_to_string(self.point_dir(p).join("outcome.yaml")).ok()?;
        serde_yaml::from_str(&text).ok()
    }

    /// Whether the point completed and its run directory is there.
    pub fn done(&self, p: &Point) -> bool {
        self.outcome(p).is_some_and(|o| {
            o.status == "completed" && o.run_dir.is_some_and(|d| self.dir.join(d).is_dir())
        })
    }

    /// Records how the point's run ended.
    pub fn record(&self, p: &Point, o: &Outcome) -> Result<(), CampaignError> {
        let path = self.point_dir(p).join("outcome.yaml");
        let text = serde_yaml::to_string(o).map_err(|e| CampaignError::Other(e.to_string()))?;
        write_atomic(&path, text.as_bytes())
    }

    /// The newest run directory in the point's folder, relative to the campaign folder.
    pub fn run_dir_of(&self, p: &Point) -> Option<String> {
        let dir = self.point_dir(p);
        let mut runs: Vec<String> = fs::read_dir(&dir)
            .ok()?
            .filter_map(|e| e.ok())
            .filter(|e| e.path().join("run.yaml").is_file())
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .collect();
        runs.sort();
        runs.pop().map(|r| format!("points/{}/{r}", p.name))
    }

    /// `campaign.csv`: every point with its parameters as columns, its status (`completed`,
    /// `failed`, or `not run`), run directory, wall time and message. Returns the counts
    /// (completed, failed, not run).
    pub fn write_table(&self, points: &[Point]) -> Result<(usize, usize, usize), CampaignError> {
        let mut keys: Vec<String> = Vec::new();
        for p in points {
            for (k, _) in &p.params {
                if !keys.contains(k) {
                    keys.push(k.clone());
                }
            }
        }
        let mut w = csv::Writer::from_writer(Vec::new());
        let mut header = vec!["point".to_string(), "name".into()];
        header.extend(keys.iter().cloned());
        header.extend(["status", "run_dir", "wall_s", "exit_code", "message"].map(String::from));
        let csv_err = |e: csv::Error| CampaignError::Other(e.to_string());
        w.write_record(&header).map_err(csv_err)?;
        let mut counts = (0, 0, 0);
        for p in points {
            let o = self.outcome(p);
            let status = match &o {
                Some(o) if o.status == "completed" && self.done(p) => {
                    counts.0 += 1;
                    "completed"
                }
                Some(_) => {
                    counts.1 += 1;
                    "failed"
                }
                None => {
                    counts.2 += 1;
                    "not run"
                }
            };
            let mut row = vec![p.index.to_string(), p.name.clone()];
            for k in &keys {
                row.push(
                    p.params
                        .iter()
                        .find(|(pk, _)| pk == k)
                        .map(|(_, v)| v.clone())
                        .unwrap_or_default(),
                );
            }
            row.push(status.into());
            row.push(
                o.as_ref()
                    .and_then(|o| o.run_dir.clone())
                    .unwrap_or_default(),
            );
            row.push(
                o.as_ref()
                    .map(|o| format!("{:.2}", o.wall_s))
                    .unwrap_or_default(),
            );
            row.push(
                o.as_ref()
                    .and_then(|o| o.exit_code)
                    .map(|c| c.to_string())
                    .unwrap_or_default(),
            );
            row.push(o.map(|o| o.message).unwrap_or_default());
            w.write_record(&row).map_err(csv_err)?;
        }
        let bytes = w
            .into_inner()
            .map_err(|e| CampaignError::Other(e.to_string()))?;
        write_atomic(&self.dir.join("campaign.csv"), &bytes)?;
        Ok(counts)
    }
}

/// `points.csv`: index, name, seed, and the parameters as `key=value` pairs.
fn points_csv(points: &[Point]) -> String {
    let mut out = String::from("point,name,seed,parameters\n");
    for p in points {
        let params: Vec<String> = p.params.iter().map(|(k, v)| format!("{k}={v}")).collect();
        out.push_str(&format!(
            "{},{},{},\"{}\"\n",
            p.index,
            p.name,
            p.seed,
            params.join("; ").replace('"', "\"\"")
        ));
    }
    out
}
