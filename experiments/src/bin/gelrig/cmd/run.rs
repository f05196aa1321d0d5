//! `gelrig run`.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use experiments::progress::ProgressMode;
use experiments::record::Status;
use experiments::runner::{Cancel, RunRequest, run};
use rig::ClockMode;

/// Run a protocol.
#[derive(clap::Args)]
pub(crate) struct Cmd {
    /// Protocol file.
    protocol: PathBuf,
    /// Rig file (default: the protocol's `rig:`).
    #[arg(long)]
    rig: Option<PathBuf>,
    /// Directory receiving the run directory.
    #[arg(long, default_value = "runs")]
    out: PathBuf,
    /// Seed of the simulated devices (noise, sensor offset).
    #[arg(long, default_value_t = 0)]
    seed: u64,
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
}

impl Cmd {
    pub(crate) fn run(self) -> anyhow::Result<ExitCode> {
        let loaded = match super::load_or_report(&self.protocol, self.rig.as_deref()) {
            Ok(l) => l,
            Err(code) => return Ok(code),
        };
        let clock = match (&loaded.rig.twins, self.time_scale.as_deref()) {
            // The twins of `gelrig sim serve` keep their own time: the run must match it.
            (Some(t), None) => ClockMode::Scaled {
                scale: t.time_scale,
            },
            (Some(t), Some(s)) => match parse_scale(s)? {
                ClockMode::Scaled { scale } if scale == t.time_scale => ClockMode::Scaled { scale },
                _ => anyhow::bail!(
                    "--time-scale {s}: the rig's twins run at {}× (`twins:` in {}); \
                     drop --time-scale or restart `gelrig sim serve` with it",
                    t.time_scale,
                    loaded.rig_path.display()
                ),
            },
            (None, s) if loaded.rig.uses_sim() => parse_scale(s.unwrap_or("virtual"))?,
            (None, Some(s)) => anyhow::bail!(
                "--time-scale {s}: rig `{}` drives real devices, which run in real time",
                loaded.rig.name
            ),
            (None, None) => ClockMode::Monotonic,
        };
        let plan = experiments::plan::plan(&loaded.protocol, &loaded.compiled, &loaded.rig);
        let mode = if self.quiet {
            ProgressMode::Quiet
        } else if self.plain {
            ProgressMode::Plain
        } else {
            ProgressMode::Auto
        };
        // Virtual time: tokio's paused clock jumps to the next timer whenever the run waits.
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .start_paused(clock == ClockMode::Virtual)
            .build()
            .context("starting the runtime")?;
        let cancel = Cancel::new();
        let outcome = runtime.block_on(async {
            let c = cancel.clone();
            tokio::spawn(async move {
                let Ok(mut term) =
                    tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate())
                else {
                    return;
                };
                loop {
                    tokio::select! {
                        r = tokio::signal::ctrl_c() => if r.is_err() { return },
                        _ = term.recv() => {},
                    }
                    c.interrupt();
                }
            });
            run(
                RunRequest {
                    loaded: &loaded,
                    plan: &plan,
                    out: self.out.clone(),
                    seed: self.seed,
                    clock,
                    progress: mode,
                },
                cancel.clone(),
            )
            .await
        });
        let outcome = outcome.context("recording the run")?;
        out!("{}", outcome.dir.display());
        let status = outcome.status.name();
        match &outcome.message {
            Some(m) => eprintln!("run {status}: {m}"),
            None => eprintln!("run {status}"),
        }
        Ok(match outcome.status {
            Status::Completed => ExitCode::SUCCESS,
            Status::Aborted if cancel.count() > 0 => ExitCode::from(130),
            Status::Aborted => ExitCode::from(3),
            Status::Failed | Status::Running => ExitCode::from(1),
        })
    }
}

/// `virtual` or a positive speed-up.
fn parse_scale(s: &str) -> anyhow::Result<ClockMode> {
    if s == "virtual" {
        return Ok(ClockMode::Virtual);
    }
    let scale: f64 = s
        .parse()
        .ok()
        .filter(|v: &f64| *v > 0.0 && v.is_finite())
        .with_context(|| {
            format!("--time-scale `{s}`: write `virtual` or a positive number, e.g. 60")
        })?;
    Ok(ClockMode::Scaled { scale })
}
