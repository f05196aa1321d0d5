//! Step 1b: identity through frames the lattice makes ambiguous.
//!
//! When two placements of the markers explain a frame equally well and are equally small
//! motions (a grid panned by half a spacing along its axis), no rule can pick one. Guessing
//! is how a tracker runs away: the guess is locally perfect, and every later frame follows
//! it. Withholding alone is not enough either: a tracker that only remembers its last
//! certain frame is fooled when the gel comes back to a place one lattice step from it,
//! which looks exactly like coming back.
//!
//! So the tracker keeps following the frame — the smaller motion, provisionally — and
//! carries the *aliases* of that placement: the uniform offsets (about a lattice vector
//! each) at which the markers would explain every frame since just as well. Each new
//! frame's own ties add to them; evidence that cannot alias removes them — the lattice's
//! edges and holes, markers where an alias puts none, blobs an alias leaves unexplained.
//! Identities are reported again only when no alias is left standing; until then every
//! matched marker is `ambiguous`. Where nothing ever tells the aliases apart (a perfect grid
//! larger than the view on every side), the identities stay withheld: that is the truth
//! about such a frame.

use super::super::detect::Blob;
use super::hypotheses::Explanation;
use super::{Tracker, dist, norm};

/// At most this many aliases are carried (the nearest, two lattice steps around in every
/// direction); beyond them the placement is lost anyway.
const MAX_ALIASES: usize = 24;
/// Two offsets closer than this, in spacings, are one alias.
const SAME: f64 = 0.3;

impl Tracker {
    /// Folds the frame's own ties (`tie`: offsets from `self.hyp`) into the aliases
    /// carried, drops those the frame refutes, and moves the provisional placement onto
    /// another alias if the frame refutes it instead. Returns whether the identities are
    /// certain (no alias left).
    pub(super) fn settle_aliases(&mut self, tie: &[[f64; 2]], blobs: &[Blob]) -> bool {
        if self.aliases.is_empty() && tie.is_empty() {
            return true;
        }
        let s = self.spacing_px;
        let mut set: Vec<[f64; 2]> = vec![[0.0; 2]];
        let carried = std::mem::take(&mut self.aliases);
        for o in std::iter::once([0.0; 2]).chain(carried) {
            for d in std::iter::once(&[0.0; 2]).chain(tie) {
                let c = [o[0] + d[0], o[1] + d[1]];
                if !set.iter().any(|&x| dist(x, c) < SAME * s) {
                    set.push(c);
                }
            }
        }
        let explained: Vec<Explanation> = set
            .iter()
            .map(|o| {
                let motion: Vec<[f64; 2]> = self
                    .hyp
                    .iter()
                    .map(|m| [m[0] + o[0], m[1] + o[1]])
                    .collect();
                self.explain(&motion, blobs)
            })
            .collect();
        let most = explained.iter().map(|e| e.matched).max().unwrap_or(0);
        let least = explained
            .iter()
            .filter(|e| 2 * e.matched >= most)
            .map(Explanation::against)
            .min()
            .unwrap_or(0);
        let slack = 3.max(most / 50).max(least);
        let standing: Vec<usize> = (0..set.len())
            .filter(|&k| {
                2 * explained[k].matched >= most && explained[k].against() <= least + slack
            })
            .collect();
        // The placement followed: the provisional one if it stands, else the least refuted
        // (then the nearest).
        let centre = if standing.contains(&0) {
            0
        } else {
            standing
                .iter()
                .copied()
                .min_by(|&a, &b| {
                    explained[a]
                        .against()
                        .cmp(&explained[b].against())
                        .then(norm(set[a]).total_cmp(&norm(set[b])))
                })
                .unwrap_or(0)
        };
        let c = set[centre];
        if centre != 0 {
            for m in &mut self.hyp {
                *m = [m[0] + c[0], m[1] + c[1]];
            }
        }
        let mut rest: Vec<[f64; 2]> = standing
            .into_iter()
            .filter(|&k| k != centre)
            .map(|k| [set[k][0] - c[0], set[k][1] - c[1]])
            .collect();
        rest.sort_by(|a, b| norm(*a).total_cmp(&norm(*b)));
        rest.truncate(MAX_ALIASES);
        self.aliases = rest;
        self.aliases.is_empty()
    }

    /// The offsets, px, at which the markers would explain every frame since their
    /// identities were last certain as well as where they are placed; empty when the
    /// identities are certain.
    pub fn aliases_px(&self) -> &[[f64; 2]] {
        &self.aliases
    }
}
