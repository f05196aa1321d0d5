//! What a run shows while it runs: a progress bar on a terminal, plain lines otherwise.
//!
//! Plain lines (one per completed step, plus notable events) go to stderr so a log or a CI
//! job shows the run's history; the bar shows step, phase and the remaining time, in run
//! (virtual) time and, when that differs, wall time.

use std::io::Write as _;
use std::sync::{Arc, Mutex};
use std::time::Instant;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

use experiments::plan::human_duration;

/// How to show progress.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ProgressMode {
    /// A bar on a terminal, lines otherwise.
    Auto,
    /// Always plain lines.
    Plain,
    /// Nothing.
    Quiet,
}

/// Progress reporting for one run.
pub struct Progress {
    bar: Option<ProgressBar>,
    plain: bool,
    total_steps: u32,
    eta_total_s: f64,
    time_scale: Option<f64>,
    last_tick: Mutex<Instant>,
    /// Steps completed so far: between steps (an approach, a trial's set-up) the bar stays
    /// there instead of falling back to 0.
    done: std::sync::atomic::AtomicU32,
    /// The grasp's tactile state while frames are tracked live (e.g. `slip: stick`).
    tactile: Mutex<Option<String>>,
    /// The trial under way in a repeated block, and how many there are.
    trial: Mutex<Option<(u32, u32)>>,
    /// The live view's board, with `--live`: it gets every line and phase the bar shows.
    live: Option<Arc<liveview::Board>>,
    observer: Option<crate::events::Observer>,
}

impl Progress {
    /// A reporter for a run of `total_steps` steps planned to take `eta_total_s` of run
    /// time; `time_scale` is how much faster than the wall the run clock goes (None for
    /// virtual time).
    pub fn new(
        mode: ProgressMode,
        total_steps: u32,
        eta_total_s: f64,
        time_scale: Option<f64>,
    ) -> Self {
        let tty = std::io::IsTerminal::is_terminal(&std::io::stderr());
        let bar = (mode == ProgressMode::Auto && tty).then(|| {
            let pb = ProgressBar::with_draw_target(
                Some(total_steps as u64),
                ProgressDrawTarget::stderr_with_hz(10),
            );
            let style = ProgressStyle::with_template(
                "{prefix:.bold} [{bar:30.cyan/blue}] {pos}/{len} {msg}",
            )
            .unwrap_or_else(|_| ProgressStyle::default_bar());
            pb.set_style(style.progress_chars("=> "));
            pb.set_prefix("gelrig");
            pb
        });
        Self {
            plain: mode == ProgressMode::Plain || (mode == ProgressMode::Auto && !tty),
            bar,
            total_steps,
            eta_total_s,
            time_scale,
            last_tick: Mutex::new(Instant::now()),
            done: std::sync::atomic::AtomicU32::new(0),
            tactile: Mutex::new(None),
            trial: Mutex::new(None),
            live: None,
            observer: None,
        }
    }

    /// Also tells `observer` every event of the run.
    pub fn with_observer(mut self, observer: Option<crate::events::Observer>) -> Self {
        self.observer = observer;
        self
    }

    /// Tells the observer, if any.
    pub fn emit(&self, event: crate::events::Event) {
        if let Some(o) = &self.observer {
            o(&event);
        }
    }

    /// A force reading the run records: to the live view and the observer.
    pub fn force(&self, t_ns: u64, wrench: [f64; 4]) {
        if let Some(b) = &self.live {
            b.force(t_ns, wrench);
        }
        self.emit(crate::events::Event::Force {
            t_ns,
            fx_n: wrench[0],
            fy_n: wrench[1],
            fz_n: wrench[2],
            tz_nmm: wrench[3],
        });
    }

    /// Also shows the run on the live view's `board`.
    pub fn with_live(mut self, board: Option<Arc<liveview::Board>>) -> Self {
        self.live = board;
        self
    }

    /// The live view's board, when the run has one.
    pub fn live(&self) -> Option<&liveview::Board> {
        self.live.as_deref()
    }

    /// A repeated block's trial `trial` of `of` begins: the line and the step lines say so.
    pub fn set_trial(&self, trial: u32, of: u32) {
        *self
            .trial
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner) =
            (trial > 0).then_some((trial, of));
    }

    /// `trial k/n · ` while a repeated block runs.
    fn trial_text(&self) -> String {
        self.trial
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .map(|(k, n)| format!("trial {k}/{n} · "))
            .unwrap_or_default()
    }

    fn clock_text(&self, t_s: f64) -> String {
        let left = (self.eta_total_s - t_s).max(0.0);
        match self.time_scale {
            None => format!(
                "{} run time, ~{} left (virtual)",
                human_duration(t_s),
                human_duration(left)
            ),
            Some(k) if (k - 1.0).abs() < 1e-9 => format!(
                "{} elapsed, ~{} left",
                human_duration(t_s),
                human_duration(left)
            ),
            Some(k) => format!(
                "{} run time, ~{} left (~{} wall at ×{k})",
                human_duration(t_s),
                human_duration(left),
                human_duration(left / k)
            ),
        }
    }

    /// A step starts: `what` is e.g. `load normal → 0.336 mm`. Step 0 is the time between
    /// steps (homing, an approach, a trial's set-up).
    pub fn step(&self, step: u32, what: &str, phase: &str, t_s: f64) {
        let trial = self
            .trial
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .map_or(0, |(k, _)| k);
        let t_ns = (t_s * 1e9).max(0.0) as u64;
        if let Some(b) = &self.live {
            b.phase(step, trial, what, phase, t_ns);
        }
        self.emit(crate::events::Event::Step {
            step,
            trial,
            what: what.to_string(),
            phase: phase.to_string(),
            t_ns,
        });
        if let Some(pb) = &self.bar {
            let done = self.done.load(std::sync::atomic::Ordering::Relaxed);
            pb.set_position(bar_position(step, done));
            let label = match step {
                0 if done == 0 => "before step 1".to_string(),
                0 => format!("after step {done}"),
                k => format!("step {k}"),
            };
            let tactile = self
                .tactile
                .lock()
                .unwrap_or_else(std::sync::PoisonError::into_inner)
                .as_ref()
                .map(|t| format!(" · {t}"))
                .unwrap_or_default();
            pb.set_message(format!(
                "{}{label}: {what} · {phase}{tactile} · {}",
                self.trial_text(),
                self.clock_text(t_s)
            ));
        }
    }

    /// The live tactile text shown in the line (`None` hides it).
    pub fn set_tactile(&self, text: Option<String>) {
        *self
            .tactile
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner) = text;
    }

    /// The phase changes within a step.
    pub fn phase(&self, step: u32, what: &str, phase: &str, t_s: f64) {
        self.step(step, what, phase, t_s);
    }

    /// Refreshes the clock display at most a few times per wall second.
    pub fn tick(&self, step: u32, what: &str, phase: &str, t_s: f64) {
        if self.bar.is_none() && self.live.is_none() {
            return;
        }
        let mut last = self
            .last_tick
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        if last.elapsed().as_millis() >= 200 {
            *last = Instant::now();
            self.step(step, what, phase, t_s);
        }
    }

    /// A step is done; `line` summarises it.
    pub fn step_done(&self, step: u32, line: &str) {
        let text = format!(
            "{}step {step}/{}: {line}",
            self.trial_text(),
            self.total_steps
        );
        self.done
            .fetch_max(step, std::sync::atomic::Ordering::Relaxed);
        if let Some(b) = &self.live {
            b.note(&text);
        }
        self.emit(crate::events::Event::StepDone {
            step,
            line: line.to_string(),
        });
        if let Some(pb) = &self.bar {
            pb.set_position(step as u64);
            pb.println(text);
        } else if self.plain {
            let _ = writeln!(std::io::stderr().lock(), "{text}");
        }
    }

    /// Something worth a line of its own (contact found, tare, safety trip).
    pub fn note(&self, line: &str) {
        if let Some(b) = &self.live {
            b.note(line);
        }
        self.emit(crate::events::Event::Note {
            line: line.to_string(),
        });
        if let Some(pb) = &self.bar {
            pb.println(line);
        } else if self.plain {
            let _ = writeln!(std::io::stderr().lock(), "{line}");
        }
    }

    /// Clears the bar.
    pub fn finish(&self) {
        if let Some(pb) = &self.bar {
            pb.finish_and_clear();
        }
    }
}

/// Where the bar stands while `step` runs (0: between steps) after `done` steps: a running
/// step counts the ones before it; between steps the bar keeps what was done (a repeat's
/// trials used to send it back to 0/N at every approach).
fn bar_position(step: u32, done: u32) -> u64 {
    match step {
        0 => done as u64,
        k => (k - 1) as u64,
    }
}

#[cfg(test)]
mod tests {
    use super::bar_position;

    #[test]
    fn the_bar_never_falls_back_between_trials() {
        // Trial 2's approach (step 0) after 5 steps: 5, not 0.
        assert_eq!(bar_position(0, 5), 5);
        // Step 6 running: 5 done.
        assert_eq!(bar_position(6, 5), 5);
        // Before anything: 0.
        assert_eq!(bar_position(0, 0), 0);
        assert_eq!(bar_position(1, 0), 0);
    }
}
