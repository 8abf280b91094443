//! Python classes for sensor models, CRMs and log-odds maps.

use crlam_core::crm::{
    self, BatchKernel, CrmConfig, CrmScratch, LevelPlacement, ScanOptions, ScanStats,
    ScanUpdateMode,
};
use crlam_core::grid::{CellRect, GridGeometry, TileStats};
use crlam_core::ogm::{LogOddsGrid, LogOddsParams};
use crlam_core::sensor::{self, SensorModelKind};
use numpy::ndarray::{Array2, Array3};
use numpy::{
    IntoPyArray, PyArray1, PyArray2, PyArray3, PyReadonlyArray1, PyReadonlyArray2,
    PyReadonlyArray3, PyUntypedArrayMethods,
};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::convert::{guard, pose3, poses_n3, shape_err, slice1, IntoPy};

/// A cause-conditional range likelihood model (crm-spec 2.3).
#[pyclass(module = "crlam._native", frozen)]
#[derive(Clone)]
pub struct SensorModel {
    pub inner: sensor::SensorModel,
}

#[pymethods]
impl SensorModel {
    #[new]
    #[pyo3(signature = (kind="ijrr", z_max=8.0, resolution=0.2, *, cause_kernel="midpoint", sigma_hit=None, w_hit=None, w_short=None, w_max=None, w_rand=None, lambda_short=0.2, z_min=0.0))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        kind: &str,
        z_max: f64,
        resolution: f64,
        cause_kernel: &str,
        sigma_hit: Option<f64>,
        w_hit: Option<f64>,
        w_short: Option<f64>,
        w_max: Option<f64>,
        w_rand: Option<f64>,
        lambda_short: f64,
        z_min: f64,
    ) -> PyResult<Self> {
        guard("SensorModel.new", || {
            let kind = SensorModelKind::parse(kind).py_err()?;
            let mut m = sensor::SensorModel::with_defaults(kind, z_max, resolution);
            m.kernel = sensor::CauseKernel::parse(cause_kernel).py_err()?;
            if let Some(v) = sigma_hit {
                m.sigma_hit = v;
            }
            m.w_hit = w_hit.unwrap_or(m.w_hit);
            m.w_short = w_short.unwrap_or(m.w_short);
            m.w_max = w_max.unwrap_or(m.w_max);
            m.w_rand = w_rand.unwrap_or(m.w_rand);
            m.lambda_short = lambda_short;
            m.z_min = z_min;
            if !(resolution.is_finite() && resolution > 0.0) {
                return Err(shape_err(format!(
                    "resolution must be finite and > 0, got {resolution}"
                )));
            }
            m.validate().py_err()?;
            Ok(Self { inner: m })
        })
    }

    #[getter]
    fn kind(&self) -> &'static str {
        self.inner.kind.name()
    }
    #[getter]
    fn z_max(&self) -> f64 {
        self.inner.z_max
    }
    #[getter]
    fn cause_kernel(&self) -> &'static str {
        self.inner.kernel.name()
    }
    #[getter]
    fn z_min(&self) -> f64 {
        self.inner.z_min
    }
    #[getter]
    fn sigma_hit(&self) -> f64 {
        self.inner.sigma_hit
    }
    #[getter]
    fn w_hit(&self) -> f64 {
        self.inner.w_hit
    }
    #[getter]
    fn w_short(&self) -> f64 {
        self.inner.w_short
    }
    #[getter]
    fn w_max(&self) -> f64 {
        self.inner.w_max
    }
    #[getter]
    fn w_rand(&self) -> f64 {
        self.inner.w_rand
    }
    #[getter]
    fn lambda_short(&self) -> f64 {
        self.inner.lambda_short
    }

    /// L_l(z) for a cause at distance d; z >= z_max (or inf/NaN) is the no-return atom.
    fn on_ray(&self, z: f64, d: f64) -> PyResult<f64> {
        guard("SensorModel.on_ray", || Ok(self.inner.on_ray(z, d)))
    }

    /// L_∞(z): likelihood of the reading when nothing lies within range.
    fn infinity(&self, z: f64) -> PyResult<f64> {
        guard("SensorModel.infinity", || Ok(self.inner.infinity(z)))
    }

    fn __repr__(&self) -> String {
        let m = &self.inner;
        format!(
            "SensorModel(kind={:?}, z_max={}, sigma_hit={:.4}, w=({}, {}, {}, {}), lambda_short={}, z_min={})",
            m.kind.name(),
            m.z_max,
            m.sigma_hit,
            m.w_hit,
            m.w_short,
            m.w_max,
            m.w_rand,
            m.lambda_short,
            m.z_min
        )
    }
}

fn rect_from(t: Option<(i64, i64, i64, i64)>) -> PyResult<Option<CellRect>> {
    t.map(|(ix0, iy0, nx, ny)| CellRect::checked(ix0, iy0, nx, ny).py_err())
        .transpose()
}

fn rect_tuple(r: CellRect) -> (i64, i64, i64, i64) {
    (r.ix0, r.iy0, r.nx, r.ny)
}

fn stats_dict<'py>(py: Python<'py>, s: &ScanStats) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("n_beams", s.n_beams)?;
    d.set_item("n_used", s.n_used)?;
    d.set_item("n_no_return", s.n_no_return)?;
    d.set_item("n_dropped_short", s.n_dropped_short)?;
    d.set_item("n_skipped_eta", s.n_skipped_eta)?;
    d.set_item("n_empty_ray", s.n_empty_ray)?;
    d.set_item("n_cell_updates", s.n_cell_updates)?;
    d.set_item("n_frozen", s.n_frozen)?;
    Ok(d)
}

fn tiles_dict<'py>(py: Python<'py>, s: &TileStats) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("n_slots", s.n_slots)?;
    d.set_item("n_allocated", s.n_allocated)?;
    d.set_item("n_shared", s.n_shared)?;
    d.set_item("bytes_allocated", s.bytes_allocated)?;
    Ok(d)
}

fn scan_opts(
    mode: &str,
    kernel: &str,
    beam_stride: usize,
    zero_is_no_return: bool,
    hits_first: bool,
) -> PyResult<ScanOptions> {
    Ok(ScanOptions {
        mode: ScanUpdateMode::parse(mode).py_err()?,
        kernel: BatchKernel::parse(kernel).py_err()?,
        beam_stride,
        zero_is_no_return,
        hits_first,
    })
}

/// A confidence-rich map (tiled, copy-on-write pmfs per cell).
#[pyclass(module = "crlam._native")]
pub struct CrmMap {
    inner: crm::CrmMap,
    scratch: CrmScratch,
    tile_size: usize,
}

impl CrmMap {
    /// Wraps a core map (e.g. a particle's).
    pub fn from_core(inner: crm::CrmMap, tile_size: usize) -> Self {
        Self {
            inner,
            scratch: CrmScratch::default(),
            tile_size,
        }
    }

    fn rect_or_bounds(&self, rect: Option<(i64, i64, i64, i64)>) -> PyResult<CellRect> {
        Ok(rect_from(rect)?.unwrap_or_else(|| self.inner.grid().bounds()))
    }

    /// The core map (read-only).
    pub fn core(&self) -> &crm::CrmMap {
        &self.inner
    }

    /// The core map, for in-place updates.
    pub fn core_mut(&mut self) -> &mut crm::CrmMap {
        &mut self.inner
    }
}

#[pymethods]
impl CrmMap {
    #[new]
    #[pyo3(signature = (resolution, origin=(0.0, 0.0), *, n_levels=10, levels="midpoints", prior_mean=None, belief_floor=1e-12, tile_size=32, extent=None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        resolution: f64,
        origin: (f64, f64),
        n_levels: usize,
        levels: &str,
        prior_mean: Option<f64>,
        belief_floor: f64,
        tile_size: usize,
        extent: Option<(i64, i64, i64, i64)>,
    ) -> PyResult<Self> {
        guard("CrmMap.new", || {
            let geometry = GridGeometry::new([origin.0, origin.1], resolution).py_err()?;
            let cfg = CrmConfig {
                geometry,
                n_levels,
                placement: LevelPlacement::parse(levels).py_err()?,
                prior_mean,
                belief_floor,
                tile_size,
                extent: rect_from(extent)?,
            };
            Ok(Self {
                inner: crm::CrmMap::new(&cfg).py_err()?,
                scratch: CrmScratch::default(),
                tile_size,
            })
        })
    }

    #[getter]
    fn resolution(&self) -> f64 {
        self.inner.geometry().resolution
    }
    #[getter]
    fn origin(&self) -> (f64, f64) {
        let o = self.inner.geometry().origin;
        (o[0], o[1])
    }
    #[getter]
    fn tile_size(&self) -> usize {
        self.tile_size
    }
    /// Level values μ_k, shape (K,).
    #[getter]
    fn levels<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, self.inner.levels())
    }
    #[getter]
    fn placement(&self) -> &'static str {
        self.inner.placement().name()
    }
    /// Prior pmf, shape (K,).
    #[getter]
    fn prior<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, self.inner.prior())
    }
    #[getter]
    fn belief_floor(&self) -> f64 {
        self.inner.belief_floor()
    }
    /// Fixed extent (ix0, iy0, nx, ny) or None.
    #[getter]
    fn extent(&self) -> Option<(i64, i64, i64, i64)> {
        self.inner.grid().fixed_extent().map(rect_tuple)
    }

    /// Cells covered by storage, (ix0, iy0, nx, ny).
    fn bounds(&self) -> (i64, i64, i64, i64) {
        rect_tuple(self.inner.grid().bounds())
    }

    /// Bounding rectangle of the tiles written so far, or None.
    fn written_bounds(&self) -> Option<(i64, i64, i64, i64)> {
        self.inner.grid().written_bounds().map(rect_tuple)
    }

    /// Cell index (ix, iy) of a world point (finite, within 1e7 m of the origin).
    fn cell_of(&self, x: f64, y: f64) -> PyResult<(i64, i64)> {
        guard("CrmMap.cell_of", || {
            self.inner.geometry().checked_cell_of(x, y).py_err()
        })
    }

    /// Expected occupancy of one cell.
    fn mean_at(&self, ix: i64, iy: i64) -> PyResult<f64> {
        guard("CrmMap.mean_at", || Ok(self.inner.mean_at(ix, iy)))
    }

    /// Stored pmf of one cell, shape (K,).
    fn cell<'py>(&self, py: Python<'py>, ix: i64, iy: i64) -> PyResult<Bound<'py, PyArray1<f32>>> {
        guard("CrmMap.cell", || {
            Ok(PyArray1::from_slice(py, self.inner.cell(ix, iy)))
        })
    }

    /// Updates the map with one scan from the sensor pose; returns counters.
    #[pyo3(signature = (pose, angles, ranges, model, *, mode="batch", batch_kernel="windowed", beam_stride=1, zero_is_no_return=false, hits_first=false))]
    #[allow(clippy::too_many_arguments)]
    fn update_scan<'py>(
        &mut self,
        py: Python<'py>,
        pose: PyReadonlyArray1<'py, f64>,
        angles: PyReadonlyArray1<'py, f64>,
        ranges: PyReadonlyArray1<'py, f64>,
        model: &SensorModel,
        mode: &str,
        batch_kernel: &str,
        beam_stride: usize,
        zero_is_no_return: bool,
        hits_first: bool,
    ) -> PyResult<Bound<'py, PyDict>> {
        guard("CrmMap.update_scan", || {
            let opts = scan_opts(
                mode,
                batch_kernel,
                beam_stride,
                zero_is_no_return,
                hits_first,
            )?;
            let pose = pose3(&pose)?;
            let (a, r) = (slice1(&angles, "angles")?, slice1(&ranges, "ranges")?);
            let m = model.inner;
            let (inner, sc) = (&mut self.inner, &mut self.scratch);
            let st = py
                .allow_threads(|| inner.update_scan(pose, a, r, &m, &opts, sc))
                .py_err()?;
            stats_dict(py, &st)
        })
    }

    /// Updates the map with n scans (poses (n, 3), ranges (n, m), shared angles (m,)).
    #[pyo3(signature = (poses, angles, ranges, model, *, mode="batch", batch_kernel="windowed", beam_stride=1, zero_is_no_return=false, hits_first=false))]
    #[allow(clippy::too_many_arguments)]
    fn update_scans<'py>(
        &mut self,
        py: Python<'py>,
        poses: PyReadonlyArray2<'py, f64>,
        angles: PyReadonlyArray1<'py, f64>,
        ranges: PyReadonlyArray2<'py, f64>,
        model: &SensorModel,
        mode: &str,
        batch_kernel: &str,
        beam_stride: usize,
        zero_is_no_return: bool,
        hits_first: bool,
    ) -> PyResult<Bound<'py, PyDict>> {
        guard("CrmMap.update_scans", || {
            let opts = scan_opts(
                mode,
                batch_kernel,
                beam_stride,
                zero_is_no_return,
                hits_first,
            )?;
            let poses = poses_n3(&poses)?;
            let a = slice1(&angles, "angles")?;
            let shape = ranges.shape();
            if shape[0] != poses.len() || shape[1] != a.len() {
                return Err(shape_err(format!(
                    "ranges must have shape ({}, {}) to match poses and angles, got {shape:?}",
                    poses.len(),
                    a.len()
                )));
            }
            let r = ranges
                .as_slice()
                .map_err(|_| shape_err("ranges must be contiguous"))?;
            let m = model.inner;
            let (inner, sc) = (&mut self.inner, &mut self.scratch);
            let st = py
                .allow_threads(|| {
                    let mut total = ScanStats::default();
                    for (i, p) in poses.iter().enumerate() {
                        let s = inner.update_scan(
                            *p,
                            a,
                            &r[i * a.len()..(i + 1) * a.len()],
                            &m,
                            &opts,
                            sc,
                        )?;
                        total.add(&s);
                    }
                    Ok(total)
                })
                .py_err()?;
            stats_dict(py, &st)
        })
    }

    /// (Σ log η over beams, beams used) of a scan under the current beliefs, map unchanged.
    #[pyo3(signature = (pose, angles, ranges, model, *, beam_stride=1, zero_is_no_return=false))]
    fn scan_log_likelihood<'py>(
        &mut self,
        py: Python<'py>,
        pose: PyReadonlyArray1<'py, f64>,
        angles: PyReadonlyArray1<'py, f64>,
        ranges: PyReadonlyArray1<'py, f64>,
        model: &SensorModel,
        beam_stride: usize,
        zero_is_no_return: bool,
    ) -> PyResult<(f64, usize)> {
        guard("CrmMap.scan_log_likelihood", || {
            let opts = scan_opts("batch", "windowed", beam_stride, zero_is_no_return, false)?;
            let pose = pose3(&pose)?;
            let (a, r) = (slice1(&angles, "angles")?, slice1(&ranges, "ranges")?);
            let m = model.inner;
            let (inner, sc) = (&self.inner, &mut self.scratch);
            py.allow_threads(|| inner.scan_log_likelihood(pose, a, r, &m, &opts, sc))
                .py_err()
        })
    }

    /// Pmfs over a cell rectangle (default: bounds), shape (ny, nx, K), float32.
    #[pyo3(signature = (rect=None))]
    fn beliefs<'py>(
        &self,
        py: Python<'py>,
        rect: Option<(i64, i64, i64, i64)>,
    ) -> PyResult<Bound<'py, PyArray3<f32>>> {
        guard("CrmMap.beliefs", || {
            let r = self.rect_or_bounds(rect)?;
            let k = self.inner.levels().len();
            let v = self.inner.beliefs(r).py_err()?;
            let a = Array3::from_shape_vec((r.ny.max(0) as usize, r.nx.max(0) as usize, k), v)
                .map_err(|e| shape_err(e.to_string()))?;
            Ok(a.into_pyarray(py))
        })
    }

    /// Writes pmfs (ny, nx, K) with cell (ix0, iy0) at index [0, 0]; each pmf is normalised.
    fn set_beliefs(
        &mut self,
        ix0: i64,
        iy0: i64,
        beliefs: PyReadonlyArray3<'_, f64>,
    ) -> PyResult<()> {
        guard("CrmMap.set_beliefs", || {
            let s = beliefs.shape();
            if s[2] != self.inner.levels().len() {
                return Err(shape_err(format!(
                    "beliefs have {} levels, the map has {}",
                    s[2],
                    self.inner.levels().len()
                )));
            }
            if s[0] == 0 || s[1] == 0 {
                return Ok(());
            }
            let side = |n: usize| i64::try_from(n).unwrap_or(i64::MAX);
            let r = CellRect::checked(ix0, iy0, side(s[1]), side(s[0])).py_err()?;
            let v = beliefs
                .as_slice()
                .map_err(|_| shape_err("beliefs must be contiguous"))?;
            self.inner.set_beliefs(r, v).py_err()
        })
    }

    /// (expected occupancy, variance, entropy in bits), each (ny, nx) over the rectangle.
    #[pyo3(signature = (rect=None))]
    fn derived_maps<'py>(
        &self,
        py: Python<'py>,
        rect: Option<(i64, i64, i64, i64)>,
    ) -> PyResult<(
        Bound<'py, PyArray2<f64>>,
        Bound<'py, PyArray2<f64>>,
        Bound<'py, PyArray2<f64>>,
    )> {
        guard("CrmMap.derived_maps", || {
            let r = self.rect_or_bounds(rect)?;
            let (m, v, h) = py.allow_threads(|| self.inner.derived(r)).py_err()?;
            let shape = (r.ny.max(0) as usize, r.nx.max(0) as usize);
            let to = |x: Vec<f64>| {
                Array2::from_shape_vec(shape, x).map_err(|e| shape_err(e.to_string()))
            };
            Ok((
                to(m)?.into_pyarray(py),
                to(v)?.into_pyarray(py),
                to(h)?.into_pyarray(py),
            ))
        })
    }

    /// A copy sharing every tile copy-on-write (O(tiles), no cell data copied).
    fn copy(&self) -> Self {
        Self {
            inner: self.inner.clone(),
            scratch: CrmScratch::default(),
            tile_size: self.tile_size,
        }
    }

    /// Tile counts and bytes (shared tiles counted in full).
    fn tile_stats<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        guard("CrmMap.tile_stats", || {
            tiles_dict(py, &self.inner.tile_stats())
        })
    }
}

/// Baseline log-odds occupancy grid.
#[pyclass(module = "crlam._native")]
pub struct LogOddsMap {
    inner: LogOddsGrid,
}

impl LogOddsMap {
    /// Wraps a core grid (e.g. a particle's).
    pub fn from_core(inner: LogOddsGrid) -> Self {
        Self { inner }
    }
}

#[pymethods]
impl LogOddsMap {
    #[new]
    #[pyo3(signature = (resolution, origin=(0.0, 0.0), *, z_max=8.0, l_occ=1.0, l_free=-0.5, l_min=-100.0, l_max=100.0, base=2.0, clear_no_return=true, tile_size=32, extent=None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        resolution: f64,
        origin: (f64, f64),
        z_max: f64,
        l_occ: f64,
        l_free: f64,
        l_min: f64,
        l_max: f64,
        base: f64,
        clear_no_return: bool,
        tile_size: usize,
        extent: Option<(i64, i64, i64, i64)>,
    ) -> PyResult<Self> {
        guard("LogOddsMap.new", || {
            let g = GridGeometry::new([origin.0, origin.1], resolution).py_err()?;
            let p = LogOddsParams {
                l_occ,
                l_free,
                l_min,
                l_max,
                base,
                z_max,
                clear_no_return,
                hit_means: false,
            };
            Ok(Self {
                inner: LogOddsGrid::new(g, p, tile_size, rect_from(extent)?).py_err()?,
            })
        })
    }

    #[getter]
    fn resolution(&self) -> f64 {
        self.inner.grid().geometry().resolution
    }
    #[getter]
    fn origin(&self) -> (f64, f64) {
        let o = self.inner.grid().geometry().origin;
        (o[0], o[1])
    }
    #[getter]
    fn base(&self) -> f64 {
        self.inner.params().base
    }

    fn bounds(&self) -> (i64, i64, i64, i64) {
        rect_tuple(self.inner.grid().bounds())
    }

    fn written_bounds(&self) -> Option<(i64, i64, i64, i64)> {
        self.inner.grid().written_bounds().map(rect_tuple)
    }

    /// Integrates one scan; returns (beams used, beams dropped).
    fn update_scan(
        &mut self,
        py: Python<'_>,
        pose: PyReadonlyArray1<'_, f64>,
        angles: PyReadonlyArray1<'_, f64>,
        ranges: PyReadonlyArray1<'_, f64>,
    ) -> PyResult<(usize, usize)> {
        guard("LogOddsMap.update_scan", || {
            let pose = pose3(&pose)?;
            let (a, r) = (slice1(&angles, "angles")?, slice1(&ranges, "ranges")?);
            let inner = &mut self.inner;
            py.allow_threads(|| inner.update_scan(pose, a, r)).py_err()
        })
    }

    /// Integrates n scans (poses (n, 3), ranges (n, m)); returns totals (used, dropped).
    fn update_scans(
        &mut self,
        py: Python<'_>,
        poses: PyReadonlyArray2<'_, f64>,
        angles: PyReadonlyArray1<'_, f64>,
        ranges: PyReadonlyArray2<'_, f64>,
    ) -> PyResult<(usize, usize)> {
        guard("LogOddsMap.update_scans", || {
            let poses = poses_n3(&poses)?;
            let a = slice1(&angles, "angles")?;
            let shape = ranges.shape();
            if shape[0] != poses.len() || shape[1] != a.len() {
                return Err(shape_err(format!(
                    "ranges must have shape ({}, {}), got {shape:?}",
                    poses.len(),
                    a.len()
                )));
            }
            let r = ranges
                .as_slice()
                .map_err(|_| shape_err("ranges must be contiguous"))?;
            let inner = &mut self.inner;
            py.allow_threads(|| {
                let (mut u, mut d) = (0, 0);
                for (i, p) in poses.iter().enumerate() {
                    let (a1, b1) = inner.update_scan(*p, a, &r[i * a.len()..(i + 1) * a.len()])?;
                    u += a1;
                    d += b1;
                }
                Ok((u, d))
            })
            .py_err()
        })
    }

    /// Log-odds over a cell rectangle (default: bounds), shape (ny, nx).
    #[pyo3(signature = (rect=None))]
    fn log_odds<'py>(
        &self,
        py: Python<'py>,
        rect: Option<(i64, i64, i64, i64)>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        guard("LogOddsMap.log_odds", || {
            let r = rect_from(rect)?.unwrap_or_else(|| self.inner.grid().bounds());
            let v: Vec<f64> = self
                .inner
                .export(r)
                .py_err()?
                .into_iter()
                .map(f64::from)
                .collect();
            let a = Array2::from_shape_vec((r.ny.max(0) as usize, r.nx.max(0) as usize), v)
                .map_err(|e| shape_err(e.to_string()))?;
            Ok(a.into_pyarray(py))
        })
    }

    fn copy(&self) -> Self {
        Self {
            inner: self.inner.clone(),
        }
    }

    fn tile_stats<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        guard("LogOddsMap.tile_stats", || {
            tiles_dict(py, &self.inner.tile_stats())
        })
    }
}
