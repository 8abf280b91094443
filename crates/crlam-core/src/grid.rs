//! Grid geometry and tiled, copy-on-write cell storage.
//!
//! Cells are addressed by signed global indices `(ix, iy)`: cell `(ix, iy)` covers
//! `[ox + ix·Δ, ox + (ix+1)·Δ) × [oy + iy·Δ, oy + (iy+1)·Δ)`. Storage is split into square tiles
//! (`2^shift` cells a side) held behind `Arc`, so cloning a grid is O(number of tiles) and the
//! clones share every tile until one of them writes to it (`Arc::make_mut`). A particle filter
//! with hundreds of maps that differ only near the robot therefore pays for the differences only.
//!
//! Tiles that were never written are not allocated: reads return the per-cell fill value (the
//! prior), so the map is conceptually infinite. A grid either grows on demand (writes outside the
//! current tile rectangle enlarge it) or has a fixed extent, outside of which writes are refused.
//!
//! The submodules: `geometry` (cell addressing: [`GridGeometry`], [`CellRect`], the coordinate
//! limits), `tiled` ([`TiledGrid`]) and `tile_pool` (the tiles a family of clones recycles);
//! everything public is re-exported here.

mod geometry;
mod tile_pool;
mod tiled;

pub use geometry::{
    check_pose, floor_to_i64, CellRect, GridGeometry, MAX_CELL_INDEX, MAX_COORD, MIN_RESOLUTION,
};
pub use tiled::{check_dense_rect, TileStats, TiledGrid};
