//! The Python `InfoFunction` class: one class that dispatches to every core information
//! function, with evaluation, commit and parallel batches (GIL released).

use crlam_core::info::crmi::{CellDedupe, Crmi, CrmiConfig, CrmiQuadrature};
use crlam_core::info::crmi_authors::{AuthorsCrmiConfig, MlScanBinary, R1Map};
use crlam_core::info::entropy::EdgeMotionNoise;
use crlam_core::info::fsmi::{Fsmi, FsmiVariant, OgmiParams};
use crlam_core::info::gp::{Gpvr, GpvrOptions, Mode, Ugpvr, UgpvrOptions};
use crlam_core::info::iig_mi::IigMi;
use crlam_core::info::lattice::BeamAngles;
use crlam_core::info::ucrmi::{Ucrmi, UcrmiConfig};
use crlam_core::info::{self as core_info, Candidate, InfoUnits, InformationFunction};
use numpy::{IntoPyArray, PyArray1, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;

use crate::convert::{guard, pose3, poses_n3, shape_err, IntoPy};
use crate::dispatch::{dispatch, Func, GlueFunction, StateClass};
use crate::info_state::InfoUpdate;
use crate::maps::SensorModel;

/// One of the information functions (crm-spec 5–6, planner-spec 4–5).
#[pyclass(module = "crlam._native", frozen)]
pub struct InfoFunction {
    pub(crate) f: Func,
}

fn units_parse(name: &str) -> PyResult<InfoUnits> {
    match name {
        "bits" => Ok(InfoUnits::Bits),
        "nats" => Ok(InfoUnits::Nats),
        other => Err(shape_err(format!(
            "units must be bits or nats, got {other:?}"
        ))),
    }
}

fn candidate(pose: [f64; 3], parent: Option<(f64, f64)>) -> Candidate {
    match parent {
        Some((x, y)) => Candidate {
            pose,
            parent: [x, y],
        },
        None => Candidate::at(pose),
    }
}

impl InfoFunction {
    /// The function's name (for result dicts).
    pub(crate) fn f_name(&self) -> &'static str {
        self.name()
    }

    /// The function's units (for result dicts).
    pub(crate) fn f_units(&self) -> &'static str {
        self.units()
    }
}

#[pymethods]
impl InfoFunction {
    /// CRMI (bits). `variant` "exact" is the discrete channel of crm-spec 5.2 with `model` the
    /// mapping model; "ml_scan_binary" (5.4) and "r1_map" (5.3) are the authors' variants, which
    /// use the `authors_code` update at `resolution` (m) and ignore the channel settings.
    #[staticmethod]
    #[pyo3(signature = (model, *, n_beams=10, beam_angles="distinct", lambda_z=0.1, quadrature="cdf", dedupe_cells="sum", units="bits", hit_threshold=0.5, variant="exact", resolution=0.2))]
    fn crmi(
        model: &SensorModel,
        n_beams: usize,
        beam_angles: &str,
        lambda_z: f64,
        quadrature: &str,
        dedupe_cells: &str,
        units: &str,
        hit_threshold: f64,
        variant: &str,
        resolution: f64,
    ) -> PyResult<Self> {
        guard("InfoFunction.crmi", || {
            if variant != "exact" {
                let mut cfg = AuthorsCrmiConfig::new(model.inner.z_max, resolution);
                cfg.n_beams = n_beams;
                cfg.beam_angles = BeamAngles::parse(beam_angles).py_err()?;
                cfg.hit_threshold = hit_threshold;
                let f = match variant {
                    "ml_scan_binary" => Func::CrmiMl(MlScanBinary::new(cfg).py_err()?),
                    "r1_map" => Func::CrmiR1(R1Map::new(cfg).py_err()?),
                    other => {
                        return Err(shape_err(format!(
                            "variant must be exact, ml_scan_binary or r1_map, got {other:?}"
                        )))
                    }
                };
                return Ok(Self { f });
            }
            let cfg = crmi_config(
                model,
                n_beams,
                beam_angles,
                lambda_z,
                quadrature,
                dedupe_cells,
                units,
                hit_threshold,
            )?;
            Ok(Self {
                f: Func::Crmi(Crmi::new(cfg).py_err()?),
            })
        })
    }

    /// UCRMI at a node (crm-spec 6.4), in bits.
    #[staticmethod]
    #[pyo3(signature = (model, weight_model, *, alpha=0.5, n_particles=100, n_beams=10, beam_angles="distinct", lambda_z=0.1, quadrature="cdf", dedupe_cells="sum", hit_threshold=0.5, edge_noise=(0.01, 6.853891945200942e-6), root_cov_diag=(0.16, 0.01, 1e-6), resample_threshold=0.5))]
    fn ucrmi(
        model: &SensorModel,
        weight_model: &SensorModel,
        alpha: f64,
        n_particles: usize,
        n_beams: usize,
        beam_angles: &str,
        lambda_z: f64,
        quadrature: &str,
        dedupe_cells: &str,
        hit_threshold: f64,
        edge_noise: (f64, f64),
        root_cov_diag: (f64, f64, f64),
        resample_threshold: f64,
    ) -> PyResult<Self> {
        guard("InfoFunction.ucrmi", || {
            let crmi = crmi_config(
                model,
                n_beams,
                beam_angles,
                lambda_z,
                quadrature,
                dedupe_cells,
                "bits",
                hit_threshold,
            )?;
            let cfg = UcrmiConfig {
                crmi,
                alpha,
                n_particles,
                noise: EdgeMotionNoise {
                    q_xy: edge_noise.0,
                    q_theta: edge_noise.1,
                },
                root_cov_diag: [root_cov_diag.0, root_cov_diag.1, root_cov_diag.2],
                weight_model: weight_model.inner,
                resample_threshold,
            };
            Ok(Self {
                f: Func::Ucrmi(Ucrmi::new(cfg).py_err()?),
            })
        })
    }

    /// OGMI on an occupancy lattice: `variant` full | truncated | noise_free | julian (nats).
    #[staticmethod]
    #[pyo3(signature = (*, variant="full", width_sigmas=3.0, points_per_cell=16, delta_occ=1.5, delta_emp=1.0/1.5, sigma=0.05, z_max=5.0, n_beams=10, beam_angles="distinct", p_occ=0.65))]
    fn fsmi(
        variant: &str,
        width_sigmas: f64,
        points_per_cell: usize,
        delta_occ: f64,
        delta_emp: f64,
        sigma: f64,
        z_max: f64,
        n_beams: usize,
        beam_angles: &str,
        p_occ: f64,
    ) -> PyResult<Self> {
        guard("InfoFunction.fsmi", || {
            let variant = match variant {
                "full" => FsmiVariant::Full,
                "truncated" => FsmiVariant::Truncated { width_sigmas },
                "noise_free" => FsmiVariant::NoiseFree,
                "julian" => FsmiVariant::Julian { points_per_cell },
                other => {
                    return Err(shape_err(format!(
                        "variant must be full, truncated, noise_free or julian, got {other:?}"
                    )))
                }
            };
            let f = Fsmi {
                params: OgmiParams {
                    delta_occ,
                    delta_emp,
                    sigma,
                    z_max,
                },
                variant,
                n_beams,
                beam_angles: BeamAngles::parse(beam_angles).py_err()?,
                p_occ,
            };
            f.validate().py_err()?;
            Ok(Self { f: Func::Fsmi(f) })
        })
    }

    /// The IIG reference 'mi' heuristic (or 'miub' with `upper_bound`), nats.
    #[staticmethod]
    #[pyo3(signature = (*, upper_bound=false, n_beams=10, beam_angles="reference", z_max=5.0, p_occ=0.65, int_res=0.5))]
    fn iig_mi(
        upper_bound: bool,
        n_beams: usize,
        beam_angles: &str,
        z_max: f64,
        p_occ: f64,
        int_res: f64,
    ) -> PyResult<Self> {
        guard("InfoFunction.iig_mi", || {
            let f = IigMi {
                upper_bound,
                n_beams,
                beam_angles: BeamAngles::parse(beam_angles).py_err()?,
                z_max,
                p_occ,
                int_res,
            };
            f.validate().py_err()?;
            Ok(Self { f: Func::IigMi(f) })
        })
    }

    /// GPVR on a GP variance map (planner-spec 5.2), nats; `mode` reference | clean.
    #[staticmethod]
    #[pyo3(signature = (*, mode="reference"))]
    fn gpvr(mode: &str) -> PyResult<Self> {
        guard("InfoFunction.gpvr", || {
            let f = Gpvr::new(GpvrOptions::preset(Mode::parse(mode).py_err()?)).py_err()?;
            Ok(Self { f: Func::Gpvr(f) })
        })
    }

    /// UGPVR with the expected kernel (planner-spec 5.3), nats; `mode` reference | clean.
    #[staticmethod]
    #[pyo3(signature = (*, mode="reference"))]
    fn ugpvr(mode: &str) -> PyResult<Self> {
        guard("InfoFunction.ugpvr", || {
            let f = Ugpvr::new(UgpvrOptions::preset(Mode::parse(mode).py_err()?)).py_err()?;
            Ok(Self { f: Func::Ugpvr(f) })
        })
    }

    #[getter]
    fn name(&self) -> &'static str {
        dispatch!(&self.f, |f, S| f.name())
    }

    #[getter]
    fn units(&self) -> &'static str {
        dispatch!(&self.f, |f, S| f.units()).name()
    }

    /// "crm", "lattice" or "gp": the map state the function reads.
    #[getter]
    fn state_kind(&self) -> &'static str {
        match &self.f {
            Func::Crmi(_) | Func::CrmiMl(_) | Func::CrmiR1(_) | Func::Ucrmi(_) => "crm",
            Func::Fsmi(_) | Func::IigMi(_) => "lattice",
            Func::Gpvr(_) | Func::Ugpvr(_) => "gp",
        }
    }

    /// "none", "particles" or "covariance": the pose belief carried per node.
    #[getter]
    fn belief_kind(&self) -> &'static str {
        match &self.f {
            Func::Ucrmi(_) => "particles",
            Func::Ugpvr(_) => "covariance",
            _ => "none",
        }
    }

    /// The root belief for a pose-aware function: particles for UCRMI (seeded), the root
    /// covariance for UGPVR; None otherwise.
    #[pyo3(signature = (pose, seed=0))]
    fn root_belief(
        &self,
        py: Python<'_>,
        pose: numpy::PyReadonlyArray1<'_, f64>,
        seed: u64,
    ) -> PyResult<PyObject> {
        guard("InfoFunction.root_belief", || {
            let p = pose3(&pose)?;
            dispatch!(&self.f, |f, S| root_with(py, f, p, seed))
        })
    }

    /// Gain of one candidate (pure: `state` is not changed). `parent` is the (x, y) of the edge
    /// start (default: the pose itself); `belief` the parent's pose belief for pose-aware
    /// functions. Returns (gain, candidate belief or None, update).
    #[pyo3(signature = (state, pose, *, parent=None, belief=None, seed=0))]
    fn evaluate(
        &self,
        py: Python<'_>,
        state: &Bound<'_, PyAny>,
        pose: numpy::PyReadonlyArray1<'_, f64>,
        parent: Option<(f64, f64)>,
        belief: Option<&Bound<'_, PyAny>>,
        seed: u64,
    ) -> PyResult<(f64, PyObject, InfoUpdate)> {
        guard("InfoFunction.evaluate", || {
            let c = candidate(pose3(&pose)?, parent);
            dispatch!(&self.f, |f, S| evaluate_with::<_, S>(
                py, f, state, &c, belief, seed
            ))
        })
    }

    /// Applies an update from `evaluate` to `state` (the planner's map mutation).
    fn commit(&self, state: &Bound<'_, PyAny>, update: &InfoUpdate) -> PyResult<()> {
        guard("InfoFunction.commit", || {
            dispatch!(&self.f, |f, S| commit_with::<_, S>(f, state, update))
        })
    }

    /// Gains of many candidates (n, 3) on one state, in parallel (rayon, GIL released);
    /// identical to evaluating them one by one with seeds `candidate_seed(seed, i)`.
    /// `parents` (n, 2) are the edge starts (default: each pose itself).
    #[pyo3(signature = (state, poses, *, parents=None, belief=None, seed=0))]
    fn gains<'py>(
        &self,
        py: Python<'py>,
        state: &Bound<'py, PyAny>,
        poses: PyReadonlyArray2<'py, f64>,
        parents: Option<PyReadonlyArray2<'py, f64>>,
        belief: Option<&Bound<'py, PyAny>>,
        seed: u64,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        guard("InfoFunction.gains", || {
            let p = poses_n3(&poses)?;
            let cands: Vec<Candidate> = match parents {
                None => p.iter().map(|&q| Candidate::at(q)).collect(),
                Some(par) => {
                    if par.shape() != [p.len(), 2] {
                        return Err(shape_err(format!(
                            "parents must have shape ({}, 2), got {:?}",
                            p.len(),
                            par.shape()
                        )));
                    }
                    let s = par
                        .as_slice()
                        .map_err(|_| shape_err("parents must be a contiguous float64 array"))?;
                    p.iter()
                        .zip(s.chunks(2))
                        .map(|(&q, xy)| Candidate {
                            pose: q,
                            parent: [xy[0], xy[1]],
                        })
                        .collect()
                }
            };
            let g = dispatch!(&self.f, |f, S| gains_with::<_, S>(
                py, f, state, &cands, belief, seed
            ))?;
            Ok(g.into_pyarray(py))
        })
    }
}

/// The root belief of a function (None for map-only ones).
fn root_with<F: GlueFunction>(
    py: Python<'_>,
    f: &F,
    pose: [f64; 3],
    seed: u64,
) -> PyResult<PyObject> {
    let b = f.parent_belief(None, pose, seed)?;
    F::belief_to_py(py, b)
}

/// One evaluation through the function's glue (beliefs and updates converted).
fn evaluate_with<F: GlueFunction, S: StateClass<Core = F::Map>>(
    py: Python<'_>,
    f: &F,
    state: &Bound<'_, PyAny>,
    c: &Candidate,
    belief: Option<&Bound<'_, PyAny>>,
    seed: u64,
) -> PyResult<(f64, PyObject, InfoUpdate)> {
    let parent = f.parent_belief(belief, c.pose, 0)?;
    let guard = state.downcast::<S>()?.borrow();
    let map = guard.state();
    let e = py
        .allow_threads(|| f.evaluate(map, &parent, c, seed))
        .py_err()?;
    Ok((
        e.gain,
        F::belief_to_py(py, e.belief)?,
        InfoUpdate {
            inner: F::wrap_update(e.update),
        },
    ))
}

/// Applies an update made by the same kind of function.
fn commit_with<F: GlueFunction, S: StateClass<Core = F::Map>>(
    f: &F,
    state: &Bound<'_, PyAny>,
    update: &InfoUpdate,
) -> PyResult<()> {
    let u = F::unwrap_update(&update.inner)
        .ok_or_else(|| shape_err("this update was not made by this kind of function"))?;
    let mut guard = state.downcast::<S>()?.borrow_mut();
    f.commit(guard.state_mut(), u).py_err()
}

/// Batch gains on one state.
fn gains_with<F: GlueFunction, S: StateClass<Core = F::Map>>(
    py: Python<'_>,
    f: &F,
    state: &Bound<'_, PyAny>,
    cands: &[Candidate],
    belief: Option<&Bound<'_, PyAny>>,
    seed: u64,
) -> PyResult<Vec<f64>> {
    let guard = state.downcast::<S>()?.borrow();
    f.batch_gains(guard.state(), belief, cands, seed, py)
}

#[allow(clippy::too_many_arguments)]
fn crmi_config(
    model: &SensorModel,
    n_beams: usize,
    beam_angles: &str,
    lambda_z: f64,
    quadrature: &str,
    dedupe_cells: &str,
    units: &str,
    hit_threshold: f64,
) -> PyResult<CrmiConfig> {
    let mut cfg = CrmiConfig::new(model.inner.z_max, 0.2);
    cfg.model = model.inner;
    cfg.n_beams = n_beams;
    cfg.beam_angles = BeamAngles::parse(beam_angles).py_err()?;
    cfg.lambda_z = lambda_z;
    cfg.quadrature = CrmiQuadrature::parse(quadrature).py_err()?;
    cfg.dedupe = CellDedupe::parse(dedupe_cells).py_err()?;
    cfg.units = units_parse(units)?;
    cfg.hit_threshold = hit_threshold;
    cfg.validate().py_err()?;
    Ok(cfg)
}

/// The seed a batch gives candidate `index` (for reproducing one batch entry serially).
#[pyfunction]
pub fn candidate_seed(seed: u64, index: u64) -> u64 {
    core_info::candidate_seed(seed, index)
}
