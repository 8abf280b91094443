//! Thin PyO3 glue: `crlam._native`. Conversions, error mapping and GIL release only; all
//! computation lives in `crlam-core`.

// PyO3 signatures mirror the Python API, argument for argument.
#![allow(clippy::too_many_arguments, clippy::type_complexity)]

mod bench;
mod convert;
mod dispatch;
mod filters;
mod info;
mod info_state;
mod local_matcher;
mod localize;
mod maps;
mod planner;
mod rays;

use pyo3::prelude::*;

use crate::convert::guard;

/// Sets the core's resource limits (each left unchanged when None); returns the limits in force
/// as (map_cells, particles).
#[pyfunction]
#[pyo3(signature = (*, map_cells=None, particles=None))]
fn set_limits(map_cells: Option<u64>, particles: Option<u64>) -> PyResult<(u64, u64)> {
    guard("set_limits", || {
        use crlam_core::limits;
        for (name, v) in [("map_cells", map_cells), ("particles", particles)] {
            if v == Some(0) {
                return Err(convert::shape_err(format!("limit {name} must be >= 1")));
            }
        }
        if let Some(n) = map_cells {
            limits::set_max_map_cells(n);
        }
        if let Some(n) = particles {
            limits::set_max_particles(n);
        }
        Ok((limits::max_map_cells(), limits::max_particles()))
    })
}

/// Panics inside the panic guard every Python-facing function runs in: the test suite checks with
/// it that a panic reaches Python as `crlam.errors.InternalError` (a `CrlamError`), never as
/// PyO3's `PanicException`.
#[pyfunction]
fn _guarded_panic(message: &str) -> PyResult<()> {
    guard("_guarded_panic", || panic!("{message}"))
}

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__core_version__", env!("CARGO_PKG_VERSION"))?;
    m.add_class::<maps::SensorModel>()?;
    m.add_class::<maps::CrmMap>()?;
    m.add_class::<maps::LogOddsMap>()?;
    m.add_class::<filters::ClamFilter>()?;
    m.add_class::<filters::OgmFilter>()?;
    m.add_class::<local_matcher::LocalMapMatcher>()?;
    m.add_class::<localize::MclFilter>()?;
    m.add_class::<info_state::OccupancyLattice>()?;
    m.add_class::<info_state::GpVarianceMap>()?;
    m.add_class::<info_state::ParticleBelief>()?;
    m.add_class::<info_state::InfoUpdate>()?;
    m.add_class::<info::InfoFunction>()?;
    m.add_function(wrap_pyfunction!(filters::mode_seeking_pose, m)?)?;
    m.add_function(wrap_pyfunction!(local_matcher::loop_match, m)?)?;
    m.add_function(wrap_pyfunction!(info::candidate_seed, m)?)?;
    m.add_function(wrap_pyfunction!(planner::run_iig, m)?)?;
    m.add_function(wrap_pyfunction!(planner::geodesic, m)?)?;
    m.add_function(wrap_pyfunction!(rays::traverse_ray, m)?)?;
    m.add_function(wrap_pyfunction!(rays::cast_ranges, m)?)?;
    m.add_function(wrap_pyfunction!(rays::crm_update_ray, m)?)?;
    m.add_function(wrap_pyfunction!(bench::run_benchmark, m)?)?;
    m.add_function(wrap_pyfunction!(bench::simd_level, m)?)?;
    m.add_function(wrap_pyfunction!(bench::simd_info, m)?)?;
    m.add_function(wrap_pyfunction!(set_limits, m)?)?;
    m.add_function(wrap_pyfunction!(_guarded_panic, m)?)?;
    Ok(())
}
