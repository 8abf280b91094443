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

use std::sync::{Arc, Mutex};

use crate::error::{config_err, CrlamError, Result};
use crate::limits::{check_map_cells, try_filled, try_vec};

/// `x.floor() as i64` (saturating, NaN to 0), bit for bit, without the call to libm's `floor`
/// that the baseline x86-64 target makes of `f64::floor` (no SSE4.1 `roundsd`): every walk
/// starts with two of them.
#[inline(always)]
pub fn floor_to_i64(x: f64) -> i64 {
    // Truncation saturates and maps NaN to 0; |t| <= |x| and t is an integer, so `t as f64` is
    // exact (below 2^53 every integer is, above it x is itself an integer).
    let t = x as i64;
    if (t as f64) > x {
        t.saturating_sub(1)
    } else {
        t
    }
}

/// Origin and cell size of a grid.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridGeometry {
    /// World coordinates (m) of the lower-left corner of cell (0, 0).
    pub origin: [f64; 2],
    /// Cell edge length Δ (m).
    pub resolution: f64,
}

impl GridGeometry {
    /// Validated constructor: `resolution` in [[`MIN_RESOLUTION`], [`MAX_COORD`]] and the origin
    /// within [`MAX_COORD`] of (0, 0), so that every cell index of a valid pose fits an `i64`
    /// with room to spare (|index| < 2^45).
    pub fn new(origin: [f64; 2], resolution: f64) -> Result<Self> {
        if !(resolution.is_finite() && (MIN_RESOLUTION..=MAX_COORD).contains(&resolution)) {
            return Err(config_err(
                "resolution",
                format!("must be a finite cell size in [{MIN_RESOLUTION:e}, {MAX_COORD:e}] m, got {resolution}"),
            ));
        }
        if !(origin[0].is_finite() && origin[1].is_finite())
            || origin[0].abs() > MAX_COORD
            || origin[1].abs() > MAX_COORD
        {
            return Err(config_err(
                "origin",
                format!("must be finite and within {MAX_COORD:e} m of (0, 0), got {origin:?}"),
            ));
        }
        Ok(Self { origin, resolution })
    }

    /// Index of the cell containing the world point (x, y) (saturating; NaN gives 0: check the
    /// point first with [`Self::checked_cell_of`] when it comes from input).
    #[inline]
    pub fn cell_of(&self, x: f64, y: f64) -> (i64, i64) {
        (
            floor_to_i64((x - self.origin[0]) / self.resolution),
            floor_to_i64((y - self.origin[1]) / self.resolution),
        )
    }

    /// Index of the cell containing (x, y), refusing non-finite points and points farther than
    /// [`MAX_COORD`] from the origin.
    pub fn checked_cell_of(&self, x: f64, y: f64) -> Result<(i64, i64)> {
        for (field, v) in [("x", x), ("y", y)] {
            if !v.is_finite() {
                return Err(CrlamError::NonFinite { field, value: v });
            }
        }
        if (x - self.origin[0]).abs() > MAX_COORD || (y - self.origin[1]).abs() > MAX_COORD {
            return Err(CrlamError::OutOfBounds(format!(
                "point ({x:.3e}, {y:.3e}) is more than {MAX_COORD:.0e} m from the map origin"
            )));
        }
        Ok(self.cell_of(x, y))
    }

    /// World coordinates of the centre of cell (ix, iy).
    #[inline]
    pub fn cell_center(&self, ix: i64, iy: i64) -> [f64; 2] {
        [
            self.origin[0] + (ix as f64 + 0.5) * self.resolution,
            self.origin[1] + (iy as f64 + 0.5) * self.resolution,
        ]
    }
}

/// Poses farther than this (m) from the grid origin are refused: they would overflow cell indices.
pub const MAX_COORD: f64 = 1e7;

/// Smallest cell size (m): with [`MAX_COORD`] it bounds every cell index of a valid pose by 2^45.
pub const MIN_RESOLUTION: f64 = 1e-6;

/// Largest |cell index| (and rectangle side) accepted from input: far beyond any valid pose
/// (2^45 > 2 x 10^7 m / 10^-6 m), and small enough that sums of two indices never overflow.
pub const MAX_CELL_INDEX: i64 = 1 << 46;

/// Checks that a pose (x, y, θ) is finite and within [`MAX_COORD`] of the origin.
pub fn check_pose(pose: [f64; 3]) -> Result<()> {
    for (i, name) in ["x", "y", "theta"].iter().enumerate() {
        if !pose[i].is_finite() {
            return Err(CrlamError::NonFinite {
                field: name,
                value: pose[i],
            });
        }
    }
    if pose[0].abs() > MAX_COORD || pose[1].abs() > MAX_COORD {
        return Err(CrlamError::OutOfBounds(format!(
            "pose ({:.3e}, {:.3e}) is more than {MAX_COORD:.0e} m from the map origin",
            pose[0], pose[1]
        )));
    }
    Ok(())
}

/// A rectangle of cells `[ix0, ix0 + nx) × [iy0, iy0 + ny)`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CellRect {
    pub ix0: i64,
    pub iy0: i64,
    pub nx: i64,
    pub ny: i64,
}

impl CellRect {
    /// A rectangle from input, refused unless `nx, ny > 0` and every index lies within
    /// [`MAX_CELL_INDEX`] (so that no arithmetic on it can overflow).
    pub fn checked(ix0: i64, iy0: i64, nx: i64, ny: i64) -> Result<Self> {
        let r = CellRect { ix0, iy0, nx, ny };
        r.validate()?;
        Ok(r)
    }

    /// See [`Self::checked`].
    pub fn validate(&self) -> Result<()> {
        let ok = |v: i64| v.unsigned_abs() <= MAX_CELL_INDEX as u64;
        if !(self.nx > 0 && self.ny > 0) {
            return Err(CrlamError::Shape(format!(
                "a cell rectangle (ix0, iy0, nx, ny) needs nx, ny > 0, got {self:?}"
            )));
        }
        if !(ok(self.ix0) && ok(self.iy0) && ok(self.nx) && ok(self.ny)) {
            return Err(CrlamError::OutOfBounds(format!(
                "cell rectangle {self:?}: indices and sizes must lie within +-2^46"
            )));
        }
        Ok(())
    }

    /// True when (ix, iy) lies inside.
    #[inline]
    pub fn contains(&self, ix: i64, iy: i64) -> bool {
        ix >= self.ix0 && iy >= self.iy0 && ix < self.ix0 + self.nx && iy < self.iy0 + self.ny
    }

    /// Smallest rectangle containing both.
    pub fn union(&self, other: &CellRect) -> CellRect {
        let ix0 = self.ix0.min(other.ix0);
        let iy0 = self.iy0.min(other.iy0);
        let ix1 = (self.ix0 + self.nx).max(other.ix0 + other.nx);
        let iy1 = (self.iy0 + self.ny).max(other.iy0 + other.ny);
        CellRect {
            ix0,
            iy0,
            nx: ix1 - ix0,
            ny: iy1 - iy0,
        }
    }

    /// Number of cells (saturating at `usize::MAX` for an absurd rectangle).
    pub fn n_cells(&self) -> usize {
        (self.nx.max(0) as u128 * self.ny.max(0) as u128).min(usize::MAX as u128) as usize
    }

    /// Number of cells as a float (exact below 2^53), for limit checks that must not overflow.
    pub fn cells_f64(&self) -> f64 {
        self.nx.max(0) as f64 * self.ny.max(0) as f64
    }
}

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

/// Most bytes of tiles a pool keeps for reuse.
const MAX_POOLED_BYTES: usize = 256 << 20;

/// Tiles of dropped grids, kept for the copies and new tiles of the grids that share the pool
/// (a grid and its clones). A particle filter drops the maps resampling discards and copies
/// the tiles of the kept ones as they diverge: recycling the memory, already faulted in, avoids
/// the allocator returning it to the system and faulting it in again (zeroed) for the next copy.
/// Invariant: every pooled tile is unshared (`Arc::get_mut` succeeds) and has the grid's tile
/// length.
struct TilePool<T> {
    free: Mutex<Vec<Arc<[T]>>>,
}

impl<T> TilePool<T> {
    fn new() -> Self {
        Self {
            free: Mutex::new(Vec::new()),
        }
    }

    /// The pooled tiles (a poisoned lock only means a thread panicked while pushing or popping:
    /// the vector itself is intact).
    fn lock(&self) -> std::sync::MutexGuard<'_, Vec<Arc<[T]>>> {
        self.free.lock().unwrap_or_else(|e| e.into_inner())
    }
}

impl<T> std::fmt::Debug for TilePool<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "TilePool({} tiles)", self.lock().len())
    }
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

/// A tile of `len` values written by `init`: a pooled one if the pool has any, else `fresh()`.
fn take_pooled<T: Copy>(
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

#[cfg(test)]
mod tests {
    use super::*;

    fn geom() -> GridGeometry {
        GridGeometry::new([0.0, 0.0], 0.5).unwrap()
    }

    #[test]
    fn dropped_grids_lend_their_tiles_to_the_copies_of_their_family() {
        let rect = CellRect {
            ix0: 0,
            iy0: 0,
            nx: 16,
            ny: 16,
        };
        let mut a = TiledGrid::new(geom(), 8, &[1.0f32, 2.0], None).unwrap();
        a.reserve(rect).unwrap();
        a.get_mut(1, 1).unwrap()[0] = 5.0;
        // A clone writes: its tile is a copy, freed to the pool when the clone is dropped.
        let mut b = a.clone();
        b.get_mut(2, 2).unwrap()[1] = 7.0;
        b.get_mut(12, 12).unwrap()[0] = 9.0;
        let b_tiles: Vec<usize> = b.tile_addresses().map(|(p, _)| p).collect();
        let a_tiles: Vec<usize> = a.tile_addresses().map(|(p, _)| p).collect();
        drop(b);
        assert_eq!(a.pool.lock().len(), 2, "both of b's own tiles are pooled");
        // Another clone reuses them: a copy of a's tile and a never-written tile from the fill,
        // with none of b's values left in either.
        let mut c = a.clone();
        c.get_mut(3, 3).unwrap()[0] = 4.0;
        c.get_mut(9, 1).unwrap()[0] = 6.0;
        assert!(a.pool.lock().is_empty());
        for (p, _) in c.tile_addresses() {
            assert!(b_tiles.contains(&p) && !a_tiles.contains(&p));
        }
        for iy in 0..16 {
            for ix in 0..16 {
                if (ix, iy) != (3, 3) && (ix, iy) != (9, 1) {
                    assert_eq!(c.get(ix, iy), a.get(ix, iy), "cell ({ix}, {iy})");
                }
            }
        }
        assert_eq!(c.get(1, 1), &[5.0, 2.0]);
        assert_eq!(c.get(2, 2), &[1.0, 2.0]);
        assert_eq!(c.get(3, 3), &[4.0, 2.0]);
        assert_eq!(c.get(9, 1), &[6.0, 2.0]);
        assert_eq!(c.get(12, 12), &[1.0, 2.0]);
        assert_eq!(a.get(3, 3), &[1.0, 2.0]);
        // The last grid of a family keeps nothing back.
        drop(c);
        let n = a.pool.lock().len();
        assert_eq!(n, 2);
        drop(a);
    }

    #[test]
    fn floor_to_i64_is_floor_as_i64() {
        let specials = [
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            -1e-300,
            1e-300,
            f64::EPSILON,
            -f64::EPSILON,
            1.0 - f64::EPSILON / 2.0,
            -1.0 + f64::EPSILON / 2.0,
            4503599627370495.5,
            -4503599627370495.5,
            9007199254740993.0,
            -9007199254740993.0,
            9_223_372_036_854_775_807i64 as f64,
            i64::MIN as f64,
            1e19,
            -1e19,
            f64::MAX,
            f64::MIN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
        ];
        for x in specials {
            assert_eq!(floor_to_i64(x), x.floor() as i64, "x = {x:e}");
        }
        // A deterministic sweep of magnitudes and fractions.
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        for _ in 0..200_000 {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let x = f64::from_bits(state);
            if x.is_finite() {
                assert_eq!(floor_to_i64(x), x.floor() as i64, "x = {x:e}");
                let y = (state >> 11) as f64 / (1u64 << 40) as f64 - 4096.0;
                assert_eq!(floor_to_i64(y), y.floor() as i64, "y = {y:e}");
            }
        }
    }

    #[test]
    fn cell_of_floors_negative_coordinates() {
        let g = geom();
        assert_eq!(g.cell_of(0.1, 0.1), (0, 0));
        assert_eq!(g.cell_of(-0.1, 0.6), (-1, 1));
        let c = g.cell_center(-1, 1);
        assert_eq!(g.cell_of(c[0], c[1]), (-1, 1));
    }

    #[test]
    fn unwritten_cells_read_fill_and_growth_keeps_data() {
        let mut g = TiledGrid::new(geom(), 8, &[1.0f32, 2.0], None).unwrap();
        assert_eq!(g.get(100, -100), &[1.0, 2.0]);
        g.reserve(CellRect {
            ix0: 0,
            iy0: 0,
            nx: 1,
            ny: 1,
        })
        .unwrap();
        g.get_mut(3, 4).unwrap()[1] = 7.0;
        g.reserve(CellRect {
            ix0: -100,
            iy0: 50,
            nx: 1,
            ny: 1,
        })
        .unwrap();
        g.get_mut(-100, 50).unwrap()[0] = 9.0;
        assert_eq!(g.get(3, 4), &[1.0, 7.0]);
        assert_eq!(g.get(-100, 50), &[9.0, 2.0]);
        assert_eq!(g.tile_stats().n_allocated, 2);
    }

    #[test]
    fn clones_share_tiles_until_written() {
        let mut a = TiledGrid::new(geom(), 8, &[0.0f32], None).unwrap();
        a.reserve(CellRect {
            ix0: 0,
            iy0: 0,
            nx: 64,
            ny: 64,
        })
        .unwrap();
        for i in 0..64 {
            a.get_mut(i, i).unwrap()[0] = i as f32;
        }
        let mut b = a.clone();
        assert_eq!(b.tile_stats().n_shared, 8);
        b.get_mut(0, 0).unwrap()[0] = -1.0;
        assert_eq!(a.get(0, 0), &[0.0]);
        assert_eq!(b.get(0, 0), &[-1.0]);
        assert_eq!(b.tile_stats().n_shared, 7);
        assert_eq!(a.get(9, 9), b.get(9, 9));
    }

    #[test]
    fn fixed_extent_refuses_outside_writes() {
        let r = CellRect {
            ix0: 0,
            iy0: 0,
            nx: 10,
            ny: 10,
        };
        let mut g = TiledGrid::new(geom(), 8, &[0u8], Some(r)).unwrap();
        assert!(g.get_mut(9, 9).is_ok());
        assert!(g.get_mut(10, 0).is_err());
        assert!(g
            .reserve(CellRect {
                ix0: 5,
                iy0: 5,
                nx: 10,
                ny: 1
            })
            .is_err());
        assert_eq!(g.bounds(), r);
    }

    #[test]
    fn export_import_round_trip() {
        let mut g = TiledGrid::new(geom(), 4, &[0i32, 0], None).unwrap();
        let r = CellRect {
            ix0: -3,
            iy0: 2,
            nx: 5,
            ny: 3,
        };
        let vals: Vec<i32> = (0..30).collect();
        g.import(r, &vals).unwrap();
        assert_eq!(g.export(r).unwrap(), vals);
    }

    #[test]
    fn bad_config_is_an_error() {
        assert!(GridGeometry::new([0.0, 0.0], 0.0).is_err());
        assert!(TiledGrid::new(geom(), 7, &[0u8], None).is_err());
    }
}
