//! `gelrig run`.

use crate::cli::Exit;
use std::path::PathBuf;
use std::sync::Arc;

use crate::run::ClockMode;
use crate::run::ProgressMode;
use crate::run::{Cancel, Launch};
use crate::runs::Status;
use anyhow::Context;

/// How a run is timed, shown and watched (`gelrig run` and `gelrig resume`).
#[derive(clap::Args)]
pub(crate) struct RunOpts {
    /// Clock of a simulated rig: `virtual` (as fast as possible) or a speed-up over real
    /// time, e.g. `60` (an hour in a minute) or `1` (real time).
    /// [default: `virtual`; the `twins:` scale of a `gelrig sim serve` rig]
    #[arg(long)]
    time_scale: Option<String>,
    /// Plain progress lines even on a terminal.
    #[arg(long, conflicts_with = "quiet")]
    plain: bool,
    /// No progress output.
    #[arg(long)]
    quiet: bool,
    /// Watch the run in a browser: serves a read-only page on ADDR (default 127.0.0.1 and a
    /// free port) and prints its URL. Without it, the run opens no socket.
    #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = "127.0.0.1:0")]
    live: Option<String>,
}

/// Run a protocol, or several in sequence.
#[derive(clap::Args)]
pub(crate) struct Cmd {
    /// Protocol file(s): several run one after the other (a queue), all checked before the
    /// first starts; the queue stops at the first run that does not complete.
    #[arg(required = true, num_args = 1..)]
    protocols: Vec<PathBuf>,
    /// Rig file (default: the protocol's `rig:`).
    #[arg(long)]
    rig: Option<PathBuf>,
    #[command(flatten)]
    budget: super::BudgetArgs,
    /// Directory receiving the run directory.
    #[arg(long, default_value = "runs")]
    out: PathBuf,
    /// Seed of the simulated devices (noise, sensor offset).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    #[command(flatten)]
    pub(crate) opts: RunOpts,
    /// Also write the run as it goes in another format, beside the CSVs: `mcap` writes
    /// `run.mcap` (ROS 2 messages, as `gelrig export --format mcap` does).
    #[arg(long, value_name = "FORMAT", value_parser = ["mcap"])]
    record: Option<String>,
}

impl Cmd {
    pub(crate) fn run(self) -> anyhow::Result<Exit> {
        // First of all: from here on, Ctrl-C and SIGTERM are counted, never fatal, so the
        // operator's interrupt always ends in a recorded stop.
        let cancel = Cancel::new();
        watch_signals(cancel.clone())?;
        if self.protocols.len() > 1 && self.budget.has_name() {
            err!(
                "error: --name names one run, and {} protocols are queued; fix: drop --name, or run them one by one",
                self.protocols.len()
            );
            return Ok(Exit::from(super::EXIT_INVALID));
        }
        // The whole queue is checked before anything moves: a typo in the third protocol
        // must not be found at two in the morning.
        let mut queue = Vec::new();
        for p in &self.protocols {
            let loaded = match super::load_or_report(p, self.rig.as_deref(), &self.budget) {
                Ok(l) => l,
                Err(code) => return Ok(code),
            };
            let clock = match self.opts.clock(&loaded) {
                Ok(c) => c,
                Err(e) => {
                    err!("error: {}: {e}", p.display());
                    return Ok(Exit::from(super::EXIT_INVALID));
                }
            };
            queue.push((loaded, clock));
        }
        let mut live: Option<(Arc<crate::view::LiveRun>, crate::live::Server)> = None;
        let total = queue.len();
        for (k, (loaded, clock)) in queue.iter().enumerate() {
            if total > 1 {
                err!("queue: {} of {total}: {}", k + 1, loaded.protocol.name);
            }
            let code = execute(
                &self.opts,
                Target {
                    out: &self.out,
                    seed: self.seed,
                    record_mcap: self.record.as_deref() == Some("mcap"),
                    resume: None,
                },
                loaded,
                *clock,
                &cancel,
                &mut live,
            )?;
            if code != Exit::SUCCESS {
                if k + 1 < total {
                    let left: Vec<&str> = queue[k + 1..]
                        .iter()
                        .map(|(l, _)| l.protocol.name.as_str())
                        .collect();
                    err!(
                        "queue stopped: run {} of {total} did not complete; not run: {}",
                        k + 1,
                        left.join(", ")
                    );
                }
                return Ok(code);
            }
        }
        end_live(live);
        Ok(Exit::SUCCESS)
    }
}

/// The live view's library and server, started with the first run that asks.
pub(crate) type Live = Option<(Arc<crate::view::LiveRun>, crate::live::Server)>;

/// Lets the page's next poll show how the last run ended before the server goes.
pub(crate) fn end_live(live: Live) {
    if let Some((_, server)) = live {
        std::thread::sleep(std::time::Duration::from_millis(1500));
        drop(server);
    }
}

/// Where a run records: a new directory under `out`, or the one it resumes.
pub(crate) struct Target<'a> {
    pub(crate) out: &'a std::path::Path,
    pub(crate) seed: u64,
    pub(crate) record_mcap: bool,
    pub(crate) resume: Option<crate::run::Resume>,
}

/// Runs one protocol (of a queue, or resumed); its exit code. The live view's server, when
/// asked for, is started with the first run and shows each run of the queue in turn.
pub(crate) fn execute(
    opts: &RunOpts,
    target: Target<'_>,
    loaded: &crate::protocol::Loaded,
    clock: ClockMode,
    cancel: &Cancel,
    live: &mut Live,
) -> anyhow::Result<Exit> {
    {
        let mode = if opts.quiet {
            ProgressMode::Quiet
        } else if opts.plain {
            ProgressMode::Plain
        } else {
            ProgressMode::Auto
        };
        if cancel.count() > 0 {
            err!("interrupted before the run started: nothing ran, no run directory");
            return Ok(Exit::from(130));
        }
        if let (false, Some(sim)) = (opts.quiet, &loaded.plan.sim) {
            err!("{}", sim.summary());
        }
        let board = opts
            .live
            .is_some()
            .then(|| crate::live::Board::new(crate::view::live_meta(loaded, &loaded.plan, clock)));
        if let (Some(addr), Some(b)) = (&opts.live, &board) {
            match live {
                Some((lib, _)) => lib.set(b.clone()),
                None => {
                    let lib = Arc::new(crate::view::LiveRun::new(b.clone()));
                    let server = super::serve(addr, lib.clone())?;
                    err!("live view: {}", server.url());
                    *live = Some((lib, server));
                }
            }
        }
        let outcome = Launch::new(loaded)
            .out(target.out)
            .seed(target.seed)
            .clock(clock)
            .progress(mode)
            .live(board)
            .record_mcap(target.record_mcap)
            .resume(target.resume)
            .run_blocking(cancel.clone());
        let outcome = outcome.context("recording the run")?;
        // A table cache that could not be written costs the next run a solve, not this
        // run its data: said, not failed.
        for p in tablecache::problems() {
            err!("warning: {p}");
        }
        out!("{}", outcome.dir.display());
        let status = outcome.status.name();
        match &outcome.message {
            Some(m) => err!("run {status}: {m}"),
            None => err!("run {status}"),
        }
        Ok(match outcome.status {
            Status::Completed => Exit::SUCCESS,
            Status::Aborted if cancel.count() > 0 => Exit::from(130),
            Status::Aborted => Exit::from(3),
            Status::Failed | Status::Running => Exit::from(1),
        })
    }
}

impl RunOpts {
    /// The run's clock: the twins' scale, virtual or `--time-scale` on a simulated rig,
    /// real time as soon as any real device is opened.
    pub(crate) fn clock(&self, loaded: &crate::protocol::Loaded) -> anyhow::Result<ClockMode> {
        let requested = self.time_scale.as_deref().map(parse_scale).transpose()?;
        crate::run::clock_for(loaded, requested).map_err(|e| {
            let s = self.time_scale.as_deref().unwrap_or_default();
            anyhow::anyhow!("--time-scale {s}: {e}")
        })
    }
}

/// Installs SIGINT and SIGTERM handlers that count into `cancel`, on a thread of their own
/// (the run's runtime cannot exist yet: whether its clock is virtual depends on the rig,
/// which is still to be read). Returns once the handlers are in place.
pub(crate) fn watch_signals(cancel: Cancel) -> anyhow::Result<()> {
    let (ready_tx, ready_rx) = std::sync::mpsc::channel();
    std::thread::Builder::new()
        .name("signals".into())
        .spawn(move || {
            let rt = match tokio::runtime::Builder::new_current_thread()
                .enable_io()
                .build()
            {
                Ok(rt) => rt,
                Err(e) => {
                    let _ = ready_tx.send(Err(e.to_string()));
                    return;
                }
            };
            rt.block_on(async move {
                use tokio::signal::unix::{SignalKind, signal};
                let (mut int, mut term) = match (
                    signal(SignalKind::interrupt()),
                    signal(SignalKind::terminate()),
                ) {
                    (Ok(i), Ok(t)) => (i, t),
                    (Err(e), _) | (_, Err(e)) => {
                        let _ = ready_tx.send(Err(e.to_string()));
                        return;
                    }
                };
                let _ = ready_tx.send(Ok(()));
                loop {
                    tokio::select! {
                        _ = int.recv() => {}
                        _ = term.recv() => {}
                    }
                    cancel.interrupt();
                }
            });
        })
        .context("starting the signal thread")?;
    match ready_rx.recv() {
        Ok(Ok(())) => Ok(()),
        Ok(Err(e)) => anyhow::bail!("installing the Ctrl-C and SIGTERM handlers: {e}"),
        Err(_) => anyhow::bail!("installing the Ctrl-C and SIGTERM handlers: the thread ended"),
    }
}

/// `virtual` or a positive speed-up.
fn parse_scale(s: &str) -> anyhow::Result<ClockMode> {
    if s == "virtual" {
        return Ok(ClockMode::Virtual);
    }
    // Below 1/100 a step's settle would take days of wall time; above 10⁵ the wall's
    // millisecond timer is a hundred seconds of run time and nothing can be timed.
    let scale: f64 = s
        .parse()
        .ok()
        .filter(|v: &f64| (0.01..=1e5).contains(v))
        .with_context(|| {
            format!(
                "--time-scale `{s}`: write `virtual` or a speed-up between 0.01 and 100000, e.g. 60"
            )
        })?;
    Ok(ClockMode::Scaled { scale })
}
