//! Python class for Monte Carlo localization on a fixed CRM.

use std::sync::Arc;

use crlam_core::grid::CellRect;
use crlam_core::mcl::{
    BeamParams, Cluster, KldSettings, LikelihoodFieldParams, LikelihoodSettings, Mcl, MclConfig,
    MclInit, MclStep, MeanField, Measurement,
};
use crlam_core::pose::Pose;
use crlam_core::rbpf::{ScanInput, UpdateTrigger};
use numpy::ndarray::{Array1, Array2};
use numpy::{IntoPyArray, PyArray1, PyArray2, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::convert::{guard, pose3, shape_err, slice1, IntoPy};
use crate::filters::motion_model;
use crate::maps::{CrmMap, SensorModel};

fn cov3(a: &PyReadonlyArray2<'_, f64>) -> PyResult<[[f64; 3]; 3]> {
    let v = a.as_array();
    if v.shape() != [3, 3] {
        return Err(shape_err(format!(
            "the initial covariance must have shape (3, 3), got {:?}",
            v.shape()
        )));
    }
    let mut c = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            c[i][j] = v[[i, j]];
        }
    }
    Ok(c)
}

/// The measurement model named `name` (`crm`, `likelihood_field`, `beam`) with AMCL's defaults,
/// overridden by `params` (the parameter names of [`LikelihoodFieldParams`] or [`BeamParams`]).
fn measurement(name: &str, params: Option<Vec<(String, f64)>>) -> PyResult<Measurement> {
    let params = params.unwrap_or_default();
    let unknown = |k: &str, known: &str| {
        shape_err(format!(
            "measurement model {name:?} has no parameter {k:?} (it has {known})"
        ))
    };
    match name {
        "crm" => match params.first() {
            None => Ok(Measurement::Crm),
            Some((k, _)) => Err(unknown(k, "none: its parameters are the mixture's")),
        },
        "likelihood_field" => {
            let mut p = LikelihoodFieldParams::default();
            for (k, v) in params {
                match k.as_str() {
                    "z_hit" => p.z_hit = v,
                    "z_rand" => p.z_rand = v,
                    "sigma_hit" => p.sigma_hit = v,
                    "max_dist" => p.max_dist = v,
                    _ => return Err(unknown(&k, "z_hit, z_rand, sigma_hit, max_dist")),
                }
            }
            Ok(Measurement::LikelihoodField(p))
        }
        "beam" => {
            let mut p = BeamParams::default();
            for (k, v) in params {
                match k.as_str() {
                    "z_hit" => p.z_hit = v,
                    "z_short" => p.z_short = v,
                    "z_max" => p.z_max = v,
                    "z_rand" => p.z_rand = v,
                    "sigma_hit" => p.sigma_hit = v,
                    "lambda_short" => p.lambda_short = v,
                    _ => {
                        return Err(unknown(
                            &k,
                            "z_hit, z_short, z_max, z_rand, sigma_hit, lambda_short",
                        ))
                    }
                }
            }
            Ok(Measurement::Beam(p))
        }
        _ => Err(shape_err(format!(
            "unknown measurement model {name:?} (crm, likelihood_field or beam)"
        ))),
    }
}

fn cluster_dict<'py>(py: Python<'py>, c: &Cluster) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("weight", c.weight)?;
    d.set_item("count", c.count)?;
    d.set_item("mean", (c.mean[0], c.mean[1], c.mean[2]))?;
    d.set_item("cov_xy", (c.cov_xy[0], c.cov_xy[1], c.cov_xy[2]))?;
    d.set_item("std_theta", c.std_theta)?;
    d.set_item("spread_xy", c.spread_xy())?;
    Ok(d)
}

fn step_dict<'py>(py: Python<'py>, s: &MclStep) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("processed", s.processed)?;
    d.set_item("estimate", (s.estimate[0], s.estimate[1], s.estimate[2]))?;
    d.set_item("n_particles", s.n_particles)?;
    d.set_item("n_after", s.n_after)?;
    d.set_item("neff", s.neff)?;
    d.set_item("resampled", s.resampled)?;
    d.set_item("n_injected", s.n_injected)?;
    d.set_item("inject_probability", s.inject_probability)?;
    d.set_item("fit", s.fit)?;
    d.set_item("n_beams", s.n_beams)?;
    d.set_item("tempering", s.tempering)?;
    d.set_item("sigma_hit", s.sigma_hit)?;
    d.set_item("cluster", cluster_dict(py, &s.cluster)?)?;
    d.set_item("n_clusters", s.n_clusters)?;
    d.set_item("second_weight", s.second_weight)?;
    d.set_item("n_kept", s.n_kept)?;
    Ok(d)
}

fn poses_array<'py>(py: Python<'py>, poses: &[Pose]) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let v: Vec<f64> = poses.iter().flatten().copied().collect();
    Ok(Array2::from_shape_vec((poses.len(), 3), v)
        .map_err(|e| shape_err(e.to_string()))?
        .into_pyarray(py))
}

/// Monte Carlo localization (AMCL's algorithm with KLD sampling and recovery) on a fixed CRM,
/// weighing scans with the CRM predictive likelihood (`crlam_core::mcl`).
#[pyclass(module = "crlam._native")]
pub struct MclFilter {
    inner: Mcl,
}

#[pymethods]
impl MclFilter {
    /// A localizer on `crm`'s cells `rect` (ix0, iy0, nx, ny) with the mixture `model`; the
    /// particles start from N(initial_pose, initial_cov) or, without an initial pose, uniformly
    /// over the free cells (m̂ <= free_threshold).
    #[new]
    #[pyo3(signature = (crm, rect, model, *, initial_pose=None, initial_cov=None, free_threshold=0.25, margin=0,
        n_min=100, n_max=5000, kld_err=0.01, kld_z=2.326_347_874_040_840_8, bin_xy=0.5, bin_theta=0.174_532_925_199_432_95,
        alpha_slow=0.001, alpha_fast=0.1, tempering=1.0, min_neff=0.0, sigma_max=0.0, anneal=0.5, beam_stride=1, max_beams=0, motion="gmapping",
        motion_params=None, linear_update=0.0, angular_update=0.0, spread_update=(0.0, 0.0), spread_limit=0.5, resample_threshold=0.5, min_cluster=0, keep_ratio=1e-3, min_bin=0, place_xy=0.0, place_theta=std::f64::consts::FRAC_PI_2, spread_max=0, spread_climb=false, tail_tolerance=1e-6, skip_no_returns=false, measurement="crm", measurement_params=None, seed=0))]
    fn new(
        py: Python<'_>,
        crm: &CrmMap,
        rect: (i64, i64, i64, i64),
        model: &SensorModel,
        initial_pose: Option<PyReadonlyArray1<'_, f64>>,
        initial_cov: Option<PyReadonlyArray2<'_, f64>>,
        free_threshold: f64,
        margin: usize,
        n_min: usize,
        n_max: usize,
        kld_err: f64,
        kld_z: f64,
        bin_xy: f64,
        bin_theta: f64,
        alpha_slow: f64,
        alpha_fast: f64,
        tempering: f64,
        min_neff: f64,
        sigma_max: f64,
        anneal: f64,
        beam_stride: usize,
        max_beams: usize,
        motion: &str,
        motion_params: Option<Vec<f64>>,
        linear_update: f64,
        angular_update: f64,
        spread_update: (f64, f64),
        spread_limit: f64,
        resample_threshold: f64,
        min_cluster: usize,
        keep_ratio: f64,
        min_bin: usize,
        place_xy: f64,
        place_theta: f64,
        spread_max: usize,
        spread_climb: bool,
        tail_tolerance: f64,
        skip_no_returns: bool,
        measurement: &str,
        measurement_params: Option<Vec<(String, f64)>>,
        seed: u64,
    ) -> PyResult<Self> {
        guard("MclFilter.new", || {
            let (ix0, iy0, nx, ny) = rect;
            let rect = CellRect::checked(ix0, iy0, nx, ny).py_err()?;
            let init = match (initial_pose, initial_cov) {
                (None, None) => MclInit::Global,
                (Some(p), Some(c)) => MclInit::Pose {
                    mean: pose3(&p)?,
                    cov: cov3(&c)?,
                },
                _ => return Err(shape_err(
                    "give both initial_pose and initial_cov (or neither, for global localization)",
                )),
            };
            let cfg = MclConfig {
                measurement: self::measurement(measurement, measurement_params)?,
                likelihood: LikelihoodSettings {
                    model: model.inner,
                    tail_tolerance,
                    skip_no_returns,
                },
                motion: motion_model(motion, motion_params)?,
                trigger: UpdateTrigger {
                    linear: linear_update,
                    angular: angular_update,
                },
                spread_trigger: UpdateTrigger {
                    linear: spread_update.0,
                    angular: spread_update.1,
                },
                spread_limit,
                kld: KldSettings {
                    n_min,
                    n_max,
                    epsilon: kld_err,
                    z: kld_z,
                    bin_xy,
                    bin_theta,
                },
                alpha_slow,
                alpha_fast,
                tempering,
                min_neff,
                sigma_max,
                anneal,
                beam_stride,
                max_beams,
                resample_threshold,
                min_cluster,
                keep_ratio,
                min_bin,
                place_xy,
                place_theta,
                spread_max,
                spread_climb,
                seed,
            };
            // Validate before building the field (which may be large).
            cfg.validate().py_err()?;
            let core = crm.core();
            let inner = py
                .allow_threads(|| {
                    let field = MeanField::from_crm(core, rect, free_threshold, margin)?;
                    Mcl::new(cfg, Arc::new(field), init)
                })
                .py_err()?;
            Ok(Self { inner })
        })
    }

    /// Feeds one scan (odometry pose, beam bearings, ranges, laser offset in the robot frame);
    /// returns a dict: processed, estimate, n_particles, n_after, neff, resampled, n_injected,
    /// inject_probability, fit, n_beams, cluster (weight, count, mean, cov_xy, std_theta,
    /// spread_xy), n_clusters, second_weight (the second-heaviest cluster's weight) and n_kept
    /// (clusters kept by the `min_cluster` floor at this scan's resampling).
    fn process<'py>(
        &mut self,
        py: Python<'py>,
        odom: PyReadonlyArray1<'py, f64>,
        angles: PyReadonlyArray1<'py, f64>,
        ranges: PyReadonlyArray1<'py, f64>,
        laser_offset: PyReadonlyArray1<'py, f64>,
    ) -> PyResult<Bound<'py, PyDict>> {
        guard("MclFilter.process", || {
            let scan = ScanInput {
                odom: pose3(&odom)?,
                angles: slice1(&angles, "angles")?,
                ranges: slice1(&ranges, "ranges")?,
                laser_offset: pose3(&laser_offset)?,
            };
            let inner = &mut self.inner;
            let s = py.allow_threads(|| inner.process(&scan)).py_err()?;
            step_dict(py, &s)
        })
    }

    /// Places the particles anew from N(pose, cov).
    fn reset_pose(
        &mut self,
        pose: PyReadonlyArray1<'_, f64>,
        cov: PyReadonlyArray2<'_, f64>,
    ) -> PyResult<()> {
        guard("MclFilter.reset_pose", || {
            let init = MclInit::Pose {
                mean: pose3(&pose)?,
                cov: cov3(&cov)?,
            };
            self.inner.reset(init).py_err()
        })
    }

    /// Places the particles anew uniformly over the free cells.
    fn reset_global(&mut self) -> PyResult<()> {
        guard("MclFilter.reset_global", || {
            self.inner.reset(MclInit::Global).py_err()
        })
    }

    /// The estimate: the heaviest cluster's mean at the last processed scan.
    fn estimate(&self) -> (f64, f64, f64) {
        let e = self.inner.estimate();
        (e[0], e[1], e[2])
    }

    /// Particle poses, shape (n, 3).
    fn particle_poses<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        guard("MclFilter.particle_poses", || {
            poses_array(py, self.inner.poses())
        })
    }

    /// Normalised weights, shape (n,).
    fn weights<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        Array1::from_vec(self.inner.weights()).into_pyarray(py)
    }

    /// The clusters of the current set, heaviest first (dicts as in `process`).
    fn clusters<'py>(&self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyDict>>> {
        guard("MclFilter.clusters", || {
            self.inner
                .clusters()
                .iter()
                .map(|c| cluster_dict(py, c))
                .collect()
        })
    }

    /// (w_slow, w_fast) of the recovery, or None before the first weighed scan.
    #[getter]
    fn averages(&self) -> Option<(f64, f64)> {
        self.inner.averages()
    }

    #[getter]
    fn n_particles(&self) -> usize {
        self.inner.poses().len()
    }

    #[getter]
    fn n_processed(&self) -> u64 {
        self.inner.n_processed()
    }

    /// Number of free cells (where global initialisation and recovery place particles).
    #[getter]
    fn n_free(&self) -> usize {
        self.inner.field().n_free()
    }

    /// The scan's likelihood at a robot pose under the filter's measurement model with the
    /// model's own σ_hit, on the beams the filter keeps (before tempering): (Σ log-likelihood
    /// per beam, Σ explained share, beams used).
    fn scan_fit(
        &self,
        py: Python<'_>,
        pose: PyReadonlyArray1<'_, f64>,
        angles: PyReadonlyArray1<'_, f64>,
        ranges: PyReadonlyArray1<'_, f64>,
        laser_offset: PyReadonlyArray1<'_, f64>,
    ) -> PyResult<(f64, f64, usize)> {
        guard("MclFilter.scan_fit", || {
            let sensor = crlam_core::pose::compose(pose3(&pose)?, pose3(&laser_offset)?);
            let (a, r) = (slice1(&angles, "angles")?, slice1(&ranges, "ranges")?);
            let inner = &self.inner;
            let fit = py.allow_threads(|| inner.scan_fit(sensor, a, r)).py_err()?;
            Ok((fit.log_likelihood, fit.explained, fit.n_beams))
        })
    }

    /// Distance (m) from every cell centre of the map's rectangle to the nearest cell with
    /// m̂ >= `occupied` (inf where none), shape (ny, nx), row 0 at the minimum y.
    fn occupied_distance<'py>(
        &self,
        py: Python<'py>,
        occupied: f64,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        guard("MclFilter.occupied_distance", || {
            let field = self.inner.field();
            let r = field.rect();
            let d = py.allow_threads(|| field.occupied_distance(occupied));
            Ok(Array2::from_shape_vec((r.ny as usize, r.nx as usize), d)
                .map_err(|e| shape_err(e.to_string()))?
                .into_pyarray(py))
        })
    }
}
