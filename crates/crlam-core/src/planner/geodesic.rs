//! Geodesic (shortest-path) distances on a grid of traversable cells: the path search of the
//! exploration loop (`crlam.experiments.explore`).
//!
//! Cells are 8-connected: an edge step costs `res`, a diagonal step `√2·res`, and a diagonal step
//! needs both cells beside it traversable, so a path never cuts the corner of a blocked cell.
//! The search is Dijkstra's algorithm with a binary heap ordered by `(distance, flat index)`,
//! the order of Python's `heapq` over `(d, u)` tuples; with the same float operations
//! (`d + c·res`) and strict improvements only, it reproduces the pure-Python reference's
//! distances *and* predecessors bit for bit (ties resolve the same way).

use std::cmp::{Ordering, Reverse};
use std::collections::BinaryHeap;
use std::f64::consts::SQRT_2;

use crate::error::{config_err, CrlamError, Result};

/// Shortest-path distances from one start cell over a row-major `(ny, nx)` grid.
#[derive(Clone, Debug, PartialEq)]
pub struct Geodesic {
    /// Rows of the grid.
    pub ny: usize,
    /// Columns of the grid.
    pub nx: usize,
    /// Path length (m) from the start to every cell, row-major `(ny, nx)`; `+inf` for cells the
    /// search did not reach. The start has 0.
    pub dist: Vec<f64>,
    /// Flat index `iy·nx + ix` of each cell's predecessor on its shortest path, row-major
    /// `(ny, nx)`; −1 for the start and for unreached cells.
    pub pred: Vec<i64>,
}

impl Geodesic {
    /// The cells `(iy, ix)` of the shortest path from the start to `goal` (flat index), start
    /// first; empty when `goal` is outside the grid or was not reached.
    pub fn path(&self, goal: usize) -> Vec<(usize, usize)> {
        if goal >= self.dist.len() || !self.dist[goal].is_finite() {
            return Vec::new();
        }
        let mut cells = Vec::new();
        let mut u = goal as i64;
        // Predecessors strictly decrease the distance, so the walk ends at the start.
        while u >= 0 {
            let k = u as usize;
            cells.push((k / self.nx, k % self.nx));
            u = self.pred[k];
        }
        cells.reverse();
        cells
    }
}

/// A heap entry ordered by distance, then flat index (both ascending once wrapped in
/// [`Reverse`]). Distances are finite sums of positive steps, so `total_cmp` agrees with `<`.
#[derive(Clone, Copy, Debug)]
struct Entry {
    dist: f64,
    cell: usize,
}

impl PartialEq for Entry {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}

impl Eq for Entry {}

impl PartialOrd for Entry {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for Entry {
    fn cmp(&self, other: &Self) -> Ordering {
        self.dist
            .total_cmp(&other.dist)
            .then(self.cell.cmp(&other.cell))
    }
}

/// The eight moves `(dy, dx, step in cells)`, in the reference's order (which does not change
/// the result: every relaxation of a popped cell is independent of the others).
const MOVES: [(i64, i64, f64); 8] = [
    (-1, 0, 1.0),
    (1, 0, 1.0),
    (0, -1, 1.0),
    (0, 1, 1.0),
    (-1, -1, SQRT_2),
    (-1, 1, SQRT_2),
    (1, -1, SQRT_2),
    (1, 1, SQRT_2),
];

/// 8-connected shortest-path distances (m) over the `traversable` cells of a row-major
/// `(ny, nx)` grid from `start = (iy, ix)`, with cell size `res` (m).
///
/// The start itself need not be traversable (it is where the robot is); every other cell of a
/// path must be. Errors: `traversable.len() != ny·nx` (shape), a start outside the grid (out of
/// bounds), `res` not finite and > 0 (config).
pub fn geodesic(
    traversable: &[bool],
    ny: usize,
    nx: usize,
    start: (i64, i64),
    res: f64,
) -> Result<Geodesic> {
    if !(res.is_finite() && res > 0.0) {
        return Err(config_err(
            "resolution",
            format!("must be finite and > 0, got {res}"),
        ));
    }
    if ny.checked_mul(nx) != Some(traversable.len()) {
        return Err(CrlamError::Shape(format!(
            "traversable has {} cells, not ny·nx = {ny}·{nx}",
            traversable.len()
        )));
    }
    let (sy, sx) = start;
    if !(0..ny as i64).contains(&sy) || !(0..nx as i64).contains(&sx) {
        return Err(CrlamError::OutOfBounds(format!(
            "start cell ({sy}, {sx}) is outside the {ny} x {nx} grid"
        )));
    }
    let n = ny * nx;
    let mut dist = vec![f64::INFINITY; n];
    let mut pred = vec![-1i64; n];
    let s = sy as usize * nx + sx as usize;
    dist[s] = 0.0;
    let mut heap = BinaryHeap::new();
    heap.push(Reverse(Entry { dist: 0.0, cell: s }));
    let (ny_i, nx_i) = (ny as i64, nx as i64);
    while let Some(Reverse(Entry { dist: d, cell: u })) = heap.pop() {
        // A stale entry: the cell was reached by a shorter path after this was pushed.
        if d > dist[u] {
            continue;
        }
        let (y, x) = ((u / nx) as i64, (u % nx) as i64);
        for &(dy, dx, c) in &MOVES {
            let (yy, xx) = (y + dy, x + dx);
            if !(0..ny_i).contains(&yy) || !(0..nx_i).contains(&xx) {
                continue;
            }
            let v = (yy * nx_i + xx) as usize;
            if !traversable[v] {
                continue;
            }
            if dy != 0
                && dx != 0
                && !(traversable[(y * nx_i + xx) as usize] && traversable[(yy * nx_i + x) as usize])
            {
                continue;
            }
            // The reference's exact operations: c·res first, then the sum (no fused multiply-add).
            let nd = d + c * res;
            if nd < dist[v] {
                dist[v] = nd;
                pred[v] = u as i64;
                heap.push(Reverse(Entry { dist: nd, cell: v }));
            }
        }
    }
    Ok(Geodesic { ny, nx, dist, pred })
}
