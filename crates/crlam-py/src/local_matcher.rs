//! Python class of one scan matcher on one GMapping-style grid (`crlam.slam.scan_odometry`).

use crlam_core::rbpf::{
    match_against_points, CorrelativeSettings, LocalMapMatcher as CoreLocalMapMatcher,
    MatcherParams,
};
use numpy::{PyReadonlyArray1, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;

use crate::convert::{guard, pose3, shape_err, slice1, IntoPy};
use crate::maps::LogOddsMap;

/// One scan matcher on one GMapping-style grid: match a scan from a start pose, insert a scan
/// at a pose (the building block of `crlam.slam.scan_odometry`).
#[pyclass(module = "crlam._native")]
pub struct LocalMapMatcher {
    inner: CoreLocalMapMatcher,
}

#[pymethods]
impl LocalMapMatcher {
    #[new]
    #[pyo3(signature = (*, resolution=0.05, usable_range=8.0, score_sigma=0.05, lstep=0.05, astep=0.05, iterations=5, kernel_size=1, beam_stride=1))]
    fn new(
        resolution: f64,
        usable_range: f64,
        score_sigma: f64,
        lstep: f64,
        astep: f64,
        iterations: usize,
        kernel_size: usize,
        beam_stride: usize,
    ) -> PyResult<Self> {
        guard("LocalMapMatcher.new", || {
            let params = MatcherParams {
                score_sigma,
                lstep,
                astep,
                iterations,
                kernel_size,
                beam_stride,
                ..MatcherParams::default()
            };
            Ok(Self {
                inner: CoreLocalMapMatcher::new(resolution, usable_range, params).py_err()?,
            })
        })
    }

    /// Hill-climbs the scan from the robot pose `start`: (pose, score, matched beams, used beams).
    fn match_scan(
        &self,
        py: Python<'_>,
        start: PyReadonlyArray1<'_, f64>,
        angles: PyReadonlyArray1<'_, f64>,
        ranges: PyReadonlyArray1<'_, f64>,
        laser_offset: PyReadonlyArray1<'_, f64>,
    ) -> PyResult<((f64, f64, f64), f64, usize, usize)> {
        guard("LocalMapMatcher.match_scan", || {
            let (s, a, r, o) = (
                pose3(&start)?,
                slice1(&angles, "angles")?,
                slice1(&ranges, "ranges")?,
                pose3(&laser_offset)?,
            );
            let inner = &self.inner;
            let m = py.allow_threads(|| inner.match_scan(s, a, r, o)).py_err()?;
            Ok((
                (m.pose[0], m.pose[1], m.pose[2]),
                m.score,
                m.matched,
                m.used,
            ))
        })
    }

    /// Integrates the scan with the robot at `pose`.
    fn insert(
        &mut self,
        py: Python<'_>,
        pose: PyReadonlyArray1<'_, f64>,
        angles: PyReadonlyArray1<'_, f64>,
        ranges: PyReadonlyArray1<'_, f64>,
        laser_offset: PyReadonlyArray1<'_, f64>,
    ) -> PyResult<()> {
        guard("LocalMapMatcher.insert", || {
            let (p, a, r, o) = (
                pose3(&pose)?,
                slice1(&angles, "angles")?,
                slice1(&ranges, "ranges")?,
                pose3(&laser_offset)?,
            );
            let inner = &mut self.inner;
            py.allow_threads(|| inner.insert(p, a, r, o)).py_err()
        })
    }

    /// Forgets every inserted scan.
    fn clear(&mut self) {
        self.inner.clear();
    }

    /// Scans inserted since the last `clear`.
    #[getter]
    fn n_inserted(&self) -> usize {
        self.inner.n_inserted()
    }

    /// The grid (a copy-on-write copy; log-odds of the hit-rate cells).
    fn map(&self) -> LogOddsMap {
        LogOddsMap::from_core(self.inner.map().clone())
    }
}

/// An (n, 2) point array as a vector of points.
fn points_n2(a: &PyReadonlyArray2<'_, f64>, name: &str) -> PyResult<Vec<[f64; 2]>> {
    let shape = a.shape();
    if shape[1] != 2 {
        return Err(shape_err(format!(
            "{name} must have shape (n, 2), got {shape:?}"
        )));
    }
    let s = a
        .as_slice()
        .map_err(|_| shape_err(format!("{name} must be a contiguous float64 array")))?;
    Ok(s.chunks(2).map(|c| [c[0], c[1]]).collect())
}

/// The loop-closure search (`crlam_core::rbpf::loop_match`): the robot pose within
/// ±`linear_window` m and ±`angular_window` rad of `guess` at which `endpoints` (n, 2; robot
/// frame) fall best on the cells of `world_points` (m, 2; world frame) on a `resolution` grid.
/// With `exclude` ((x, y), radius; m), the best pose farther than the radius from (x, y).
/// Returns (pose, explained share, the share explained at the guess, lattice poses evaluated).
#[pyfunction]
#[pyo3(signature = (world_points, endpoints, guess, *, resolution, linear_window, angular_window, penalty=0.0, exclude=None))]
#[allow(clippy::too_many_arguments)]
pub fn loop_match(
    py: Python<'_>,
    world_points: PyReadonlyArray2<'_, f64>,
    endpoints: PyReadonlyArray2<'_, f64>,
    guess: PyReadonlyArray1<'_, f64>,
    resolution: f64,
    linear_window: f64,
    angular_window: f64,
    penalty: f64,
    exclude: Option<((f64, f64), f64)>,
) -> PyResult<((f64, f64, f64), f64, f64, usize)> {
    guard("loop_match", || {
        let pts = points_n2(&world_points, "world_points")?;
        let ends = points_n2(&endpoints, "endpoints")?;
        let g = pose3(&guess)?;
        let settings = CorrelativeSettings {
            linear_window,
            angular_window,
            penalty,
            min_score: 0.0,
            min_gain: 0.0,
        };
        let m = py
            .allow_threads(|| {
                match_against_points(
                    &pts,
                    resolution,
                    &ends,
                    g,
                    &settings,
                    exclude.map(|((x, y), r)| ([x, y], r)),
                )
            })
            .py_err()?;
        Ok((
            (m.pose[0], m.pose[1], m.pose[2]),
            m.explained,
            m.guess_score,
            m.evaluated,
        ))
    })
}
