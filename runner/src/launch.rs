//! One run of a loaded protocol, said once: what to run, where and how — seed, clock,
//! progress, live view, MCAP, resume, who hears its events — and the runtime that hosts it
//! (virtual time needs tokio's paused single-threaded clock; a real clock gives the safety
//! watchdog a worker thread of its own). The `gelrig` command, the Python package, the
//! studies and the tests all start runs through it.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use rig::ClockMode;
use rundir::write::RecordError;

use crate::events::Observer;
use crate::progress::ProgressMode;
use crate::{Cancel, Resume, RunOutcome};

/// What to run, where, and how.
pub struct Launch<'a> {
    /// The checked protocol and rig, with its plan.
    pub(crate) loaded: &'a experiments::load::Loaded,
    /// Directory that receives the run directory.
    pub(crate) out: PathBuf,
    /// Seed of simulated devices.
    pub(crate) seed: u64,
    /// Run clock.
    pub(crate) clock: ClockMode,
    /// Progress display.
    pub(crate) progress: ProgressMode,
    /// The live view's board; `None` serves nothing.
    pub(crate) live: Option<Arc<liveview::Board>>,
    /// Also write `run.mcap` as the run goes.
    pub(crate) record_mcap: bool,
    /// Continue this run in its own directory instead of starting one; `out` is then unused.
    pub(crate) resume: Option<Resume>,
    /// Who hears the run's events.
    pub(crate) observer: Option<Observer>,
}

impl<'a> Launch<'a> {
    /// A run of `loaded` into `runs/`, seed 0, in virtual time, quietly.
    pub fn new(loaded: &'a experiments::load::Loaded) -> Self {
        Self {
            loaded,
            out: PathBuf::from("runs"),
            seed: 0,
            clock: ClockMode::Virtual,
            progress: ProgressMode::Quiet,
            live: None,
            record_mcap: false,
            resume: None,
            observer: None,
        }
    }

    /// The directory that receives the run directory.
    pub fn out(mut self, dir: impl AsRef<Path>) -> Self {
        self.out = dir.as_ref().to_path_buf();
        self
    }

    /// The seed of the simulated devices (noise, sensor offset).
    pub fn seed(mut self, seed: u64) -> Self {
        self.seed = seed;
        self
    }

    /// The run's clock: virtual (as fast as possible), scaled, or real time.
    pub fn clock(mut self, clock: ClockMode) -> Self {
        self.clock = clock;
        self
    }

    /// How the run shows its progress.
    pub fn progress(mut self, progress: ProgressMode) -> Self {
        self.progress = progress;
        self
    }

    /// Feeds the live view's `board`.
    pub fn live(mut self, board: Option<Arc<liveview::Board>>) -> Self {
        self.live = board;
        self
    }

    /// Also writes `run.mcap` as the run goes.
    pub fn record_mcap(mut self, on: bool) -> Self {
        self.record_mcap = on;
        self
    }

    /// Continues an interrupted run in its own directory.
    pub fn resume(mut self, resume: Option<Resume>) -> Self {
        self.resume = resume;
        self
    }

    /// Tells `observer` every event of the run ([`crate::Event`]).
    pub fn on_event(mut self, observer: Observer) -> Self {
        self.observer = Some(observer);
        self
    }

    /// The runtime this run needs: tokio's paused single-threaded clock in virtual time
    /// (it jumps to the next timer whenever the run waits), two workers on a real or scaled
    /// clock (so nothing the plan computes can delay the watchdog).
    ///
    /// Virtual time has timers and no I/O driver: such a run has no real or twin device
    /// (either puts it on a real or scaled clock), and the signal handler and the live view
    /// keep runtimes of their own. With the driver, every timer set woke it through its
    /// event file and every wait polled it: 100 000 writes and 250 000 polls in a dry run
    /// of `box-normal-ellipse` (docs/benchmarks/dry-runs.md).
    pub fn runtime(&self) -> std::io::Result<tokio::runtime::Runtime> {
        if self.clock == ClockMode::Virtual {
            tokio::runtime::Builder::new_current_thread()
                .enable_time()
                .start_paused(true)
                .build()
        } else {
            tokio::runtime::Builder::new_multi_thread()
                .worker_threads(2)
                .enable_all()
                .build()
        }
    }

    /// Runs on the caller's runtime ([`Self::runtime`] builds the right one).
    pub async fn run(self, cancel: Cancel) -> Result<RunOutcome, RecordError> {
        crate::run(self, cancel).await
    }

    /// Runs on a runtime of its own and returns how the run ended; a device open abandoned
    /// by an interrupt is not waited for.
    pub fn run_blocking(self, cancel: Cancel) -> Result<RunOutcome, RecordError> {
        let runtime = self.runtime().map_err(|source| RecordError::Io {
            path: self.out.clone(),
            source,
        })?;
        let outcome = runtime.block_on(crate::run(self, cancel));
        runtime.shutdown_background();
        outcome
    }
}

/// The clock a run of `loaded` must use when `requested` (a time scale, or virtual time) is
/// asked for, or nothing is: the twins of `gelrig sim serve` keep their own time and the run
/// must match it; any real device puts the whole run, simulated devices included, in real
/// time; otherwise virtual time unless a scale is asked for. An error says why the request
/// cannot be kept and what to do.
pub fn clock_for(
    loaded: &experiments::load::Loaded,
    requested: Option<ClockMode>,
) -> Result<ClockMode, String> {
    let real = loaded.real_devices();
    match (&loaded.rig.twins, requested) {
        (Some(t), None) => Ok(ClockMode::Scaled {
            scale: t.time_scale,
        }),
        (Some(t), Some(ClockMode::Scaled { scale })) if scale == t.time_scale => {
            Ok(ClockMode::Scaled { scale })
        }
        (Some(t), Some(_)) => Err(format!(
            "the rig's twins run at {}× (`twins:` in {}); drop the time scale or restart \
             `gelrig sim serve` with it",
            t.time_scale,
            loaded.rig_path.display()
        )),
        (None, c) if real.is_empty() => Ok(c.unwrap_or(ClockMode::Virtual)),
        (None, Some(_)) => Err(format!(
            "this run drives real devices ({}) on rig `{}`, which run in real time; drop the \
             time scale",
            real.join(", "),
            loaded.rig.name
        )),
        (None, None) => Ok(ClockMode::Monotonic),
    }
}
