//! The confidence-rich map: tiled f32 pmfs per cell, updated beam by beam in f64.

use crate::crm::beam::{
    check_scan, plan_beam, BatchKernel, BeamPlan, ScanOptions, ScanStats, ScanUpdateMode,
};
use crate::crm::forward::mixture_log_eta_forward;
use crate::crm::levels::{level_values, moments, tilted_prior, uniform_prior, LevelPlacement};
use crate::crm::mean_cache::{MeanCache, TileMeans};
use crate::crm::scan_cells::{scan_window, ScanCells};
use crate::crm::update::{apply_factor, cause_sweep, cause_sweep_log, LINEAR_ETA_MIN};
use crate::crm::windowed::{WindowScratch, WindowedBeam, WindowedScan};
use crate::error::{config_err, CrlamError, Result};
use crate::grid::{check_pose, CellRect, GridGeometry, TileStats, TiledGrid};
use crate::raycast::{traverse_with, RayCell};
use crate::sensor::{MixtureReading, SensorModel, SensorModelKind};

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

/// Scan windows up to this many cells (8 m at 0.05 m, 25 m at 0.2 m) get a mean table of their
/// own even when the map is not shared.
const SMALL_WINDOW_CELLS: usize = 1 << 17;

/// Reusable buffers of the scan update (one per thread).
#[derive(Debug, Default)]
pub struct CrmScratch {
    cells: Vec<RayCell>,
    mhat: Vec<f64>,
    like: Vec<f64>,
    alpha: Vec<f64>,
    s: Vec<f64>,
    /// Batch mode: the scan's cell table and, per gathered cell, its id there.
    pub(super) scan: ScanCells,
    ids: Vec<usize>,
    /// Buffers of the windowed batch kernel.
    pub(super) window: WindowScratch,
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
    grid: TiledGrid<f32>,
    mu: Vec<f64>,
    prior: Vec<f64>,
    placement: LevelPlacement,
    floor: f64,
    /// Means shared with the copies of this map that have not written since (a batch scan
    /// fills it when the map is shared); replaced on every write.
    means: MeanCache,
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

    /// Expected occupancy m̂ of every cell of `rect` into `out` (row-major [iy][ix], length
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

    /// Replaces the pmfs over `rect` (row-major [iy][ix][k], normalised here).
    pub fn set_beliefs(&mut self, rect: CellRect, values: &[f64]) -> Result<()> {
        let k = self.mu.len();
        if values.len() != rect.n_cells() * k {
            return Err(CrlamError::Shape(format!(
                "beliefs for {} cells x {k} levels need {} values, got {}",
                rect.n_cells(),
                rect.n_cells() * k,
                values.len()
            )));
        }
        let mut out = Vec::with_capacity(values.len());
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

    /// Pmfs over `rect`, row-major [iy][ix][k].
    pub fn beliefs(&self, rect: CellRect) -> Vec<f32> {
        self.grid.export(rect)
    }

    /// (mean, variance, entropy in bits) per cell over `rect`, each row-major [iy][ix].
    pub fn derived(&self, rect: CellRect) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let n = rect.n_cells();
        let (mut m, mut v, mut h) = (
            Vec::with_capacity(n),
            Vec::with_capacity(n),
            Vec::with_capacity(n),
        );
        for iy in rect.iy0..rect.iy0 + rect.ny {
            for ix in rect.ix0..rect.ix0 + rect.nx {
                let (a, b, c) = moments(&self.mu, self.grid.get(ix, iy));
                m.push(a);
                v.push(b);
                h.push(c);
            }
        }
        (m, v, h)
    }

    /// Traverses the ray of `plan`, filling `sc.cells` and `sc.mhat` (and `sc.ids` if
    /// `batch`, see [`Self::gather_cells`]). A fixed extent truncates the ray; a hit beyond the
    /// truncation becomes a no-return over the truncated ray (2.1).
    fn gather_ray(&self, plan: &mut BeamPlan, sc: &mut CrmScratch, batch: bool) {
        let end = self.gather_cells(plan.origin, plan.angle, plan.length, sc, batch);
        self.truncation_to_no_return(plan, end);
    }

    /// Traverses a ray of `length` (clipped to a fixed extent) into `sc.cells` / `sc.mhat`;
    /// returns where the traversal ended. With `batch`, the means come from the scan's cell
    /// table (each cell read once per scan) and `sc.ids` holds the cells' ids there.
    fn gather_cells(
        &self,
        origin: [f64; 2],
        angle: f64,
        length: f64,
        sc: &mut CrmScratch,
        batch: bool,
    ) -> f64 {
        sc.cells.clear();
        let g = *self.grid.geometry();
        let ext = self.grid.fixed_extent();
        let cells = &mut sc.cells;
        let end = traverse_with(&g, origin, angle, length, ext.as_ref(), |c| {
            cells.push(c);
            true
        });
        sc.mhat.clear();
        sc.ids.clear();
        if batch {
            for c in sc.cells.iter() {
                let id = sc.scan.id(&self.grid, &self.mu, c.ix, c.iy);
                sc.ids.push(id);
                sc.mhat.push(sc.scan.mean(id));
            }
        } else {
            for c in sc.cells.iter() {
                sc.mhat.push(self.mean_at(c.ix, c.iy));
            }
        }
        end
    }

    /// A hit beyond where a fixed extent cut the ray is a no-return over the cut ray (2.1).
    fn truncation_to_no_return(&self, plan: &mut BeamPlan, end: f64) {
        if self.grid.fixed_extent().is_some() && !plan.no_return && end + 1e-9 < plan.z {
            plan.no_return = true;
        }
    }

    /// Computes α for the gathered ray into `sc.alpha` and returns log η (−∞ if unexplained).
    fn beam_alpha(
        &self,
        model: &SensorModel,
        plan: &BeamPlan,
        sc: &mut CrmScratch,
        need_alpha: bool,
    ) -> f64 {
        let n = sc.cells.len();
        sc.alpha.clear();
        sc.alpha.resize(n, 0.0);
        let z = if plan.no_return {
            f64::INFINITY
        } else {
            plan.z
        };
        if model.kind == SensorModelKind::AuthorsCode {
            return self.authors_alpha(model, plan, sc);
        }
        model.on_ray_cells(z, &sc.cells, &mut sc.like);
        let like_inf = model.infinity(z);
        let alpha = if need_alpha {
            Some(&mut sc.alpha[..])
        } else {
            None
        };
        let eta = cause_sweep(&sc.mhat, &sc.like, like_inf, &mut sc.s, alpha);
        if eta >= LINEAR_ETA_MIN && eta.is_finite() {
            return eta.ln();
        }
        // Far-off Gaussians underflowed: redo the sweep in logs (crm-spec 4.2).
        for (l, c) in sc.like.iter_mut().zip(sc.cells.iter()) {
            *l = model.log_on_ray_cell(z, c.t_in, c.t_out);
        }
        let alpha = if need_alpha {
            Some(&mut sc.alpha[..])
        } else {
            None
        };
        let mut s = std::mem::take(&mut sc.s);
        let log_eta = cause_sweep_log(&sc.mhat, &sc.like, like_inf.ln(), &mut s, alpha);
        sc.s = s;
        log_eta
    }

    /// The authors' MATLAB update restated (crm-spec 3.4): reach scaled by (1 − Δ·m̂), grid-index
    /// distances, no ∞ cause for hits. Returns log η and the equivalent α per cell.
    fn authors_alpha(&self, model: &SensorModel, plan: &BeamPlan, sc: &mut CrmScratch) -> f64 {
        let g = self.grid.geometry();
        let res = g.resolution;
        let (rx, ry) = g.cell_of(plan.origin[0], plan.origin[1]);
        let n = sc.cells.len();
        sc.like.clear();
        let mut pass = 1.0;
        for (l, c) in sc.cells.iter().enumerate() {
            let m = sc.mhat[l];
            let w = if plan.no_return {
                pass *= 1.0 - res * m;
                pass / model.z_max
            } else {
                let dist = res * (((c.ix - rx).pow(2) + (c.iy - ry).pow(2)) as f64).sqrt();
                let w = model.authors_bsm(dist, plan.z) * m * pass;
                pass *= 1.0 - res * m;
                w
            };
            sc.like.push(w.max(0.0));
        }
        let total: f64 = sc.like.iter().sum();
        let eta = if plan.no_return {
            total + 1.0 / model.z_max
        } else {
            total
        };
        if !(eta > 0.0 && eta.is_finite()) {
            return f64::NEG_INFINITY;
        }
        let mut after = total;
        for l in 0..n {
            let p_on = sc.like[l] / eta;
            after -= sc.like[l];
            let p_after = after.max(0.0) / eta;
            let m = sc.mhat[l];
            // α = P_on/m̂ − P_after/(1 − m̂), so that the factor αμ + β equals 1 + α(μ − m̂).
            sc.alpha[l] = p_on / m - p_after / (1.0 - m).max(1e-300);
        }
        eta.ln()
    }

    /// Predictive log-likelihood Σ_beams log η of a scan under the current beliefs (crm-spec
    /// 4.1), without changing the map. Returns (sum, beams used); dropped readings add nothing.
    pub fn scan_log_likelihood(
        &self,
        pose: [f64; 3],
        angles: &[f64],
        ranges: &[f64],
        model: &SensorModel,
        opts: &ScanOptions,
        sc: &mut CrmScratch,
    ) -> Result<(f64, usize)> {
        check_scan(angles, ranges, model, opts)?;
        check_pose(pose)?;
        let res = self.grid.geometry().resolution;
        let mut total = 0.0;
        let mut used = 0;
        for b in (0..angles.len()).step_by(opts.beam_stride) {
            let Ok(mut plan) = plan_beam(
                model,
                opts,
                res,
                [pose[0], pose[1]],
                pose[2] + angles[b],
                ranges[b],
            ) else {
                continue;
            };
            used += 1;
            let z = if plan.no_return {
                f64::INFINITY
            } else {
                plan.z
            };
            let forward = MixtureReading::new(model, z)
                .and_then(|r| mixture_log_eta_forward(self, &r, &plan));
            if let Some(log_eta) = forward {
                total += log_eta;
                continue;
            }
            self.gather_ray(&mut plan, sc, false);
            total += self.beam_alpha(model, &plan, sc, false);
        }
        Ok((total, used))
    }

    /// Weighs a scan under the pre-update beliefs (Σ log η with `weight_model` over every
    /// `weight_stride`-th beam, crm-spec 4.1) and then updates the map with `mapping_model`
    /// (`opts`), walking each beam once. The result equals [`Self::scan_log_likelihood`] followed
    /// by [`Self::update_scan`]; in batch mode both use the pre-scan beliefs, so one traversal
    /// serves both (sequential mode falls back to the two calls). Returns (Σ log η, beams
    /// weighed, update counters).
    #[allow(clippy::too_many_arguments)]
    pub fn weigh_and_update_scan(
        &mut self,
        pose: [f64; 3],
        angles: &[f64],
        ranges: &[f64],
        weight_model: &SensorModel,
        weight_stride: usize,
        mapping_model: &SensorModel,
        opts: &ScanOptions,
        sc: &mut CrmScratch,
    ) -> Result<(f64, usize, ScanStats)> {
        let wopts = ScanOptions {
            beam_stride: weight_stride,
            ..*opts
        };
        if opts.mode != ScanUpdateMode::Batch {
            let (ll, used) =
                self.scan_log_likelihood(pose, angles, ranges, weight_model, &wopts, sc)?;
            let st = self.update_scan(pose, angles, ranges, mapping_model, opts, sc)?;
            return Ok((ll, used, st));
        }
        check_scan(angles, ranges, weight_model, &wopts)?;
        self.batch_scan(
            pose,
            angles,
            ranges,
            Some((weight_model, weight_stride)),
            mapping_model,
            opts,
            sc,
        )
    }

    /// The batch scan (crm-spec 3.3) with an optional weight: every beam's coefficients from
    /// the pre-scan beliefs, one walk per beam for the weight and the update, factors multiplied
    /// per cell and written back once. `opts.kernel` picks the windowed kernel where it applies.
    #[allow(clippy::too_many_arguments)]
    fn batch_scan(
        &mut self,
        pose: [f64; 3],
        angles: &[f64],
        ranges: &[f64],
        weight: Option<(&SensorModel, usize)>,
        mapping_model: &SensorModel,
        opts: &ScanOptions,
        sc: &mut CrmScratch,
    ) -> Result<(f64, usize, ScanStats)> {
        check_scan(angles, ranges, mapping_model, opts)?;
        let z_max = weight.map_or(mapping_model.z_max, |(w, _)| {
            w.z_max.max(mapping_model.z_max)
        });
        self.grid.prepare_scan(pose, z_max)?;
        let res = self.grid.geometry().resolution;
        let origin = [pose[0], pose[1]];
        let mut st = ScanStats::default();
        let (mut total, mut used) = (0.0, 0);
        let windowed = if opts.kernel == BatchKernel::Windowed && self.grid.fixed_extent().is_none()
        {
            WindowedScan::new(mapping_model, weight.map(|(w, _)| w))
        } else {
            None
        };
        // The window's means in one table: read row by row, they cost less than the cells' first
        // reads from the tiles (scattered along the beams) unless the window is much larger
        // than what the scan touches (long ranges on fine grids); there only a table other
        // copies of the map share pays for itself.
        let window = scan_window(self.grid.geometry(), origin, z_max);
        let small = window.n_cells() <= SMALL_WINDOW_CELLS;
        let means = (windowed.is_some() && window.nx > 0 && (small || self.means.is_shared()))
            .then(|| {
                self.means.table(window, |rect, out| {
                    // The rectangle is valid and `out` sized for it, so this cannot fail.
                    let _ = self.means_into(rect, out);
                })
            });
        sc.scan.begin(self.grid.geometry(), origin, z_max, means);
        for b in 0..angles.len() {
            let angle = pose[2] + angles[b];
            let w_plan = match weight {
                Some((w, stride)) if b % stride == 0 => {
                    let wopts = ScanOptions {
                        beam_stride: stride,
                        ..*opts
                    };
                    plan_beam(w, &wopts, res, origin, angle, ranges[b]).ok()
                }
                _ => None,
            };
            let m_plan = if b % opts.beam_stride == 0 {
                st.n_beams += 1;
                let p = plan_beam(mapping_model, opts, res, origin, angle, ranges[b]).ok();
                st.n_dropped_short += usize::from(p.is_none());
                p
            } else {
                None
            };
            if w_plan.is_none() && m_plan.is_none() {
                continue;
            }
            if let Some(k) = &windowed {
                let out = k.beam(
                    &self.grid,
                    &self.mu,
                    &mut sc.scan,
                    &mut sc.window,
                    w_plan.as_ref(),
                    m_plan.as_ref(),
                    &mut st,
                );
                if let WindowedBeam::Done(log_eta) = out {
                    if let Some(l) = log_eta {
                        total += l;
                        used += 1;
                    }
                    continue;
                }
            }
            let (ll, weighed) = self.full_ray_beam(
                weight.map(|(w, _)| w),
                w_plan,
                mapping_model,
                m_plan,
                sc,
                &mut st,
            );
            total += ll;
            used += usize::from(weighed);
        }
        self.means.invalidate();
        sc.scan.write_back(&mut self.grid, &self.mu, self.floor)?;
        Ok((total, used, st))
    }

    /// One beam of a batch scan by the full sweep ([`BatchKernel::FullRay`]): its weight (log η,
    /// and whether it was weighed) and its factors into the scan table.
    fn full_ray_beam(
        &self,
        weight_model: Option<&SensorModel>,
        w_plan: Option<BeamPlan>,
        mapping_model: &SensorModel,
        m_plan: Option<BeamPlan>,
        sc: &mut CrmScratch,
        st: &mut ScanStats,
    ) -> (f64, bool) {
        let Some(any) = w_plan.or(m_plan) else {
            return (0.0, false);
        };
        let length = w_plan
            .map_or(0.0, |p| p.length)
            .max(m_plan.map_or(0.0, |p| p.length));
        let end = self.gather_cells(any.origin, any.angle, length, sc, true);
        let (mut total, mut weighed) = (0.0, false);
        // The longer ray is evaluated first; the shorter one is then a prefix of it.
        let weight_first = w_plan.map_or(0.0, |p| p.length) >= m_plan.map_or(0.0, |p| p.length);
        for stage in 0..2 {
            let is_weight = (stage == 0) == weight_first;
            let Some(mut plan) = (if is_weight { w_plan } else { m_plan }) else {
                continue;
            };
            truncate_ray(sc, plan.length);
            let cut = end.min(plan.length);
            self.truncation_to_no_return(&mut plan, cut);
            if is_weight {
                if let Some(w) = weight_model {
                    total += self.beam_alpha(w, &plan, sc, false);
                    weighed = true;
                }
                continue;
            }
            if sc.cells.is_empty() {
                st.n_empty_ray += 1;
                continue;
            }
            let log_eta = self.beam_alpha(mapping_model, &plan, sc, true);
            if !log_eta.is_finite() {
                st.n_skipped_eta += 1;
                continue;
            }
            st.n_used += 1;
            st.n_no_return += usize::from(plan.no_return);
            for l in 0..sc.cells.len() {
                sc.scan
                    .apply(&self.grid, sc.ids[l], sc.alpha[l], sc.mhat[l], &self.mu, st);
            }
        }
        (total, weighed)
    }

    /// Updates the map with one scan taken from the sensor pose `pose` (x, y, θ); beam b points
    /// at θ + angles[b] and read ranges[b] (crm-spec 3.1, 3.3).
    pub fn update_scan(
        &mut self,
        pose: [f64; 3],
        angles: &[f64],
        ranges: &[f64],
        model: &SensorModel,
        opts: &ScanOptions,
        sc: &mut CrmScratch,
    ) -> Result<ScanStats> {
        if opts.mode == ScanUpdateMode::Batch {
            return Ok(self
                .batch_scan(pose, angles, ranges, None, model, opts, sc)?
                .2);
        }
        check_scan(angles, ranges, model, opts)?;
        self.grid.prepare_scan(pose, model.z_max)?;
        let res = self.grid.geometry().resolution;
        let mut st = ScanStats::default();
        for b in (0..angles.len()).step_by(opts.beam_stride) {
            st.n_beams += 1;
            let mut plan = match plan_beam(
                model,
                opts,
                res,
                [pose[0], pose[1]],
                pose[2] + angles[b],
                ranges[b],
            ) {
                Ok(p) => p,
                Err(_) => {
                    st.n_dropped_short += 1;
                    continue;
                }
            };
            self.gather_ray(&mut plan, sc, false);
            if sc.cells.is_empty() {
                st.n_empty_ray += 1;
                continue;
            }
            let log_eta = self.beam_alpha(model, &plan, sc, true);
            if !log_eta.is_finite() {
                st.n_skipped_eta += 1;
                continue;
            }
            st.n_used += 1;
            st.n_no_return += usize::from(plan.no_return);
            for l in 0..sc.cells.len() {
                let (ix, iy) = (sc.cells[l].ix, sc.cells[l].iy);
                let ok = self.apply_to_cell(ix, iy, sc.alpha[l], sc.mhat[l])?;
                st.n_cell_updates += usize::from(ok);
                st.n_frozen += usize::from(!ok);
            }
        }
        Ok(st)
    }

    fn apply_to_cell(&mut self, ix: i64, iy: i64, alpha: f64, mhat: f64) -> Result<bool> {
        let k = self.mu.len();
        let mut p = [0.0f64; 65];
        let stored = self.grid.get(ix, iy);
        let mut s = 0.0;
        for i in 0..k {
            p[i] = stored[i] as f64;
            s += p[i];
        }
        for x in p[..k].iter_mut() {
            *x /= s;
        }
        if !apply_factor(&mut p[..k], &self.mu, alpha, mhat, self.floor) {
            return Ok(false);
        }
        self.means.invalidate();
        let dst = self.grid.get_mut(ix, iy)?;
        for i in 0..k {
            dst[i] = p[i] as f32;
        }
        Ok(true)
    }
}

/// Cuts a gathered ray to `length`: drops cells that start at or beyond it and ends the last
/// chord there, exactly as a traversal of that length would have reported them.
fn truncate_ray(sc: &mut CrmScratch, length: f64) {
    let keep = sc
        .cells
        .iter()
        .take_while(|c| c.t_in < length && length - c.t_in >= crate::raycast::MIN_CHORD)
        .count();
    sc.cells.truncate(keep);
    sc.mhat.truncate(keep);
    sc.ids.truncate(keep);
    if let Some(last) = sc.cells.last_mut() {
        last.t_out = last.t_out.min(length);
    }
}
