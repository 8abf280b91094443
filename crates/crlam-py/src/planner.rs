//! `run_iig`: the IIG planner over any information function (GIL released for the run), and
//! `geodesic`: grid shortest-path distances for the exploration loop.

use crlam_core::info::posecov::PoseJacobian;
use crlam_core::planner::{
    geodesic as core_geodesic, run_iig as core_run_iig, CollisionMode, IigResult, IigSettings,
    InfoAccumulation, MapMutation, NearestMode, PlannerWorld, SteerMode,
};
use numpy::ndarray::{Array1, Array2, Array3};
use numpy::{IntoPyArray, PyArray1, PyArray2, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use crate::convert::{guard, shape_err, IntoPy};
use crate::dispatch::{dispatch, GlueFunction, StateClass};
use crate::info::InfoFunction;
use crate::info_state::OccupancyLattice;

/// Settings from a `mode` preset ("reference" | "clean") and overrides in `options`.
fn settings_from(mode: &str, options: Option<&Bound<'_, PyDict>>) -> PyResult<IigSettings> {
    let mut s = match mode {
        "reference" => IigSettings::reference(),
        "clean" => IigSettings::clean(),
        other => {
            return Err(shape_err(format!(
                "mode must be reference or clean, got {other:?}"
            )))
        }
    };
    let Some(opts) = options else {
        s.validate().py_err()?;
        return Ok(s);
    };
    for (k, v) in opts.iter() {
        let key: String = k.extract()?;
        match key.as_str() {
            "start" => {
                let (x, y): (f64, f64) = v.extract()?;
                s.start = [x, y];
            }
            "budget" => s.budget = v.extract()?,
            "delta_ric" => s.delta_ric = v.extract()?,
            "ric_window" => s.ric_window = v.extract()?,
            "r_near" => s.r_near = v.extract()?,
            "clearance" => s.clearance = v.extract()?,
            "sample_threshold" => s.sample_threshold = v.extract()?,
            "max_iterations" => s.max_iterations = v.extract()?,
            "max_wall_seconds" => s.max_wall_seconds = v.extract()?,
            "steer" => s.steer = SteerMode::parse(&v.extract::<String>()?).py_err()?,
            "collision" => s.collision = CollisionMode::parse(&v.extract::<String>()?).py_err()?,
            "accumulation" => {
                s.accumulation = InfoAccumulation::parse(&v.extract::<String>()?).py_err()?
            }
            "mutation" => s.mutation = MapMutation::parse(&v.extract::<String>()?).py_err()?,
            "nearest" => s.nearest = NearestMode::parse(&v.extract::<String>()?).py_err()?,
            "jacobian" => s.jacobian = PoseJacobian::parse(&v.extract::<String>()?).py_err()?,
            other => return Err(shape_err(format!("unknown planner setting {other:?}"))),
        }
    }
    s.validate().py_err()?;
    Ok(s)
}

/// The resolved settings as a dict (for result folders).
fn settings_dict<'py>(py: Python<'py>, s: &IigSettings) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("start", (s.start[0], s.start[1]))?;
    d.set_item("budget", s.budget)?;
    d.set_item("delta_ric", s.delta_ric)?;
    d.set_item("ric_window", s.ric_window)?;
    d.set_item("r_near", s.r_near)?;
    d.set_item("clearance", s.clearance)?;
    d.set_item("sample_threshold", s.sample_threshold)?;
    d.set_item("max_iterations", s.max_iterations)?;
    d.set_item("max_wall_seconds", s.max_wall_seconds)?;
    d.set_item("steer", s.steer.name())?;
    d.set_item("collision", s.collision.name())?;
    d.set_item("accumulation", s.accumulation.name())?;
    d.set_item("mutation", s.mutation.name())?;
    d.set_item("nearest", s.nearest.name())?;
    d.set_item("jacobian", s.jacobian.name())?;
    Ok(d)
}

/// The planner's tree and logs as numpy arrays and lists.
fn result_dict<'py, B>(
    py: Python<'py>,
    r: &IigResult<B>,
    belief_cov: impl Fn(&B) -> Option<[[f64; 2]; 2]>,
) -> PyResult<Bound<'py, PyDict>> {
    let n = r.nodes.len();
    let d = PyDict::new(py);
    let pos: Vec<f64> = r.nodes.iter().flat_map(|u| u.position).collect();
    d.set_item(
        "positions",
        Array2::from_shape_vec((n, 2), pos)
            .map_err(|e| shape_err(e.to_string()))?
            .into_pyarray(py),
    )?;
    let parents: Vec<i64> = r
        .nodes
        .iter()
        .map(|u| u.parent.map_or(-1, |p| p as i64))
        .collect();
    d.set_item("parents", Array1::from(parents).into_pyarray(py))?;
    let col = |f: &dyn Fn(usize) -> f64| Array1::from_iter((0..n).map(f)).into_pyarray(py);
    d.set_item("costs", col(&|i| r.nodes[i].cost))?;
    d.set_item("infos", col(&|i| r.nodes[i].info))?;
    d.set_item("gains", col(&|i| r.nodes[i].gain))?;
    d.set_item("closed", col(&|i| f64::from(u8::from(r.nodes[i].closed))))?;
    d.set_item("node_iterations", col(&|i| r.nodes[i].iteration as f64))?;
    let cov: Vec<f64> = r
        .nodes
        .iter()
        .flat_map(|u| u.covariance.iter().flatten().copied().collect::<Vec<_>>())
        .collect();
    d.set_item(
        "covariances",
        Array3::from_shape_vec((n, 3, 3), cov)
            .map_err(|e| shape_err(e.to_string()))?
            .into_pyarray(py),
    )?;
    let bcov: Vec<f64> = r
        .nodes
        .iter()
        .flat_map(|u| {
            belief_cov(&u.belief).map_or([f64::NAN; 4], |c| [c[0][0], c[0][1], c[1][0], c[1][1]])
        })
        .collect();
    d.set_item(
        "belief_covariances",
        Array3::from_shape_vec((n, 2, 2), bcov)
            .map_err(|e| shape_err(e.to_string()))?
            .into_pyarray(py),
    )?;
    d.set_item("root_gain", r.root_gain)?;
    d.set_item("ric", Array1::from(r.ric.clone()).into_pyarray(py))?;
    d.set_item("cum_ric", Array1::from(r.cum_ric.clone()).into_pyarray(py))?;
    d.set_item(
        "iteration_gain",
        Array1::from(r.iteration_gain.clone()).into_pyarray(py),
    )?;
    d.set_item("iterations", r.iterations)?;
    d.set_item("evaluations", r.evaluations)?;
    d.set_item("ric_skipped", r.ric_skipped)?;
    d.set_item("stop", r.stop.name())?;
    d.set_item("seconds", r.seconds)?;
    d.set_item("main_paths", PyList::new(py, r.main_paths.iter().cloned())?)?;
    d.set_item("max_info_path", r.max_info_path.clone())?;
    d.set_item("total_cost", r.total_cost)?;
    d.set_item("total_info", r.total_info)?;
    d.set_item("max_info_path_length", r.max_info_path_length)?;
    d.set_item("max_info_path_info", r.max_info_path_info)?;
    Ok(d)
}

/// One planner run through the function's glue: the root belief is the given one, else the
/// function's root at the start (the root covariance of the settings for UGPVR).
#[allow(clippy::too_many_arguments)]
fn plan_with<'py, F: GlueFunction, S: StateClass<Core = F::Map>>(
    py: Python<'py>,
    f: &F,
    state: &Bound<'py, PyAny>,
    world: &PlannerWorld,
    settings: &IigSettings,
    start: [f64; 3],
    seed: u64,
    belief: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyDict>>
where
    F::Belief: Send,
    F::Map: Send,
{
    let root = f.parent_belief(belief, start, seed)?;
    let mut guard = state.downcast::<S>()?.borrow_mut();
    let map = guard.state_mut();
    let r = py
        .allow_threads(|| core_run_iig(f, map, root, world, settings, seed))
        .py_err()?;
    result_dict(py, &r, F::belief_covariance)
}

/// Runs IIG with `function` on `state` (mutated, as the planner's map mutation), over the prior
/// `lattice` (SampleFree) and `obstacle_points` (n, 2) (NoCollision). `mode` picks the preset,
/// `options` overrides single settings. Returns a dict with the tree, the logs and the settings.
#[pyfunction]
#[pyo3(signature = (function, state, lattice, obstacle_points, *, mode="reference", options=None, seed=0, belief=None))]
pub fn run_iig<'py>(
    py: Python<'py>,
    function: &InfoFunction,
    state: &Bound<'py, PyAny>,
    lattice: &OccupancyLattice,
    obstacle_points: PyReadonlyArray2<'py, f64>,
    mode: &str,
    options: Option<&Bound<'py, PyDict>>,
    seed: u64,
    belief: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    guard("run_iig", || {
        let settings = settings_from(mode, options)?;
        if obstacle_points.shape()[1] != 2 {
            return Err(shape_err(format!(
                "obstacle_points must have shape (n, 2), got {:?}",
                obstacle_points.shape()
            )));
        }
        let pts: Vec<[f64; 2]> = obstacle_points
            .as_slice()
            .map_err(|_| shape_err("obstacle_points must be a contiguous float64 array"))?
            .chunks(2)
            .map(|c| [c[0], c[1]])
            .collect();
        let world = PlannerWorld::new(lattice.inner.clone(), pts).py_err()?;
        let start = [settings.start[0], settings.start[1], 0.0];
        let d = dispatch!(&function.f, |f, S| plan_with::<_, S>(
            py, f, state, &world, &settings, start, seed, belief
        ))?;
        d.set_item("settings", settings_dict(py, &settings)?)?;
        d.set_item("mode", mode)?;
        d.set_item("function", function.f_name())?;
        d.set_item("units", function.f_units())?;
        Ok(d)
    })
}

/// A 2-D traversability mask: bool, or uint8 with nonzero = traversable.
#[derive(FromPyObject)]
pub enum Mask<'py> {
    Bool(PyReadonlyArray2<'py, bool>),
    U8(PyReadonlyArray2<'py, u8>),
}

/// 8-connected shortest-path distances (m) over the traversable cells of a 2-D mask (ny, nx)
/// from `start` = (iy, ix), with cell size `res` (m); diagonal moves need both side cells
/// traversable. Returns (dist (ny, nx), +inf where unreached; pred (ny·nx,), the flat index of
/// each cell's predecessor, -1 for none).
#[pyfunction]
pub fn geodesic<'py>(
    py: Python<'py>,
    traversable: Mask<'py>,
    start: (i64, i64),
    res: f64,
) -> PyResult<(Bound<'py, PyArray2<f64>>, Bound<'py, PyArray1<i64>>)> {
    guard("geodesic", || {
        let not_contiguous = || shape_err("traversable must be a C-contiguous 2-D array");
        let (shape, mask): (Vec<usize>, Vec<bool>) = match &traversable {
            Mask::Bool(a) => (
                a.shape().to_vec(),
                a.as_slice().map_err(|_| not_contiguous())?.to_vec(),
            ),
            Mask::U8(a) => (
                a.shape().to_vec(),
                a.as_slice()
                    .map_err(|_| not_contiguous())?
                    .iter()
                    .map(|&v| v != 0)
                    .collect(),
            ),
        };
        let (ny, nx) = (shape[0], shape[1]);
        let g = py
            .allow_threads(|| core_geodesic(&mask, ny, nx, start, res))
            .py_err()?;
        let dist =
            Array2::from_shape_vec((ny, nx), g.dist).map_err(|e| shape_err(e.to_string()))?;
        Ok((dist.into_pyarray(py), Array1::from(g.pred).into_pyarray(py)))
    })
}
