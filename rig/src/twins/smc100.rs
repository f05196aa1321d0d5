//! A Newport SMC100 controller on a pseudo-terminal (spec `devices.md` §5, "SMC100").
//!
//! States: NOT REFERENCED (0A) → `OR` → HOMING (1E) → READY from homing (32); `PA`/`PR` →
//! MOVING (28) → READY from moving (33). Set commands are silent; `TP`, `TS`, `TE`, `ID?`,
//! `VA?` reply. Illegal-state commands latch `TE` = H (not referenced), M (moving), E (home
//! already started); targets beyond `SL`/`SR` latch C and do not move; unknown commands
//! latch A. `TE` reports the latched error and clears it. A wrong address gets no reply.

use std::sync::{Arc, Mutex};
use std::time::Instant;

use super::motion::{Motion, Timing};
pub use super::pty::Faults;
use super::pty::PtyTwin;
use crate::lock;

/// Controller parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct TwinParams {
    /// Address (1–31).
    pub address: u8,
    /// Software limits `SL`, `SR`, mm.
    pub limits: (f64, f64),
    /// Homing speed, mm/s.
    pub home_speed: f64,
    /// How many times faster than the wall the stage moves (1 for tests of the driver).
    pub time_scale: f64,
}

struct State {
    motion: Motion,
    timing: Timing,
    referenced: bool,
    homing: bool,
    error: char,
    velocity: f64,
}

/// A running controller twin.
pub struct Smc100Twin {
    pty: PtyTwin,
    state: Arc<Mutex<State>>,
}

impl Smc100Twin {
    /// Starts a controller on a new pseudo-terminal, at an unknown position, NOT REFERENCED.
    pub fn spawn(params: TwinParams) -> std::io::Result<Self> {
        let state = Arc::new(Mutex::new(State {
            motion: Motion::at_rest(3.3),
            timing: Timing::default(),
            referenced: false,
            homing: false,
            error: '@',
            velocity: 1.0,
        }));
        let st = state.clone();
        let pty = PtyTwin::spawn(
            move |line, faults| respond(line, &params, &mut lock(&st), faults),
            |r| r.replacen("TP", "T?", 1).replacen("TE", "T#", 1),
        )?;
        Ok(Self { pty, state })
    }

    /// The pseudo-terminal path the driver opens.
    pub fn path(&self) -> &str {
        self.pty.path()
    }

    /// The fault switches.
    pub fn faults(&self) -> &Arc<Mutex<Faults>> {
        self.pty.faults()
    }

    /// How moves from now on behave: latency to MOVING, overshoot (mm).
    pub fn set_timing(&self, timing: Timing) {
        lock(&self.state).timing = timing;
    }

    /// Where the stage is now, mm.
    pub fn position_mm(&self) -> f64 {
        (self.position_probe())()
    }

    /// A handle reading the position in mm, for a plant that follows the stage.
    pub fn position_probe(&self) -> impl Fn() -> f64 + Send + 'static {
        let st = self.state.clone();
        move || lock(&st).motion.at(Instant::now()).position
    }
}

fn respond(line: &str, p: &TwinParams, st: &mut State, faults: &Faults) -> Option<String> {
    let digits = line.chars().take_while(char::is_ascii_digit).count();
    let address: u8 = line[..digits].parse().ok()?;
    if address != p.address {
        return None;
    }
    let rest = &line[digits..];
    // Two-letter command, then the value; split on a character boundary (garbage may be
    // any bytes).
    let cut = rest.char_indices().nth(2).map_or(rest.len(), |(i, _)| i);
    let (cmd, value) = rest.split_at(cut);
    let now = Instant::now();
    let r = st.motion.at(now);
    let (pos, moving) = (r.position, r.busy);
    if faults.stuck_busy {
        // Frozen where it is, and MOVING: whatever it is told.
        st.motion = Motion::at_rest(pos);
    }
    let moving = moving || faults.stuck_busy;
    if !moving && st.homing {
        st.homing = false;
        st.referenced = true;
    }
    let state_code = if !st.referenced && !st.homing {
        "0A"
    } else if st.homing {
        "1E"
    } else if moving {
        "28"
    } else {
        "33"
    };
    let reply = |s: String| Some(format!("{address}{s}"));
    let go = |st: &mut State, to: f64| {
        if !st.referenced {
            st.error = 'H';
        } else if moving {
            st.error = 'M';
        } else if to < p.limits.0 || to > p.limits.1 {
            st.error = 'C';
        } else {
            st.motion = Motion::new(pos, to, st.velocity * p.time_scale, st.timing);
        }
    };
    match (cmd, value) {
        ("TP", "") => match &faults.position_reply {
            Some(text) => reply(format!("TP{text}")),
            None => reply(format!("TP{pos:.5}")),
        },
        ("TS", "") => reply(format!("TS0000{state_code}")),
        ("TE", "") => {
            let e = st.error;
            st.error = '@';
            reply(format!("TE{e}"))
        }
        ("ID", "?") => reply("IDSMC100CC_TWIN".into()),
        ("VA", "?") => reply(format!("VA{}", st.velocity)),
        ("VA", v) => {
            match v.parse::<f64>() {
                Ok(v) if v > 0.0 => st.velocity = v,
                _ => st.error = 'C',
            }
            None
        }
        ("OR", "") => {
            if st.homing {
                st.error = 'E';
            } else if st.referenced {
                st.error = 'K';
            } else {
                // Homing finds its switch: no latency to show, no overshoot.
                st.motion = Motion::new(pos, 0.0, p.home_speed * p.time_scale, Timing::default());
                st.homing = true;
            }
            None
        }
        ("PA", v) => {
            match v.parse::<f64>() {
                Ok(to) => go(st, to),
                Err(_) => st.error = 'C',
            }
            None
        }
        ("PR", v) => {
            match v.parse::<f64>() {
                Ok(d) => go(st, pos + d),
                Err(_) => st.error = 'C',
            }
            None
        }
        ("ST", "") => {
            st.motion = Motion::at_rest(pos);
            st.homing = false;
            None
        }
        _ => {
            st.error = 'A';
            None
        }
    }
}
