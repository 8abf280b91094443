//! What the glue needs of each information function, so that `InfoFunction` and `run_iig` are
//! written once: how its map state is read from the Python object, how the parent's pose belief
//! comes in and goes out, and how its map update is wrapped.

use crlam_core::crm;
use crlam_core::info::crmi::{Crmi, VirtualScan};
use crlam_core::info::crmi_authors::{MlScanBinary, R1Map};
use crlam_core::info::entropy::weighted_position_covariance;
use crlam_core::info::fsmi::Fsmi;
use crlam_core::info::gp::{GpVarianceMap as CoreGpMap, Gpvr, Ugpvr};
use crlam_core::info::iig_mi::IigMi;
use crlam_core::info::lattice;
use crlam_core::info::posecov::{root_covariance, Cov3};
use crlam_core::info::ucrmi::{self, Ucrmi};
use crlam_core::info::{self as core_info, Candidate, InformationFunction};
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::PyClass;

use crate::convert::{shape_err, IntoPy};
use crate::info_state::{GpVarianceMap, OccupancyLattice, ParticleBelief, UpdateKind};
use crate::maps::CrmMap;

/// Every core information function the glue serves, by kind: what `InfoFunction` holds and
/// what [`dispatch!`] matches on.
pub(crate) enum Func {
    Crmi(Crmi),
    CrmiMl(MlScanBinary),
    CrmiR1(R1Map),
    Ucrmi(Ucrmi),
    Fsmi(Fsmi),
    IigMi(IigMi),
    Gpvr(Gpvr),
    Ugpvr(Ugpvr),
}

/// A Python class holding a core map state.
pub(crate) trait StateClass: PyClass<Frozen = pyo3::pyclass::boolean_struct::False> {
    type Core: Sync;
    fn state(&self) -> &Self::Core;
    fn state_mut(&mut self) -> &mut Self::Core;
}

impl StateClass for CrmMap {
    type Core = crm::CrmMap;
    fn state(&self) -> &crm::CrmMap {
        self.core()
    }
    fn state_mut(&mut self) -> &mut crm::CrmMap {
        self.core_mut()
    }
}

impl StateClass for OccupancyLattice {
    type Core = lattice::OccupancyLattice;
    fn state(&self) -> &lattice::OccupancyLattice {
        &self.inner
    }
    fn state_mut(&mut self) -> &mut lattice::OccupancyLattice {
        &mut self.inner
    }
}

impl StateClass for GpVarianceMap {
    type Core = CoreGpMap;
    fn state(&self) -> &CoreGpMap {
        &self.inner
    }
    fn state_mut(&mut self) -> &mut CoreGpMap {
        &mut self.inner
    }
}

/// The Python side of a function's pose belief and map update.
pub(crate) trait GlueFunction: InformationFunction + Sized {
    /// The parent belief from the Python argument; `None` gives the root at `pose` (seeded).
    fn parent_belief(
        &self,
        belief: Option<&Bound<'_, PyAny>>,
        pose: [f64; 3],
        seed: u64,
    ) -> PyResult<Self::Belief>;
    /// The candidate's belief as a Python object (None for map-only functions).
    fn belief_to_py(py: Python<'_>, belief: Self::Belief) -> PyResult<PyObject>;
    /// The 2×2 position covariance of a belief, for the planner's ellipses.
    fn belief_covariance(belief: &Self::Belief) -> Option<[[f64; 2]; 2]>;
    fn wrap_update(update: Self::Update) -> UpdateKind;
    fn unwrap_update(update: &UpdateKind) -> Option<&Self::Update>;
    /// Gains of candidates on one state in parallel; with no parent belief a pose-aware function
    /// starts every candidate from its own root.
    fn batch_gains(
        &self,
        map: &Self::Map,
        belief: Option<&Bound<'_, PyAny>>,
        candidates: &[Candidate],
        seed: u64,
        py: Python<'_>,
    ) -> PyResult<Vec<f64>> {
        let pose = candidates.first().map_or([0.0; 3], |c| c.pose);
        let parent = self.parent_belief(belief, pose, 0)?;
        py.allow_threads(|| core_info::gain_batch(self, map, &parent, candidates, seed))
            .py_err()
    }
}

/// Map-only functions on a CRM (their updates are virtual scans).
macro_rules! crm_map_only {
    ($($t:ty),+) => {$(
        impl GlueFunction for $t {
            fn parent_belief(&self, _: Option<&Bound<'_, PyAny>>, _: [f64; 3], _: u64) -> PyResult<()> {
                Ok(())
            }
            fn belief_to_py(py: Python<'_>, _: ()) -> PyResult<PyObject> {
                Ok(py.None())
            }
            fn belief_covariance(_: &()) -> Option<[[f64; 2]; 2]> {
                None
            }
            fn wrap_update(update: VirtualScan) -> UpdateKind {
                UpdateKind::Scan(update)
            }
            fn unwrap_update(update: &UpdateKind) -> Option<&VirtualScan> {
                match update {
                    UpdateKind::Scan(s) => Some(s),
                    UpdateKind::Nodes(_) => None,
                }
            }
        }
    )+};
}

/// Map-only functions on a lattice or GP map (their updates are node values).
macro_rules! node_map_only {
    ($($t:ty),+) => {$(
        impl GlueFunction for $t {
            fn parent_belief(&self, _: Option<&Bound<'_, PyAny>>, _: [f64; 3], _: u64) -> PyResult<()> {
                Ok(())
            }
            fn belief_to_py(py: Python<'_>, _: ()) -> PyResult<PyObject> {
                Ok(py.None())
            }
            fn belief_covariance(_: &()) -> Option<[[f64; 2]; 2]> {
                None
            }
            fn wrap_update(update: Vec<(usize, f64)>) -> UpdateKind {
                UpdateKind::Nodes(update)
            }
            fn unwrap_update(update: &UpdateKind) -> Option<&Vec<(usize, f64)>> {
                match update {
                    UpdateKind::Nodes(v) => Some(v),
                    UpdateKind::Scan(_) => None,
                }
            }
        }
    )+};
}

crm_map_only!(Crmi, MlScanBinary, R1Map);
node_map_only!(Fsmi, IigMi, Gpvr);

impl GlueFunction for Ucrmi {
    fn parent_belief(
        &self,
        belief: Option<&Bound<'_, PyAny>>,
        pose: [f64; 3],
        seed: u64,
    ) -> PyResult<ucrmi::ParticleBelief> {
        match belief {
            Some(b) if !b.is_none() => Ok(b.downcast::<ParticleBelief>()?.get().inner.clone()),
            _ => self.root_belief(pose, seed).py_err(),
        }
    }
    fn belief_to_py(py: Python<'_>, belief: ucrmi::ParticleBelief) -> PyResult<PyObject> {
        Ok(ParticleBelief { inner: belief }
            .into_pyobject(py)?
            .into_any()
            .unbind())
    }
    fn belief_covariance(b: &ucrmi::ParticleBelief) -> Option<[[f64; 2]; 2]> {
        weighted_position_covariance(&b.particles, &b.weights()).ok()
    }
    fn wrap_update(update: VirtualScan) -> UpdateKind {
        UpdateKind::Scan(update)
    }
    fn unwrap_update(update: &UpdateKind) -> Option<&VirtualScan> {
        match update {
            UpdateKind::Scan(s) => Some(s),
            UpdateKind::Nodes(_) => None,
        }
    }
    fn batch_gains(
        &self,
        map: &crm::CrmMap,
        belief: Option<&Bound<'_, PyAny>>,
        candidates: &[Candidate],
        seed: u64,
        py: Python<'_>,
    ) -> PyResult<Vec<f64>> {
        match belief {
            Some(b) if !b.is_none() => {
                let parent = b.downcast::<ParticleBelief>()?.get().inner.clone();
                py.allow_threads(|| core_info::gain_batch(self, map, &parent, candidates, seed))
                    .py_err()
            }
            // No parent: every candidate starts from its own root belief (a surface).
            _ => py
                .allow_threads(|| self.gains_from_roots(map, candidates, seed))
                .py_err(),
        }
    }
}

impl GlueFunction for Ugpvr {
    fn parent_belief(
        &self,
        belief: Option<&Bound<'_, PyAny>>,
        _: [f64; 3],
        _: u64,
    ) -> PyResult<Cov3> {
        let Some(b) = belief.filter(|b| !b.is_none()) else {
            return Ok(root_covariance());
        };
        let a: PyReadonlyArray2<'_, f64> = b.extract()?;
        if a.shape() != [3, 3] {
            return Err(shape_err(format!(
                "covariance must be 3x3, got {:?}",
                a.shape()
            )));
        }
        let s = a
            .as_slice()
            .map_err(|_| shape_err("covariance must be a contiguous float64 array"))?;
        Ok([[s[0], s[1], s[2]], [s[3], s[4], s[5]], [s[6], s[7], s[8]]])
    }
    fn belief_to_py(py: Python<'_>, c: Cov3) -> PyResult<PyObject> {
        Ok(covariance_array(py, &c)?.into_any().unbind())
    }
    fn belief_covariance(c: &Cov3) -> Option<[[f64; 2]; 2]> {
        Some([[c[0][0], c[0][1]], [c[1][0], c[1][1]]])
    }
    fn wrap_update(update: Vec<(usize, f64)>) -> UpdateKind {
        UpdateKind::Nodes(update)
    }
    fn unwrap_update(update: &UpdateKind) -> Option<&Vec<(usize, f64)>> {
        match update {
            UpdateKind::Nodes(v) => Some(v),
            UpdateKind::Scan(_) => None,
        }
    }
}

/// A 3×3 covariance as a numpy array.
pub(crate) fn covariance_array<'py>(
    py: Python<'py>,
    c: &Cov3,
) -> PyResult<Bound<'py, numpy::PyArray2<f64>>> {
    let flat: Vec<f64> = c.iter().flatten().copied().collect();
    Ok(Array2::from_shape_vec((3, 3), flat)
        .map_err(|e| shape_err(e.to_string()))?
        .into_pyarray(py))
}

/// Runs `$body` with `$f` bound to the function and `$S` to its state class, for whichever
/// function `$func` holds.
macro_rules! dispatch {
    ($func:expr, |$f:ident, $S:ident| $body:expr) => {{
        use crate::dispatch::Func;
        match $func {
            Func::Crmi($f) => {
                #[allow(dead_code)]
                type $S = crate::maps::CrmMap;
                $body
            }
            Func::CrmiMl($f) => {
                #[allow(dead_code)]
                type $S = crate::maps::CrmMap;
                $body
            }
            Func::CrmiR1($f) => {
                #[allow(dead_code)]
                type $S = crate::maps::CrmMap;
                $body
            }
            Func::Ucrmi($f) => {
                #[allow(dead_code)]
                type $S = crate::maps::CrmMap;
                $body
            }
            Func::Fsmi($f) => {
                #[allow(dead_code)]
                type $S = crate::info_state::OccupancyLattice;
                $body
            }
            Func::IigMi($f) => {
                #[allow(dead_code)]
                type $S = crate::info_state::OccupancyLattice;
                $body
            }
            Func::Gpvr($f) => {
                #[allow(dead_code)]
                type $S = crate::info_state::GpVarianceMap;
                $body
            }
            Func::Ugpvr($f) => {
                #[allow(dead_code)]
                type $S = crate::info_state::GpVarianceMap;
                $body
            }
        }
    }};
}
pub(crate) use dispatch;
