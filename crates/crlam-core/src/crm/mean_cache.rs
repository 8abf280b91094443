//! Expected occupancies of a map, computed once and shared by every copy of the map: a window
//! around a scan (for the batch update) and tile by tile on demand (for likelihood walks).
//!
//! After resampling, the particles of a filter are copies of a few parents and share their map
//! tiles until they write. Each particle's scan reads the means of the same few thousand cells;
//! read from each particle's tiles they miss the cache every time (the cells along a beam are
//! not contiguous in memory). A [`MeanCache`] travels with the map's clones: the first scan of
//! any copy fills it for a window around its pose, the others read it. A map that is written
//! gets a fresh cache, so a cache only ever holds means of the content it was filled from (a
//! batch update carries its window table over, with the cells it wrote recomputed). The
//! values are [`super::CrmMap::mean_at`]'s bit for bit, so results do not depend on which copy
//! (or thread) filled it.

use std::sync::{Arc, Mutex, OnceLock};

use crate::grid::CellRect;

/// Cells added on each side of a requested window, so that copies at slightly different poses
/// (a particle cloud) find their windows inside the one that was filled.
pub(crate) const MEAN_WINDOW_MARGIN: i64 = 16;

/// Means over a rectangle, row-major.
#[derive(Debug)]
pub(crate) struct MeanTable {
    pub(crate) rect: CellRect,
    pub(crate) values: Vec<f64>,
}

impl MeanTable {
    /// The mean of cell (ix, iy), which must lie in the rectangle.
    #[inline]
    pub(crate) fn get(&self, ix: i64, iy: i64) -> f64 {
        let r = &self.rect;
        self.values[((iy - r.iy0) * r.nx + (ix - r.ix0)) as usize]
    }

    /// True if `rect` lies inside this table's rectangle.
    pub(crate) fn covers(&self, rect: &CellRect) -> bool {
        let r = &self.rect;
        rect.ix0 >= r.ix0
            && rect.iy0 >= r.iy0
            && rect.ix0 + rect.nx <= r.ix0 + r.nx
            && rect.iy0 + rect.ny <= r.iy0 + r.ny
    }
}

/// Means in square blocks of cells, each filled the first time one of its cells is asked for
/// (lock-free reads after that). The blocks tile the map's storage at creation; every cell
/// outside holds the prior. Values are `means_of`'s, i.e. `CrmMap::mean_at`'s bit for bit.
#[derive(Debug)]
pub(crate) struct TileMeans {
    shift: u32,
    /// Storage at creation, in blocks.
    bx0: i64,
    by0: i64,
    nbx: i64,
    nby: i64,
    outside: f64,
    blocks: Vec<OnceLock<Box<[f64]>>>,
}

impl TileMeans {
    /// Blocks of `side` cells (a power of two) over `storage` (block-aligned), with `outside`
    /// the mean of every cell beyond it.
    pub(crate) fn new(storage: CellRect, side: usize, outside: f64) -> Self {
        let shift = side.trailing_zeros();
        let (nbx, nby) = (storage.nx >> shift, storage.ny >> shift);
        Self {
            shift,
            bx0: storage.ix0 >> shift,
            by0: storage.iy0 >> shift,
            nbx,
            nby,
            outside,
            blocks: (0..(nbx * nby).max(0)).map(|_| OnceLock::new()).collect(),
        }
    }

    /// The block holding cell (ix, iy) as (key, means): `means` is `None` beyond the storage
    /// (every cell there holds the prior, [`Self::outside`]); `means_of(rect, out)` fills a
    /// block's means row-major the first time. Cells of one block share its key.
    #[inline]
    pub(crate) fn block(
        &self,
        ix: i64,
        iy: i64,
        means_of: impl FnOnce(CellRect, &mut [f64]),
    ) -> (i64, Option<&[f64]>) {
        let bx = (ix >> self.shift) - self.bx0;
        let by = (iy >> self.shift) - self.by0;
        if bx < 0 || by < 0 || bx >= self.nbx || by >= self.nby {
            // One key for all of the outside, distinct from every block's.
            return (-1, None);
        }
        let side = 1i64 << self.shift;
        let key = by * self.nbx + bx;
        let block = self.blocks[key as usize].get_or_init(|| {
            let rect = CellRect {
                ix0: (bx + self.bx0) << self.shift,
                iy0: (by + self.by0) << self.shift,
                nx: side,
                ny: side,
            };
            let mut v = vec![0.0; rect.n_cells()];
            means_of(rect, &mut v);
            v.into_boxed_slice()
        });
        (key, Some(block))
    }

    /// The key of the block holding cell (ix, iy), as [`Self::block`] gives it.
    #[inline]
    pub(crate) fn key(&self, ix: i64, iy: i64) -> i64 {
        let bx = (ix >> self.shift) - self.bx0;
        let by = (iy >> self.shift) - self.by0;
        if bx < 0 || by < 0 || bx >= self.nbx || by >= self.nby {
            -1
        } else {
            by * self.nbx + bx
        }
    }

    /// Index of cell (ix, iy) within its block's means.
    #[inline]
    pub(crate) fn offset(&self, ix: i64, iy: i64) -> usize {
        let mask = (1i64 << self.shift) - 1;
        (((iy & mask) << self.shift) | (ix & mask)) as usize
    }

    /// The mean of every cell beyond the storage (the prior's).
    #[inline]
    pub(crate) fn outside(&self) -> f64 {
        self.outside
    }
}

#[derive(Debug, Default)]
struct Shared {
    window: Mutex<Option<Arc<MeanTable>>>,
    tiles: OnceLock<TileMeans>,
}

/// The shared caches (see the module documentation). Cloning shares them.
#[derive(Clone, Debug, Default)]
pub(crate) struct MeanCache {
    shared: Arc<Shared>,
}

impl MeanCache {
    /// True if another copy of the map holds this cache (a table then pays for itself).
    pub(crate) fn is_shared(&self) -> bool {
        Arc::strong_count(&self.shared) > 1
    }

    /// A table covering `rect`: the cached one if it does, else one filled by `fill` over
    /// `rect` grown by [`MEAN_WINDOW_MARGIN`] (and cached). `fill` must give the map's means.
    pub(crate) fn table(
        &self,
        rect: CellRect,
        fill: impl FnOnce(CellRect, &mut [f64]),
    ) -> Arc<MeanTable> {
        // A poisoned lock only means another thread panicked while filling; start afresh.
        let mut slot = self.shared.window.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(t) = slot.as_ref().filter(|t| t.covers(&rect)) {
            return Arc::clone(t);
        }
        let m = MEAN_WINDOW_MARGIN;
        let grown = CellRect {
            ix0: rect.ix0 - m,
            iy0: rect.iy0 - m,
            nx: rect.nx + 2 * m,
            ny: rect.ny + 2 * m,
        };
        let mut values = vec![0.0; grown.n_cells()];
        fill(grown, &mut values);
        let t = Arc::new(MeanTable {
            rect: grown,
            values,
        });
        *slot = Some(Arc::clone(&t));
        t
    }

    /// The window table cached for this map version, if one was filled (or carried over).
    pub(crate) fn window_table(&self) -> Option<Arc<MeanTable>> {
        let slot = self.shared.window.lock().unwrap_or_else(|e| e.into_inner());
        slot.clone()
    }

    /// Caches `table` as this map version's window table. It must hold this version's means
    /// (see [`super::CrmMap`]'s batch update, which carries the pre-scan table over the write).
    pub(crate) fn set_window_table(&self, table: MeanTable) {
        let mut slot = self.shared.window.lock().unwrap_or_else(|e| e.into_inner());
        *slot = Some(Arc::new(table));
    }

    /// The block means of the map, made by `make` on first use.
    pub(crate) fn tiles(&self, make: impl FnOnce() -> TileMeans) -> &TileMeans {
        self.shared.tiles.get_or_init(make)
    }

    /// Detaches this map from the copies it shared the caches with (call before writing).
    pub(crate) fn invalidate(&mut self) {
        *self = Self::default();
    }
}
