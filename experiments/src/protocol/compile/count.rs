//! Counting what a protocol expands into, before expanding it.
//!
//! `to: 1e12 %` in 2 % steps, `from: 1e18 mm`, or two nested `repeat: {times: 1000}` used to
//! be expanded step by step until memory ran out. The compiler now counts steps and actions
//! arithmetically (in floating point, so products of huge counts saturate instead of
//! wrapping) and refuses a protocol over its [`Budget`] with the numbers, before anything
//! is allocated. The run's data volume is checked against the budget after planning
//! ([`crate::protocol::load_with`]).

use rig::config::YamlPath;
use rig::units::fmt_value;

use super::Compiler;
use crate::protocol::schema::{Block, Direction};

/// Limits on what one protocol may ask of a run, raised on the command line
/// (`--max-steps`, `--max-data`) for the rare run that really is that big.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Budget {
    /// Rows of `steps.csv` (100,000 by default: a protocol of the thesis has 20–200).
    pub max_steps: u64,
    /// Bytes the run may write, against the plan's upper estimate (100 GB by default: ten
    /// hours of 60 Hz frames).
    pub max_bytes: u64,
}

impl Default for Budget {
    fn default() -> Self {
        Self {
            max_steps: 100_000,
            max_bytes: 100_000_000_000,
        }
    }
}

impl Budget {
    /// Parses a size such as `50GB`, `500 MB`, `2 TB` or a plain number of bytes.
    pub fn parse_bytes(text: &str) -> Result<u64, String> {
        let t = text.trim();
        let split = t
            .find(|c: char| !(c.is_ascii_digit() || c == '.'))
            .unwrap_or(t.len());
        let (num, unit) = t.split_at(split);
        let v: f64 = num
            .parse()
            .map_err(|_| format!("`{text}` is not a size; write e.g. `200GB`"))?;
        let k = match unit.trim().to_ascii_uppercase().as_str() {
            "" | "B" => 1.0,
            "KB" => 1e3,
            "MB" => 1e6,
            "GB" => 1e9,
            "TB" => 1e12,
            other => {
                return Err(format!(
                    "unknown size unit `{other}`; write B, KB, MB, GB or TB"
                ));
            }
        };
        let bytes = v * k;
        if !(1.0..1e18).contains(&bytes) {
            return Err(format!("`{text}` is not a size between 1 B and 1 EB"));
        }
        Ok(bytes as u64)
    }
}

/// Actions one step may bring with it beyond its own (trial and stream markers), so the
/// action count follows from the step budget.
const ACTIONS_PER_STEP: f64 = 10.0;
/// Actions allowed however few the steps: homes, tares and markers of a long protocol.
const ACTIONS_FLOOR: f64 = 100_000.0;

/// What a list of blocks expands into.
#[derive(Debug, Clone, Copy, Default)]
struct Count {
    steps: f64,
    actions: f64,
}

impl Compiler<'_> {
    /// Counts the sequence; errors (at `sequence`) and returns `false` if it is over budget.
    pub(super) fn within_budget(&mut self, budget: &crate::protocol::compile::Budget) -> bool {
        let c = self.count(&self.p.sequence, 0);
        let at = YamlPath::root().key("sequence");
        let max_steps = budget.max_steps as f64;
        if c.steps > max_steps {
            self.error(
                &at,
                format!(
                    "the sequence expands into {} steps, over the budget of {} (repeats multiply the steps of their blocks)",
                    big(c.steps),
                    budget.max_steps
                ),
                "check the `from`, `to`, `step` and `times` values; if the run really is that long, pass `--max-steps N`",
            );
            return false;
        }
        let max_actions = (max_steps * ACTIONS_PER_STEP).max(ACTIONS_FLOOR);
        if c.actions > max_actions {
            self.error(
                &at,
                format!(
                    "the sequence expands into {} actions (homes, tares, trials, streams), over {}",
                    big(c.actions),
                    big(max_actions)
                ),
                "check the `times` of nested repeats",
            );
            return false;
        }
        true
    }

    fn count(&self, blocks: &[Block], depth: usize) -> Count {
        let mut total = Count::default();
        if depth > super::bounds::NESTING {
            return total;
        }
        for b in blocks {
            let c = match b {
                Block::Home(_) | Block::Approach(_) | Block::Tare(_) => Count {
                    steps: 0.0,
                    actions: 1.0,
                },
                Block::Hold(_) | Block::Move(_) | Block::Capture(_) | Block::Disturb(_) => Count {
                    steps: 1.0,
                    actions: 1.0,
                },
                Block::Stepped(s) => {
                    let n = self.stepped_count(s);
                    Count {
                        steps: n,
                        actions: n,
                    }
                }
                Block::Record(r) => {
                    let inner = self.count(&r.blocks, depth + 1);
                    Count {
                        steps: inner.steps,
                        actions: inner.actions + 2.0,
                    }
                }
                Block::Repeat(r) => {
                    let inner = self.count(&r.blocks, depth + 1);
                    let times = f64::from(r.times);
                    Count {
                        steps: times * inner.steps,
                        actions: times * (inner.actions + 2.0),
                    }
                }
            };
            total.steps += c.steps;
            total.actions += c.actions;
        }
        total
    }

    /// Steps of a stepped block, from its values in the axis unit; 0 when they cannot be
    /// read (the compile pass reports why).
    fn stepped_count(&self, s: &crate::protocol::schema::Stepped) -> f64 {
        let Some(cfg) = self.rig.axes.get(&s.axis) else {
            return 0.0;
        };
        let unit = cfg.unit();
        let h = self.thickness_mm;
        let (Some(from), Some(to), Some(step)) = (
            s.from.in_axis_unit(unit, h),
            s.to.in_axis_unit(unit, h),
            s.step.in_axis_unit(unit, h),
        ) else {
            return 0.0;
        };
        if !(step > 0.0 && from.is_finite() && to.is_finite()) {
            return 0.0;
        }
        let per_direction = ((to - from).abs() / step).round();
        match s.direction {
            Direction::LoadUnload => 2.0 * per_direction,
            Direction::Load | Direction::Unload => per_direction,
        }
    }
}

/// A count for a message: exact when small, `1.2e+15` when not.
fn big(v: f64) -> String {
    if v < 1e12 {
        fmt_value(v.round())
    } else {
        format!("{v:.1e}")
    }
}

#[cfg(test)]
mod tests {
    use super::Budget;

    #[test]
    fn sizes_parse_with_their_units() {
        assert_eq!(Budget::parse_bytes("200GB"), Ok(200_000_000_000));
        assert_eq!(Budget::parse_bytes("1.5 TB"), Ok(1_500_000_000_000));
        assert_eq!(Budget::parse_bytes("4096"), Ok(4096));
        for bad in ["", "GB", "1e999GB", "5 parsecs", "-3MB"] {
            assert!(Budget::parse_bytes(bad).is_err(), "{bad}");
        }
    }
}
