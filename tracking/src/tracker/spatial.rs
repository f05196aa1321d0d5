//! Spatial helpers of the tracker: the reference neighbour graph and a bucket grid for
//! radius queries over blobs.

use delaunator::{Point, triangulate};

use super::super::detect::Blob;
use super::dist;

/// Delaunay edges shorter than twice the spacing, plus each marker's nearest neighbour
/// (so collinear or sparse layouts still connect), as compressed rows.
pub(super) fn neighbour_graph(points: &[[f64; 2]], spacing_px: f64) -> (Vec<u32>, Vec<u32>) {
    let n = points.len();
    let mut adj: Vec<Vec<u32>> = vec![Vec::new(); n];
    let mut link = |a: usize, b: usize| {
        if a != b && !adj[a].contains(&(b as u32)) {
            adj[a].push(b as u32);
            adj[b].push(a as u32);
        }
    };
    let pts: Vec<Point> = points.iter().map(|p| Point { x: p[0], y: p[1] }).collect();
    let tri = triangulate(&pts);
    for t in tri.triangles.chunks_exact(3) {
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            if dist(points[a], points[b]) < 2.0 * spacing_px {
                link(a, b);
            }
        }
    }
    for a in 0..n {
        let nearest = (0..n)
            .filter(|&b| b != a)
            .min_by(|&x, &y| dist(points[a], points[x]).total_cmp(&dist(points[a], points[y])));
        if let Some(b) = nearest {
            link(a, b);
        }
    }
    let mut start = Vec::with_capacity(n + 1);
    let mut flat = Vec::new();
    start.push(0);
    for mut list in adj {
        list.sort_unstable();
        flat.extend(list);
        start.push(flat.len() as u32);
    }
    (start, flat)
}

/// A uniform grid of blob indices for radius queries.
#[derive(Debug, Clone, Default)]
pub(super) struct Buckets {
    cell: f64,
    cols: usize,
    rows: usize,
    start: Vec<u32>,
    items: Vec<u32>,
    xy: Vec<[f64; 2]>,
}

impl Buckets {
    pub(super) fn build(&mut self, blobs: &[Blob], width: f64, height: f64, cell: f64) {
        self.build_points(blobs.iter().map(|b| [b.x, b.y]), width, height, cell);
    }

    /// As [`Self::build`], over any points.
    pub(super) fn build_points(
        &mut self,
        points: impl Iterator<Item = [f64; 2]>,
        width: f64,
        height: f64,
        cell: f64,
    ) {
        self.cell = cell.max(1.0);
        self.cols = (width / self.cell).ceil() as usize + 1;
        self.rows = (height / self.cell).ceil() as usize + 1;
        let cells = self.cols * self.rows;
        self.start.clear();
        self.start.resize(cells + 1, 0);
        self.xy.clear();
        self.xy.extend(points);
        let cell_of = |p: [f64; 2], cols: usize, rows: usize, size: f64| {
            // `as usize` truncates toward zero and saturates below at 0: the floor of a
            // non-negative value, 0 for a negative one (the x86-64 baseline has no floor
            // instruction, and its library call is on every query).
            let cx = ((p[0] / size).max(0.0) as usize).min(cols - 1);
            let cy = ((p[1] / size).max(0.0) as usize).min(rows - 1);
            cy * cols + cx
        };
        for p in &self.xy {
            self.start[cell_of(*p, self.cols, self.rows, self.cell) + 1] += 1;
        }
        for c in 0..cells {
            self.start[c + 1] += self.start[c];
        }
        self.items.clear();
        self.items.resize(self.xy.len(), 0);
        let mut fill = self.start.clone();
        for (i, p) in self.xy.iter().enumerate() {
            let c = cell_of(*p, self.cols, self.rows, self.cell);
            self.items[fill[c] as usize] = i as u32;
            fill[c] += 1;
        }
    }

    /// Calls `f` for every blob in the cells that overlap the disc (a superset of it).
    pub(super) fn for_each_near(&self, p: [f64; 2], radius: f64, mut f: impl FnMut(u32)) {
        if self.cols == 0 || !p[0].is_finite() || !p[1].is_finite() {
            return;
        }
        // Truncation is the floor here: negative values saturate to 0 (see `build_points`).
        let lo = |v: f64| ((v - radius) / self.cell).max(0.0) as usize;
        let hi = |v: f64, n: usize| (((v + radius) / self.cell).max(0.0) as usize).min(n - 1);
        let (x0, x1) = (lo(p[0]).min(self.cols - 1), hi(p[0], self.cols));
        let (y0, y1) = (lo(p[1]).min(self.rows - 1), hi(p[1], self.rows));
        for cy in y0..=y1 {
            for cx in x0..=x1 {
                let c = cy * self.cols + cx;
                for k in self.start[c]..self.start[c + 1] {
                    f(self.items[k as usize]);
                }
            }
        }
    }
}
