//! `gelrig view`.

use crate::cli::Exit;
use std::path::PathBuf;
use std::sync::Arc;

/// Open finished runs in the browser: the list of runs, each run's page and report.
#[derive(clap::Args)]
pub(crate) struct Cmd {
    /// A runs directory (every run in it), or one run directory.
    #[arg(default_value = "runs")]
    path: PathBuf,
    /// Address to serve on [default: 127.0.0.1 and a free port].
    #[arg(long, value_name = "ADDR", default_value = "127.0.0.1:0")]
    addr: String,
}

impl Cmd {
    pub(crate) fn run(self) -> anyhow::Result<Exit> {
        let runs = match crate::view::RunsOnDisk::open(&self.path) {
            Ok(r) => r,
            Err(e) => {
                err!("error: {e}");
                return Ok(Exit::from(super::EXIT_INVALID));
            }
        };
        let server = super::serve(&self.addr, Arc::new(runs))?;
        err!("view: {} (Ctrl-C to stop)", server.url());
        out!("{}", server.url());
        wait_for_interrupt()?;
        drop(server);
        Ok(Exit::SUCCESS)
    }
}

/// Blocks until SIGINT or SIGTERM.
fn wait_for_interrupt() -> anyhow::Result<()> {
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_io()
        .build()?;
    rt.block_on(async {
        use tokio::signal::unix::{SignalKind, signal};
        let mut int = signal(SignalKind::interrupt())?;
        let mut term = signal(SignalKind::terminate())?;
        tokio::select! {
            _ = int.recv() => {}
            _ = term.recv() => {}
        }
        Ok::<_, std::io::Error>(())
    })?;
    Ok(())
}
