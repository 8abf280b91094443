//! The tiles of dropped grids, kept for reuse by the grids that share the pool.

use std::sync::{Arc, Mutex};

/// Most bytes of tiles a pool keeps for reuse.
pub(super) const MAX_POOLED_BYTES: usize = 256 << 20;

/// Tiles of dropped grids, kept for the copies and new tiles of the grids that share the pool
/// (a grid and its clones). A particle filter drops the maps resampling discards and copies
/// the tiles of the kept ones as they diverge: recycling the memory, already faulted in, avoids
/// the allocator returning it to the system and faulting it in again (zeroed) for the next copy.
/// Invariant: every pooled tile is unshared (`Arc::get_mut` succeeds) and has the grid's tile
/// length.
pub(super) struct TilePool<T> {
    free: Mutex<Vec<Arc<[T]>>>,
}

impl<T> TilePool<T> {
    pub(super) fn new() -> Self {
        Self {
            free: Mutex::new(Vec::new()),
        }
    }

    /// The pooled tiles (a poisoned lock only means a thread panicked while pushing or popping:
    /// the vector itself is intact).
    pub(super) fn lock(&self) -> std::sync::MutexGuard<'_, Vec<Arc<[T]>>> {
        self.free.lock().unwrap_or_else(|e| e.into_inner())
    }
}

impl<T> std::fmt::Debug for TilePool<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "TilePool({} tiles)", self.lock().len())
    }
}

/// A tile of `len` values written by `init`: a pooled one if the pool has any, else `fresh()`.
pub(super) fn take_pooled<T: Copy>(
    pool: &TilePool<T>,
    len: usize,
    init: impl FnOnce(&mut [T]),
    fresh: impl FnOnce() -> Arc<[T]>,
) -> Arc<[T]> {
    let pooled = pool.lock().pop();
    match pooled {
        Some(mut t) => match Arc::get_mut(&mut t) {
            Some(d) if d.len() == len => {
                init(d);
                t
            }
            _ => fresh(),
        },
        None => fresh(),
    }
}
