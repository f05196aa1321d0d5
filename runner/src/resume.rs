//! Continuing an interrupted, aborted or failed run in its own directory (`gelrig resume`).
//!
//! What a resume checks and does, in order (docs/how-to/resume-a-run.md):
//! 1. The run is not completed and no process is recording it; its recorded protocol
//!    (`protocol.yaml`, as run) still compiles to the steps it planned.
//! 2. The devices opened report the identities the run recorded (a different sensor or
//!    stage is refused before anything moves).
//! 3. The protocol's own opening runs again — home, tare, approach: the contact is found
//!    afresh and compared with the recorded origin; beyond the tolerance (stated in the
//!    error) the run is refused, since every recorded depth is relative to that origin. An
//!    approach inside a trial (a grasp finds the can where it stands) is not checked.
//! 4. The completed steps outside trials are replayed as moves to the positions they
//!    recorded (no settle, no row), so the gel is loaded along the same path — the loading
//!    or unloading branch of its hysteresis — and the last of them is held for as long as
//!    it settled then (re-settling the preload).
//! 5. The run continues at the first incomplete step; a trial under way restarts at its
//!    first step. The journal and `run.yaml` record the segment; readers treat the run as
//!    one ([`rundir::resumed`]).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use rig::ClockMode;
use rig::config::AxisRole;
use rundir::read::{StepRow, read_csv};
use rundir::resumed::Segments;
use rundir::write::{DeviceRecord, Manifest, Segment, Status, is_locked, read_manifest};
use serde_json::json;

use super::Stop;
use super::exec::Exec;
use super::wait::Until;
use experiments::load::Loaded;
use experiments::protocol::compile::{ActionKind, Step};

/// The gap left on the run's timebase between the last record and the resumed segment, so
/// the two never touch.
const GAP_NS: u64 = 1_000_000_000;

/// What a resumed run continues from, read from its directory.
#[derive(Debug, Clone)]
pub struct Resume {
    /// The run directory.
    pub dir: PathBuf,
    /// The first step run again.
    pub from_step: u32,
    /// Completed steps outside trials before `from_step`: the position each ended at
    /// (relative to the origin) and how long it settled, s.
    replay: BTreeMap<u32, (Option<f64>, f64)>,
    /// The replayed step held for its settle time (the last one before `from_step`).
    resettle: Option<u32>,
    /// Trials wholly before `from_step`.
    skipped_trials: BTreeSet<u32>,
    /// Origins the run recorded, by axis name.
    origins: BTreeMap<String, f64>,
    /// How late each recorded origin's approach can have noticed its contact, s (the
    /// journal's `contact` event; runs from before it was journaled have none).
    approach_gaps_s: BTreeMap<String, f64>,
    /// How far the re-found contact may be from the recorded origin, axis unit.
    pub origin_tolerance: f64,
    /// The segment's start on the run's timebase, ns.
    pub t_start_ns: u64,
    /// Devices the run recorded.
    devices: Vec<DeviceRecord>,
    /// How the previous segment ended.
    previous_status: String,
    previous_message: Option<String>,
    /// When the previous segment ended (a killed one: when it last wrote), RFC 3339 UTC.
    previous_ended_utc: Option<String>,
}

/// Why a run cannot be resumed, naming the fix.
fn refuse(dir: &Path, why: impl std::fmt::Display) -> String {
    format!("cannot resume {}: {why}", dir.display())
}

/// Whether the run of `manifest` can be resumed with `loaded`: not completed, not still
/// running, and its protocol still the one it planned. Returns how its last segment ended
/// (`interrupted` for a run that stopped without saying).
fn resumable(dir: &Path, manifest: &Manifest, loaded: &Loaded) -> Result<String, String> {
    let previous_status = match manifest.status {
        Status::Completed => {
            return Err(refuse(
                dir,
                "it completed every step; fix: nothing to resume — `gelrig report` it",
            ));
        }
        Status::Running if is_locked(dir) => {
            return Err(refuse(
                dir,
                format!(
                    "it is still running (process {} holds run.lock); fix: wait for it, or stop it first",
                    manifest.pid
                ),
            ));
        }
        Status::Running => "interrupted".to_string(),
        s => s.name().to_string(),
    };
    if manifest.protocol != loaded.protocol.name || manifest.steps_planned != loaded.compiled.steps
    {
        return Err(refuse(
            dir,
            format!(
                "its protocol.yaml now reads as `{}` with {} steps, and the run was `{}` with {}; fix: restore the run directory's protocol.yaml",
                loaded.protocol.name,
                loaded.compiled.steps,
                manifest.protocol,
                manifest.steps_planned
            ),
        ));
    }
    Ok(previous_status)
}

/// What a resumed run does with the steps before the one it continues at.
struct ReplayPlan {
    /// Completed steps outside trials: the position each ended at (from the origin) and
    /// how long it settled, s.
    replay: BTreeMap<u32, (Option<f64>, f64)>,
    /// The replayed step held for its settle time (the last one, if outside trials).
    resettle: Option<u32>,
    /// Trials wholly before.
    skipped_trials: BTreeSet<u32>,
}

/// The [`ReplayPlan`] of a run continuing at `from_step`, from the plan's `steps` (each
/// with its trial, 0 outside trials) and the rows `done`.
fn replay_plan(
    steps: &[(&Step, u32)],
    done: &BTreeMap<u32, &StepRow>,
    from_step: u32,
) -> ReplayPlan {
    let replay: BTreeMap<u32, (Option<f64>, f64)> = steps
        .iter()
        .filter(|(s, t)| *t == 0 && s.step < from_step)
        .filter_map(|(s, _)| {
            done.get(&s.step)
                .map(|r| (s.step, (r.position, r.settle_s)))
        })
        .collect();
    let resettle = steps
        .iter()
        .rev()
        .find(|(s, _)| s.step < from_step)
        .filter(|(_, t)| *t == 0)
        .map(|(s, _)| s.step);
    let mut first_of_trial: BTreeMap<u32, u32> = BTreeMap::new();
    for (s, t) in steps {
        if *t != 0 {
            first_of_trial.entry(*t).or_insert(s.step);
        }
    }
    let skipped_trials = first_of_trial
        .into_iter()
        .filter(|(_, first)| *first < from_step)
        .map(|(t, _)| t)
        .collect();
    ReplayPlan {
        replay,
        resettle,
        skipped_trials,
    }
}

impl Resume {
    /// Reads what `dir` holds and decides where the run continues. `loaded` is the run's
    /// recorded protocol and rig.
    pub fn prepare(
        dir: &Path,
        loaded: &Loaded,
        origin_tolerance: f64,
        mode: ClockMode,
    ) -> Result<Self, String> {
        let manifest = read_manifest(dir).map_err(|e| refuse(dir, e))?;
        let previous_status = resumable(dir, &manifest, loaded)?;
        let rows: Vec<StepRow> =
            read_csv(&dir.join(rundir::names::STEPS)).map_err(|e| refuse(dir, e))?;
        let rows = Segments::last_per_step(rows, |r| r.step);
        let done: BTreeMap<u32, &StepRow> = rows.iter().map(|r| (r.step, r)).collect();
        let steps: Vec<(&Step, u32)> = loaded
            .compiled
            .actions
            .iter()
            .filter_map(|a| match &a.kind {
                ActionKind::Step(s) => Some((s, a.trial)),
                _ => None,
            })
            .collect();
        let Some(&(first_missing, trial)) = steps
            .iter()
            .find(|(s, _)| !done.contains_key(&s.step))
            .map(|(s, t)| (s.step, *t))
            .as_ref()
        else {
            return Err(refuse(
                dir,
                "every step is on disk (the run ended before writing its status); fix: nothing to resume — `gelrig report` it",
            ));
        };
        // A trial under way is done again from its first step: a grasp cannot be picked up
        // in the middle.
        let from_step = if trial == 0 {
            first_missing
        } else {
            steps
                .iter()
                .find(|(_, t)| *t == trial)
                .map_or(first_missing, |(s, _)| s.step)
        };
        let ReplayPlan {
            replay,
            resettle,
            skipped_trials,
        } = replay_plan(&steps, &done, from_step);
        let last_ns = last_record_ns(dir);
        if mode == ClockMode::Monotonic && rig::clock::monotonic_ns() <= last_ns {
            return Err(refuse(
                dir,
                "this machine's clock restarted since the run (it reads earlier than the run's last record), so the run's timebase cannot continue; fix: start a new run",
            ));
        }
        Ok(Self {
            dir: dir.to_path_buf(),
            from_step,
            replay,
            resettle,
            skipped_trials,
            approach_gaps_s: approach_gaps_s(dir, &manifest.origins),
            origins: manifest.origins.clone(),
            origin_tolerance,
            t_start_ns: last_ns + GAP_NS,
            devices: manifest.devices.clone(),
            previous_status,
            previous_message: manifest.reason.clone().or(manifest.error.clone()),
            previous_ended_utc: manifest.ended_utc.clone().or_else(|| last_written_utc(dir)),
        })
    }

    /// The manifest as the resumed segment starts.
    pub(super) fn begin(&self, m: &mut Manifest) {
        m.resumed.push(Segment {
            started_utc: jiff::Timestamp::now().to_string(),
            t_start_ns: self.t_start_ns,
            from_step: self.from_step,
            pid: std::process::id(),
            previous_status: self.previous_status.clone(),
            previous_message: self.previous_message.clone(),
            previous_ended_utc: self.previous_ended_utc.clone(),
        });
        m.status = Status::Running;
        m.reason = None;
        m.error = None;
        m.ended_utc = None;
        m.pid = std::process::id();
    }

    /// The journal's record of the segment.
    pub(super) fn record(&self, cut: &[(String, u64)]) -> serde_json::Value {
        json!({
            "from_step": self.from_step,
            "previous_status": self.previous_status,
            "previous_message": self.previous_message,
            "replayed_steps": self.replay.keys().collect::<Vec<_>>(),
            "resettle_step": self.resettle,
            "skipped_trials": self.skipped_trials,
            "torn_rows_cut_bytes": cut.iter().map(|(f, b)| json!({"file": f, "bytes": b})).collect::<Vec<_>>(),
        })
    }

    /// The devices opened must be the ones the run recorded, role by role.
    pub(super) fn check_devices(&self, opened: &[DeviceRecord]) -> Result<(), String> {
        for was in &self.devices {
            if let Some(now) = opened.iter().find(|d| d.role == was.role)
                && now.identity != was.identity
            {
                return Err(format!(
                    "the {} is `{}`, and the run recorded `{}`; fix: reconnect the device the run used, or start a new run",
                    was.role, now.identity, was.identity
                ));
            }
        }
        Ok(())
    }

    /// Whether a trial's actions are skipped (it completed before the resume).
    pub(super) fn skips_trial(&self, trial: u32) -> bool {
        trial != 0 && self.skipped_trials.contains(&trial)
    }

    /// Checks the first contact re-found on an axis, outside trials, against the origin the
    /// run recorded (later approaches set their own). The re-finding approach crept at
    /// `speed` for up to `gap_s` past the crossing before it stopped, on a stage of
    /// `resolution`: with the recorded approach's own delay (the journal's `reading_gap_s`)
    /// they make the jitter two approaches to an unmoved surface show. Gives the recorded
    /// origin and that jitter.
    pub(super) fn check_origin(
        &mut self,
        axis: AxisRole,
        found: f64,
        speed: f64,
        gap_s: f64,
        resolution: f64,
    ) -> Result<Option<(f64, f64)>, Stop> {
        let Some(recorded) = self.origins.remove(axis.name()) else {
            return Ok(None);
        };
        let recorded_gap_s = self.approach_gaps_s.remove(axis.name()).unwrap_or(0.0);
        // Each approach stops up to its own creep past the crossing, and on a step of the
        // stage's resolution.
        let jitter = speed * gap_s.max(recorded_gap_s) + 2.0 * resolution;
        let off = found - recorded;
        if off.abs() > self.origin_tolerance {
            let why = if off.abs() <= jitter {
                format!(
                    "the two approaches can differ by {jitter:.4} by themselves (the stage creeps {speed} per s for up to {:.3} s before the plan sees the force cross), more than the tolerance, so a moved bench cannot be told apart; fix: approach more slowly, or resume on a slower clock (`--time-scale`), or pass a wider --origin-tolerance",
                    gap_s.max(recorded_gap_s)
                )
            } else {
                "the sensor, indenter or stage has moved, and the recorded depths would not hold; fix: start a new run, or pass --origin-tolerance if the shift is known to be harmless".to_string()
            };
            return Err(Stop::Resume(format!(
                "contact on the {axis} axis found at {found:.4}, {off:+.4} from the run's recorded origin {recorded:.4} (tolerance ±{}): {why}",
                self.origin_tolerance
            )));
        }
        Ok(Some((recorded, jitter)))
    }
}

/// How late the approach behind each recorded origin can have noticed its contact, s: the
/// `reading_gap_s` of the journal's last `contact` event on that axis at that origin.
fn approach_gaps_s(dir: &Path, origins: &BTreeMap<String, f64>) -> BTreeMap<String, f64> {
    let journal = rundir::read::read_journal(dir).unwrap_or_default();
    origins
        .iter()
        .filter_map(|(axis, &origin)| {
            let gap = journal.iter().rev().find_map(|e| {
                (e["event"] == "contact"
                    && e["axis"] == axis.as_str()
                    && e["position"]
                        .as_f64()
                        .is_some_and(|p| (p - origin).abs() < 1e-9))
                .then(|| e["reading_gap_s"].as_f64())
                .flatten()
            })?;
            Some((axis.clone(), gap))
        })
        .collect()
}

impl Exec<'_> {
    /// A completed step of a resumed run, before the step it continues at: replayed as a
    /// move to where it ended (outside trials), held for its settle time if it is the last.
    pub(super) async fn replay(&mut self, s: &Step) -> Result<(), Stop> {
        let Some(r) = self.resume.as_ref() else {
            return Ok(());
        };
        let Some(&(position, settle_s)) = r.replay.get(&s.step) else {
            return Ok(());
        };
        let resettle = r.resettle == Some(s.step);
        self.what = format!("replay step {}", s.step);
        if let (Some(axis), Some(p)) = (s.axis, position) {
            self.set_phase("replaying");
            let origin = self.origin.get(&axis).copied().unwrap_or(0.0);
            self.move_axis(axis, origin + p, s.speed).await?;
        }
        let t = self.now();
        self.rec.journal(
            t,
            "replay_step",
            json!({ "step": s.step, "position": position, "hold_s": if resettle { settle_s } else { 0.0 } }),
            false,
        )?;
        if resettle {
            self.set_phase("re-settling");
            self.progress.note(&format!(
                "resume: holding step {}'s position for its {settle_s:.0} s settle before step {}",
                s.step,
                s.step + 1
            ));
            let end = self.now() + (settle_s.max(0.0) * 1e9) as u64;
            self.wait(&mut Until::Time(end)).await?;
        }
        Ok(())
    }

    /// True if the step comes before where the resumed run continues.
    pub(super) fn before_resume(&self, step: u32) -> bool {
        self.resume.as_ref().is_some_and(|r| step < r.from_step)
    }
}

/// The latest time stamped in the run's records, ns (the last whole row of each table and
/// of the journal; a torn one is skipped).
fn last_record_ns(dir: &Path) -> u64 {
    let mut last = 0;
    for name in [
        rundir::names::FORCE,
        rundir::names::AXES,
        rundir::names::FRAMES,
        rundir::names::TACTILE,
        rundir::names::STEPS,
    ] {
        let column = if name == rundir::names::STEPS {
            "t_end_ns"
        } else {
            "t_ns"
        };
        if let Some(t) = last_in_column(&dir.join(name), column) {
            last = last.max(t);
        }
    }
    if let Ok(text) = tail(&dir.join(rundir::names::JOURNAL)) {
        for line in text.lines() {
            if let Some(t) = serde_json::from_str::<serde_json::Value>(line)
                .ok()
                .and_then(|v| v.get("t_ns").and_then(serde_json::Value::as_u64))
            {
                last = last.max(t);
            }
        }
    }
    last
}

/// When the run's files were last written (a killed segment records no end), RFC 3339 UTC.
fn last_written_utc(dir: &Path) -> Option<String> {
    [
        rundir::names::JOURNAL,
        rundir::names::FORCE,
        rundir::names::FRAMES,
        rundir::names::STEPS,
        rundir::names::MANIFEST,
    ]
    .iter()
    .filter_map(|f| std::fs::metadata(dir.join(f)).ok()?.modified().ok())
    .max()
    .and_then(|t| jiff::Timestamp::try_from(t).ok())
    .map(|t| t.to_string())
}

/// The last 64 KiB of a file, as text.
fn tail(path: &Path) -> std::io::Result<String> {
    use std::io::{Read, Seek, SeekFrom};
    let mut f = std::fs::File::open(path)?;
    let end = f.seek(SeekFrom::End(0))?;
    let from = end.saturating_sub(64 * 1024);
    f.seek(SeekFrom::Start(from))?;
    let mut buf = Vec::new();
    f.read_to_end(&mut buf)?;
    Ok(String::from_utf8_lossy(&buf).into_owned())
}

/// The largest value of `column` in the whole rows of a CSV file's tail.
fn last_in_column(path: &Path, column: &str) -> Option<u64> {
    use std::io::BufRead;
    let mut header = String::new();
    std::io::BufReader::new(std::fs::File::open(path).ok()?)
        .read_line(&mut header)
        .ok()?;
    let k = header.trim_end().split(',').position(|c| c == column)?;
    let text = tail(path).ok()?;
    // From the first line break on: the tail may start inside a row.
    let rows = text.split_once('\n').map_or("", |(_, rest)| rest);
    csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .from_reader(rows.as_bytes())
        .records()
        .flatten()
        .filter_map(|r| r.get(k)?.parse::<u64>().ok())
        .max()
}
