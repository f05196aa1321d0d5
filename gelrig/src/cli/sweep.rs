//! `gelrig sweep`: a protocol run over a sweep of its parameters, each point its own
//! `gelrig run` process, on this machine (`-j N`) or as the shards of a job array.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use crate::campaign::{Campaign, Outcome, Point, Shard, Sweep, points, slurm};
use crate::cli::Exit;
use crate::protocol::{Budget, Overrides, load_with_overrides};

/// Run a protocol over a sweep of its parameters (a grid, a list, or random or
/// Latin-hypercube points): every point checked first, each run named by its parameters, a
/// finished point never run again, failures recorded per point.
#[derive(clap::Args)]
pub(crate) struct Cmd {
    /// The sweep file (docs/how-to/sweep.md).
    sweep: PathBuf,
    /// The campaign folder [default: campaigns/<the sweep's name>].
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Show the points, the runs and what they cost; run nothing.
    #[arg(long, conflicts_with_all = ["slurm", "merge"])]
    plan: bool,
    /// Points run at once, each its own process [default: the cores].
    #[arg(short = 'j', long = "jobs", value_name = "N")]
    jobs: Option<usize>,
    /// Run only shard I of N (1 ≤ I ≤ N): the points k with k mod N = I − 1 [default: a job
    /// array's task (SLURM_ARRAY_TASK_ID of SLURM_ARRAY_TASK_COUNT, or JOB_COMPLETION_INDEX
    /// of JOB_COMPLETIONS), else every point].
    #[arg(long, value_name = "I/N")]
    shard: Option<String>,
    /// Write a Slurm job array for the sweep (CAMPAIGN/slurm/: sweep.sbatch, merge.sbatch,
    /// submit.sh) instead of running it.
    #[arg(long, conflicts_with = "merge")]
    slurm: bool,
    /// Array tasks for --slurm [default: the points, at most 100].
    #[arg(long, value_name = "N", requires = "slurm")]
    shards: Option<usize>,
    /// Array tasks running at once for --slurm [default: all].
    #[arg(long, value_name = "N", requires = "slurm")]
    throttle: Option<usize>,
    /// Only write CAMPAIGN/campaign.csv from the points' outcomes (after the shards).
    #[arg(long)]
    merge: bool,
}

impl Cmd {
    pub(crate) fn run(self) -> anyhow::Result<Exit> {
        let invalid = || Ok(Exit::from(super::EXIT_INVALID));
        let sweep = match Sweep::read(&self.sweep) {
            Ok(s) => s,
            Err(e) => {
                err!("error: {e}");
                return invalid();
            }
        };
        let points = match points(&sweep) {
            Ok(p) => p,
            Err(e) => {
                err!("error: {}: {e}", self.sweep.display());
                return invalid();
            }
        };
        let (protocol, _) = crate::protocol::shipped::resolve(&sweep.protocol);
        let campaign = Campaign {
            dir: self
                .out
                .clone()
                .unwrap_or_else(|| Path::new("campaigns").join(safe(&sweep.name))),
        };
        if self.merge {
            return merge(&campaign, &points);
        }
        let Some(costs) = validate(&sweep, &protocol, &points) else {
            return invalid();
        };
        if self.plan {
            print_plan(&sweep, &points, &costs);
            return Ok(Exit::SUCCESS);
        }
        let text = std::fs::read_to_string(&self.sweep)?;
        if let Err(e) = campaign.create(&text, &points) {
            err!("error: {e}");
            return invalid();
        }
        if self.slurm {
            return self.write_slurm(&sweep, &campaign, points.len());
        }
        let shard = match self.shard.as_deref() {
            Some(s) => Shard::parse(s),
            None => Shard::from_env(|k| std::env::var(k).ok()).map(|s| s.unwrap_or(Shard::ALL)),
        };
        let shard = match shard {
            Ok(s) => s,
            Err(e) => {
                err!("error: {e}");
                return invalid();
            }
        };
        let jobs = match self.jobs {
            Some(0) => {
                err!("error: -j 0 runs nothing; fix: give at least 1");
                return invalid();
            }
            Some(n) => n,
            None => std::thread::available_parallelism().map_or(1, |n| n.get()),
        };
        let mine: Vec<&Point> = points.iter().filter(|p| shard.has(p.index)).collect();
        let todo: Vec<&Point> = mine.iter().copied().filter(|p| !campaign.done(p)).collect();
        err!(
            "sweep {}: {} points{}; {} done before, {} to run, {} at a time, in {}",
            sweep.name,
            mine.len(),
            if shard == Shard::ALL {
                String::new()
            } else {
                format!(
                    " in shard {}/{} of {}",
                    shard.index,
                    shard.count,
                    points.len()
                )
            },
            mine.len() - todo.len(),
            todo.len(),
            jobs.min(todo.len().max(1)),
            campaign.dir.display()
        );
        let failed = run_points(&sweep, &protocol, &campaign, &todo, jobs)?;
        let (done, failed_all, not_run) = campaign.write_table(&points)?;
        out!(
            "campaign {}: {done} completed, {failed_all} failed, {not_run} not run (of {}); wrote {}",
            sweep.name,
            points.len(),
            campaign.dir.join("campaign.csv").display()
        );
        Ok(if failed == 0 {
            Exit::SUCCESS
        } else {
            Exit::from(1)
        })
    }

    /// `--slurm`: the array job, the merge job and `submit.sh` in CAMPAIGN/slurm/.
    fn write_slurm(&self, sweep: &Sweep, campaign: &Campaign, n: usize) -> anyhow::Result<Exit> {
        let shards = self.shards.unwrap_or(n.min(100)).clamp(1, n);
        let abs = |p: &Path| std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
        let (exe, sweep_file, dir) = (gelrig_exe()?, abs(&self.sweep), abs(&campaign.dir));
        let plan = slurm::SlurmPlan {
            gelrig: &exe,
            sweep_file: &sweep_file,
            campaign: &dir,
            shards,
            throttle: self.throttle.unwrap_or(shards),
            points_per_shard: n.div_ceil(shards),
        };
        let folder = dir.join("slurm");
        std::fs::create_dir_all(&folder)?;
        for (name, text) in slurm::scripts(sweep, &plan) {
            let path = folder.join(name);
            crate::campaign::write_atomic(&path, text.as_bytes())?;
            #[cfg(unix)]
            {
                use std::os::unix::fs::PermissionsExt;
                std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o755))?;
            }
        }
        out!(
            "wrote a Slurm array of {shards} tasks ({} points each at most, {} min a point, {} MB) and its merge job to {}; submit with: bash {}",
            plan.points_per_shard,
            sweep.time_per_point_s / 60.0,
            sweep.memory_mb,
            folder.display(),
            folder.join("submit.sh").display()
        );
        Ok(Exit::SUCCESS)
    }
}

/// A name safe for a folder.
fn safe(name: &str) -> String {
    name.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.') {
                c
            } else {
                '-'
            }
        })
        .collect()
}

/// The binary the points run: this one (not a Python interpreter that embeds gelrig).
fn gelrig_exe() -> anyhow::Result<PathBuf> {
    if let Ok(p) = std::env::var("GELRIG_BIN") {
        return Ok(PathBuf::from(p));
    }
    let exe = std::env::current_exe()?;
    let stem = exe
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    if stem.starts_with("python") {
        anyhow::bail!(
            "gelrig sweep runs each point as a `gelrig run` process, and this process is {}; \
             fix: run the gelrig binary, or set GELRIG_BIN to it",
            exe.display()
        );
    }
    Ok(exe)
}

/// What a point's run costs by its plan: (experiment time on a real rig, s; data, bytes).
type Cost = (f64, f64);

/// Loads every point's protocol before anything runs; `None` (with every point's
/// diagnostics on stderr) when any does not load.
fn validate(sweep: &Sweep, protocol: &Path, points: &[Point]) -> Option<Vec<Cost>> {
    let mut costs = Vec::with_capacity(points.len());
    let mut bad = 0;
    for p in points {
        let overrides = Overrides {
            set: p.set.clone(),
            name: Some(p.name.clone()),
            fidelity: None,
        };
        match load_with_overrides(
            protocol,
            sweep.rig.as_deref(),
            &Budget::default(),
            &overrides,
        ) {
            Ok(loaded) => {
                costs.push((loaded.plan.duration_s.max, loaded.plan.bytes.max));
            }
            Err(diags) => {
                bad += 1;
                if bad <= 5 {
                    err!("point {} ({}):", p.index, p.name);
                    super::report(&diags);
                }
            }
        }
    }
    if bad > 0 {
        err!(
            "error: {bad} of {} points do not load{}; no point was run. fix: correct the sweep \
             file's values (or the base protocol)",
            points.len(),
            if bad > 5 { " (the first 5 shown)" } else { "" }
        );
        return None;
    }
    Some(costs)
}

/// `--plan`: the points, and what they cost.
fn print_plan(sweep: &Sweep, points: &[Point], costs: &[Cost]) {
    out!(
        "sweep {}: {} points of {} ({} design); every point loads",
        sweep.name,
        points.len(),
        sweep.protocol.display(),
        match sweep.design {
            crate::campaign::Design::Grid(_) => "grid",
            crate::campaign::Design::List(_) => "list",
            crate::campaign::Design::Random { .. } => "random",
            crate::campaign::Design::LatinHypercube { .. } => "latin_hypercube",
        }
    );
    for (p, (t, b)) in points.iter().zip(costs).take(50) {
        let params: Vec<String> = p.params.iter().map(|(k, v)| format!("{k}={v}")).collect();
        out!(
            "  {}  {}  (seed {}; on a real rig {}, {})",
            p.name,
            params.join(", "),
            p.seed,
            experiments::plan::human_duration(*t),
            experiments::plan::human_bytes(*b)
        );
    }
    if points.len() > 50 {
        out!("  … and {} more", points.len() - 50);
    }
    let (t, b): (f64, f64) = costs.iter().fold((0.0, 0.0), |a, c| (a.0 + c.0, a.1 + c.1));
    out!(
        "{} runs: on a real rig {} of experiment time one after another, {} of data; on the \
         simulated bench each takes what `gelrig run` takes (a cluster's time per point: \
         resources.time_per_point, {} min)",
        points.len(),
        experiments::plan::human_duration(t),
        experiments::plan::human_bytes(b),
        sweep.time_per_point_s / 60.0
    );
}

/// `--merge`: campaign.csv from the outcomes; exit 1 when a point failed or did not run.
fn merge(campaign: &Campaign, points: &[Point]) -> anyhow::Result<Exit> {
    let (done, failed, not_run) = campaign.write_table(points)?;
    out!(
        "{done} completed, {failed} failed, {not_run} not run (of {}); wrote {}",
        points.len(),
        campaign.dir.join("campaign.csv").display()
    );
    Ok(if failed + not_run == 0 {
        Exit::SUCCESS
    } else {
        Exit::from(1)
    })
}

/// Runs `todo` with `jobs` processes at a time; returns how many failed.
fn run_points(
    sweep: &Sweep,
    protocol: &Path,
    campaign: &Campaign,
    todo: &[&Point],
    jobs: usize,
) -> anyhow::Result<usize> {
    let exe = gelrig_exe()?;
    let next = AtomicUsize::new(0);
    let finished = AtomicUsize::new(0);
    let failed = AtomicUsize::new(0);
    let first_error: Mutex<Option<anyhow::Error>> = Mutex::new(None);
    std::thread::scope(|s| {
        for _ in 0..jobs.min(todo.len()) {
            s.spawn(|| {
                loop {
                    let k = next.fetch_add(1, Ordering::SeqCst);
                    let Some(p) = todo.get(k) else { break };
                    match run_point(&exe, sweep, protocol, campaign, p) {
                        Ok(o) => {
                            let n = finished.fetch_add(1, Ordering::SeqCst) + 1;
                            if o.status != "completed" {
                                failed.fetch_add(1, Ordering::SeqCst);
                            }
                            err!(
                                "[{n}/{}] {} {} in {:.1} s{}",
                                todo.len(),
                                p.name,
                                o.status,
                                o.wall_s,
                                if o.message.is_empty() {
                                    String::new()
                                } else {
                                    format!(": {}", o.message)
                                }
                            );
                        }
                        Err(e) => {
                            if let Ok(mut slot) = first_error.lock() {
                                slot.get_or_insert(e);
                            }
                            break;
                        }
                    }
                }
            });
        }
    });
    if let Some(e) = first_error.into_inner().ok().flatten() {
        return Err(e);
    }
    Ok(failed.load(Ordering::SeqCst))
}

/// One point's `gelrig run`, its output in the point's `log.txt`, its outcome recorded.
fn run_point(
    exe: &Path,
    sweep: &Sweep,
    protocol: &Path,
    campaign: &Campaign,
    p: &Point,
) -> anyhow::Result<Outcome> {
    let dir = campaign.point_dir(p);
    std::fs::create_dir_all(&dir)?;
    let log_path = dir.join("log.txt");
    let log = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(&log_path)?;
    let mut cmd = Command::new(exe);
    cmd.arg("run").arg(protocol);
    if let Some(rig) = &sweep.rig {
        cmd.arg("--rig").arg(rig);
    }
    for s in &p.set {
        cmd.arg("--set").arg(s);
    }
    cmd.args([
        "--name",
        &p.name,
        "--seed",
        &p.seed.to_string(),
        "--quiet",
        "--out",
    ])
    .arg(&dir)
    .stdin(Stdio::null())
    .stdout(log.try_clone()?)
    .stderr(log);
    let started = Instant::now();
    let status = cmd.status()?;
    let wall_s = started.elapsed().as_secs_f64();
    let run_dir = campaign.run_dir_of(p);
    let completed = status.success() && run_dir.is_some();
    let message = if completed {
        String::new()
    } else {
        let text = std::fs::read_to_string(&log_path).unwrap_or_default();
        text.lines()
            .rev()
            .find(|l| !l.trim().is_empty())
            .unwrap_or("the run ended without a word")
            .chars()
            .take(300)
            .collect()
    };
    let mut parameters: std::collections::BTreeMap<String, String> =
        p.params.iter().cloned().collect();
    parameters.insert("seed".into(), p.seed.to_string());
    for s in &p.set {
        if let Some((k, v)) = s.split_once('=') {
            parameters
                .entry(k.to_string())
                .or_insert_with(|| v.to_string());
        }
    }
    let outcome = Outcome {
        name: p.name.clone(),
        parameters,
        status: if completed { "completed" } else { "failed" }.into(),
        exit_code: status.code(),
        message,
        wall_s,
        run_dir,
    };
    campaign.record(p, &outcome)?;
    Ok(outcome)
}
