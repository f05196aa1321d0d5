//! A sweep's points: each named by its parameters, with its `--set` pairs and seed.

use crate::design::Params;
use crate::sweep::Sweep;

/// One point of a sweep.
#[derive(Debug, Clone, PartialEq)]
pub struct Point {
    /// Its place in the design, from 0.
    pub index: usize,
    /// Its name: the index and the parameters, safe for a file name
    /// (`0003_diameter-9.5mm_seed-2`); its run and folder carry it.
    pub name: String,
    /// The parameters that vary, in the design's order.
    pub params: Params,
    /// Every `--set` pair of its run: the sweep's fixed ones, then its own.
    pub set: Vec<String>,
    /// The simulated devices' seed (`seed:`, else 0 as `gelrig run`).
    pub seed: u64,
}

/// The longest name a point gets: its run's name (`gelrig run --name`), which a protocol
/// caps at 64 characters (a run directory adds a time stamp before it). The index keeps
/// names cut short apart.
const MAX_NAME: usize = 64;

/// The points of `sweep`, or the first parameter that cannot be a point's.
pub fn points(sweep: &Sweep) -> Result<Vec<Point>, String> {
    sweep
        .design
        .points()
        .into_iter()
        .enumerate()
        .map(|(index, params)| {
            let mut seed = 0;
            let mut set: Vec<String> = sweep
                .fixed
                .iter()
                .map(|(k, v)| format!("{k}={v}"))
                .collect();
            for (k, v) in &params {
                if k == "seed" {
                    seed = v.trim().parse::<u64>().map_err(|_| {
                        format!("point {index}: seed {v:?} is not a whole number ≥ 0")
                    })?;
                } else {
                    set.push(format!("{k}={v}"));
                }
            }
            Ok(Point {
                index,
                name: name(index, &params),
                params,
                set,
                seed,
            })
        })
        .collect()
}

/// A value as a name shows it: a mapping (`{shape: cylinder, diameter: 4 mm}`, kept as
/// JSON) by its values alone (`cylinder-4mm`), anything else as written.
fn value_text(v: &str) -> String {
    match serde_json::from_str::<serde_json::Value>(v) {
        Ok(serde_json::Value::Object(m)) => m
            .values()
            .map(|x| match x {
                serde_json::Value::String(s) => s.clone(),
                other => other.to_string(),
            })
            .collect::<Vec<_>>()
            .join("-"),
        _ => v.to_string(),
    }
}

/// `0003_diameter-9.5mm_seed-2`: the index, then each key's last part and its value.
fn name(index: usize, params: &Params) -> String {
    let mut name = format!("{index:04}");
    for (k, v) in params {
        let short = k.rsplit('.').next().unwrap_or(k);
        name.push('_');
        name.push_str(short);
        name.push('-');
        name.push_str(&value_text(v));
    }
    let safe: String = name
        .replace('%', "pct")
        .chars()
        .filter(|c| !c.is_whitespace())
        .map(|c| {
            if c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.') {
                c
            } else {
                '~'
            }
        })
        .take(MAX_NAME)
        .collect();
    safe
}
