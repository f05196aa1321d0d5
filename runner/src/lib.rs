//! Executes a compiled protocol on a rig: move, wait for motion, settle, capture, record.
//!
//! Two tasks on the run's clock. The **watchdog** ([`watchdog`]) owns the force sensor: it
//! reads it at the safety monitor's rate (and the force stream's), judges every reading
//! against the limits and for freshness, and on a fault stops every axis itself, without
//! waiting for the plan. The **plan task** ([`Exec`]) walks the compiled actions: it moves
//! axes ([`motion`]), waits ([`wait`]) while servicing streams and taking the watchdog's
//! readings for settle rules ([`settle`]), capture windows and the record, and runs each
//! block ([`blocks`]). On one thread in virtual time the two interleave deterministically
//! and the clock jumps from one due event to the next; on a real clock they run on
//! separate worker threads, so a plan busy encoding a frame or waiting on a slow reply
//! cannot delay the watchdog.
//!
//! Every wait has a deadline: moves from distance, speed and a margin, homing from the
//! travel, an approach from its travel, device replies from the drivers' timeouts.
//!
//! Every way a run ends goes through the same exit: stop all motion, send each axis with a
//! retract position there ([`retract`]), record final positions, write the manifest's final
//! status. Ctrl-C (or SIGTERM) wakes any wait and aborts; a second one gives up the retract.

mod adaptive;
mod blocks;
mod cancel;
pub mod events;
mod exec;
mod frame_force;
mod launch;
mod motion;
pub mod progress;
mod resume;
mod retract;
mod settle;
mod step;
mod tactile;
mod wait;
mod watchdog;

use std::collections::BTreeMap;
use std::path::PathBuf;

use rig::{Clock, ClockMode, RigError};
use serde_json::json;
use simbench::{OpenRequest, Rig};

use crate::progress::Progress;
use experiments::load::Loaded;
use experiments::protocol::plant_spec;
use rundir::write::{DeviceRecord, Manifest, RecordError, Recorder, Status};

pub use cancel::Cancel;
pub use events::{Event, Observer};
use exec::Exec;
pub use launch::{Launch, clock_for};
pub use resume::Resume;
use watchdog::{Limits, Monitor, TripKind, WatchConfig};

/// Where a run keeps a copy of the sensor file it read the GelSight's force with.
pub const GELSIGHT_SENSOR_FILE: &str = rundir::names::GELSIGHT_SENSOR;

/// The sensor file of `record.gelsight_force` (relative to the protocol), read before any
/// step runs; a file that does not read stops the run there, naming why.
fn gelsight_sensor(loaded: &Loaded) -> Result<Option<sensing::sensor::SensorFile>, String> {
    let Some(rel) = &loaded.protocol.record.gelsight_force else {
        return Ok(None);
    };
    let base = loaded.path.parent().unwrap_or(std::path::Path::new("."));
    sensing::sensor::SensorFile::read(&base.join(rel))
        .map(Some)
        .map_err(|e| e.to_string())
}

/// The camera's image scale, mm/px: the sensor's view fitted into the frame (as `gelrig
/// track` reads a run directory's scale).
fn image_scale(loaded: &Loaded, rig: &Rig) -> Option<f64> {
    let cam = rig.camera.as_ref()?.info();
    let spec = plant_spec(&loaded.protocol, &loaded.compiled).ok()?;
    let s = (spec.view_width_mm / cam.width as f64).max(spec.view_height_mm / cam.height as f64);
    (s.is_finite() && s > 0.0).then_some(s)
}

/// How a run ended.
#[derive(Debug, Clone, PartialEq)]
pub struct RunOutcome {
    /// The run directory.
    pub dir: PathBuf,
    /// Final status.
    pub status: Status,
    /// Abort reason or error.
    pub message: Option<String>,
}

/// Why execution stopped early.
#[derive(Debug, thiserror::Error)]
enum Stop {
    #[error("interrupted by the operator")]
    Interrupted,
    #[error("safety limit: {0}")]
    Safety(String),
    #[error("safety monitor: {0}; the watchdog stopped every axis")]
    Blind(String),
    #[error("{0}")]
    SettleTimeout(String),
    #[error("{0}")]
    NoContact(String),
    #[error("{0}")]
    Stuck(String),
    #[error("{0}")]
    Missed(String),
    #[error(transparent)]
    Device(#[from] RigError),
    #[error("recording failed: {0}")]
    Record(#[from] RecordError),
    #[error("record.gelsight_force: {0}")]
    Sensor(String),
    #[error("resume refused: {0}")]
    Resume(String),
}

impl Stop {
    fn status(&self) -> Status {
        match self {
            Stop::Interrupted | Stop::Safety(_) | Stop::SettleTimeout(_) => Status::Aborted,
            Stop::Blind(_)
            | Stop::NoContact(_)
            | Stop::Stuck(_)
            | Stop::Missed(_)
            | Stop::Device(_)
            | Stop::Record(_)
            | Stop::Sensor(_)
            | Stop::Resume(_) => Status::Failed,
        }
    }
}

fn clock_label(mode: ClockMode) -> String {
    match mode {
        ClockMode::Virtual => "virtual".into(),
        ClockMode::Scaled { scale } => format!("scaled x{scale}"),
        ClockMode::Monotonic => "monotonic".into(),
    }
}

/// The clock's speed-up over the wall; `None` in virtual time.
pub fn time_scale(mode: ClockMode) -> Option<f64> {
    match mode {
        ClockMode::Virtual => None,
        ClockMode::Scaled { scale } => Some(scale),
        ClockMode::Monotonic => Some(1.0),
    }
}

pub(crate) fn period_ns(hz: f64) -> u64 {
    (1e9 / hz).round().max(1.0) as u64
}

/// Dry-runs `loaded` on its simulated rig in virtual time with `seed` into a new run
/// directory under `out`, quietly, on a runtime of its own (for studies and scripts; the
/// `gelrig run` command does the same with progress and signals).
pub fn run_virtual_blocking(
    loaded: &experiments::load::Loaded,
    out: &std::path::Path,
    seed: u64,
) -> Result<RunOutcome, RecordError> {
    Launch::new(loaded)
        .out(out)
        .seed(seed)
        .run_blocking(Cancel::new())
}

/// Runs `req`; returns how it ended. Fails only if the run directory cannot be created.
pub async fn run(req: Launch<'_>, cancel: Cancel) -> Result<RunOutcome, RecordError> {
    let loaded = req.loaded;
    let p = &loaded.protocol;
    let clock = match &req.resume {
        Some(r) => Clock::starting_at(req.clock, r.t_start_ns),
        None => Clock::new(req.clock),
    };
    let mut rec = open_record(&req, &clock)?;
    let progress = Progress::new(
        req.progress,
        loaded.compiled.steps,
        req.loaded.plan.duration_s.max,
        time_scale(req.clock),
    )
    .with_live(req.live.clone())
    .with_observer(req.observer.clone());
    if let Some(b) = progress.live() {
        b.set_dir(&rec.dir().display().to_string());
    }
    let _ = rec.journal(
        clock.now_ns(),
        "run_start",
        json!({"protocol": p.name, "rig": loaded.rig.name, "seed": req.seed, "clock": clock_label(req.clock)}),
        true,
    );
    if cancel.count() > 0 {
        let msg = "interrupted by the operator before the devices were opened; nothing moved";
        return finish(rec, &clock, &progress, Status::Aborted, Some(msg.into()));
    }
    // Opening builds the simulated bench's contact model (up to seconds of computation) and
    // talks to real devices: off this thread, so an interrupt is seen at once.
    let rig = tokio::select! {
        r = open_bench(loaded, &clock, req.seed) => match r {
            Ok(r) => r,
            Err(e) => return finish(rec, &clock, &progress, Status::Failed, Some(e)),
        },
        _ = cancel.interrupted(0) => {
            let msg = "interrupted by the operator while the devices were being opened; nothing moved";
            return finish(rec, &clock, &progress, Status::Aborted, Some(msg.into()));
        }
    };
    let devices = device_records(&rig);
    if let Some(Err(why)) = req.resume.as_ref().map(|r| r.check_devices(&devices)) {
        let msg = format!("resume refused before anything moved: {why}");
        return finish(rec, &clock, &progress, Status::Failed, Some(msg));
    }
    let opened = rec
        .update_manifest(|m| m.devices = devices.clone())
        .and_then(|()| {
            rec.journal(
                clock.now_ns(),
                "devices_opened",
                json!({ "devices": devices }),
                true,
            )
        });
    let mut rig = rig;
    let monitor = start_watchdog(&mut rig, loaded, &clock, req.clock);
    let mut exec = Exec::new(rig, monitor, clock.clone(), rec, &progress, cancel, loaded);
    exec.mm_per_px = image_scale(loaded, &exec.rig);
    exec.resume = req.resume.clone();
    let result = match (opened, gelsight_sensor(loaded)) {
        (Ok(()), Ok(sensor)) => run_plan(&mut exec, sensor, loaded).await,
        (Err(e), _) => Err(Stop::Record(e)),
        (_, Err(why)) => Err(Stop::Sensor(why)),
    };
    let (status, message) = exec.stopped(result).await;
    let retract = exec.retract().await;
    let (status, message) = with_retract(status, message, retract);
    let rec = exec.close().await;
    finish(rec, &clock, &progress, status, message)
}

/// The manifest a new run starts with (status `running`, nothing done yet).
fn new_manifest(req: &Launch<'_>) -> Manifest {
    let loaded = req.loaded;
    Manifest {
        status: Status::Running,
        reason: None,
        error: None,
        protocol: loaded.protocol.name.clone(),
        protocol_file: loaded.path.display().to_string(),
        rig: loaded.rig.name.clone(),
        rig_file: loaded.rig_path.display().to_string(),
        started_utc: jiff::Timestamp::now().to_string(),
        ended_utc: None,
        gelrig_version: env!("CARGO_PKG_VERSION").to_string(),
        seed: req.seed,
        clock: clock_label(req.clock),
        pid: std::process::id(),
        steps_planned: loaded.compiled.steps,
        steps_completed: 0,
        eta_s: [
            (req.loaded.plan.duration_s.min * 10.0).round() / 10.0,
            (req.loaded.plan.duration_s.max * 10.0).round() / 10.0,
        ],
        devices: Vec::new(),
        tare: None,
        origins: BTreeMap::new(),
        final_positions: BTreeMap::new(),
        safety_events: Vec::new(),
        warnings: loaded
            .warnings
            .iter()
            .map(|d| format!("{}:{}: {}", d.line, d.column, d.message))
            .collect(),
        resumed: Vec::new(),
        timing: BTreeMap::new(),
    }
}

/// The run's recorder: a new run directory under `req.out`, or the resumed run's own
/// (journaled as a resume); `run.mcap` is written when asked, and a resumed run goes on
/// writing it if its first segment did.
fn open_record(req: &Launch<'_>, clock: &Clock) -> Result<Recorder, RecordError> {
    let loaded = req.loaded;
    let manifest = new_manifest(req);
    let mut rec = match &req.resume {
        None => {
            // The resolved protocol (sensor defaults filled in) is what actually ran.
            let protocol_yaml =
                serde_yaml::to_string(&loaded.protocol).unwrap_or_else(|_| loaded.text.clone());
            Recorder::create(&req.out, manifest, &protocol_yaml, &loaded.rig_text)?
        }
        Some(r) => {
            let (mut rec, cut) = Recorder::reopen(&r.dir, |m| r.begin(m))?;
            let _ = rec.journal(clock.now_ns(), "resume", r.record(&cut), true);
            rec
        }
    };
    match &req.resume {
        Some(r) if req.record_mcap || r.dir.join(rundir::names::MCAP).is_file() => {
            rec.record_mcap_resumed(&loaded.rig_text)?;
        }
        None if req.record_mcap => rec.record_mcap(&loaded.rig_text)?,
        _ => {}
    }
    Ok(rec)
}

/// The opened devices as the manifest records them.
fn device_records(rig: &Rig) -> Vec<DeviceRecord> {
    rig.opened
        .iter()
        .map(|d| DeviceRecord {
            role: d.role.clone(),
            identity: d.identity.clone(),
        })
        .collect()
}

/// Runs the protocol's actions with the GelSight sensor file read for it (if any), after
/// keeping a copy of that file in the run directory: the protocol only names it, and the
/// file may be recalibrated later.
async fn run_plan(
    exec: &mut Exec<'_>,
    sensor: Option<sensing::sensor::SensorFile>,
    loaded: &Loaded,
) -> Result<(), Stop> {
    let kept = match &sensor {
        Some(s) => s
            .write(&exec.rec.dir().join(GELSIGHT_SENSOR_FILE))
            .map_err(|e| Stop::Sensor(e.to_string())),
        None => Ok(()),
    };
    exec.gelsight = sensor.map(std::sync::Arc::new);
    match kept {
        Ok(()) => exec.run_actions(&loaded.compiled.actions).await,
        Err(e) => Err(e),
    }
}

/// The run's status and message once the retract is done: a failed retract fails a
/// completed run, and is added to the message of one that had already stopped.
fn with_retract(
    status: Status,
    message: Option<String>,
    retract: Result<(), String>,
) -> (Status, Option<String>) {
    match (status, retract) {
        (s, Ok(())) => (s, message),
        (Status::Completed, Err(e)) => (
            Status::Failed,
            Some(format!("run completed but the retract failed: {e}")),
        ),
        (s, Err(e)) => (
            s,
            Some(format!(
                "{}; retract failed: {e}",
                message.unwrap_or_default()
            )),
        ),
    }
}

/// Starts the watchdog on the rig's force sensor, with a stopper for every axis.
fn start_watchdog(
    rig: &mut Rig,
    loaded: &Loaded,
    clock: &Clock,
    mode: ClockMode,
) -> Option<Monitor> {
    let sensor = rig.force.take()?;
    let safety = &loaded.protocol.safety;
    let monitor_period_ns = period_ns(safety.monitor_rate.map(|r| r.hz()).unwrap_or(50.0));
    let info = sensor.info().clone();
    let config = WatchConfig {
        monitor_period_ns,
        stale_ns: WatchConfig::stale_bound_ns(
            monitor_period_ns,
            info.max_rate_hz,
            match mode {
                ClockMode::Scaled { scale } => Some(scale),
                _ => None,
            },
        ),
        range: info.range,
    };
    let limits = Limits {
        max_fz_n: safety.max_fz.n(),
        max_fxy_n: safety.max_fxy.n(),
        max_tz_nmm: safety.max_tz.nmm(),
    };
    let stoppers = rig.axes.iter().map(|(r, a)| (*r, a.stopper())).collect();
    Some(Monitor::start(
        sensor,
        stoppers,
        limits,
        config,
        clock.clone(),
    ))
}

/// Opens the devices the protocol needs, building the simulated bench if the rig has one.
/// Runs on the blocking pool: the contact model's precomputation must not hold the thread
/// that sees interrupts.
async fn open_bench(loaded: &Loaded, clock: &Clock, seed: u64) -> Result<Rig, String> {
    let plant = if loaded.rig.uses_sim() {
        Some(
            plant_spec(&loaded.protocol, &loaded.compiled)
                .map_err(|e| format!("simulated bench: {e}"))?,
        )
    } else {
        None
    };
    let needs = &loaded.compiled.needs;
    let open = OpenRequest {
        axes: needs.axes.clone(),
        force: needs.force,
        camera: needs.camera,
        disturber: needs.disturber,
        plant,
        clock: clock.clone(),
        seed,
        traction_maps_px: loaded.protocol.record.traction_maps,
    };
    let config = loaded.rig.clone();
    let handle = tokio::runtime::Handle::current();
    let opening =
        tokio::task::spawn_blocking(move || handle.block_on(simbench::open(&config, open)));
    match opening.await {
        Ok(r) => r.map_err(|e| format!("opening devices: {e}")),
        Err(e) => Err(format!("opening devices: {e}")),
    }
}

fn finish(
    mut rec: Recorder,
    clock: &Clock,
    progress: &Progress,
    status: Status,
    message: Option<String>,
) -> Result<RunOutcome, RecordError> {
    progress.finish();
    // Frames still queued for the encoder are part of the run: a failure writing them
    // fails it (the data is incomplete), whatever the plan's own outcome.
    let (status, message) = match rec.flush_frames() {
        Ok(()) => (status, message),
        Err(e) => (Status::Failed, Some(format!("writing frames: {e}"))),
    };
    let _ = rec.journal(
        clock.now_ns(),
        "run_end",
        json!({ "status": status.name(), "message": message }),
        true,
    );
    let written = rec.update_manifest(|m| {
        m.status = status;
        m.ended_utc = Some(jiff::Timestamp::now().to_string());
        match status {
            Status::Aborted => m.reason = message.clone(),
            Status::Failed => m.error = message.clone(),
            _ => {}
        }
    });
    rec.finish_mcap();
    if let Some(msg) = rec.mcap_failure() {
        progress.note(&format!("warning: {msg}"));
        let _ = rec.update_manifest(|m| m.warnings.push(msg));
    }
    rec.close();
    if let Some(b) = progress.live() {
        b.finished(status.name(), message.as_deref());
    }
    progress.emit(events::Event::End {
        status: status.name().to_string(),
        message: message.clone(),
        dir: rec.dir().display().to_string(),
    });
    written?;
    Ok(RunOutcome {
        dir: rec.dir().to_path_buf(),
        status,
        message,
    })
}

/// The journal and manifest record of a watchdog trip.
fn trip_record(t: &watchdog::Trip) -> serde_json::Value {
    json!({
        "kind": match t.kind { TripKind::Limit => "limit", TripKind::Sensor => "sensor" },
        "message": t.message,
        "t_sample_ns": t.t_sample_ns,
        "t_detect_ns": t.t_detect_ns,
        "t_stop_sent_ns": t.t_stop_sent_ns,
        "detect_to_stop_wall_us": (t.detect_to_stop_wall_us * 10.0).round() / 10.0,
        "reading": t.reading.map(|w| w.as_array().map(|v| (v * 1e6).round() / 1e6)),
        "stop_errors": t.stop_errors,
    })
}
