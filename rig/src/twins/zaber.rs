//! A Zaber ASCII device on a pseudo-terminal: the production driver opens `/dev/pts/N`
//! by path and cannot tell it from a stage (spec `devices.md` §5, "Zaber").
//!
//! It parses `/d a [id] cmd[:CC]` with CR, LF or CRLF endings, verifies the LRC, echoes the
//! message id, and replies `@0d a [id] OK|RJ IDLE|BUSY ww data`. Motion runs at the
//! commanded speed in real time (`get pos` interpolates, BUSY until done); the travel
//! limits reject with BADDATA; unknown commands BADCOMMAND, other axes BADAXIS; `WR`
//! until homed (moves rejected); `NI` after a move interrupted by another move or `stop`.
//! Faults are injected through [`Faults`] (see [`super::pty`]).

use std::sync::{Arc, Mutex};
use std::time::Instant;

use super::motion::{Motion, Timing};
pub use super::pty::Faults;
use super::pty::PtyTwin;

use crate::drivers::zaber_ascii::{parse_command, with_checksum};
use crate::lock;

/// Device parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct TwinParams {
    /// Device address.
    pub device: u8,
    /// Travel in microsteps.
    pub limits: (i64, i64),
    /// Whether the device requires checksums on commands.
    pub require_checksum: bool,
    /// How many times faster than the wall the stage moves (1 for tests of the driver;
    /// `gelrig sim serve --time-scale` to run a long protocol quickly).
    pub time_scale: f64,
}

struct State {
    motion: Motion,
    timing: Timing,
    homed: bool,
    interrupted: bool,
}

/// A running twin.
pub struct ZaberTwin {
    pty: PtyTwin,
    state: Arc<Mutex<State>>,
}

impl ZaberTwin {
    /// Starts a twin on a new pseudo-terminal.
    pub fn spawn(params: TwinParams) -> std::io::Result<Self> {
        let state = Arc::new(Mutex::new(State {
            motion: Motion::at_rest(0.0),
            timing: Timing::default(),
            homed: false,
            interrupted: false,
        }));
        let st = state.clone();
        let pty = PtyTwin::spawn(
            move |line, faults| respond(line, &params, &mut lock(&st), faults),
            |r| r.replacen('@', "@X", 1).replace(" OK ", " 0K "),
        )?;
        Ok(Self { pty, state })
    }

    /// The pseudo-terminal path the driver opens.
    pub fn path(&self) -> &str {
        self.pty.path()
    }

    /// Where the stage is now, in microsteps (for coupling it to a simulated load).
    pub fn position_microsteps(&self) -> f64 {
        (self.position_probe())()
    }

    /// A handle reading the position in microsteps, for a plant that follows the stage.
    pub fn position_probe(&self) -> impl Fn() -> f64 + Send + 'static {
        let st = self.state.clone();
        move || lock(&st).motion.at(Instant::now()).position
    }

    /// The fault switches.
    pub fn faults(&self) -> &Arc<Mutex<Faults>> {
        self.pty.faults()
    }

    /// How moves from now on behave: latency to BUSY, overshoot (microsteps).
    pub fn set_timing(&self, timing: Timing) {
        lock(&self.state).timing = timing;
    }

    /// A handle that reads the transcript from another thread.
    pub fn transcript_probe(&self) -> impl Fn() -> Vec<String> + Send + 'static {
        self.pty.transcript_probe()
    }

    /// Every line received and sent, for test diagnostics.
    pub fn transcript(&self) -> Vec<String> {
        self.pty.transcript()
    }
}

/// The reply to one command line, or `None` for a message to another device.
fn respond(line: &str, p: &TwinParams, st: &mut State, faults: &Faults) -> Option<String> {
    let now = Instant::now();
    let r = st.motion.at(now);
    let (pos, busy) = (r.position, r.busy);
    if faults.stuck_busy {
        // Frozen where it is, and busy: whatever it is told.
        st.motion = Motion::at_rest(pos);
    }
    let busy = busy || faults.stuck_busy;
    let reply = |axis: u8, id: Option<u8>, ok: bool, busy: bool, warn: &str, data: &str| {
        let id = id.map(|i| format!(" {i}")).unwrap_or_default();
        let body = format!(
            "{:02} {axis}{id} {} {} {warn} {data}",
            p.device,
            if ok { "OK" } else { "RJ" },
            if busy { "BUSY" } else { "IDLE" }
        );
        format!("@{}", with_checksum(&body, true))
    };
    let cmd = match parse_command(line) {
        Ok(c) => c,
        Err(reason) => return Some(reply(0, None, false, busy, "--", reason)),
    };
    if cmd.device != 0 && cmd.device != p.device {
        return None;
    }
    if p.require_checksum && !line.contains(':') {
        return Some(reply(cmd.axis, cmd.id, false, busy, "--", "BADDATA"));
    }
    let warn = if !st.homed {
        "WR"
    } else if st.interrupted {
        "NI"
    } else {
        "--"
    };
    if cmd.axis > 1 {
        return Some(reply(cmd.axis, cmd.id, false, busy, warn, "BADAXIS"));
    }
    let words: Vec<&str> = cmd.words.iter().map(String::as_str).collect();
    let ok =
        |data: &str, busy: bool, warn: &str| Some(reply(cmd.axis, cmd.id, true, busy, warn, data));
    let rj = |why: &str| Some(reply(cmd.axis, cmd.id, false, busy, warn, why));
    match words.as_slice() {
        [] => ok("0", busy, warn),
        ["get", "pos"] => match &faults.position_reply {
            Some(text) => ok(text, busy, warn),
            None => ok(&format!("{}", pos.round() as i64), busy, warn),
        },
        ["get", "deviceid"] => ok("50081", busy, warn),
        ["get", "version"] => ok("7.38", busy, warn),
        ["home"] => {
            st.interrupted = busy;
            // Homing finds its sensor: it lands on 0 whatever the overshoot of moves.
            let timing = Timing {
                overshoot: 0.0,
                ..st.timing
            };
            st.motion = Motion::new(pos, 0.0, 200_000.0 * p.time_scale, timing);
            st.homed = true;
            ok("0", st.motion.at(now).busy, "--")
        }
        ["stop"] => {
            st.interrupted = busy;
            st.motion = Motion::at_rest(pos);
            ok("0", false, if busy { "NI" } else { warn })
        }
        ["move", "abs", target, rest @ ..] => {
            if !st.homed {
                return rj("BADDATA");
            }
            let (Ok(t), speed) = (
                target.parse::<i64>(),
                rest.first().map(|s| s.parse::<f64>()),
            ) else {
                return rj("BADDATA");
            };
            let speed = match speed {
                None => 100_000.0 * p.time_scale,
                Some(Ok(s)) if s > 0.0 => s / 1.6384 * p.time_scale,
                Some(_) => return rj("BADDATA"),
            };
            if t < p.limits.0 || t > p.limits.1 {
                return rj("BADDATA");
            }
            st.interrupted = busy;
            st.motion = Motion::new(pos, t as f64, speed, st.timing);
            ok("0", st.motion.at(now).busy, if busy { "NI" } else { "--" })
        }
        _ => rj("BADCOMMAND"),
    }
}
