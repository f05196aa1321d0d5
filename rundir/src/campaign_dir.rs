//! A campaign folder (`gelrig sweep`) as a collection of runs: its `campaign.csv` names each
//! point's run directory and parameters (the columns between `name` and `status`), which
//! `gelrig export --format parquet` adds to every table as columns.

use std::path::{Path, PathBuf};

/// One completed point: its run directory and parameters as (column, value).
pub type CampaignRun = (PathBuf, Vec<(String, String)>);

/// The completed runs of the campaign at `root`, in point order; `None` when `root` has no
/// `campaign.csv` (it is not a campaign), `Err` when the file cannot be read as one.
pub fn campaign_runs(root: &Path) -> Option<Result<Vec<CampaignRun>, String>> {
    let path = root.join("campaign.csv");
    if !path.is_file() {
        return None;
    }
    Some(read(root, &path))
}

fn read(root: &Path, path: &Path) -> Result<Vec<CampaignRun>, String> {
    let bad = |d: String| {
        format!(
            "{}: {d}; fix: write it again with gelrig sweep --merge",
            path.display()
        )
    };
    let mut r = csv::Reader::from_path(path).map_err(|e| bad(e.to_string()))?;
    let header: Vec<String> = r
        .headers()
        .map_err(|e| bad(e.to_string()))?
        .iter()
        .map(String::from)
        .collect();
    let at = |name: &str| header.iter().position(|h| h == name);
    let (Some(name), Some(status), Some(run_dir)) = (at("name"), at("status"), at("run_dir"))
    else {
        return Err(bad("no name, status or run_dir column".into()));
    };
    let params: Vec<(usize, String)> = ((name + 1)..status)
        .map(|i| (i, header[i].clone()))
        .collect();
    let mut runs = Vec::new();
    for rec in r.records() {
        let rec = rec.map_err(|e| bad(e.to_string()))?;
        if rec.get(status) != Some("completed") {
            continue;
        }
        let dir = root.join(rec.get(run_dir).unwrap_or_default());
        let values = params
            .iter()
            .map(|(i, k)| (k.clone(), rec.get(*i).unwrap_or_default().to_string()))
            .collect();
        runs.push((dir, values));
    }
    Ok(runs)
}

/// Parameter columns for tables: a parameter whose values are all numbers with one unit
/// (`6 mm`, `9.5 mm`) becomes a number column named with its unit (`indenter.diameter_mm`);
/// any other stays text under its own name.
pub fn parameter_columns(runs: &[CampaignRun]) -> Vec<(String, Vec<String>)> {
    let Some((_, first)) = runs.first() else {
        return Vec::new();
    };
    first
        .iter()
        .enumerate()
        .map(|(i, (key, _))| {
            let values: Vec<&str> = runs
                .iter()
                .map(|(_, p)| p.get(i).map_or("", |v| v.1.as_str()))
                .collect();
            let split: Vec<Option<(f64, String)>> =
                values.iter().map(|v| number_and_unit(v)).collect();
            let unit = split.first().cloned().flatten().map(|(_, u)| u);
            match unit {
                Some(u)
                    if split
                        .iter()
                        .all(|s| s.as_ref().is_some_and(|(_, su)| *su == u)) =>
                {
                    let name = if u.is_empty() {
                        key.clone()
                    } else {
                        format!("{key}_{}", u.replace('/', "_per_").replace('%', "pct"))
                    };
                    (
                        name,
                        split
                            .into_iter()
                            .map(|s| s.map(|(n, _)| n.to_string()).unwrap_or_default())
                            .collect(),
                    )
                }
                _ => (key.clone(), values.iter().map(|v| v.to_string()).collect()),
            }
        })
        .collect()
}

fn number_and_unit(v: &str) -> Option<(f64, String)> {
    let t = v.trim();
    let end = t
        .char_indices()
        .find(|(_, c)| !(c.is_ascii_digit() || matches!(c, '.' | '-' | '+')))
        .map_or(t.len(), |(i, _)| i);
    let n = t[..end].parse::<f64>().ok().filter(|n| n.is_finite())?;
    Some((n, t[end..].trim().to_string()))
}
