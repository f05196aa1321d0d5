//! `gelrig sim serve`.

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use anyhow::Context as _;
use experiments::bench::{serve, write_bound};
use experiments::protocol::load_rig;

/// Simulated devices on real transports.
#[derive(clap::Args)]
pub(crate) struct Cmd {
    #[command(subcommand)]
    action: Action,
}

#[derive(clap::Subcommand)]
enum Action {
    /// Start twins of a rig file's devices (Zaber on pseudo-terminals, Net F/T on loopback
    /// UDP/TCP) and write the rig file with their addresses; runs until Ctrl-C.
    Serve {
        /// The rig file naming the devices to twin.
        #[arg(long, value_name = "RIG.yaml")]
        rig: PathBuf,
        /// Where to write the bound rig file [default: RIG.bound.yaml beside it].
        #[arg(long, value_name = "FILE")]
        write: Option<PathBuf>,
        /// Spring stiffness coupling the normal stage to the force sensor, N/mm.
        #[arg(long, default_value_t = 12.5)]
        stiffness: f64,
    },
}

impl Cmd {
    pub(crate) fn run(self) -> anyhow::Result<ExitCode> {
        let Action::Serve {
            rig: path,
            write,
            stiffness,
        } = self.action;
        let (rig, _) = match load_rig(&path) {
            Ok(r) => r,
            Err(diags) => {
                super::report(&diags);
                return Ok(ExitCode::from(super::EXIT_INVALID));
            }
        };
        let served = serve(&rig).context("starting the twins")?;
        let out = write.unwrap_or_else(|| path.with_extension("bound.yaml"));
        write_bound(&served, &out).with_context(|| format!("writing {}", out.display()))?;
        for (role, a) in &served.bound.axes {
            if let Some(p) = &a.port {
                out!("{role}: zaber twin on {p}");
            }
        }
        if let Some(f) = &served.bound.force
            && let Some(a) = &f.address
        {
            out!(
                "force: net f/t twin at {a} (calibration port {})",
                f.calibration_port.unwrap_or(0)
            );
        }
        out!("wrote {}; Ctrl-C to stop", out.display());
        let stop = Arc::new(AtomicBool::new(false));
        let contact = rig.sim.as_ref().map_or(10.0, |s| s.normal_contact.mm());
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .context("starting the runtime")?;
        std::thread::scope(|scope| {
            let flag = stop.clone();
            let served = &served;
            scope.spawn(move || served.couple(stiffness, contact, &flag));
            let waited = rt.block_on(async {
                let mut term =
                    tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate())?;
                tokio::select! {
                    r = tokio::signal::ctrl_c() => r,
                    _ = term.recv() => Ok(()),
                }
            });
            stop.store(true, std::sync::atomic::Ordering::Relaxed);
            waited.context("waiting for Ctrl-C")
        })?;
        out!("twins stopped");
        Ok(ExitCode::SUCCESS)
    }
}
