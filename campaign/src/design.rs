//! How a sweep lays out its points: every combination of listed values (`grid`), points
//! named one by one (`list`), or `n` points drawn from ranges — independently (`random`) or
//! one in each of `n` equal strata of every parameter, the strata paired at random
//! (`latin_hypercube`: McKay, Beckman & Conover, Technometrics 21(2), 1979). Draws use
//! ChaCha8 seeded by the design's own seed, so a design is the same on every machine.

use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde_yaml::Value;

use crate::sweep::{scalar, value_text};

/// One point's parameters, in the design's order: (key, value as text).
pub type Params = Vec<(String, String)>;

/// A sweep's design.
#[derive(Debug, Clone, PartialEq)]
pub enum Design {
    /// Each key's values; every combination, the last key varying fastest.
    Grid(Vec<(String, Vec<String>)>),
    /// The points as given.
    List(Vec<Params>),
    /// `n` points, each parameter drawn uniformly from its range.
    Random {
        /// Points.
        n: usize,
        /// The draws' seed.
        seed: u64,
        /// Each key's range.
        ranges: Vec<(String, Range)>,
    },
    /// `n` points, one in each of `n` strata of every range.
    LatinHypercube {
        /// Points.
        n: usize,
        /// The draws' seed.
        seed: u64,
        /// Each key's range.
        ranges: Vec<(String, Range)>,
    },
}

/// A range `{from: 5 mm, to: 10 mm}`: numbers with one unit; whole numbers on both ends and
/// no unit draw whole numbers (seeds, counts).
#[derive(Debug, Clone, PartialEq)]
pub struct Range {
    /// Lower end.
    pub from: f64,
    /// Upper end.
    pub to: f64,
    /// The unit as written after the number (`mm`, `mm/s`), or empty.
    pub unit: String,
    /// Draw whole numbers.
    pub integer: bool,
}

/// The most points a design may have: a guard against a typo that would queue millions.
pub const MAX_POINTS: usize = 1_000_000;

type ParseErr = (String, String);

impl Range {
    /// `7.5 mm` → (7.5, "mm"); `3` → (3, "").
    pub fn quantity(text: &str) -> Option<(f64, String)> {
        let t = text.trim();
        let split = t
            .char_indices()
            .find(|(_, c)| !(c.is_ascii_digit() || matches!(c, '.' | '-' | '+' | 'e' | 'E')))
            .map_or(t.len(), |(i, _)| i);
        // `e` could begin a unit (`em`): back off while the number does not parse.
        let mut end = split;
        while end > 0 {
            if let Ok(v) = t[..end].parse::<f64>() {
                return v.is_finite().then(|| (v, t[end..].trim().to_string()));
            }
            end -= 1;
        }
        None
    }

    fn parse(v: &Value) -> Result<Self, String> {
        let Value::Mapping(m) = v else {
            return Err("a range is {from: A, to: B}".into());
        };
        let end = |k: &str| -> Result<(f64, String, bool), String> {
            let text = m
                .get(Value::String(k.into()))
                .and_then(scalar)
                .ok_or_else(|| format!("the range needs {k}:"))?;
            let (n, unit) =
                Self::quantity(&text).ok_or_else(|| format!("{k}: {text:?} is not a number"))?;
            let whole = unit.is_empty() && !text.contains('.') && n.fract() == 0.0;
            Ok((n, unit, whole))
        };
        let (from, u1, w1) = end("from")?;
        let (to, u2, w2) = end("to")?;
        if u1 != u2 {
            return Err(format!(
                "from is in {u1:?}, to in {u2:?}: give both in one unit"
            ));
        }
        if to <= from {
            return Err(format!("to ({to}) must exceed from ({from})"));
        }
        Ok(Self {
            from,
            to,
            unit: u1,
            integer: w1 && w2,
        })
    }

    /// The value at `u` ∈ [0, 1) of the range, as text.
    fn at(&self, u: f64) -> String {
        if self.integer {
            // Whole numbers from..=to, each equally likely.
            let span = self.to - self.from + 1.0;
            let v = (self.from + (u * span).floor()).min(self.to);
            return format!("{v:.0}");
        }
        let v = self.from + u * (self.to - self.from);
        // Six significant figures: the value a run records and a name shows.
        let text = format!("{:.6}", v);
        let text = text.trim_end_matches('0').trim_end_matches('.');
        if self.unit.is_empty() {
            text.to_string()
        } else {
            format!("{text} {}", self.unit)
        }
    }
}

impl Design {
    /// Parses the design named `kind` (`grid`, `list`, `random`, `latin_hypercube`);
    /// errors carry the key path below the design (`.indenter.diameter`) and what is wrong.
    pub(crate) fn parse(kind: &str, v: &Value) -> Result<Self, ParseErr> {
        let here = |detail: &str| (String::new(), detail.to_string());
        match kind {
            "grid" => {
                let Value::Mapping(m) = v else {
                    return Err(here("a grid maps each key to a list of values"));
                };
                let mut axes = Vec::new();
                for (k, vals) in m {
                    let key = scalar(k).unwrap_or_default();
                    let at = |d: &str| (format!(".{key}"), d.to_string());
                    let values: Vec<String> = match vals {
                        Value::Sequence(s) if !s.is_empty() => s
                            .iter()
                            .map(|x| value_text(x).ok_or_else(|| at("each value a value")))
                            .collect::<Result<_, _>>()?,
                        Value::Sequence(_) => return Err(at("an empty list")),
                        other => vec![value_text(other).ok_or_else(|| at("a list of values"))?],
                    };
                    axes.push((key, values));
                }
                if axes.is_empty() {
                    return Err(here("an empty grid"));
                }
                let count = axes
                    .iter()
                    .try_fold(1usize, |n, (_, v)| n.checked_mul(v.len()))
                    .filter(|n| *n <= MAX_POINTS);
                if count.is_none() {
                    return Err(here(&format!("more than {MAX_POINTS} points")));
                }
                Ok(Design::Grid(axes))
            }
            "list" => {
                let Value::Sequence(s) = v else {
                    return Err(here("a list of points, each a mapping KEY: VALUE"));
                };
                let mut points = Vec::new();
                for (i, p) in s.iter().enumerate() {
                    let Value::Mapping(m) = p else {
                        return Err((format!(".{i}"), "a point is a mapping KEY: VALUE".into()));
                    };
                    let mut params = Vec::new();
                    for (k, v) in m {
                        let key = scalar(k).unwrap_or_default();
                        let value = value_text(v)
                            .ok_or_else(|| (format!(".{i}.{key}"), "a value".to_string()))?;
                        params.push((key, value));
                    }
                    points.push(params);
                }
                if points.is_empty() {
                    return Err(here("an empty list"));
                }
                Ok(Design::List(points))
            }
            _ => {
                let Value::Mapping(m) = v else {
                    return Err(here("{n: N, seed: S, parameters: {KEY: {from: A, to: B}}}"));
                };
                let get = |k: &str| m.get(Value::String(k.into()));
                let n = get("n")
                    .and_then(Value::as_u64)
                    .filter(|n| (1..=MAX_POINTS as u64).contains(n))
                    .ok_or_else(|| {
                        (
                            ".n".to_string(),
                            format!("the number of points, 1 to {MAX_POINTS}"),
                        )
                    })? as usize;
                let seed = get("seed").and_then(Value::as_u64).ok_or_else(|| {
                    (
                        ".seed".to_string(),
                        "the design's own seed, a whole number".into(),
                    )
                })?;
                let Some(Value::Mapping(ps)) = get("parameters") else {
                    return Err((
                        ".parameters".into(),
                        "each key's range {from: A, to: B}".into(),
                    ));
                };
                let mut ranges = Vec::new();
                for (k, r) in ps {
                    let key = scalar(k).unwrap_or_default();
                    let range = Range::parse(r).map_err(|d| (format!(".parameters.{key}"), d))?;
                    ranges.push((key, range));
                }
                if ranges.is_empty() {
                    return Err((".parameters".into(), "no parameters".into()));
                }
                Ok(if kind == "random" {
                    Design::Random { n, seed, ranges }
                } else {
                    Design::LatinHypercube { n, seed, ranges }
                })
            }
        }
    }

    /// The points, in the design's order.
    pub fn points(&self) -> Vec<Params> {
        match self {
            Design::Grid(axes) => {
                let total: usize = axes.iter().map(|(_, v)| v.len()).product();
                (0..total)
                    .map(|mut k| {
                        let mut p: Params = Vec::with_capacity(axes.len());
                        for (key, values) in axes.iter().rev() {
                            p.push((key.clone(), values[k % values.len()].clone()));
                            k /= values.len();
                        }
                        p.reverse();
                        p
                    })
                    .collect()
            }
            Design::List(points) => points.clone(),
            Design::Random { n, seed, ranges } => {
                let mut rng = ChaCha8Rng::seed_from_u64(*seed);
                (0..*n)
                    .map(|_| {
                        ranges
                            .iter()
                            .map(|(k, r)| (k.clone(), r.at(rng.random::<f64>())))
                            .collect()
                    })
                    .collect()
            }
            Design::LatinHypercube { n, seed, ranges } => {
                let mut rng = ChaCha8Rng::seed_from_u64(*seed);
                let columns: Vec<Vec<String>> = ranges
                    .iter()
                    .map(|(_, r)| {
                        let mut strata: Vec<usize> = (0..*n).collect();
                        strata.shuffle(&mut rng);
                        strata
                            .into_iter()
                            .map(|s| r.at((s as f64 + rng.random::<f64>()) / *n as f64))
                            .collect()
                    })
                    .collect();
                (0..*n)
                    .map(|i| {
                        ranges
                            .iter()
                            .zip(&columns)
                            .map(|((k, _), col)| (k.clone(), col[i].clone()))
                            .collect()
                    })
                    .collect()
            }
        }
    }
}
