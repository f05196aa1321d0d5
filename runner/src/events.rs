//! What a run tells as it goes, to whoever asked (`Launch::on_event`): each step and phase
//! as it begins and ends, every force reading the run records, every frame captured, the
//! tactile state of every tracked frame, notable lines, and the end. The live view's board
//! is fed from the same places.

use std::sync::Arc;

use serde::Serialize;

/// One event of a run.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Event {
    /// A step (or a phase within one) begins; step 0 is the time between steps.
    Step {
        /// The step, 1-based (0 between steps).
        step: u32,
        /// The repeated block's trial, 1-based (0 outside one).
        trial: u32,
        /// What it does (`load normal → 0.336 mm`).
        what: String,
        /// The phase (`move`, `settle`, `capture`, …).
        phase: String,
        /// Run time, ns.
        t_ns: u64,
    },
    /// A step is done.
    StepDone {
        /// The step.
        step: u32,
        /// Its summary line.
        line: String,
    },
    /// A force reading the run records (tared).
    Force {
        /// Run time, ns.
        t_ns: u64,
        /// Force along x, N.
        fx_n: f64,
        /// Force along y, N.
        fy_n: f64,
        /// Normal force, N.
        fz_n: f64,
        /// Torque about the normal, N·mm.
        tz_nmm: f64,
    },
    /// A frame was captured and recorded.
    Frame {
        /// Its index in the run directory.
        index: u64,
        /// Run time of its exposure, ns.
        t_ns: u64,
    },
    /// The tactile state of a tracked frame.
    Tactile {
        /// Run time, ns.
        t_ns: u64,
        /// `stick`, `incipient` or `slip`.
        state: String,
        /// Whether the grip holds something.
        gripping: bool,
        /// Share of the contact that sticks.
        stuck_fraction: f64,
        /// The GelSight's Fz where the protocol reads it, N.
        gelsight_fz_n: Option<f64>,
    },
    /// A line worth noting (contact found, tare, a warning, a safety trip).
    Note {
        /// The line.
        line: String,
    },
    /// The run ended.
    End {
        /// `completed`, `aborted` or `failed`.
        status: String,
        /// Why, where it did not complete.
        message: Option<String>,
        /// The run directory.
        dir: String,
    },
}

/// Who receives a run's events. Called on the run's own thread: it must return quickly (a
/// slow observer slows the run's plan, never its safety watchdog, which runs apart).
pub type Observer = Arc<dyn Fn(&Event) + Send + Sync>;
