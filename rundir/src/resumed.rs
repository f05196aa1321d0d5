//! A resumed run, read as one: which rows are the run's.
//!
//! `gelrig resume` continues a run in the same directory, appending to the same tables on
//! one timebase; each continuation starts a segment (`run.yaml`'s `resumed`). A step that
//! was under way when a segment ended is done again in the next one (and a trial that was
//! under way, from its first step), so its rows — force samples, frames, tactile states, a
//! step row when a trial is redone — exist twice: the abandoned attempt and the one that
//! completed. Readers keep, for every step, the rows of the segment in which its final row
//! was written, and the last step row; rows between the steps of a trial (its approach) from
//! the segment in which the trial's last step was written; other rows with no step (the
//! run's opening, between blocks) from every segment. Nothing is deleted from the files.

use std::collections::BTreeMap;

use crate::manifest::Manifest;

/// The segments of a run and, per step, the segment its kept rows come from.
#[derive(Debug, Clone, Default)]
pub struct Segments {
    /// Segment start times, ns, ascending (the first is 0).
    starts: Vec<u64>,
    /// Per step, the segment its final row was written in.
    final_segment: BTreeMap<u32, usize>,
    /// Per trial, the segment its last step row was written in.
    trial_segment: BTreeMap<u32, usize>,
}

impl Segments {
    /// The run's segments, from its manifest and its step rows' (step, trial, end time).
    pub fn new(manifest: &Manifest, step_ends: impl IntoIterator<Item = (u32, u32, u64)>) -> Self {
        let mut starts = vec![0];
        starts.extend(manifest.resumed.iter().map(|s| s.t_start_ns));
        starts.sort_unstable();
        let mut s = Self {
            starts,
            final_segment: BTreeMap::new(),
            trial_segment: BTreeMap::new(),
        };
        for (step, trial, t_end_ns) in step_ends {
            let seg = s.segment_of(t_end_ns);
            s.final_segment.insert(step, seg);
            if trial != 0 {
                let t = s.trial_segment.entry(trial).or_insert(seg);
                *t = (*t).max(seg);
            }
        }
        s
    }

    /// True if the run was resumed at least once.
    pub fn resumed(&self) -> bool {
        self.starts.len() > 1
    }

    /// The segment a time falls in.
    pub fn segment_of(&self, t_ns: u64) -> usize {
        self.starts
            .partition_point(|&s| s <= t_ns)
            .saturating_sub(1)
    }

    /// True if a row of `step` in `trial` stamped `t_ns` is the run's (not an abandoned
    /// attempt's).
    pub fn keeps(&self, step: u32, trial: u32, t_ns: u64) -> bool {
        let seg = match (step, self.final_segment.get(&step)) {
            (0, _) => self.trial_segment.get(&trial).filter(|_| trial != 0),
            (_, s) => s,
        };
        seg.is_none_or(|&seg| self.segment_of(t_ns) == seg)
    }

    /// Keeps the last row of each step, in step order of first appearance.
    pub fn last_per_step<T>(rows: Vec<T>, step: impl Fn(&T) -> u32) -> Vec<T> {
        let mut last: BTreeMap<u32, usize> = BTreeMap::new();
        for (i, r) in rows.iter().enumerate() {
            last.insert(step(r), i);
        }
        if last.len() == rows.len() {
            return rows;
        }
        let keep: std::collections::BTreeSet<usize> = last.into_values().collect();
        let mut out: Vec<T> = rows
            .into_iter()
            .enumerate()
            .filter(|(i, _)| keep.contains(i))
            .map(|(_, r)| r)
            .collect();
        out.sort_by_key(|r| step(r));
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn manifest_with(starts: &[u64]) -> Manifest {
        let text = "status: completed\nprotocol: p\nprotocol_file: p.yaml\nrig: r\n\
                    rig_file: r.yaml\nstarted_utc: t\ngelrig_version: v\nseed: 0\n\
                    clock: virtual\npid: 1\nsteps_planned: 4\nsteps_completed: 4\n\
                    eta_s: [1.0, 2.0]\n";
        let mut m: Manifest = serde_yaml::from_str(text).expect("a minimal manifest");
        m.resumed = starts
            .iter()
            .map(|&t| crate::manifest::Segment {
                started_utc: String::new(),
                t_start_ns: t,
                from_step: 0,
                pid: 0,
                previous_status: "interrupted".into(),
                previous_message: None,
                previous_ended_utc: None,
            })
            .collect();
        m
    }

    #[test]
    fn rows_of_an_abandoned_attempt_are_not_the_runs() {
        // Step 3 was under way when segment 0 ended at ~100 s; resumed at 150 s, step 3
        // ended at 200 s.
        let m = manifest_with(&[150]);
        let s = Segments::new(&m, [(1, 0, 40), (2, 0, 90), (3, 0, 200)]);
        assert!(s.resumed());
        assert!(s.keeps(2, 0, 80), "step 2's own rows");
        assert!(!s.keeps(3, 0, 95), "step 3's first, abandoned attempt");
        assert!(s.keeps(3, 0, 160), "step 3 as completed");
        assert!(
            s.keeps(0, 0, 95) && s.keeps(0, 0, 155),
            "between blocks: every segment"
        );
        assert!(
            s.keeps(4, 0, 95),
            "a step never completed keeps what it has"
        );
    }

    #[test]
    fn a_trial_done_again_keeps_its_approach_from_the_attempt_that_completed() {
        // Trial 2 (steps 3–4) cut short at 100 s in segment 0, done again from 150 s.
        let m = manifest_with(&[150]);
        let s = Segments::new(
            &m,
            [(1, 1, 40), (2, 1, 60), (3, 2, 90), (3, 2, 170), (4, 2, 190)],
        );
        assert!(!s.keeps(0, 2, 80), "the abandoned attempt's approach");
        assert!(s.keeps(0, 2, 160), "the completed attempt's approach");
        assert!(s.keeps(0, 1, 30), "trial 1 was completed in segment 0");
        assert!(!s.keeps(3, 2, 85) && s.keeps(3, 2, 165));
    }

    #[test]
    fn the_last_row_of_a_step_wins() {
        let rows = vec![(1, "a"), (2, "first"), (3, "x"), (2, "second")];
        let kept = Segments::last_per_step(rows, |r| r.0);
        assert_eq!(kept, vec![(1, "a"), (2, "second"), (3, "x")]);
    }
}
