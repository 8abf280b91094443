//! Python functions on single rays: traversal, casting against a world raster, one CRM update.

use crlam_core::crm;
use crlam_core::grid::GridGeometry;
use crlam_core::raycast;
use crlam_core::sim::WorldRaster;
use numpy::ndarray::{Array1, Array2};
use numpy::{
    IntoPyArray, PyArray1, PyArray2, PyReadonlyArray1, PyReadonlyArray2, PyUntypedArrayMethods,
};
use pyo3::prelude::*;

use crate::convert::{guard, poses_n3, shape_err, slice1, IntoPy};

/// Cells crossed by a ray: (cells (n, 2) int64 [ix, iy], t_in (n,), t_out (n,)).
#[pyfunction]
#[pyo3(signature = (origin_x, origin_y, angle, length, resolution, grid_origin=(0.0, 0.0)))]
#[allow(clippy::type_complexity)]
pub fn traverse_ray<'py>(
    py: Python<'py>,
    origin_x: f64,
    origin_y: f64,
    angle: f64,
    length: f64,
    resolution: f64,
    grid_origin: (f64, f64),
) -> PyResult<(
    Bound<'py, PyArray2<i64>>,
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray1<f64>>,
)> {
    guard("traverse_ray", || {
        let g = GridGeometry::new([grid_origin.0, grid_origin.1], resolution).py_err()?;
        if ![origin_x, origin_y, angle, length]
            .iter()
            .all(|v| v.is_finite())
            || length > 1e6
        {
            return Err(shape_err(
                "origin, angle and length must be finite (length <= 1e6 m)",
            ));
        }
        // A ray crosses at most 2 (length / resolution) + 2 cells.
        crlam_core::limits::check_map_cells(
            &format!("a ray of {length} m on {resolution} m cells"),
            2.0 * length / resolution + 2.0,
        )
        .py_err()?;
        let mut cells = Vec::new();
        raycast::traverse(&g, [origin_x, origin_y], angle, length, None, &mut cells);
        let idx: Vec<i64> = cells.iter().flat_map(|c| [c.ix, c.iy]).collect();
        let idx =
            Array2::from_shape_vec((cells.len(), 2), idx).map_err(|e| shape_err(e.to_string()))?;
        let t_in = Array1::from_iter(cells.iter().map(|c| c.t_in));
        let t_out = Array1::from_iter(cells.iter().map(|c| c.t_out));
        Ok((
            idx.into_pyarray(py),
            t_in.into_pyarray(py),
            t_out.into_pyarray(py),
        ))
    })
}

/// Exact ranges to the first occupied cell of a world raster (n poses x m beams); inf when
/// nothing lies within max_range.
#[pyfunction]
#[allow(clippy::too_many_arguments)]
pub fn cast_ranges<'py>(
    py: Python<'py>,
    occupied: PyReadonlyArray2<'py, u8>,
    origin_x: f64,
    origin_y: f64,
    resolution: f64,
    poses: PyReadonlyArray2<'py, f64>,
    angles: PyReadonlyArray1<'py, f64>,
    max_range: f64,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    guard("cast_ranges", || {
        let g = GridGeometry::new([origin_x, origin_y], resolution).py_err()?;
        let shape = occupied.shape();
        let occ = occupied
            .as_slice()
            .map_err(|_| shape_err("occupied must be a contiguous uint8 array"))?;
        let world = WorldRaster::new(g, shape[1], shape[0], occ).py_err()?;
        let poses = poses_n3(&poses)?;
        let a = slice1(&angles, "angles")?;
        let mut out = crlam_core::limits::try_filled(
            poses.len().saturating_mul(a.len()),
            0.0,
            "cast_ranges output",
        )
        .py_err()?;
        py.allow_threads(|| world.cast(&poses, a, max_range, &mut out))
            .py_err()?;
        let arr = Array2::from_shape_vec((poses.len(), a.len()), out)
            .map_err(|e| shape_err(e.to_string()))?;
        Ok(arr.into_pyarray(py))
    })
}

/// One CRM beam update on explicit beliefs (N, K) and cause likelihoods (crm-spec 3.1); returns
/// (updated beliefs, η). For tests and for users with their own likelihoods.
#[pyfunction]
#[pyo3(signature = (beliefs, levels, like, like_inf, belief_floor=0.0))]
pub fn crm_update_ray<'py>(
    py: Python<'py>,
    beliefs: PyReadonlyArray2<'py, f64>,
    levels: PyReadonlyArray1<'py, f64>,
    like: PyReadonlyArray1<'py, f64>,
    like_inf: f64,
    belief_floor: f64,
) -> PyResult<(Bound<'py, PyArray2<f64>>, f64)> {
    guard("crm_update_ray", || {
        let mu = slice1(&levels, "levels")?;
        let l = slice1(&like, "like")?;
        let s = beliefs.shape();
        if s[1] != mu.len() || s[0] != l.len() || mu.len() > 64 {
            return Err(shape_err(format!(
            "beliefs must be (N, K) with N = len(like) = {} and K = len(levels) = {} <= 64, got {s:?}",
            l.len(),
            mu.len()
        )));
        }
        if l.iter()
            .chain(std::iter::once(&like_inf))
            .any(|x| !(x.is_finite() && *x >= 0.0))
        {
            return Err(shape_err("likelihoods must be finite and >= 0"));
        }
        let mut b = beliefs
            .as_slice()
            .map_err(|_| shape_err("beliefs must be contiguous"))?
            .to_vec();
        let eta = crm::update::update_ray(&mut b, mu, l, like_inf, belief_floor);
        let arr = Array2::from_shape_vec((s[0], s[1]), b).map_err(|e| shape_err(e.to_string()))?;
        Ok((arr.into_pyarray(py), eta))
    })
}
