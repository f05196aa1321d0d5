//! The rate settle rule: settled once the drift of a force channel is confidently small.

use std::collections::VecDeque;

use rig::Wrench;

use experiments::protocol::schema::Channel;

/// State of a rate-based settle.
pub(super) struct SettleTrack {
    pub(super) channel: Channel,
    pub(super) below: f64,
    pub(super) window_ns: u64,
    pub(super) start_ns: u64,
    pub(super) min_ns: u64,
    pub(super) max_ns: u64,
    pub(super) verdict: Option<&'static str>,
}

impl SettleTrack {
    /// Upper bound of |slope| of the channel over the last window, per second: the
    /// least-squares slope plus twice its standard error. Judging the bound rather than
    /// the slope itself keeps sensor noise from "settling" a step by chance: a threshold
    /// below what the noise can resolve is never met (and times out) instead of being met
    /// at random.
    pub(super) fn drift_bound(
        &self,
        window: &VecDeque<(u64, Wrench, u32)>,
        now: u64,
    ) -> Option<f64> {
        let from = now.saturating_sub(self.window_ns);
        let (t, y): (Vec<f64>, Vec<f64>) = window
            .iter()
            .filter(|(t, _, _)| *t >= from)
            .map(|(t, w, _)| ((*t - from) as f64 * 1e-9, self.channel.of(w)))
            .unzip();
        analysis::settle_rules::drift_bound(&t, &y)
    }
}
