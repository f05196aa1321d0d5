//! The Slurm job array for a sweep: one array task per shard (each runs `gelrig sweep
//! SWEEP.yaml --out CAMPAIGN -j 1`, which reads its shard from `SLURM_ARRAY_TASK_ID`), a
//! merge job that writes `campaign.csv` once every task has ended, and the two lines that
//! submit them.

use std::path::Path;

use crate::sweep::Sweep;

/// What the scripts need.
#[derive(Debug, Clone)]
pub struct SlurmPlan<'a> {
    /// The gelrig binary the tasks run.
    pub gelrig: &'a Path,
    /// The sweep file (absolute).
    pub sweep_file: &'a Path,
    /// The campaign folder (absolute).
    pub campaign: &'a Path,
    /// Array tasks (shards).
    pub shards: usize,
    /// Tasks running at once (`%` in `--array`).
    pub throttle: usize,
    /// Points in the largest shard.
    pub points_per_shard: usize,
}

fn q(p: &Path) -> String {
    format!("'{}'", p.display().to_string().replace('\'', r"'\''"))
}

/// `HH:MM:SS`, at least a minute.
fn hms(s: f64) -> String {
    let s = s.max(60.0).ceil() as u64;
    format!("{:02}:{:02}:{:02}", s / 3600, (s / 60) % 60, s % 60)
}

/// The array job, the merge job and `submit.sh`: (file name, text).
pub fn scripts(sweep: &Sweep, plan: &SlurmPlan<'_>) -> Vec<(&'static str, String)> {
    // A shard's time: its points one after another, plus five minutes to start and finish.
    let time = hms(sweep.time_per_point_s * plan.points_per_shard as f64 + 300.0);
    let logs = plan.campaign.join("slurm");
    let array = format!(
        "#!/bin/bash\n\
         # gelrig sweep {name}: one array task per shard of the sweep's points.\n\
         #SBATCH --job-name=gelrig-{name}\n\
         #SBATCH --array=0-{last}%{throttle}\n\
         #SBATCH --cpus-per-task=1\n\
         #SBATCH --mem={mem}M\n\
         #SBATCH --time={time}\n\
         #SBATCH --output={logs}/%A_%a.out\n\
         set -euo pipefail\n\
         exec {gelrig} sweep {sweep_file} --out {campaign} -j 1\n",
        name = sweep.name,
        last = plan.shards - 1,
        throttle = plan.throttle.max(1),
        mem = sweep.memory_mb,
        logs = logs.display(),
        gelrig = q(plan.gelrig),
        sweep_file = q(plan.sweep_file),
        campaign = q(plan.campaign),
    );
    let merge = format!(
        "#!/bin/bash\n\
         # gelrig sweep {name}: campaign.csv once every array task has ended.\n\
         #SBATCH --job-name=gelrig-{name}-merge\n\
         #SBATCH --cpus-per-task=1\n\
         #SBATCH --mem=512M\n\
         #SBATCH --time=00:10:00\n\
         #SBATCH --output={logs}/merge_%j.out\n\
         set -euo pipefail\n\
         exec {gelrig} sweep {sweep_file} --out {campaign} --merge\n",
        name = sweep.name,
        logs = logs.display(),
        gelrig = q(plan.gelrig),
        sweep_file = q(plan.sweep_file),
        campaign = q(plan.campaign),
    );
    let submit = format!(
        "#!/bin/bash\n\
         # Submits the array, then the merge to run after it (whether tasks failed or not).\n\
         set -euo pipefail\n\
         cd {dir}\n\
         jid=$(sbatch --parsable sweep.sbatch)\n\
         jid=${{jid%%;*}}\n\
         mid=$(sbatch --parsable --dependency=afterany:\"$jid\" merge.sbatch)\n\
         echo \"array job $jid, merge job ${{mid%%;*}}\"\n",
        dir = q(&logs),
    );
    vec![
        ("sweep.sbatch", array),
        ("merge.sbatch", merge),
        ("submit.sh", submit),
    ]
}
