//! Shards of a sweep for job arrays: point k belongs to shard k mod N (the points of a grid
//! alternate between shards, so neighbours of similar cost are spread), numbered 1..=N.

use crate::CampaignError;

/// Shard `index` of `count` (1-based).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    /// 1..=count.
    pub index: usize,
    /// Shards in all.
    pub count: usize,
}

impl Shard {
    /// The whole sweep.
    pub const ALL: Shard = Shard { index: 1, count: 1 };

    /// `I/N`, as `--shard` takes it.
    pub fn parse(text: &str) -> Result<Self, CampaignError> {
        let bad = || {
            CampaignError::Shard(format!(
                "--shard {text:?}: give I/N with 1 ≤ I ≤ N, e.g. 2/4"
            ))
        };
        let (i, n) = text.split_once('/').ok_or_else(bad)?;
        let (index, count) = (
            i.trim().parse::<usize>().map_err(|_| bad())?,
            n.trim().parse::<usize>().map_err(|_| bad())?,
        );
        Self::new(index, count).ok_or_else(bad)
    }

    fn new(index: usize, count: usize) -> Option<Self> {
        (count >= 1 && (1..=count).contains(&index)).then_some(Self { index, count })
    }

    /// The shard a job array gives this process: Slurm's `SLURM_ARRAY_TASK_ID` (0-based, as
    /// `--slurm` writes the array) of `SLURM_ARRAY_TASK_COUNT`, or a Kubernetes Indexed Job's
    /// `JOB_COMPLETION_INDEX` of `JOB_COMPLETIONS` (set it in the Job's env to its
    /// completions). `None` outside a job array.
    pub fn from_env(get: impl Fn(&str) -> Option<String>) -> Result<Option<Self>, CampaignError> {
        for (id, count, fix) in [
            (
                "SLURM_ARRAY_TASK_ID",
                "SLURM_ARRAY_TASK_COUNT",
                "run it as an array job (sbatch --array=0-N)",
            ),
            (
                "JOB_COMPLETION_INDEX",
                "JOB_COMPLETIONS",
                "set JOB_COMPLETIONS in the Job's env to its completions",
            ),
        ] {
            let Some(i) = get(id) else { continue };
            let parse = |name: &str, v: Option<String>| -> Result<usize, CampaignError> {
                v.as_deref()
                    .and_then(|v| v.trim().parse::<usize>().ok())
                    .ok_or_else(|| CampaignError::Shard(format!("{name} is {v:?}: {fix}")))
            };
            let i = parse(id, Some(i))?;
            let n = parse(count, get(count))?;
            return Self::new(i + 1, n)
                .map(Some)
                .ok_or_else(|| CampaignError::Shard(format!("{id}={i} of {count}={n}: {fix}")));
        }
        Ok(None)
    }

    /// Whether point `k` (0-based) is this shard's.
    pub fn has(&self, k: usize) -> bool {
        k % self.count == self.index - 1
    }
}
