//! The adaptive settle rule: while a step relaxes, F∞ of its channel is fitted to the record
//! so far ([`analysis::equilibrium`]) every few seconds, and the step ends as soon as F∞ is
//! known within the tolerance — twice its honest uncertainty below `tolerance × |F∞|`, and
//! no drift left unexplained. What the run learns of the gel's time constants from a step
//! followed long enough serves every later step ([`GelMemory`]).

use std::collections::VecDeque;

use analysis::equilibrium::{self, Equilibrium, Learned};
use rig::Wrench;

use crate::protocol::schema::Channel;

/// Records kept for learning the gel's time constants (the newest).
const KEEP_RECORDS: usize = 4;

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
        let elapsed = now.saturating_sub(self.start_ns);
        self.next_ns = now + (elapsed / 10).max(2_000_000_000);
        let (t, f) = self.record(window);
        let Some(e) = equilibrium::estimate_with(&t, &f, self.window_s, memory.learned.as_ref())
        else {
            return false;
        };
        let floor = 0.1 * memory.peak;
        let known = e.known_within(self.tolerance, floor);
        self.last = Some(e);
        known
    }

    /// The band the statistic must fall into: tolerance × max(|F∞|, a tenth of the run's
    /// largest force so far), against 2σ.
    pub(super) fn band(&self, memory: &GelMemory) -> Option<(f64, f64)> {
        let e = self.last.as_ref()?;
        Some((
            2.0 * e.sigma,
            self.tolerance * e.f_inf.abs().max(0.1 * memory.peak),
        ))
    }
}

/// What the run has learned of the gel's relaxation.
#[derive(Default)]
pub(super) struct GelMemory {
    records: VecDeque<(Vec<f64>, Vec<f64>)>,
    learned: Option<Learned>,
    /// The largest |F∞| so far: near zero force a relative tolerance is measured against a
    /// tenth of it.
    peak: f64,
    /// The learned constants were announced.
    announced: bool,
}

impl GelMemory {
    /// A settle ended with `track`'s estimate: its scale counts towards the run's force
    /// scale, and a record long enough against its own fit's slowest time constant (even
    /// one whose F∞ band stayed wider than the tolerance) teaches the gel's time constants,
    /// pooled with the newest few such records. A record that did not pin them teaches
    /// nothing: later steps would inherit its mistake with a confidence they cannot have.
    pub(super) fn settled(&mut self, track: &AdaptiveTrack, window: &VecDeque<(u64, Wrench, u32)>) {
        let Some(e) = &track.last else {
            return;
        };
        self.peak = self.peak.max(e.f_inf.abs());
        if !e.pins_time_constants() {
            return;
        }
        if self.records.len() == KEEP_RECORDS {
            self.records.pop_front();
        }
        self.records.push_back(track.record(window));
        let records: Vec<(Vec<f64>, Vec<f64>)> = self.records.iter().cloned().collect();
        if let Some(l) = equilibrium::learn(&records, &e.taus_s) {
            self.learned = Some(l);
        }
    }

    /// The time constants now learned, once, the first time there are some: what later
    /// steps assume (the run says so: a gel relaxing slower than the slowest of them, over
    /// times no record so far could show, would make those steps' F∞ wrong).
    pub(super) fn newly_learned(&mut self) -> Option<String> {
        if self.announced {
            return None;
        }
        let l = self.learned.as_ref()?;
        self.announced = true;
        Some(format!(
            "adaptive settling: later steps fit F∞ with the gel's time constants learned so far              ({} s, ±{:.0} %); they assume nothing relaxes slower than {:.0} s — a slower              relaxation needs a `max` of at least 2.5× it to be seen",
            l.taus_s
                .iter()
                .map(|t| format!("{t:.1}"))
                .collect::<Vec<_>>()
                .join(", "),
            200.0 * l.rel_sigma,
            l.taus_s.last().copied().unwrap_or(0.0)
        ))
    }
}
