//! `gelrig sim serve`.

use crate::cli::Exit;
use std::path::PathBuf;

use crate::sim::bench::{ServeOptions, serve, write_bound};
use crate::{protocol::load_rig, sim::plant_spec};
use anyhow::Context as _;

/// Simulated devices on real transports.
#[derive(clap::Args)]
pub(crate) struct Cmd {
    #[command(subcommand)]
    action: Action,
}

#[derive(clap::Subcommand)]
enum Action {
    /// Start twins of a rig file's devices (Zaber and SMC100 on pseudo-terminals, Modbus on
    /// loopback TCP or a pseudo-terminal, Net F/T on loopback UDP/TCP) and write the rig
    /// file with their addresses; runs until Ctrl-C or SIGTERM.
    Serve {
        /// The rig file naming the devices to twin.
        #[arg(long, value_name = "RIG.yaml")]
        rig: PathBuf,
        /// A protocol whose sensor and indenter the twins simulate: the force sensor then
        /// reads the same elastomer as a dry run. Without it the force reads zero.
        #[arg(long, value_name = "PROTOCOL.yaml")]
        protocol: Option<PathBuf>,
        /// Speed-up over the wall of the stages and the elastomer (a run against the
        /// bound rig uses the same), e.g. 100 runs an hour-long protocol in 36 s.
        #[arg(long, default_value_t = 1.0)]
        time_scale: f64,
        /// Seed of the simulated sensor's noise and offset.
        #[arg(long, default_value_t = 0)]
        seed: u64,
        /// Where to write the bound rig file [default: RIG.bound.yaml beside it].
        #[arg(long, value_name = "FILE")]
        write: Option<PathBuf>,
        /// The stage twins show motion this many milliseconds (of plant time) after a
        /// command, as real drives do (try 20–200 to check a rig file's completion
        /// settings).
        #[arg(long, default_value_t = 0.0, value_name = "MS")]
        drive_latency_ms: f64,
        /// The stage twins come to rest this many device steps past their target.
        #[arg(long, default_value_t = 0.0, value_name = "N")]
        overshoot_steps: f64,
    },
}

impl Cmd {
    pub(crate) fn run(self) -> anyhow::Result<Exit> {
        let Action::Serve {
            rig: path,
            protocol,
            time_scale,
            seed,
            write,
            drive_latency_ms,
            overshoot_steps,
        } = self.action;
        if !(0.0..=10_000.0).contains(&drive_latency_ms)
            || !(0.0..=1000.0).contains(&overshoot_steps)
        {
            err!("error: --drive-latency-ms must be 0–10000 and --overshoot-steps 0–1000");
            return Ok(Exit::from(super::EXIT_INVALID));
        }
        let (rig, plant) = match &protocol {
            Some(p) => {
                let loaded =
                    match super::load_or_report(p, Some(&path), &super::BudgetArgs::default()) {
                        Ok(l) => l,
                        Err(code) => return Ok(code),
                    };
                let spec = plant_spec(&loaded.protocol, &loaded.compiled)
                    .map_err(anyhow::Error::msg)
                    .with_context(|| format!("the elastomer of {}", p.display()))?;
                let axes = loaded.compiled.needs.axes.clone();
                (loaded.rig, Some((spec, axes)))
            }
            None => match load_rig(&path) {
                Ok((rig, _)) => (rig, None),
                Err(diags) => {
                    super::report(&diags);
                    return Ok(Exit::from(super::EXIT_INVALID));
                }
            },
        };
        if protocol.is_none() && rig.force.is_some() {
            err!("note: no --protocol: the force sensor twin reads zero");
        }
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .context("starting the runtime")?;
        // Modbus TCP twins are tasks of this runtime: everything lives inside one block_on.
        rt.block_on(async {
            let options = ServeOptions {
                time_scale,
                plant,
                seed,
                drive_latency: std::time::Duration::from_secs_f64(drive_latency_ms * 1e-3),
                overshoot_steps,
            };
            let served = serve(&rig, options)
                .await
                .map_err(anyhow::Error::msg)
                .context("starting the twins")?;
            let out = write.unwrap_or_else(|| path.with_extension("bound.yaml"));
            write_bound(&served, &out).with_context(|| format!("writing {}", out.display()))?;
            for line in &served.listing {
                out!("{line}");
            }
            out!("time scale {time_scale}×");
            out!("wrote {}; Ctrl-C to stop", out.display());
            let mut term =
                tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate())
                    .context("listening for SIGTERM")?;
            tokio::select! {
                r = tokio::signal::ctrl_c() => r.context("waiting for Ctrl-C")?,
                _ = term.recv() => {},
            }
            drop(served);
            out!("twins stopped");
            anyhow::Ok(Exit::SUCCESS)
        })
    }
}
