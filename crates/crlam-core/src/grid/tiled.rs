//! Tiled, copy-on-write cell storage (described in the `grid` module's documentation).

use std::sync::Arc;

use super::geometry::{check_pose, CellRect, GridGeometry};
use super::tile_pool::{take_pooled, TilePool, MAX_POOLED_BYTES};
use crate::error::{config_err, CrlamError, Result};
use crate::limits::{check_map_cells, try_filled, try_vec};

/// Memory and sharing statistics of a tiled grid.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TileStats {
    /// Tile slots in the current tile rectangle.
    pub n_slots: usize,
    /// Tiles that hold data.
    pub n_allocated: usize,
    /// Allocated tiles that are also referenced by another grid.
    pub n_shared: usize,
    /// Bytes of cell data in allocated tiles (shared tiles counted in full).
    pub bytes_allocated: usize,
}

/// Tiled, copy-on-write storage of `stride` values of type `T` per cell.
#[derive(Clone, Debug)]
pub struct TiledGrid<T: Copy + Send + Sync> {
    geometry: GridGeometry,
    shift: u32,
    stride: usize,
    fill: Arc<[T]>,
    // Tile rectangle in tile units; slots are row-major over it.
    tx0: i64,
    ty0: i64,
    ntx: i64,
    nty: i64,
    tiles: Vec<Option<Arc<[T]>>>,
    fixed: Option<CellRect>,
    /// Shared by this grid and its clones.
    pool: Arc<TilePool<T>>,
}

impl<T: Copy + Send + Sync> Drop for TiledGrid<T> {
    /// Hands this grid's unshared tiles to the pool, if another grid can still use it.
    fn drop(&mut self) {
        if Arc::strong_count(&self.pool) == 1 {
            return;
        }
        let tile_bytes = (self.stride << (2 * self.shift)) * std::mem::size_of::<T>();
        let cap = MAX_POOLED_BYTES / tile_bytes.max(1);
        let mut free = self.pool.lock();
        for slot in &mut self.tiles {
            if free.len() >= cap {
                break;
            }
            if let Some(mut t) = slot.take() {
                if Arc::get_mut(&mut t).is_some() {
                    free.push(t);
                }
            }
        }
    }
}

/// Largest tile rectangle side (in tiles) a grid may grow to; keeps a corrupt pose from
/// allocating the address space. 1 << 14 tiles of 32 cells at 0.05 m is 26 km.
const MAX_TILE_SPAN: i64 = 1 << 14;

impl<T: Copy + Send + Sync> TiledGrid<T> {
    /// A grid with tiles of `tile_size` cells a side (a power of two, 4..=256) holding `stride`
    /// values per cell, every cell starting at `fill` (length `stride`). With `fixed = Some(r)`
    /// the grid covers exactly the cells of `r` and never grows.
    pub fn new(
        geometry: GridGeometry,
        tile_size: usize,
        fill: &[T],
        fixed: Option<CellRect>,
    ) -> Result<Self> {
        if !(tile_size.is_power_of_two() && (4..=256).contains(&tile_size)) {
            return Err(config_err(
                "tile_size",
                format!("must be a power of two in 4..=256, got {tile_size}"),
            ));
        }
        if fill.is_empty() {
            return Err(config_err("stride", "at least one value per cell"));
        }
        let shift = tile_size.trailing_zeros();
        let mut grid = Self {
            geometry,
            shift,
            stride: fill.len(),
            fill: Arc::from(fill),
            tx0: 0,
            ty0: 0,
            ntx: 0,
            nty: 0,
            tiles: Vec::new(),
            fixed,
            pool: Arc::new(TilePool::new()),
        };
        if let Some(r) = fixed {
            if r.nx <= 0 || r.ny <= 0 {
                return Err(config_err(
                    "extent",
                    "a fixed extent needs at least one cell",
                ));
            }
            r.validate()?;
            check_map_cells(
                &format!("a fixed map extent of {} x {} cells", r.nx, r.ny),
                r.cells_f64(),
            )?;
            grid.reserve_tiles(r)?;
        }
        Ok(grid)
    }

    /// Geometry of the grid.
    pub fn geometry(&self) -> &GridGeometry {
        &self.geometry
    }

    /// Values per cell.
    pub fn stride(&self) -> usize {
        self.stride
    }

    /// Tile side in cells.
    pub fn tile_size(&self) -> usize {
        1 << self.shift
    }

    /// The fixed extent, if any.
    pub fn fixed_extent(&self) -> Option<CellRect> {
        self.fixed
    }

    /// The per-cell fill value (prior).
    pub fn fill(&self) -> &[T] {
        &self.fill
    }

    /// Cells covered by storage: the fixed extent, or the current tile rectangle of a growing
    /// grid (empty before the first write).
    pub fn bounds(&self) -> CellRect {
        if let Some(r) = self.fixed {
            return r;
        }
        let s = self.tile_size() as i64;
        CellRect {
            ix0: self.tx0 * s,
            iy0: self.ty0 * s,
            nx: self.ntx * s,
            ny: self.nty * s,
        }
    }

    /// Bounding rectangle of the allocated (written) tiles, if any.
    pub fn written_bounds(&self) -> Option<CellRect> {
        let s = self.tile_size() as i64;
        let mut out: Option<CellRect> = None;
        for ty in 0..self.nty {
            for tx in 0..self.ntx {
                if self.tiles[(ty * self.ntx + tx) as usize].is_some() {
                    let r = CellRect {
                        ix0: (self.tx0 + tx) * s,
                        iy0: (self.ty0 + ty) * s,
                        nx: s,
                        ny: s,
                    };
                    out = Some(out.map_or(r, |o| o.union(&r)));
                }
            }
        }
        match (out, self.fixed) {
            (Some(o), Some(f)) => {
                let ix0 = o.ix0.max(f.ix0);
                let iy0 = o.iy0.max(f.iy0);
                let ix1 = (o.ix0 + o.nx).min(f.ix0 + f.nx);
                let iy1 = (o.iy0 + o.ny).min(f.iy0 + f.ny);
                Some(CellRect {
                    ix0,
                    iy0,
                    nx: ix1 - ix0,
                    ny: iy1 - iy0,
                })
            }
            (o, _) => o,
        }
    }

    #[inline]
    fn slot_of(&self, ix: i64, iy: i64) -> Option<(usize, usize)> {
        let tx = (ix >> self.shift) - self.tx0;
        let ty = (iy >> self.shift) - self.ty0;
        if tx < 0 || ty < 0 || tx >= self.ntx || ty >= self.nty {
            return None;
        }
        let mask = (1i64 << self.shift) - 1;
        let within = (((iy & mask) << self.shift) | (ix & mask)) as usize;
        Some(((ty * self.ntx + tx) as usize, within * self.stride))
    }

    /// The values of cell (ix, iy); the fill value for cells never written or outside storage.
    #[inline]
    pub fn get(&self, ix: i64, iy: i64) -> &[T] {
        if let Some((slot, off)) = self.slot_of(ix, iy) {
            if let Some(tile) = &self.tiles[slot] {
                return &tile[off..off + self.stride];
            }
        }
        &self.fill
    }

    /// A run of cells along a row: the values of (ix, iy), (ix + 1, iy), … up to the end of their
    /// tile row and at most `max_cells` (≥ 1) cells, as `(values, cells, stored)`. Stored runs
    /// are contiguous (`cells × stride` values); where no tile is stored (or outside storage) the
    /// run is the fill value, shared by all its cells (`stored = false`, `stride` values).
    #[inline]
    pub fn row_run(&self, ix: i64, iy: i64, max_cells: usize) -> (&[T], usize, bool) {
        let tile = 1i64 << self.shift;
        let left = (tile - (ix & (tile - 1))) as usize;
        let cells = left.min(max_cells.max(1));
        if let Some((slot, off)) = self.slot_of(ix, iy) {
            if let Some(t) = &self.tiles[slot] {
                return (&t[off..off + cells * self.stride], cells, true);
            }
        }
        (&self.fill, cells, false)
    }

    /// True if the cell may be written (inside the fixed extent, or any cell of a growing grid).
    #[inline]
    pub fn writable(&self, ix: i64, iy: i64) -> bool {
        self.fixed.is_none_or(|r| r.contains(ix, iy))
    }

    /// Makes sure storage covers `rect` (growing grids only; fixed grids check containment).
    /// A growing grid refuses to cover more cells than [`crate::limits::max_map_cells`].
    pub fn reserve(&mut self, rect: CellRect) -> Result<()> {
        if rect.nx <= 0 || rect.ny <= 0 {
            return Ok(());
        }
        rect.validate()?;
        if let Some(f) = self.fixed {
            if !(f.contains(rect.ix0, rect.iy0)
                && f.contains(rect.ix0 + rect.nx - 1, rect.iy0 + rect.ny - 1))
            {
                return Err(CrlamError::OutOfBounds(format!(
                    "cells {rect:?} are not inside the fixed extent {f:?}"
                )));
            }
            return Ok(());
        }
        self.reserve_tiles(rect)
    }

    fn reserve_tiles(&mut self, rect: CellRect) -> Result<()> {
        if rect.nx <= 0 || rect.ny <= 0 {
            return Ok(());
        }
        let tx0 = rect.ix0 >> self.shift;
        let ty0 = rect.iy0 >> self.shift;
        let tx1 = ((rect.ix0 + rect.nx - 1) >> self.shift) + 1;
        let ty1 = ((rect.iy0 + rect.ny - 1) >> self.shift) + 1;
        let (ntx0, nty0) = (self.ntx, self.nty);
        let (nx0, ny0, nx1, ny1) = if ntx0 == 0 {
            (tx0, ty0, tx1, ty1)
        } else {
            if tx0 >= self.tx0
                && ty0 >= self.ty0
                && tx1 <= self.tx0 + ntx0
                && ty1 <= self.ty0 + nty0
            {
                return Ok(());
            }
            // Grow with slack so that a robot moving steadily does not re-layout every scan.
            let grow = |lo: i64, hi: i64, cur_lo: i64, cur_hi: i64| {
                let slack = ((cur_hi - cur_lo) / 4).max(2);
                let new_lo = if lo < cur_lo { lo - slack } else { cur_lo };
                let new_hi = if hi > cur_hi { hi + slack } else { cur_hi };
                (new_lo, new_hi)
            };
            let (a, b) = grow(tx0, tx1, self.tx0, self.tx0 + ntx0);
            let (c, d) = grow(ty0, ty1, self.ty0, self.ty0 + nty0);
            (a, c, b, d)
        };
        // The cells the grid must cover (the union of its storage and `rect`, without the slack)
        // are what the limit bounds: the slack only adds tile slots, 16 bytes per tile.
        let s = self.tile_size() as f64;
        let (ux0, uy0) = if ntx0 == 0 {
            (tx0, ty0)
        } else {
            (tx0.min(self.tx0), ty0.min(self.ty0))
        };
        let (ux1, uy1) = if ntx0 == 0 {
            (tx1, ty1)
        } else {
            (tx1.max(self.tx0 + ntx0), ty1.max(self.ty0 + nty0))
        };
        let (cx, cy) = ((ux1 - ux0) as f64 * s, (uy1 - uy0) as f64 * s);
        check_map_cells(
            &format!(
                "a map of {cx:.0} x {cy:.0} cells ({:.0} m x {:.0} m at {} m; is a pose far from the others, or the \
                 cell size very small?)",
                cx * self.geometry.resolution,
                cy * self.geometry.resolution,
                self.geometry.resolution
            ),
            cx * cy,
        )?;
        let (ntx, nty) = (nx1 - nx0, ny1 - ny0);
        if ntx > MAX_TILE_SPAN || nty > MAX_TILE_SPAN {
            return Err(CrlamError::OutOfBounds(format!(
                "growing the map to {ntx} x {nty} tiles exceeds the limit of {MAX_TILE_SPAN} tiles a side; \
                 is a pose far outside the mapped area?"
            )));
        }
        let mut tiles: Vec<Option<Arc<[T]>>> =
            try_filled((ntx * nty) as usize, None, "map tile slots")?;
        for ty in 0..nty0 {
            for tx in 0..ntx0 {
                let old = (ty * ntx0 + tx) as usize;
                let new = ((ty + self.ty0 - ny0) * ntx + (tx + self.tx0 - nx0)) as usize;
                tiles[new] = self.tiles[old].take();
            }
        }
        self.tiles = tiles;
        self.tx0 = nx0;
        self.ty0 = ny0;
        self.ntx = ntx;
        self.nty = nty;
        Ok(())
    }

    /// Readies the grid for a scan from `pose` reaching `reach` metres: the pose must be valid
    /// and, for a fixed extent, inside it; a growing grid reserves every cell within reach.
    pub fn prepare_scan(&mut self, pose: [f64; 3], reach: f64) -> Result<()> {
        check_pose(pose)?;
        let g = self.geometry;
        let (cx, cy) = g.cell_of(pose[0], pose[1]);
        match self.fixed {
            Some(ext) if !ext.contains(cx, cy) => Err(CrlamError::OutOfBounds(format!(
                "sensor pose ({:.3}, {:.3}) lies outside the fixed map extent",
                pose[0], pose[1]
            ))),
            Some(_) => Ok(()),
            None => {
                // In floats first: a tiny cell or a huge reach must give an error, not overflow.
                let rf = (reach / g.resolution).ceil() + 2.0;
                let side = 2.0 * rf + 1.0;
                check_map_cells(
                    &format!(
                        "a scan reaching {reach} m on {} m cells ({side:.0} x {side:.0} cells)",
                        g.resolution
                    ),
                    side * side,
                )?;
                let r = rf as i64;
                self.reserve(CellRect {
                    ix0: cx - r,
                    iy0: cy - r,
                    nx: 2 * r + 1,
                    ny: 2 * r + 1,
                })
            }
        }
    }

    /// Mutable values of cell (ix, iy), allocating its tile (from the fill value) or un-sharing
    /// it (copy-on-write) as needed. Storage must already cover the cell ([`Self::reserve`]).
    #[inline]
    pub fn get_mut(&mut self, ix: i64, iy: i64) -> Result<&mut [T]> {
        if !self.writable(ix, iy) {
            return Err(CrlamError::OutOfBounds(format!(
                "cell ({ix}, {iy}) is outside the fixed extent"
            )));
        }
        let Some((slot, off)) = self.slot_of(ix, iy) else {
            return Err(CrlamError::OutOfBounds(format!(
                "cell ({ix}, {iy}) is outside reserved storage"
            )));
        };
        let stride = self.stride;
        let cells = 1usize << (2 * self.shift);
        let tile = &mut self.tiles[slot];
        let shared = tile.as_mut().is_some_and(|t| Arc::get_mut(t).is_none());
        match tile {
            None => {
                let fill = &self.fill;
                let t = take_pooled(
                    &self.pool,
                    cells * stride,
                    |d| {
                        for c in d.chunks_exact_mut(stride) {
                            c.copy_from_slice(fill);
                        }
                    },
                    || {
                        let mut v = Vec::with_capacity(cells * stride);
                        for _ in 0..cells {
                            v.extend_from_slice(fill);
                        }
                        Arc::from(v)
                    },
                );
                *tile = Some(t);
            }
            Some(t) if shared => {
                let src = Arc::clone(t);
                *t = take_pooled(
                    &self.pool,
                    src.len(),
                    |d| d.copy_from_slice(&src),
                    || Arc::from(&src[..]),
                );
            }
            Some(_) => {}
        }
        let Some(tile) = tile.as_mut() else {
            return Err(CrlamError::Shape("tile missing after allocation".into()));
        };
        let data = Arc::get_mut(tile)
            .ok_or_else(|| CrlamError::Shape("tile still shared after copy".into()))?;
        Ok(&mut data[off..off + stride])
    }

    /// Sharing statistics.
    pub fn tile_stats(&self) -> TileStats {
        let mut s = TileStats {
            n_slots: self.tiles.len(),
            ..Default::default()
        };
        for t in self.tiles.iter().flatten() {
            s.n_allocated += 1;
            if Arc::strong_count(t) > 1 {
                s.n_shared += 1;
            }
            s.bytes_allocated += t.len() * std::mem::size_of::<T>();
        }
        s
    }

    /// (address, bytes) of every allocated tile: equal addresses are the same shared tile, so
    /// summing over distinct addresses gives the memory of a set of grids.
    pub fn tile_addresses(&self) -> impl Iterator<Item = (usize, usize)> + '_ {
        self.tiles
            .iter()
            .flatten()
            .map(|t| (t.as_ptr() as usize, t.len() * std::mem::size_of::<T>()))
    }

    /// Copies the cells of `rect` into a row-major `[iy][ix][stride]` buffer. A rectangle of
    /// more cells than [`crate::limits::max_map_cells`] is refused before anything is allocated.
    pub fn export(&self, rect: CellRect) -> Result<Vec<T>> {
        if rect.nx <= 0 || rect.ny <= 0 {
            return Ok(Vec::new());
        }
        rect.validate()?;
        check_dense_rect(rect)?;
        let mut out = try_vec(rect.n_cells() * self.stride, "map export")?;
        for iy in rect.iy0..rect.iy0 + rect.ny {
            for ix in rect.ix0..rect.ix0 + rect.nx {
                out.extend_from_slice(self.get(ix, iy));
            }
        }
        Ok(out)
    }

    /// Writes a row-major `[iy][ix][stride]` buffer over the cells of `rect`.
    pub fn import(&mut self, rect: CellRect, values: &[T]) -> Result<()> {
        rect.validate()?;
        if values.len() != rect.n_cells().saturating_mul(self.stride) {
            return Err(CrlamError::Shape(format!(
                "expected {} values for {} cells x {}, got {}",
                rect.n_cells() * self.stride,
                rect.n_cells(),
                self.stride,
                values.len()
            )));
        }
        self.reserve(rect)?;
        let stride = self.stride;
        let mut k = 0;
        for iy in rect.iy0..rect.iy0 + rect.ny {
            for ix in rect.ix0..rect.ix0 + rect.nx {
                self.get_mut(ix, iy)?
                    .copy_from_slice(&values[k..k + stride]);
                k += stride;
            }
        }
        Ok(())
    }
}

/// Refuses a dense copy of `rect` (an export, a layer) of more cells than the map-cell limit.
pub fn check_dense_rect(rect: CellRect) -> Result<()> {
    check_map_cells(
        &format!("a dense copy of {} x {} cells", rect.nx, rect.ny),
        rect.cells_f64(),
    )
}

#[cfg(test)]
#[path = "tiled_tests.rs"]
mod tests;
