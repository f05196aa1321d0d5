//! The adaptive settle rule: while a step relaxes, F∞ of its channel is fitted to the record
//! so far ([`analysis::equilibrium`]) every few seconds, and the step ends as soon as F∞ is
//! known within the tolerance — twice its honest uncertainty below `tolerance × |F∞|`, and
//! no drift left unexplained. What the run learns of the gel's time constants from a step
//! followed long enough serves every later step ([`GelMemory`]). The rule itself is
//! [`analysis::settle_rules`], which a report also replays on recorded runs.

use std::collections::VecDeque;

use analysis::equilibrium::Equilibrium;
pub(super) use analysis::settle_rules::GelMemory;
use rig::Wrench;

use experiments::protocol::schema::Channel;

/// State of an adaptive settle.
pub(super) struct AdaptiveTrack {
    pub(super) channel: Channel,
    pub(super) tolerance: f64,
    pub(super) start_ns: u64,
    pub(super) min_ns: u64,
    pub(super) max_ns: u64,
    /// The quasistatic window, s (the estimate keeps its mean beside F∞).
    pub(super) window_s: f64,
    /// When to fit next, ns.
    pub(super) next_ns: u64,
    /// The last estimate.
    pub(super) last: Option<Equilibrium>,
    pub(super) verdict: Option<&'static str>,
}

impl AdaptiveTrack {
    /// The settle's start, s on the run's clock.
    pub(super) fn start_s(&self) -> f64 {
        self.start_ns as f64 * 1e-9
    }

    /// The settle's record so far: (s since its start, the channel).
    pub(super) fn record(&self, window: &VecDeque<(u64, Wrench, u32)>) -> (Vec<f64>, Vec<f64>) {
        window
            .iter()
            .filter(|(t, _, _)| *t >= self.start_ns)
            .map(|(t, w, _)| ((t - self.start_ns) as f64 * 1e-9, self.channel.of(w)))
            .unzip()
    }

    /// Fits the record now; true when F∞ is known well enough to stop. The next fit is due
    /// after a tenth of the time waited so far (at least 2 s): a fit costs milliseconds,
    /// and the answer changes slowly once the fast terms have gone.
    pub(super) fn judge(
        &mut self,
        window: &VecDeque<(u64, Wrench, u32)>,
        now: u64,
        memory: &GelMemory,
    ) -> bool {
        let elapsed_s = now.saturating_sub(self.start_ns) as f64 * 1e-9;
        self.next_ns =
            self.start_ns + (analysis::settle_rules::next_check_s(elapsed_s) * 1e9) as u64;
        let (t, f) = self.record(window);
        let Some(e) = memory.estimate_at(Some(self.start_s()), &t, &f, self.window_s) else {
            return false;
        };
        let known = e.known_within(self.tolerance, memory.floor());
        self.last = Some(e);
        known
    }

    /// The band the statistic must fall into: tolerance × max(|F∞|, a tenth of the run's
    /// largest force so far), against 2σ.
    pub(super) fn band(&self, memory: &GelMemory) -> Option<(f64, f64)> {
        let e = self.last.as_ref()?;
        Some((
            2.0 * e.sigma,
            self.tolerance * e.f_inf.abs().max(memory.floor()),
        ))
    }
}
