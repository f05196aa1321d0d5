//! `gelrig resume`.

use crate::cli::Exit;
use std::path::PathBuf;

use crate::run::{Cancel, GELSIGHT_SENSOR_FILE, Resume};

use super::run::{RunOpts, Target, end_live, execute, watch_signals};

/// Continue an interrupted, aborted or failed run in its own directory.
#[derive(clap::Args)]
pub(crate) struct Cmd {
    /// The run directory (as `gelrig run` printed it).
    run_dir: PathBuf,
    /// How far the re-found contact may lie from the run's recorded origin, in the
    /// approached axis's unit (mm for a linear stage); beyond it the resume is refused.
    #[arg(long, value_name = "DISTANCE", default_value_t = 0.02)]
    origin_tolerance: f64,
    /// Also write the run as it goes in another format: `mcap` writes `run.mcap` (the whole
    /// run: the earlier segments first). A run whose first segment wrote it goes on
    /// writing it without this.
    #[arg(long, value_name = "FORMAT", value_parser = ["mcap"])]
    record: Option<String>,
    #[command(flatten)]
    opts: RunOpts,
}

impl Cmd {
    pub(crate) fn run(self) -> anyhow::Result<Exit> {
        let cancel = Cancel::new();
        watch_signals(cancel.clone())?;
        let dir = &self.run_dir;
        if !(self.origin_tolerance.is_finite() && self.origin_tolerance >= 0.0) {
            err!(
                "error: --origin-tolerance {}: give a distance of zero or more, e.g. 0.02",
                self.origin_tolerance
            );
            return Ok(Exit::from(super::EXIT_INVALID));
        }
        if !dir.join(crate::runs::names::MANIFEST).is_file() {
            err!(
                "error: {}: not a run directory (no run.yaml); fix: give a directory `gelrig run` made (`gelrig runs` lists them)",
                dir.display()
            );
            return Ok(Exit::from(super::EXIT_INVALID));
        }
        // The run goes on with the protocol and rig it recorded, not whatever the files
        // it was started from say now.
        let mut loaded = match super::load_or_report(
            &dir.join(crate::runs::names::PROTOCOL),
            Some(&dir.join(crate::runs::names::RIG)),
            &super::BudgetArgs::default(),
        ) {
            Ok(l) => l,
            Err(code) => return Ok(code),
        };
        if loaded.protocol.record.gelsight_force.is_some() {
            // The copy of the sensor file the run read its GelSight force with.
            loaded.protocol.record.gelsight_force = Some(GELSIGHT_SENSOR_FILE.into());
        }
        let clock = match self.opts.clock(&loaded) {
            Ok(c) => c,
            Err(e) => {
                err!("error: {}: {e}", dir.display());
                return Ok(Exit::from(super::EXIT_INVALID));
            }
        };
        let resume = match Resume::prepare(dir, &loaded, self.origin_tolerance, clock) {
            Ok(r) => r,
            Err(e) => {
                err!("error: {e}");
                return Ok(Exit::from(super::EXIT_INVALID));
            }
        };
        let seed = crate::runs::read_manifest(dir)
            .map(|m| m.seed)
            .unwrap_or_default();
        err!("resuming {} at step {}", dir.display(), resume.from_step);
        let mut live = None;
        let code = execute(
            &self.opts,
            Target {
                out: dir,
                seed,
                record_mcap: self.record.as_deref() == Some("mcap"),
                resume: Some(resume),
            },
            &loaded,
            clock,
            &cancel,
            &mut live,
        )?;
        end_live(live);
        Ok(code)
    }
}
