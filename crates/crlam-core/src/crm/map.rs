//! The confidence-rich map: tiled f32 pmfs per cell, their means and derived layers (the scan
//! updates and likelihoods are in `scan.rs`).

use std::sync::Arc;

use crate::crm::beam_job::BeamJob;
use crate::crm::levels::{level_values, moments, tilted_prior, uniform_prior, LevelPlacement};
use crate::crm::mean_cache::{MeanCache, MeanTable, TileMeans};
use crate::crm::reading_table::ReadingTable;
use crate::crm::scan_cells::ScanCells;
use crate::crm::windowed::WindowScratch;
use crate::error::{config_err, CrlamError, Result};
use crate::grid::{check_dense_rect, CellRect, GridGeometry, TileStats, TiledGrid};
use crate::limits::try_vec;
use crate::raycast::RayCell;

/// Configuration of a CRM (crm-spec 9).
#[derive(Clone, Debug, PartialEq)]
pub struct CrmConfig {
    pub geometry: GridGeometry,
    /// K, the number of occupancy bins.
    pub n_levels: usize,
    pub placement: LevelPlacement,
    /// Prior mean: `None` for the uniform prior, else the tilted pmf with this mean.
    pub prior_mean: Option<f64>,
    /// ε_b: pmf entries are floored at this after each update (0 disables).
    pub belief_floor: f64,
    pub tile_size: usize,
    /// Fixed extent in cells; `None` grows with the data.
    pub extent: Option<CellRect>,
}

impl CrmConfig {
    /// Defaults of the spec at the given geometry: 10 midpoint levels, uniform prior, floor 1e-12.
    pub fn new(geometry: GridGeometry) -> Self {
        Self {
            geometry,
            n_levels: 10,
            placement: LevelPlacement::Midpoints,
            prior_mean: None,
            belief_floor: 1e-12,
            tile_size: 32,
            extent: None,
        }
    }
}

/// Reusable buffers of the scan update (one per thread).
#[derive(Debug, Default)]
pub struct CrmScratch {
    pub(super) cells: Vec<RayCell>,
    pub(super) mhat: Vec<f64>,
    pub(super) like: Vec<f64>,
    pub(super) alpha: Vec<f64>,
    pub(super) s: Vec<f64>,
    /// Batch mode: the scan's cell table and, per gathered cell, its id there.
    pub(super) scan: ScanCells,
    pub(super) ids: Vec<usize>,
    /// Buffers of the windowed batch kernel.
    pub(super) window: WindowScratch,
    /// (cos, sin) of the beam angles of the last scan layout seen.
    pub(super) directions: BeamDirections,
    /// The beams of the current batch scan.
    pub(super) jobs: Vec<BeamJob>,
    /// Pose-independent constants of the last weighed scan's readings.
    pub(super) readings: ReadingTable,
}

/// The (cos, sin) of a scan's beam angles, kept while the angles stay the same (a filter's
/// particles all walk the same scan).
#[derive(Debug, Default)]
pub(crate) struct BeamDirections {
    angles: Vec<f64>,
    cos_sin: Vec<[f64; 2]>,
}

impl BeamDirections {
    /// Makes the table match `angles`.
    pub(crate) fn prepare(&mut self, angles: &[f64]) {
        if self.angles != angles {
            self.angles = angles.to_vec();
            self.cos_sin = angles.iter().map(|a| [a.cos(), a.sin()]).collect();
        }
    }

    /// The unit vector of beam `b` turned by the heading whose cosine and sine are `c0`, `s0`.
    #[inline]
    pub(crate) fn rotated(&self, b: usize, c0: f64, s0: f64) -> [f64; 2] {
        let [c, s] = self.cos_sin[b];
        [c0 * c - s0 * s, s0 * c + c0 * s]
    }
}

/// Runs `f` with this thread's reusable [`CrmScratch`] (a fresh one if it is already in use
/// further up the stack). Reusing it across scans keeps the batch update's cell table
/// allocated: its dense part spans the sensor range around the robot (up to 16 MB for long
/// ranges on fine grids) and costs nothing to reuse, while allocating it per scan does.
pub fn with_thread_scratch<R>(f: impl FnOnce(&mut CrmScratch) -> R) -> R {
    thread_local! {
        static SCRATCH: std::cell::RefCell<CrmScratch> =
            std::cell::RefCell::new(CrmScratch::default());
    }
    SCRATCH.with(|cell| match cell.try_borrow_mut() {
        Ok(mut sc) => f(&mut sc),
        Err(_) => f(&mut CrmScratch::default()),
    })
}

/// A confidence-rich map (crm-spec 1–3). Cloning shares tiles copy-on-write.
#[derive(Clone, Debug)]
pub struct CrmMap {
    pub(super) grid: TiledGrid<f32>,
    pub(super) mu: Vec<f64>,
    prior: Vec<f64>,
    placement: LevelPlacement,
    pub(super) floor: f64,
    /// Means shared with the copies of this map that have not written since (a batch scan
    /// fills it when the map is shared); replaced on every write.
    pub(super) means: MeanCache,
}

impl CrmMap {
    /// A map where every cell holds the prior.
    pub fn new(cfg: &CrmConfig) -> Result<Self> {
        let mu = level_values(cfg.n_levels, cfg.placement)?;
        let prior = match cfg.prior_mean {
            None => uniform_prior(mu.len()),
            Some(m) => tilted_prior(&mu, m)?,
        };
        if !(cfg.belief_floor.is_finite() && (0.0..1e-3).contains(&cfg.belief_floor)) {
            return Err(config_err(
                "belief_floor",
                format!("must be in [0, 1e-3), got {}", cfg.belief_floor),
            ));
        }
        if cfg.placement == LevelPlacement::Endpoints && cfg.belief_floor == 0.0 {
            return Err(config_err(
                "belief_floor",
                "endpoint levels need a positive floor (crm-spec 3.6)",
            ));
        }
        let fill: Vec<f32> = prior.iter().map(|&p| p as f32).collect();
        let grid = TiledGrid::new(cfg.geometry, cfg.tile_size, &fill, cfg.extent)?;
        Ok(Self {
            grid,
            mu,
            prior,
            placement: cfg.placement,
            floor: cfg.belief_floor,
            means: MeanCache::default(),
        })
    }

    /// Level values μ_k.
    pub fn levels(&self) -> &[f64] {
        &self.mu
    }

    /// The prior pmf.
    pub fn prior(&self) -> &[f64] {
        &self.prior
    }

    pub fn placement(&self) -> LevelPlacement {
        self.placement
    }

    pub fn belief_floor(&self) -> f64 {
        self.floor
    }

    pub fn geometry(&self) -> &GridGeometry {
        self.grid.geometry()
    }

    /// Underlying tiled storage (read-only).
    pub fn grid(&self) -> &TiledGrid<f32> {
        &self.grid
    }

    pub fn tile_stats(&self) -> TileStats {
        self.grid.tile_stats()
    }

    /// The stored pmf of a cell (f32, normalised to storage precision).
    pub fn cell(&self, ix: i64, iy: i64) -> &[f32] {
        self.grid.get(ix, iy)
    }

    /// Expected occupancy m̂ of a cell.
    #[inline]
    pub fn mean_at(&self, ix: i64, iy: i64) -> f64 {
        let p = self.grid.get(ix, iy);
        let (mut s, mut m) = (0.0f64, 0.0f64);
        for (&x, &q) in self.mu.iter().zip(p) {
            s += q as f64;
            m += x * q as f64;
        }
        m / s
    }

    /// The window table of means cached for this map's content (filled by a batch scan's
    /// weight, or carried over its update), if there is one: `mean_at`'s values over its rect.
    pub(crate) fn window_means(&self) -> Option<Arc<MeanTable>> {
        self.means.window_table()
    }

    /// The block means shared by the copies of this map (`None` for a fixed extent), for walks
    /// that read many cells many times (the likelihoods of a proposal's hill climb).
    pub(crate) fn tile_means(&self) -> Option<&TileMeans> {
        if self.grid.fixed_extent().is_some() {
            return None;
        }
        Some(self.means.tiles(|| {
            let (mut s, mut m) = (0.0f64, 0.0f64);
            for (&x, &q) in self.mu.iter().zip(self.grid.fill()) {
                s += q as f64;
                m += x * q as f64;
            }
            TileMeans::new(self.grid.bounds(), self.grid.tile_size(), m / s)
        }))
    }

    /// The block of the block means `tm` of this map that holds cell (ix, iy) (see
    /// [`TileMeans::block`]).
    #[inline]
    pub(crate) fn mean_block<'t>(
        &self,
        tm: &'t TileMeans,
        ix: i64,
        iy: i64,
    ) -> (i64, Option<&'t [f64]>) {
        tm.block(ix, iy, |rect, out| {
            // The block is a valid rectangle and `out` is sized for it: this cannot fail.
            let _ = self.means_into(rect, out);
        })
    }

    /// Expected occupancy m̂ of every cell of `rect` into `out` (row-major `[iy][ix]`, length
    /// `rect.n_cells()`), equal to [`Self::mean_at`] cell by cell, read a tile row at a time.
    pub fn means_into(&self, rect: CellRect, out: &mut [f64]) -> Result<()> {
        if out.len() != rect.n_cells() {
            return Err(CrlamError::Shape(format!(
                "means of {} cells need {} outputs, got {}",
                rect.n_cells(),
                rect.n_cells(),
                out.len()
            )));
        }
        let k = self.mu.len();
        let mean_of = |p: &[f32]| {
            let (mut s, mut m) = (0.0f64, 0.0f64);
            for (&x, &q) in self.mu.iter().zip(p) {
                s += q as f64;
                m += x * q as f64;
            }
            m / s
        };
        for (row, out_row) in out.chunks_mut(rect.nx.max(1) as usize).enumerate() {
            let iy = rect.iy0 + row as i64;
            let mut i = 0;
            while i < out_row.len() {
                let ix = rect.ix0 + i as i64;
                let (values, cells, stored) = self.grid.row_run(ix, iy, out_row.len() - i);
                if stored {
                    for (o, p) in out_row[i..i + cells].iter_mut().zip(values.chunks(k)) {
                        *o = mean_of(p);
                    }
                } else {
                    out_row[i..i + cells].fill(mean_of(values));
                }
                i += cells;
            }
        }
        Ok(())
    }

    /// Replaces the pmfs over `rect` (row-major `[iy][ix][k]`, normalised here).
    pub fn set_beliefs(&mut self, rect: CellRect, values: &[f64]) -> Result<()> {
        let k = self.mu.len();
        rect.validate()?;
        if values.len() != rect.n_cells().saturating_mul(k) {
            return Err(CrlamError::Shape(format!(
                "beliefs for {} cells x {k} levels need {} values, got {}",
                rect.n_cells(),
                rect.n_cells().saturating_mul(k),
                values.len()
            )));
        }
        let mut out = try_vec(values.len(), "beliefs")?;
        for p in values.chunks(k) {
            let s: f64 = p.iter().sum();
            if !(s > 0.0 && s.is_finite()) || p.iter().any(|x| !(x.is_finite() && *x >= 0.0)) {
                return Err(CrlamError::Shape(
                    "every pmf must be finite, >= 0 and have positive mass".into(),
                ));
            }
            // Pmfs already normalised to storage precision are stored as given, so that a
            // save/load round trip through f32 archives is bit-exact.
            let scale = if (s - 1.0).abs() < 1e-5 { 1.0 } else { 1.0 / s };
            out.extend(p.iter().map(|x| (x * scale) as f32));
        }
        self.means.invalidate();
        self.grid.import(rect, &out)
    }

    /// Refuses rays reaching `reach` metres when they could cross more cells than the map-cell
    /// limit (on a growing map a ray is not clipped, and its cells are gathered in buffers): a
    /// huge z_max or a tiny cell must give an error before the first ray, not exhaust memory.
    pub fn check_ray_reach(&self, reach: f64) -> Result<()> {
        let res = self.geometry().resolution;
        if self.grid.fixed_extent().is_some() && reach.is_finite() {
            return Ok(()); // rays are clipped to the extent, itself within the limit
        }
        crate::limits::check_map_cells(
            &format!("a ray reaching {reach} m on {res} m cells"),
            2.0 * reach / res + 4.0,
        )
    }

    /// Pmfs over `rect`, row-major `[iy][ix][k]` (refused above the map-cell limit).
    pub fn beliefs(&self, rect: CellRect) -> Result<Vec<f32>> {
        self.grid.export(rect)
    }

    /// (mean, variance, entropy in bits) per cell over `rect`, each row-major `[iy][ix]`
    /// (refused above the map-cell limit).
    pub fn derived(&self, rect: CellRect) -> Result<(Vec<f64>, Vec<f64>, Vec<f64>)> {
        if rect.nx <= 0 || rect.ny <= 0 {
            return Ok((Vec::new(), Vec::new(), Vec::new()));
        }
        rect.validate()?;
        check_dense_rect(rect)?;
        let n = rect.n_cells();
        let (mut m, mut v, mut h) = (
            try_vec(n, "mean layer")?,
            try_vec(n, "variance layer")?,
            try_vec(n, "entropy layer")?,
        );
        for iy in rect.iy0..rect.iy0 + rect.ny {
            for ix in rect.ix0..rect.ix0 + rect.nx {
                let (a, b, c) = moments(&self.mu, self.grid.get(ix, iy));
                m.push(a);
                v.push(b);
                h.push(c);
            }
        }
        Ok((m, v, h))
    }
}
