//! Python classes of the information-function states: occupancy lattices, GP variance maps,
//! UCRMI particle beliefs and opaque map updates.

use crlam_core::grid::GridGeometry;
use crlam_core::info::crmi::VirtualScan;
use crlam_core::info::entropy::weighted_position_covariance;
use crlam_core::info::gp::GpVarianceMap as CoreGpMap;
use crlam_core::info::lattice;
use crlam_core::info::prior;
use crlam_core::info::ucrmi;
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1, PyArray2, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;

use crate::convert::{guard, shape_err, IntoPy};
use crate::maps::CrmMap;

/// Occupancy probabilities on a lattice of cell centres (planner-spec 2.2).
#[pyclass(module = "crlam._native")]
#[derive(Clone)]
pub struct OccupancyLattice {
    pub inner: lattice::OccupancyLattice,
}

fn lattice_from(
    probabilities: &PyReadonlyArray2<'_, f64>,
    resolution: f64,
    origin: (f64, f64),
) -> PyResult<lattice::OccupancyLattice> {
    let shape = probabilities.shape();
    let (ny, nx) = (shape[0], shape[1]);
    let p = probabilities
        .as_slice()
        .map_err(|_| shape_err("probabilities must be a contiguous float64 array"))?;
    let g = GridGeometry::new([origin.0, origin.1], resolution).py_err()?;
    lattice::OccupancyLattice::new(g, nx, ny, p.to_vec()).py_err()
}

#[pymethods]
impl OccupancyLattice {
    /// `probabilities` (ny, nx): row iy, column ix is the cell whose lower-left corner is
    /// origin + (ix, iy)·resolution.
    #[new]
    #[pyo3(signature = (probabilities, resolution, origin=(0.0, 0.0)))]
    fn new(
        probabilities: PyReadonlyArray2<'_, f64>,
        resolution: f64,
        origin: (f64, f64),
    ) -> PyResult<Self> {
        guard("OccupancyLattice.new", || {
            Ok(Self {
                inner: lattice_from(&probabilities, resolution, origin)?,
            })
        })
    }

    #[getter]
    fn shape(&self) -> (usize, usize) {
        let (nx, ny) = self.inner.shape();
        (ny, nx)
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

    /// The probabilities as a (ny, nx) array.
    fn probabilities<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        guard("OccupancyLattice.probabilities", || {
            let (nx, ny) = self.inner.shape();
            let a = Array2::from_shape_vec((ny, nx), self.inner.probabilities().to_vec())
                .map_err(|e| shape_err(e.to_string()))?;
            Ok(a.into_pyarray(py))
        })
    }

    fn copy(&self) -> Self {
        self.clone()
    }

    /// A CRM over the same cells whose pmfs are tilted priors with these means (crm-spec 6.5).
    #[pyo3(signature = (n_levels=10))]
    fn to_crm(&self, n_levels: usize) -> PyResult<CrmMap> {
        guard("OccupancyLattice.to_crm", || {
            let m = prior::crm_from_lattice(&self.inner, n_levels).py_err()?;
            Ok(CrmMap::from_core(m, 32))
        })
    }
}

/// GP variances on a lattice for GPVR/UGPVR; the lattice probabilities drive the ray casting.
#[pyclass(module = "crlam._native")]
#[derive(Clone)]
pub struct GpVarianceMap {
    pub inner: CoreGpMap,
}

#[pymethods]
impl GpVarianceMap {
    /// Prior variance `prior_variance` (1 in the reference) at every node.
    #[new]
    #[pyo3(signature = (lattice, prior_variance=1.0))]
    fn new(lattice: &OccupancyLattice, prior_variance: f64) -> PyResult<Self> {
        guard("GpVarianceMap.new", || {
            Ok(Self {
                inner: CoreGpMap::with_variances(
                    lattice.inner.clone(),
                    vec![prior_variance; lattice.inner.len()],
                )
                .py_err()?,
            })
        })
    }

    /// Variances as a (ny, nx) array.
    fn variances<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        guard("GpVarianceMap.variances", || {
            let (nx, ny) = self.inner.lattice().shape();
            let a = Array2::from_shape_vec((ny, nx), self.inner.variances().to_vec())
                .map_err(|e| shape_err(e.to_string()))?;
            Ok(a.into_pyarray(py))
        })
    }

    fn copy(&self) -> Self {
        self.clone()
    }
}

/// A particle set at a planner node (UCRMI).
#[pyclass(module = "crlam._native", frozen)]
#[derive(Clone)]
pub struct ParticleBelief {
    pub inner: ucrmi::ParticleBelief,
}

#[pymethods]
impl ParticleBelief {
    /// A belief from a particle set: poses (n, 3), log-weights (n,) (normalised here) and the
    /// set's entropy in nats (e.g. of a filter's particles, which carry no entropy estimate).
    #[staticmethod]
    fn from_particles(
        particles: PyReadonlyArray2<'_, f64>,
        log_weights: numpy::PyReadonlyArray1<'_, f64>,
        entropy_nats: f64,
    ) -> PyResult<Self> {
        guard("ParticleBelief.from_particles", || {
            let shape = particles.shape();
            if shape[1] != 3 {
                return Err(shape_err(format!(
                    "particles must have shape (n, 3), got {shape:?}"
                )));
            }
            let p = particles
                .as_slice()
                .map_err(|_| shape_err("particles must be a contiguous float64 array"))?;
            let lw = log_weights
                .as_slice()
                .map_err(|_| shape_err("log_weights must be a contiguous float64 array"))?;
            if lw.len() != shape[0] || shape[0] == 0 {
                return Err(shape_err(format!(
                    "{} particles and {} log-weights",
                    shape[0],
                    lw.len()
                )));
            }
            if !entropy_nats.is_finite() || p.iter().chain(lw).any(|v| v.is_nan()) {
                return Err(shape_err(
                    "particles, log-weights and entropy must not be NaN",
                ));
            }
            let w = crlam_core::resample::normalize_log_weights(lw);
            Ok(Self {
                inner: ucrmi::ParticleBelief {
                    particles: p.chunks(3).map(|c| [c[0], c[1], c[2]]).collect(),
                    log_weights: w.iter().map(|x| x.ln()).collect(),
                    entropy_nats,
                    map_gain_bits: 0.0,
                    pose_gain_bits: 0.0,
                    resampled: false,
                },
            })
        })
    }

    /// (n, 3) particle poses.
    #[getter]
    fn particles<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let n = self.inner.particles.len();
        let flat: Vec<f64> = self.inner.particles.iter().flatten().copied().collect();
        let a = Array2::from_shape_vec((n, 3), flat).map_err(|e| shape_err(e.to_string()))?;
        Ok(a.into_pyarray(py))
    }

    #[getter]
    fn weights<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.inner.weights().into_pyarray(py)
    }

    #[getter]
    fn entropy_nats(&self) -> f64 {
        self.inner.entropy_nats
    }

    #[getter]
    fn map_gain_bits(&self) -> f64 {
        self.inner.map_gain_bits
    }

    #[getter]
    fn pose_gain_bits(&self) -> f64 {
        self.inner.pose_gain_bits
    }

    #[getter]
    fn resampled(&self) -> bool {
        self.inner.resampled
    }

    fn mean_pose(&self) -> (f64, f64, f64) {
        let m = self.inner.mean_pose();
        (m[0], m[1], m[2])
    }

    /// Weighted 2×2 position covariance (m²).
    fn position_covariance(&self) -> PyResult<[[f64; 2]; 2]> {
        guard("ParticleBelief.position_covariance", || {
            weighted_position_covariance(&self.inner.particles, &self.inner.weights()).py_err()
        })
    }
}

/// The map update a candidate's virtual scan would make (opaque; pass it to `commit`).
#[pyclass(module = "crlam._native", frozen)]
pub struct InfoUpdate {
    pub(crate) inner: UpdateKind,
}

#[derive(Clone)]
pub(crate) enum UpdateKind {
    Scan(VirtualScan),
    Nodes(Vec<(usize, f64)>),
}

#[pymethods]
impl InfoUpdate {
    /// "virtual_scan" (CRM functions) or "nodes" (lattice / GP functions).
    #[getter]
    fn kind(&self) -> &'static str {
        match self.inner {
            UpdateKind::Scan(_) => "virtual_scan",
            UpdateKind::Nodes(_) => "nodes",
        }
    }

    /// Ranges (m) of a virtual scan, or the number of changed nodes.
    fn summary(&self) -> (usize, Vec<f64>) {
        match &self.inner {
            UpdateKind::Scan(s) => (s.ranges.len(), s.ranges.clone()),
            UpdateKind::Nodes(v) => (v.len(), Vec::new()),
        }
    }
}
