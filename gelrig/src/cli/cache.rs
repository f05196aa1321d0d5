//! `gelrig cache`: the simulated bench's solved contact tables kept between runs.

use crate::cli::Exit;

/// Show where the table cache is and how much it holds, or clear it.
#[derive(clap::Args)]
pub(crate) struct Cmd {
    #[command(subcommand)]
    action: Option<Action>,
}

#[derive(clap::Subcommand)]
enum Action {
    /// Where the cache is, its entries and size against its limit (the default).
    Show,
    /// Delete every kept table (the next run of each contact solves them again).
    Clear,
}

fn mib(bytes: u64) -> String {
    format!("{:.1} MiB", bytes as f64 / f64::from(1 << 20))
}

impl Cmd {
    pub(crate) fn run(self) -> anyhow::Result<Exit> {
        let Some(cache) = tablecache::DiskTables::from_env() else {
            out!(
                "the table cache is off (GELRIG_NO_CACHE is set, or no folder: set GELRIG_CACHE_DIR or HOME)"
            );
            return Ok(Exit::SUCCESS);
        };
        match self.action.unwrap_or(Action::Show) {
            Action::Show => {
                let u = cache.usage()?;
                out!("table cache: {}", cache.dir().display());
                out!(
                    "{} tables, {} of {} (least recently used dropped past it; GELRIG_CACHE_MAX_MB sets it)",
                    u.entries,
                    mib(u.bytes),
                    mib(cache.max_bytes())
                );
                out!("clear it with `gelrig cache clear`; bypass it with `--no-cache`");
            }
            Action::Clear => {
                let gone = cache.clear()?;
                out!(
                    "cleared {}: {} tables, {}",
                    cache.dir().display(),
                    gone.entries,
                    mib(gone.bytes)
                );
            }
        }
        Ok(Exit::SUCCESS)
    }
}
