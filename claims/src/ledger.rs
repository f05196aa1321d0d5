//! `claims.yaml`: every figure gelrig publishes — where the docs print it, the number, what
//! must hold of a re-measurement, the command that re-measures it and the test that guards
//! it — and the checks that need no measurement: each quote is still in its file, each
//! guard test still exists.

use std::collections::BTreeSet;
use std::path::Path;

use anyhow::{Context, Result, bail};
use serde::Deserialize;

/// The ledger file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct Ledger {
    pub(crate) claims: Vec<Claim>,
}

/// One published figure.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct Claim {
    pub(crate) id: String,
    pub(crate) what: String,
    pub(crate) docs: Vec<Quote>,
    pub(crate) value: f64,
    pub(crate) unit: String,
    #[serde(rename = "holds")]
    holds_spec: HoldsSpec,
    #[serde(default)]
    pub(crate) measure: Option<Measure>,
    #[serde(default)]
    pub(crate) quick: bool,
    pub(crate) guard: String,
    #[serde(default)]
    pub(crate) guard_tolerance: String,
    #[serde(default)]
    pub(crate) seeds: Option<String>,
}

/// Where the docs print the figure: `quote` is verbatim in `file`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct Quote {
    pub(crate) file: String,
    pub(crate) quote: String,
}

/// `holds:` as written: exactly one of its keys.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct HoldsSpec {
    at_most: Option<f64>,
    at_least: Option<f64>,
    within_rel: Option<f64>,
    within_abs: Option<f64>,
}

impl Claim {
    /// What a re-measurement must satisfy (checked to be exactly one when read).
    pub(crate) fn holds(&self) -> Holds {
        let h = &self.holds_spec;
        match (h.at_most, h.at_least, h.within_rel, h.within_abs) {
            (Some(x), None, None, None) => Holds::AtMost(x),
            (None, Some(x), None, None) => Holds::AtLeast(x),
            (None, None, Some(r), None) => Holds::WithinRel(r),
            (None, None, None, Some(a)) => Holds::WithinAbs(a),
            // Refused by `Ledger::read`; nothing can hold.
            _ => Holds::AtMost(f64::NEG_INFINITY),
        }
    }
}

/// What a re-measurement must satisfy.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Holds {
    /// At most this (a target such as "≤ 0.5 ms").
    AtMost(f64),
    /// At least this ("≥ 10×").
    AtLeast(f64),
    /// Within this fraction of the published value (a measured figure that may drift).
    WithinRel(f64),
    /// Within this of the published value, in its unit.
    WithinAbs(f64),
}

impl Holds {
    /// Whether `measured` satisfies this for a figure published as `value`.
    pub(crate) fn check(self, value: f64, measured: f64) -> bool {
        match self {
            Holds::AtMost(x) => measured <= x,
            Holds::AtLeast(x) => measured >= x,
            Holds::WithinRel(r) => (measured - value).abs() <= r * value.abs(),
            Holds::WithinAbs(a) => (measured - value).abs() <= a,
        }
    }

    /// As the docs would write it.
    pub(crate) fn describe(self, unit: &str) -> String {
        match self {
            Holds::AtMost(x) => format!("≤ {x} {unit}"),
            Holds::AtLeast(x) => format!("≥ {x} {unit}"),
            Holds::WithinRel(r) => format!("± {} %", 100.0 * r),
            Holds::WithinAbs(a) => format!("± {a} {unit}"),
        }
    }
}

/// How to re-measure: a shell command run from the repository's root, and the pattern
/// whose first group is the number (times `scale`, into the claim's unit).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct Measure {
    pub(crate) command: String,
    pub(crate) pattern: String,
    #[serde(default)]
    pub(crate) scale: Option<f64>,
    /// The longest the command may take, s (default 1800).
    #[serde(default)]
    pub(crate) timeout_s: Option<u64>,
}

impl Ledger {
    /// Reads and parses `path`, naming the place of any error.
    pub(crate) fn read(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("{}: cannot read the ledger", path.display()))?;
        let ledger: Ledger = serde_yaml::from_str(&text)
            .with_context(|| format!("{}: not a claims ledger", path.display()))?;
        let mut ids = BTreeSet::new();
        for c in &ledger.claims {
            if !ids.insert(c.id.as_str()) {
                bail!("{}: the id `{}` is used twice", path.display(), c.id);
            }
            let h = &c.holds_spec;
            let given = [h.at_most, h.at_least, h.within_rel, h.within_abs];
            if given.iter().flatten().count() != 1 {
                bail!(
                    "{}: claim `{}`: `holds` needs exactly one of at_most, at_least, within_rel, within_abs",
                    path.display(),
                    c.id
                );
            }
            if let Some(m) = &c.measure {
                regex::Regex::new(&m.pattern).with_context(|| {
                    format!("{}: claim `{}`: its pattern", path.display(), c.id)
                })?;
            }
        }
        Ok(ledger)
    }
}

/// The problems that need no measurement: a quote no longer in its file (the text drifted
/// from the ledger), a guard test that no longer exists, a claim with no docs.
pub(crate) fn static_problems(ledger: &Ledger, root: &Path) -> Vec<String> {
    let mut problems = Vec::new();
    for c in &ledger.claims {
        if c.docs.is_empty() {
            problems.push(format!("{}: no place in the docs prints it", c.id));
        }
        for q in &c.docs {
            match std::fs::read_to_string(root.join(&q.file)) {
                Ok(text) if text.contains(&q.quote) => {}
                Ok(_) => problems.push(format!(
                    "{}: {} no longer says {:?}: update the ledger or the text",
                    c.id, q.file, q.quote
                )),
                Err(e) => problems.push(format!("{}: {}: {e}", c.id, q.file)),
            }
        }
        if let Some(problem) = guard_problem(&c.guard, root) {
            problems.push(format!("{}: {problem}", c.id));
        }
    }
    problems
}

/// `file::fn` names a test function in that file, or the guard is "benchmark only".
fn guard_problem(guard: &str, root: &Path) -> Option<String> {
    if guard == "benchmark only" {
        return None;
    }
    let Some((file, func)) = guard.rsplit_once("::") else {
        return Some(format!(
            "guard `{guard}`: write `path/to/file.rs::test_fn` or `benchmark only`"
        ));
    };
    match std::fs::read_to_string(root.join(file)) {
        Ok(text) if text.contains(&format!("fn {func}(")) => None,
        Ok(_) => Some(format!("guard `{guard}`: no `fn {func}(` in {file}")),
        Err(e) => Some(format!("guard `{guard}`: {file}: {e}")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn holds_checks_each_kind() {
        assert!(Holds::AtMost(0.5).check(0.44, 0.5));
        assert!(!Holds::AtMost(0.5).check(0.44, 0.51));
        assert!(Holds::AtLeast(10.0).check(19.0, 10.0));
        assert!(!Holds::AtLeast(10.0).check(19.0, 9.9));
        assert!(Holds::WithinRel(0.1).check(2.0, 2.19));
        assert!(!Holds::WithinRel(0.1).check(2.0, 2.21));
        assert!(Holds::WithinAbs(0.01).check(0.14, 0.149));
        assert!(!Holds::WithinAbs(0.01).check(0.14, 0.151));
    }

    #[test]
    fn a_drifted_quote_and_a_missing_guard_are_named() {
        let dir = std::env::temp_dir().join(format!("claims-test-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("tests")).expect("test setup");
        std::fs::write(dir.join("README.md"), "within **0.14 %** of range\n").expect("test setup");
        std::fs::write(dir.join("tests/a.rs"), "#[test]\nfn guards_it() {}\n").expect("test setup");
        let ledger: Ledger = serde_yaml::from_str(
            "claims:\n\
             - {id: ok, what: w, docs: [{file: README.md, quote: \"**0.14 %**\"}], value: 0.14, unit: '%', holds: {at_most: 0.2}, guard: 'tests/a.rs::guards_it'}\n\
             - {id: drifted, what: w, docs: [{file: README.md, quote: \"**0.12 %**\"}], value: 0.12, unit: '%', holds: {at_most: 0.2}, guard: 'tests/a.rs::renamed'}\n",
        )
        .expect("test setup");
        let problems = static_problems(&ledger, &dir);
        assert_eq!(problems.len(), 2, "{problems:?}");
        assert!(problems[0].starts_with("drifted: README.md no longer says"));
        assert!(problems[1].contains("no `fn renamed(` in tests/a.rs"));
        let _ = std::fs::remove_dir_all(&dir);
    }
}
