//! The cells one batch-mode scan touches (crm-spec 3.3): each cell's pre-scan belief and mean,
//! read from the tiles once per scan however many beams cross it, and the product of the
//! factors its beams have applied so far, written back once at the end of the scan.

use std::collections::HashMap;

use crate::crm::beam::ScanStats;
use crate::crm::update::normalize_with_floor;
use crate::error::Result;
use crate::grid::{CellRect, GridGeometry, TiledGrid};

/// Largest window (cells) kept as a dense id table; cells outside it (or scans whose window is
/// larger) go through a hash map.
const MAX_WINDOW_CELLS: i64 = 1 << 22;

/// State of a touched cell.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum CellState {
    /// Read (its mean was used) but no factor applied yet: not written back.
    Read,
    /// At least one factor applied.
    Updated,
    /// Every level of a factor clipped to 0: keeps its pre-scan belief (crm-spec 3.6).
    Frozen,
}

/// Per-scan cell table of the batch update. Invariant between scans: every entry of the dense
/// id table is 0, so that a new scan costs nothing for the cells it does not touch (the table
/// is only cleared where the previous scan wrote, also after an aborted scan).
#[derive(Debug, Default)]
pub(crate) struct ScanCells {
    window: CellRect,
    /// Window cell → 1 + cell id (0: untouched this scan).
    ids: Vec<u32>,
    /// Dense-table indices written this scan.
    dirty: Vec<u32>,
    hashed: HashMap<(i64, i64), u32>,
    cells: Vec<(i64, i64)>,
    state: Vec<CellState>,
    mean: Vec<f64>,
    /// K per cell: the pre-scan pmf times the factors applied so far (unnormalised).
    acc: Vec<f64>,
}

impl ScanCells {
    /// Starts a scan whose beams stay within `z_max` (m) of `position` (cells beyond still work,
    /// through the hash map).
    pub(crate) fn begin(&mut self, g: &GridGeometry, position: [f64; 2], z_max: f64) {
        for &i in &self.dirty {
            self.ids[i as usize] = 0;
        }
        self.dirty.clear();
        self.hashed.clear();
        self.cells.clear();
        self.state.clear();
        self.mean.clear();
        self.acc.clear();
        let (cx, cy) = g.cell_of(position[0], position[1]);
        let r = (z_max / g.resolution).ceil() as i64 + 2;
        let side = 2 * r + 1;
        self.window = if side * side <= MAX_WINDOW_CELLS {
            CellRect {
                ix0: cx - r,
                iy0: cy - r,
                nx: side,
                ny: side,
            }
        } else {
            CellRect::default()
        };
        if self.ids.len() < self.window.n_cells() {
            self.ids.resize(self.window.n_cells(), 0);
        }
    }

    /// The id of cell (ix, iy), reading its belief from `grid` (levels `mu`) on first use.
    #[inline]
    pub(crate) fn id(&mut self, grid: &TiledGrid<f32>, mu: &[f64], ix: i64, iy: i64) -> usize {
        let w = &self.window;
        let dense = if w.contains(ix, iy) {
            let i = ((iy - w.iy0) * w.nx + (ix - w.ix0)) as usize;
            let id = self.ids[i];
            if id != 0 {
                return id as usize - 1;
            }
            Some(i)
        } else {
            if let Some(&id) = self.hashed.get(&(ix, iy)) {
                return id as usize - 1;
            }
            None
        };
        let id = self.cells.len();
        let stored = grid.get(ix, iy);
        // The same sums, in the same order, as `CrmMap::mean_at`.
        let (mut s, mut m) = (0.0f64, 0.0f64);
        for (&x, &q) in mu.iter().zip(stored) {
            s += q as f64;
            m += x * q as f64;
        }
        self.mean.push(m / s);
        self.acc.extend(stored.iter().map(|&x| x as f64 / s));
        self.cells.push((ix, iy));
        self.state.push(CellState::Read);
        let tag = id as u32 + 1;
        match dense {
            Some(i) => {
                self.ids[i] = tag;
                self.dirty.push(i as u32);
            }
            None => {
                self.hashed.insert((ix, iy), tag);
            }
        }
        id
    }

    /// Pre-scan mean m̂ of cell `id`.
    #[inline]
    pub(crate) fn mean(&self, id: usize) -> f64 {
        self.mean[id]
    }

    /// Multiplies cell `id`'s belief by the factor 1 + α(μ − m̂) (clipped at 0, crm-spec 3.1).
    #[inline]
    pub(crate) fn apply(
        &mut self,
        id: usize,
        alpha: f64,
        mhat: f64,
        mu: &[f64],
        st: &mut ScanStats,
    ) {
        if self.state[id] == CellState::Frozen {
            st.n_frozen += 1;
            return;
        }
        let k = mu.len();
        let p = &mut self.acc[id * k..(id + 1) * k];
        let c0 = 1.0 - alpha * mhat;
        let mut sum = 0.0;
        for i in 0..k {
            p[i] *= (c0 + alpha * mu[i]).max(0.0);
            sum += p[i];
        }
        if !(sum > 0.0 && sum.is_finite()) {
            self.state[id] = CellState::Frozen;
            st.n_frozen += 1;
            return;
        }
        self.state[id] = CellState::Updated;
        st.n_cell_updates += 1;
        if sum < 1e-100 {
            // Keeps long products of small factors away from underflow; the final
            // normalisation removes the scale.
            let inv = 1.0 / sum;
            p.iter_mut().for_each(|x| *x *= inv);
        }
    }

    /// Normalises (with the floor) and stores every updated cell into `grid`.
    pub(crate) fn write_back(
        &mut self,
        grid: &mut TiledGrid<f32>,
        k: usize,
        floor: f64,
    ) -> Result<()> {
        for (id, &(ix, iy)) in self.cells.iter().enumerate() {
            if self.state[id] != CellState::Updated {
                continue;
            }
            let p = &mut self.acc[id * k..(id + 1) * k];
            let s: f64 = p.iter().sum();
            normalize_with_floor(p, s, floor);
            let dst = grid.get_mut(ix, iy)?;
            for i in 0..k {
                dst[i] = p[i] as f32;
            }
        }
        Ok(())
    }
}
