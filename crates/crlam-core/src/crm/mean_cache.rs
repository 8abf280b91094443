//! Expected occupancies of a map window, computed once and shared by every copy of the map.
//!
//! After resampling, the particles of a filter are copies of a few parents and share their map
//! tiles until they write. Each particle's scan reads the means of the same few thousand cells;
//! read from each particle's tiles they miss the cache every time (the cells along a beam are
//! not contiguous in memory). A [`MeanCache`] travels with the map's clones: the first scan of
//! any copy fills it for a window around its pose, the others read it. A map that is written
//! gets a fresh cache, so a cache only ever holds means of the content it was filled from. The
//! values are [`super::CrmMap::mean_at`]'s bit for bit, so results do not depend on which copy
//! (or thread) filled it.

use std::sync::{Arc, Mutex};

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

/// The shared slot (see the module documentation). Cloning shares it.
#[derive(Clone, Debug, Default)]
pub(crate) struct MeanCache {
    slot: Arc<Mutex<Option<Arc<MeanTable>>>>,
}

impl MeanCache {
    /// True if another copy of the map holds this cache (a table then pays for itself).
    pub(crate) fn is_shared(&self) -> bool {
        Arc::strong_count(&self.slot) > 1
    }

    /// A table covering `rect`: the cached one if it does, else one filled by `fill` over
    /// `rect` grown by [`MEAN_WINDOW_MARGIN`] (and cached). `fill` must give the map's means.
    pub(crate) fn table(
        &self,
        rect: CellRect,
        fill: impl FnOnce(CellRect, &mut [f64]),
    ) -> Arc<MeanTable> {
        // A poisoned lock only means another thread panicked while filling; start afresh.
        let mut slot = self.slot.lock().unwrap_or_else(|e| e.into_inner());
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

    /// Detaches this map from the copies it shared the cache with (call before writing).
    pub(crate) fn invalidate(&mut self) {
        *self = Self::default();
    }
}
