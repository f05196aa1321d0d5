//! Step 4: the whole field must be one field.
//!
//! A region of markers that slipped by one lattice step is locally perfect — every marker
//! on a blob, every neighbour moving alike — and is only betrayed where it meets the rest:
//! along that seam neighbouring displacements differ by about a spacing, a strain no gel
//! survives. Matched markers are joined into components by edges whose displacements agree
//! within `strain_limit`; where two components meet, the smaller is undone and the larger
//! grows into the space (a swap of a whole region cannot outvote the field around it). A
//! component that no other reaches keeps its identities only if the chosen global motion
//! explains it (within `seed_radius`); otherwise they are withheld.

use super::super::detect::Blob;
use super::{NONE, Tracker, dist};

/// Rounds of undo-and-regrow; each removes at least one component, and in practice one or
/// two suffice.
const ROUNDS: usize = 4;

impl Tracker {
    /// Undoes the components that contradict a larger one, and isolated ones the global
    /// motion does not explain.
    pub(super) fn enforce_consistency(&mut self, blobs: &[Blob]) {
        for _ in 0..ROUNDS {
            let (label, size) = self.components(blobs);
            let mut undo = vec![false; size.len()];
            for i in 0..self.len() {
                let li = label[i];
                if li == NONE {
                    continue;
                }
                for &j in self.neighbours(i) {
                    let lj = label[j as usize];
                    if lj == NONE || lj == li {
                        continue;
                    }
                    // They meet across an inconsistent edge: the smaller yields.
                    let loser = match size[li as usize].cmp(&size[lj as usize]) {
                        std::cmp::Ordering::Less => li,
                        std::cmp::Ordering::Greater => lj,
                        std::cmp::Ordering::Equal => li.max(lj),
                    };
                    undo[loser as usize] = true;
                }
            }
            if !undo.iter().any(|&u| u) {
                break;
            }
            self.undo_where(|i| label[i] != NONE && undo[label[i] as usize]);
            self.regrow(blobs);
            self.validate(blobs);
        }
        // Isolated components other than the largest: kept only if the global motion
        // explains them.
        let (label, size) = self.components(blobs);
        let Some(main) = (0..size.len()).max_by_key(|&c| (size[c], std::cmp::Reverse(c))) else {
            return;
        };
        let tol = self.params.seed_radius * self.spacing_px;
        let mut unexplained = vec![false; size.len()];
        for (i, &l) in label.iter().enumerate() {
            let b = self.assigned[i];
            if l == NONE || l as usize == main {
                continue;
            }
            let q = [
                self.pos[i][0] + self.hyp[i][0],
                self.pos[i][1] + self.hyp[i][1],
            ];
            if dist(q, [blobs[b as usize].x, blobs[b as usize].y]) > tol {
                unexplained[l as usize] = true;
            }
        }
        self.undo_where(|i| label[i] != NONE && unexplained[label[i] as usize]);
    }

    fn undo_where(&mut self, pick: impl Fn(usize) -> bool) {
        for i in 0..self.len() {
            if pick(i) {
                let b = self.assigned[i];
                self.owner[b as usize] = NONE;
                self.assigned[i] = NONE;
                self.withheld[i] = true;
            }
        }
    }

    /// Components of matched markers joined by edges whose displacements from the reference
    /// agree within `strain_limit`: a label per marker (`NONE` when unmatched) and the size
    /// of each component.
    fn components(&self, blobs: &[Blob]) -> (Vec<u32>, Vec<usize>) {
        let n = self.len();
        let limit = self.params.strain_limit * self.spacing_px;
        let disp = |i: usize| {
            let b = &blobs[self.assigned[i] as usize];
            [b.x - self.reference_px[i][0], b.y - self.reference_px[i][1]]
        };
        let mut parent: Vec<u32> = (0..n as u32).collect();
        fn find(parent: &mut [u32], mut x: u32) -> u32 {
            while parent[x as usize] != x {
                parent[x as usize] = parent[parent[x as usize] as usize];
                x = parent[x as usize];
            }
            x
        }
        for i in 0..n {
            if self.assigned[i] == NONE {
                continue;
            }
            let di = disp(i);
            for &j in self.neighbours(i) {
                let j = j as usize;
                if j < i || self.assigned[j] == NONE || dist(di, disp(j)) > limit {
                    continue;
                }
                let (a, b) = (find(&mut parent, i as u32), find(&mut parent, j as u32));
                if a != b {
                    parent[a.max(b) as usize] = a.min(b);
                }
            }
        }
        let mut label = vec![NONE; n];
        let mut of_root = vec![NONE; n];
        let mut size = Vec::new();
        for (i, slot) in label.iter_mut().enumerate() {
            if self.assigned[i] == NONE {
                continue;
            }
            let r = find(&mut parent, i as u32) as usize;
            if of_root[r] == NONE {
                of_root[r] = size.len() as u32;
                size.push(0);
            }
            *slot = of_root[r];
            size[of_root[r] as usize] += 1;
        }
        (label, size)
    }
}
