//! The comparison of a run: one row per measured claim, printed as it goes and written as
//! the Markdown table BENCHMARKS links to, with the date and commit it was measured at.

use std::fmt::Write;
use std::path::Path;

use crate::ledger::{Claim, Ledger};
use crate::measure::Measured;

/// A measured claim.
pub(crate) struct Row {
    id: String,
    published: String,
    holds: String,
    measured: Result<f64, String>,
    ok: bool,
    seconds: f64,
    log: String,
}

impl Row {
    pub(crate) fn new(c: &Claim, m: Measured) -> Self {
        let ok = m.value.as_ref().is_ok_and(|v| c.holds().check(c.value, *v));
        Self {
            id: c.id.clone(),
            published: format!("{} {}", c.value, c.unit),
            holds: c.holds().describe(&c.unit),
            measured: m.value.map_err(|e| format!("{e:#}")),
            ok,
            seconds: m.seconds,
            log: m.log.display().to_string(),
        }
    }

    pub(crate) fn passed(&self) -> bool {
        self.ok
    }

    fn measured_text(&self) -> String {
        match &self.measured {
            Ok(v) if *v != 0.0 && v.abs() < 1e-3 => format!("{v:.3e}"),
            Ok(v) => format!("{v:.4}"),
            Err(e) => format!("error: {e}"),
        }
    }

    fn verdict(&self) -> &'static str {
        if self.ok { "holds" } else { "DOES NOT HOLD" }
    }

    /// One line for the terminal.
    pub(crate) fn line(&self) -> String {
        format!(
            "{}: published {}, measured {}, must be {}: {} ({:.0} s; output in {})",
            self.id,
            self.published,
            self.measured_text(),
            self.holds,
            self.verdict(),
            self.seconds,
            self.log
        )
    }
}

/// The Markdown of a run: every claim of the ledger, measured or guarded.
pub(crate) fn markdown(ledger: &Ledger, rows: &[Row], root: &Path, invocation: &str) -> String {
    let commit = std::process::Command::new("git")
        .args(["rev-parse", "--short", "HEAD"])
        .current_dir(root)
        .output()
        .ok()
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
        .unwrap_or_default();
    let date = jiff::Zoned::now().strftime("%Y-%m-%d %H:%M %Z").to_string();
    let mut s = String::new();
    let _ = writeln!(s, "# Claims, re-measured\n");
    let measured = rows.len();
    let _ = writeln!(
        s,
        "Written by `{invocation}` on {date} at commit `{commit}` from the ledger \
         [`claims.yaml`](../../claims.yaml): {} figures, {measured} of them re-measured in this \
         run. Each row gives the figure as published, what a re-measurement must satisfy, and \
         the test that guards it with what that test asserts — where a test asserts a looser \
         bound than the published figure, this column says so. `--all` re-measures every \
         figure that has a command.\n",
        ledger.claims.len()
    );
    let _ = writeln!(
        s,
        "| claim | published | must be | measured | verdict | guarded by (asserts) | seeds |\n|---|---|---|---|---|---|---|"
    );
    for c in &ledger.claims {
        let row = rows.iter().find(|r| r.id == c.id);
        let (measured, verdict) = match row {
            Some(r) => (r.measured_text(), r.verdict().to_string()),
            None => ("—".into(), "not re-measured".into()),
        };
        let guard = if c.guard_tolerance.is_empty() {
            format!("`{}`", c.guard)
        } else {
            format!("`{}` ({})", c.guard, c.guard_tolerance)
        };
        let _ = writeln!(
            s,
            "| {} — {} | {} {} | {} | {} | {} | {} | {} |",
            c.id,
            c.what.replace('|', "\\|"),
            c.value,
            c.unit,
            c.holds().describe(&c.unit),
            measured.replace('|', "\\|"),
            verdict,
            guard.replace('|', "\\|"),
            c.seeds.as_deref().unwrap_or("—")
        );
    }
    s
}
