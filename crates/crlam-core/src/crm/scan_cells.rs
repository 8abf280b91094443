//! The cells one batch-mode scan touches (crm-spec 3.3): each cell's pre-scan mean, read once
//! per scan however many beams cross it, how many beams passed it (factor ∝ 1 − μ, see
//! [`super::windowed`]) and the product of the other factors its beams applied, written back
//! once at the end of the scan.
//!
//! With hits first ([`super::ScanOptions::hits_first`]) a cell that some beam of the scan makes
//! more occupied (α > [`HIT_ALPHA_MIN`]) drops the passes of the scan's beams (a pass: a beam
//! whose reading lies so far beyond the cell that causes beyond it explain the reading, to a
//! millionth ([`PASS_LIKE`]); its factor is then (1 − μ)/(1 − m̂)). One scan then cannot erase
//! its own hits: where a beam meets a wall at a slant it crosses the wall's cells before the
//! point it hits, so without the rule the scan's neighbouring beams, ending in those cells, lose
//! their hits to it, and a wall seen at a slant is thinned into a dotted line, differently from
//! each viewpoint. The other factors (those of the cells near a reading, with their
//! likelihoods) are all applied, as without the rule.

use std::collections::HashMap;
use std::sync::Arc;

use crate::crm::beam::ScanStats;
use crate::crm::mean_cache::MeanTable;
use crate::crm::update::normalize_with_floor;
use crate::error::Result;
use crate::grid::{CellRect, GridGeometry, TiledGrid};

/// Largest window (cells) kept as a dense id table; cells outside it (or scans whose window is
/// larger) go through a hash map.
const MAX_WINDOW_CELLS: i64 = 1 << 22;

/// Largest number of levels (the level count is at most 64, plus one for endpoints).
const MAX_LEVELS: usize = 65;

/// With hits first, a factor makes its cell a hit of the scan when α exceeds this. The cells just
/// past a reading get α ≈ 0 as a difference of two nearly equal likelihoods, with a sign that
/// rounding decides; a threshold far above rounding (α enters as 1 + α(μ − m̂), so 1e-9 moves no
/// level's mass by more than a billionth) keeps the choice of hit cells from depending on it.
const HIT_ALPHA_MIN: f64 = 1e-9;

/// With hits first, a factor within this of the pass shape ((1 − μ)/(1 − m̂), |α(1 − m̂) + 1|
/// small) is one of the passes a hit cell drops: a beam whose reading is explained, to a
/// millionth, by causes beyond the cell. The windowed kernel folds the exact passes into counts
/// and applies the rest; the choice of which factors a hit cell drops must not depend on that
/// (or on rounding), so it uses this tolerance, far above both.
const PASS_LIKE: f64 = 1e-6;

/// No factor product held for the cell (its pmf is read from the tiles at write-back).
const NO_SLOT: u32 = u32::MAX;

/// State of a touched cell.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum CellState {
    /// Read (its mean was used), nothing applied yet: not written back unless passed.
    Read,
    /// At least one factor other than a pass applied.
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
    /// Means of the pre-scan map shared by its copies, when the scan was given one.
    means: Option<Arc<MeanTable>>,
    /// Window cell → 1 + cell id (0: untouched this scan).
    ids: Vec<u32>,
    /// Dense-table indices written this scan.
    dirty: Vec<u32>,
    hashed: HashMap<(i64, i64), u32>,
    cells: Vec<(i64, i64)>,
    state: Vec<CellState>,
    mean: Vec<f64>,
    /// Per cell: beams that passed it, each a factor (1 − μ_k)/(1 − m̂) applied at write-back.
    passes: Vec<u32>,
    /// Per cell: its slot in `acc`, or [`NO_SLOT`].
    slot: Vec<u32>,
    /// K per slot: the pre-scan pmf times the non-pass factors applied so far (unnormalised).
    acc: Vec<f64>,
    /// Row n (K values): ((1 − μ_k)/(1 − μ_min))^n, the pass factor of n beams scaled so that
    /// its largest entry is 1; grown on demand, rebuilt when the levels change.
    pass_pow: Vec<f64>,
    pass_levels: Vec<f64>,
    /// This scan keeps the hits first (see the module documentation).
    hits_first: bool,
    /// Per cell, with hits first: some beam made it more occupied (α > [`HIT_ALPHA_MIN`]).
    hit: Vec<bool>,
    /// K per slot, with hits first: the product of the factors within [`PASS_LIKE`] of the pass
    /// shape (unnormalised), dropped with the passes on a hit cell; `acc` then holds the
    /// pre-scan pmf times the other factors.
    misses: Vec<f64>,
}

/// The stored pmf of a cell normalised in f64: the sum in storage order, as [`pmf_mean`] and
/// `CrmMap::mean_at` take it.
#[inline]
fn read_pmf(stored: &[f32], out: &mut [f64]) {
    let s: f64 = stored.iter().map(|&q| q as f64).sum();
    for (o, &q) in out.iter_mut().zip(stored) {
        *o = q as f64 / s;
    }
}

/// The mean of a stored pmf, with `CrmMap::mean_at`'s sums in its order.
#[inline]
fn pmf_mean(stored: &[f32], mu: &[f64]) -> f64 {
    let (mut s, mut m) = (0.0f64, 0.0f64);
    for (&x, &q) in mu.iter().zip(stored) {
        s += q as f64;
        m += x * q as f64;
    }
    m / s
}

impl ScanCells {
    /// Starts a scan whose beams stay within `z_max` (m) of `position` (cells beyond still work,
    /// through the hash map). `means`, if given, holds the pre-scan means of (at least) the
    /// dense window.
    pub(crate) fn begin(
        &mut self,
        g: &GridGeometry,
        position: [f64; 2],
        z_max: f64,
        means: Option<Arc<MeanTable>>,
        hits_first: bool,
    ) {
        self.hits_first = hits_first;
        self.hit.clear();
        self.misses.clear();
        for &i in &self.dirty {
            self.ids[i as usize] = 0;
        }
        self.dirty.clear();
        self.hashed.clear();
        self.cells.clear();
        self.state.clear();
        self.mean.clear();
        self.passes.clear();
        self.slot.clear();
        self.acc.clear();
        self.window = scan_window(g, position, z_max);
        if self.ids.len() < self.window.n_cells() {
            self.ids.resize(self.window.n_cells(), 0);
        }
        self.means = means.filter(|t| t.covers(&self.window) && self.window.nx > 0);
    }

    /// The id of cell (ix, iy), reading its mean on first use.
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
        let mean = match (&self.means, dense) {
            (Some(t), Some(_)) => t.get(ix, iy),
            _ => pmf_mean(grid.get(ix, iy), mu),
        };
        self.mean.push(mean);
        self.cells.push((ix, iy));
        self.state.push(CellState::Read);
        self.passes.push(0);
        if self.hits_first {
            self.hit.push(false);
        }
        self.slot.push(NO_SLOT);
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

    /// The dense window as (ix0, iy0, nx), if this scan has one (every cell within z_max of the
    /// scan's position lies in it).
    pub(crate) fn dense_window(&self) -> Option<(i64, i64, i64)> {
        let w = &self.window;
        (w.nx > 0).then_some((w.ix0, w.iy0, w.nx))
    }

    /// [`Self::id`] of a cell of the dense window given its window index (row-major).
    #[inline]
    pub(crate) fn id_at(
        &mut self,
        index: usize,
        grid: &TiledGrid<f32>,
        mu: &[f64],
        ix: i64,
        iy: i64,
    ) -> usize {
        let id = self.ids[index];
        if id != 0 {
            return id as usize - 1;
        }
        self.id(grid, mu, ix, iy)
    }

    /// The scan's mean table, if it has one.
    pub(crate) fn mean_table(&self) -> Option<&MeanTable> {
        self.means.as_deref()
    }

    /// The pre-scan mean of a cell of the dense window (window index `index`) without
    /// registering the cell: from the scan's mean table when it has one.
    #[inline]
    pub(crate) fn pre_scan_mean(
        &mut self,
        index: usize,
        grid: &TiledGrid<f32>,
        mu: &[f64],
        ix: i64,
        iy: i64,
    ) -> f64 {
        match &self.means {
            Some(t) => t.get(ix, iy),
            None => {
                let id = self.id_at(index, grid, mu, ix, iy);
                self.mean[id]
            }
        }
    }

    /// Gives up the scan's mean table (after [`Self::write_back`] it no longer describes the
    /// map), so that a caller holding the only other reference can take it over.
    pub(crate) fn release_mean_table(&mut self) {
        self.means = None;
    }

    /// Brings `table`, which held the pre-scan means, up to date with the map after
    /// [`Self::write_back`]: every cell it wrote that lies in the table is recomputed
    /// from `grid` ([`pmf_mean`], `CrmMap::mean_at`'s sums in its order, so the table equals a
    /// fresh fill bit for bit); the scan wrote no other cell.
    pub(crate) fn refresh_means(&self, grid: &TiledGrid<f32>, mu: &[f64], table: &mut MeanTable) {
        let r = table.rect;
        for (id, &(ix, iy)) in self.cells.iter().enumerate() {
            if self.writes(id) && r.contains(ix, iy) {
                let i = ((iy - r.iy0) * r.nx + (ix - r.ix0)) as usize;
                table.values[i] = pmf_mean(grid.get(ix, iy), mu);
            }
        }
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
        grid: &TiledGrid<f32>,
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
        if self.slot[id] == NO_SLOT {
            let s = self.acc.len() / k;
            self.slot[id] = s as u32;
            self.acc.resize((s + 1) * k, 0.0);
            let (ix, iy) = self.cells[id];
            read_pmf(grid.get(ix, iy), &mut self.acc[s * k..]);
            if self.hits_first {
                self.misses.resize((s + 1) * k, 1.0);
            }
        }
        if self.hits_first && alpha > HIT_ALPHA_MIN {
            self.hit[id] = true;
        }
        let s = self.slot[id] as usize;
        let p = if self.hits_first && (alpha * (1.0 - mhat) + 1.0).abs() <= PASS_LIKE {
            &mut self.misses[s * k..(s + 1) * k]
        } else {
            &mut self.acc[s * k..(s + 1) * k]
        };
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

    /// Records that a beam passed cell `id`: its factor is (1 − μ)/(1 − m̂) (crm-spec 3.1, the
    /// cells far before a hit), applied with the others at write-back.
    #[inline]
    pub(crate) fn pass(&mut self, id: usize, st: &mut ScanStats) {
        if self.state[id] == CellState::Frozen {
            st.n_frozen += 1;
            return;
        }
        self.passes[id] += 1;
        st.n_cell_updates += 1;
    }

    /// Counts an update whose factor is 1 to rounding (|α| below 2^-50): nothing to apply.
    #[inline]
    pub(crate) fn unchanged(&mut self, id: usize, st: &mut ScanStats) {
        if self.state[id] == CellState::Frozen {
            st.n_frozen += 1;
        } else {
            st.n_cell_updates += 1;
        }
    }

    /// Whether [`Self::write_back`] writes cell `id`: a factor or a pass was applied and the
    /// cell is not frozen.
    #[inline]
    fn writes(&self, id: usize) -> bool {
        match self.state[id] {
            CellState::Frozen => false,
            CellState::Read => self.passes[id] > 0,
            CellState::Updated => true,
        }
    }

    /// Makes rows 0..=n of the pass-power table available for levels `mu`.
    fn ensure_pass_pow(&mut self, mu: &[f64], n: usize) {
        let k = mu.len();
        if self.pass_levels != mu {
            self.pass_levels = mu.to_vec();
            self.pass_pow.clear();
        }
        if self.pass_pow.is_empty() {
            self.pass_pow.resize(k, 1.0);
        }
        let mu_min = mu.iter().copied().fold(f64::INFINITY, f64::min);
        let ratio: Vec<f64> = mu.iter().map(|&m| (1.0 - m) / (1.0 - mu_min)).collect();
        while self.pass_pow.len() < (n + 1) * k {
            let start = self.pass_pow.len() - k;
            for i in 0..k {
                let v = self.pass_pow[start + i] * ratio[i];
                self.pass_pow.push(v);
            }
        }
    }

    /// Cell `id`'s pmf times the scan's factors other than the counted passes, unnormalised,
    /// into `p`: its stored pmf `stored` as it is when it has no factor product (the
    /// normalisation removes the scale with the factors'); with hits first, the pass-like
    /// factors only when the cell is not a `hit`.
    fn factored_pmf(&self, id: usize, hit: bool, stored: &[f32], p: &mut [f64]) {
        let k = p.len();
        match self.slot[id] {
            NO_SLOT => p.iter_mut().zip(stored).for_each(|(x, &q)| *x = q as f64),
            s => {
                let s = s as usize;
                p.copy_from_slice(&self.acc[s * k..(s + 1) * k]);
                if self.hits_first && !hit {
                    for (x, &m) in p.iter_mut().zip(&self.misses[s * k..(s + 1) * k]) {
                        *x *= m;
                    }
                }
            }
        }
    }

    /// Normalises (with the floor) and stores every updated or passed cell into `grid`; `mu`
    /// are the levels (for the pass factors).
    pub(crate) fn write_back(
        &mut self,
        grid: &mut TiledGrid<f32>,
        mu: &[f64],
        floor: f64,
    ) -> Result<()> {
        let k = mu.len();
        let max_passes = self.passes.iter().copied().max().unwrap_or(0) as usize;
        if max_passes > 0 {
            self.ensure_pass_pow(mu, max_passes);
        }
        let mut p = [0.0f64; MAX_LEVELS];
        let p = &mut p[..k];
        for (id, &(ix, iy)) in self.cells.iter().enumerate() {
            if !self.writes(id) {
                continue;
            }
            // With hits first, a cell some beam made more occupied drops the scan's passes.
            let hit = self.hits_first && self.hit[id];
            let n = if hit { 0 } else { self.passes[id] as usize };
            let dst = grid.get_mut(ix, iy)?;
            // A cell without a factor product starts from its stored pmf as it is: the
            // normalisation below removes its scale with the factors'.
            self.factored_pmf(id, hit, dst, p);
            let s = if n > 0 {
                let row = &self.pass_pow[n * k..(n + 1) * k];
                let mut s = 0.0;
                for (x, &r) in p.iter_mut().zip(row) {
                    *x *= r;
                    s += *x;
                }
                if s > 1e-290 && s.is_finite() {
                    s
                } else {
                    // Undo the table factors and redo them in logs (rare: underflow).
                    self.factored_pmf(id, hit, dst, p);
                    if !passes_in_logs(p, mu, n) {
                        continue;
                    }
                    p.iter().sum()
                }
            } else {
                p.iter().sum()
            };
            normalize_with_floor(p, s, floor);
            for i in 0..k {
                dst[i] = p[i] as f32;
            }
        }
        Ok(())
    }
}

/// The window of a scan from `position` reaching `z_max`: every cell a ray can reach, or the
/// empty rectangle when that is larger than [`MAX_WINDOW_CELLS`].
pub(crate) fn scan_window(g: &GridGeometry, position: [f64; 2], z_max: f64) -> CellRect {
    let (cx, cy) = g.cell_of(position[0], position[1]);
    let r = (z_max / g.resolution).ceil() as i64 + 2;
    let side = 2 * r + 1;
    if side * side <= MAX_WINDOW_CELLS {
        CellRect {
            ix0: cx - r,
            iy0: cy - r,
            nx: side,
            ny: side,
        }
    } else {
        CellRect::default()
    }
}

/// Multiplies `p` by (1 − μ_k)^n in log space, rescaled so that its largest entry is 1, for
/// the rare product that underflows the table route. Returns false if no level keeps any mass
/// (the cell then keeps its pre-scan belief, as a frozen cell does).
fn passes_in_logs(p: &mut [f64], mu: &[f64], n: usize) -> bool {
    let mut top = f64::NEG_INFINITY;
    for (x, &m) in p.iter_mut().zip(mu) {
        *x = x.ln() + n as f64 * (1.0 - m).ln();
        top = top.max(*x);
    }
    if !top.is_finite() {
        return false;
    }
    for x in p.iter_mut() {
        *x = (*x - top).exp();
    }
    true
}
