//! Python classes of the particle filters (RBPF-CLAM, RBPF-OGM) and their argument conversions;
//! the scan matcher of scan-matching odometry is in `local_matcher`.

use crlam_core::crm::{BatchKernel, CrmConfig, LevelPlacement, ScanUpdateMode};
use crlam_core::grid::{CellRect, GridGeometry};
use crlam_core::motion::MotionModel;
use crlam_core::ogm::LogOddsParams;
use crlam_core::rbpf::{
    mode_seeking_pose as core_mode_seeking_pose, ClamConfig, ClamPrior, ClamProposal,
    CorrelativeSettings, FilterStep, MatcherParams, ModeBandwidth, MotionDraws, OgmFilterConfig,
    ParticleFilter, ProposalParams, ProposalPose, RbpfClam, RbpfOgm, ScanInput, ScanMatchSettings,
    ScanMatchWeight, UpdateTrigger,
};
use crlam_core::rbpf::{Degeneracy, MatchClimb, MatchRange};
use numpy::ndarray::{Array1, Array2};
use numpy::{
    IntoPyArray, PyArray1, PyArray2, PyReadonlyArray1, PyReadonlyArray2, PyUntypedArrayMethods,
};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::convert::{guard, pose3, poses_n3, shape_err, slice1, IntoPy};
use crate::maps::{CrmMap, LogOddsMap, SensorModel};

/// `match_range` as Python gives it: a name (`"z_max"`, `"full"`) or a range in metres.
#[derive(FromPyObject)]
pub enum MatchRangeArg {
    Name(String),
    Metres(f64),
}

impl MatchRangeArg {
    fn parse(self) -> PyResult<MatchRange> {
        let range = match self {
            Self::Name(name) => MatchRange::parse(&name).py_err()?,
            Self::Metres(m) => MatchRange::Metres(m),
        };
        range.validate().py_err()?;
        Ok(range)
    }
}

/// Parses the motion model name and its parameters.
pub fn motion_model(name: &str, params: Option<Vec<f64>>) -> PyResult<MotionModel> {
    let m = match (name, params) {
        ("gaussian", None) => MotionModel::paper(),
        ("gaussian", Some(p)) if p.len() == 3 => MotionModel::Gaussian { sigma: [p[0], p[1], p[2]] },
        ("thrun", None) => MotionModel::Thrun { alpha: [0.1, 0.1, 0.2, 0.05] },
        ("thrun", Some(p)) if p.len() == 4 => MotionModel::Thrun { alpha: [p[0], p[1], p[2], p[3]] },
        ("gmapping", None) => MotionModel::gmapping(),
        ("gmapping", Some(p)) if p.len() == 4 => MotionModel::Gmapping { srr: p[0], srt: p[1], str_: p[2], stt: p[3] },
        (n, p) => {
            return Err(shape_err(format!(
                "motion model {n:?} with parameters {p:?}: expected gaussian (3 sigmas), thrun (4 alphas) or gmapping (srr, srt, str, stt)"
            )))
        }
    };
    m.validate().py_err()?;
    Ok(m)
}

/// Feeds n scans (odoms (n, 3), shared angles (m,), ranges (n, m)) to `process` with the GIL
/// released, and returns a dict of arrays: estimates (n, 3), processed, neff, resampled (n,).
fn feed_many<'py, F>(
    py: Python<'py>,
    odoms: &PyReadonlyArray2<'py, f64>,
    angles: &PyReadonlyArray1<'py, f64>,
    ranges: &PyReadonlyArray2<'py, f64>,
    laser_offset: &PyReadonlyArray1<'py, f64>,
    mut process: F,
) -> PyResult<Bound<'py, PyDict>>
where
    F: FnMut(&ScanInput) -> crlam_core::Result<FilterStep> + Send,
{
    let odoms = poses_n3(odoms)?;
    let a = slice1(angles, "angles")?;
    let shape = ranges.shape();
    if shape[0] != odoms.len() || shape[1] != a.len() {
        return Err(shape_err(format!(
            "ranges must have shape ({}, {}), got {shape:?}",
            odoms.len(),
            a.len()
        )));
    }
    let r = ranges
        .as_slice()
        .map_err(|_| shape_err("ranges must be contiguous"))?;
    let off = pose3(laser_offset)?;
    let steps = py
        .allow_threads(|| {
            odoms
                .iter()
                .enumerate()
                .map(|(i, o)| {
                    let scan = ScanInput {
                        odom: *o,
                        angles: a,
                        ranges: &r[i * a.len()..(i + 1) * a.len()],
                        laser_offset: off,
                    };
                    process(&scan)
                })
                .collect::<crlam_core::Result<Vec<_>>>()
        })
        .py_err()?;
    let n = steps.len();
    let est: Vec<f64> = steps.iter().flat_map(|s| s.estimate).collect();
    let d = PyDict::new(py);
    d.set_item(
        "estimates",
        Array2::from_shape_vec((n, 3), est)
            .map_err(|e| shape_err(e.to_string()))?
            .into_pyarray(py),
    )?;
    d.set_item(
        "processed",
        Array1::from_iter(steps.iter().map(|s| s.processed)).into_pyarray(py),
    )?;
    d.set_item(
        "neff",
        Array1::from_iter(steps.iter().map(|s| s.neff)).into_pyarray(py),
    )?;
    d.set_item(
        "resampled",
        Array1::from_iter(steps.iter().map(|s| s.resampled)).into_pyarray(py),
    )?;
    Ok(d)
}

fn scan_of<'a>(
    odom: &PyReadonlyArray1<'_, f64>,
    angles: &'a PyReadonlyArray1<'_, f64>,
    ranges: &'a PyReadonlyArray1<'_, f64>,
    laser_offset: &PyReadonlyArray1<'_, f64>,
) -> PyResult<ScanInput<'a>> {
    Ok(ScanInput {
        odom: pose3(odom)?,
        angles: slice1(angles, "angles")?,
        ranges: slice1(ranges, "ranges")?,
        laser_offset: pose3(laser_offset)?,
    })
}

fn poses_array<'py>(py: Python<'py>, poses: Vec<[f64; 3]>) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let n = poses.len();
    let v: Vec<f64> = poses.into_iter().flatten().collect();
    Ok(Array2::from_shape_vec((n, 3), v)
        .map_err(|e| shape_err(e.to_string()))?
        .into_pyarray(py))
}

/// The mode of the weighted kernel density of a particle set that holds its densest particle
/// (see `crlam_core::rbpf::mode_seeking_pose`): poses (n, 3), weights (n,) ≥ 0,
/// bandwidth (m, rad).
#[pyfunction]
pub fn mode_seeking_pose(
    py: Python<'_>,
    poses: PyReadonlyArray2<'_, f64>,
    weights: PyReadonlyArray1<'_, f64>,
    bandwidth: (f64, f64),
) -> PyResult<(f64, f64, f64)> {
    guard("mode_seeking_pose", || {
        let p = poses_n3(&poses)?;
        let w = slice1(&weights, "weights")?;
        let bw = ModeBandwidth {
            xy: bandwidth.0,
            theta: bandwidth.1,
        };
        let m = py
            .allow_threads(|| core_mode_seeking_pose(&p, w, bw))
            .py_err()?;
        Ok((m[0], m[1], m[2]))
    })
}

/// RBPF-CLAM: particles with poses, log-weights and their own copy-on-write CRMs.
#[pyclass(module = "crlam._native")]
pub struct ClamFilter {
    inner: RbpfClam,
}

fn step_tuple(s: crlam_core::rbpf::FilterStep) -> (bool, (f64, f64, f64), f64, bool) {
    (
        s.processed,
        (s.estimate[0], s.estimate[1], s.estimate[2]),
        s.neff,
        s.resampled,
    )
}

/// The `#[pymethods]` of a particle-filter class: `$extra` (its constructor and map accessor)
/// and the methods every filter shares through [`ParticleFilter`] (one `#[pymethods]` block per
/// class, so the shared part is spliced in rather than written twice).
macro_rules! filter_pymethods {
    ($class:ident { $($extra:tt)* }) => {
        #[pymethods]
        impl $class {
            $($extra)*

            /// Feeds one scan: (processed, estimate (x, y, θ), N_eff, resampled).
            fn process(
                &mut self,
                py: Python<'_>,
                odom: PyReadonlyArray1<'_, f64>,
                angles: PyReadonlyArray1<'_, f64>,
                ranges: PyReadonlyArray1<'_, f64>,
                laser_offset: PyReadonlyArray1<'_, f64>,
            ) -> PyResult<(bool, (f64, f64, f64), f64, bool)> {
                guard(concat!(stringify!($class), ".process"), || {
                let scan = scan_of(&odom, &angles, &ranges, &laser_offset)?;
                let inner = &mut self.inner;
                let s = py
                    .allow_threads(|| ParticleFilter::process(inner, &scan))
                    .py_err()?;
                Ok(step_tuple(s))
                })
            }

            /// Feeds n scans with shared beam angles: odoms (n, 3), ranges (n, m). Returns a dict
            /// of arrays: estimates (n, 3), processed (n,), neff (n,), resampled (n,).
            fn process_many<'py>(
                &mut self,
                py: Python<'py>,
                odoms: PyReadonlyArray2<'py, f64>,
                angles: PyReadonlyArray1<'py, f64>,
                ranges: PyReadonlyArray2<'py, f64>,
                laser_offset: PyReadonlyArray1<'py, f64>,
            ) -> PyResult<Bound<'py, PyDict>> {
                guard(concat!(stringify!($class), ".process_many"), || {
                let inner = &mut self.inner;
                feed_many(py, &odoms, &angles, &ranges, &laser_offset, |scan| {
                    ParticleFilter::process(inner, scan)
                })
                })
            }

            /// Current estimate (weighted mean, circular heading).
            fn estimate(&self) -> (f64, f64, f64) {
                let e = ParticleFilter::estimate(&self.inner);
                (e[0], e[1], e[2])
            }

            /// Particle poses, shape (n, 3).
            fn particle_poses<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
                guard(concat!(stringify!($class), ".particle_poses"), || {
                poses_array(py, ParticleFilter::poses(&self.inner))
                })
            }

            /// The best particle's pose at every processed scan, first to last, shape (n_processed, 3).
            fn best_path<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
                guard(concat!(stringify!($class), ".best_path"), || {
                poses_array(py, ParticleFilter::best_path(&self.inner))
                })
            }

            /// The proposal means along the best particle's path, shape (n_processed, 3); None
            /// unless the poses are drawn from a fitted proposal (the likelihood-mode / improved
            /// proposal with pose "sample").
            fn best_path_means<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyArray2<f64>>>> {
                guard(concat!(stringify!($class), ".best_path_means"), || {
                ParticleFilter::best_path_means(&self.inner)
                    .map(|p| poses_array(py, p))
                    .transpose()
                })
            }

            /// Poses (n, 3) and normalised weights (n,) of the last processed scan before
            /// resampling (uniform weights before the first).
            fn weighed_set<'py>(
                &self,
                py: Python<'py>,
            ) -> PyResult<(Bound<'py, PyArray2<f64>>, Bound<'py, PyArray1<f64>>)> {
                guard(concat!(stringify!($class), ".weighed_set"), || {
                let set = ParticleFilter::weighed_set(&self.inner);
                Ok((
                    poses_array(py, set.poses.clone())?,
                    Array1::from_vec(set.weights.clone()).into_pyarray(py),
                ))
                })
            }

            /// Smoothed means of the weighed set's lineages, shape (k, 3): row j is the weighted
            /// mean of the particles' poses j processed scans back (row 0 the weighted mean), for
            /// j up to `max_lag` (None: back to the first processed scan). `proposal_means` reads
            /// the recorded proposal means; None when the filter does not record them.
            #[pyo3(signature = (max_lag=None, proposal_means=false))]
            fn ancestor_means<'py>(
                &self,
                py: Python<'py>,
                max_lag: Option<usize>,
                proposal_means: bool,
            ) -> PyResult<Option<Bound<'py, PyArray2<f64>>>> {
                guard(concat!(stringify!($class), ".ancestor_means"), || {
                let inner = &self.inner;
                py.allow_threads(|| {
                    ParticleFilter::ancestor_means(inner, max_lag.unwrap_or(usize::MAX), proposal_means)
                })
                .map(|m| poses_array(py, m))
                .transpose()
                })
            }

            /// Particle log-weights as the filter stores them (RBPF-OGM: before its weight
            /// smoothing), shape (n,).
            fn log_weights<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
                Array1::from_vec(ParticleFilter::log_weights(&self.inner)).into_pyarray(py)
            }

            /// Normalised weights behind N_eff, resampling and the estimate, shape (n,).
            fn weights<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
                Array1::from_vec(ParticleFilter::weights(&self.inner)).into_pyarray(py)
            }

            #[getter]
            fn best_index(&self) -> usize {
                ParticleFilter::best_index(&self.inner)
            }
            #[getter]
            fn n_resamples(&self) -> usize {
                ParticleFilter::n_resamples(&self.inner)
            }
            #[getter]
            fn n_processed(&self) -> usize {
                ParticleFilter::n_processed(&self.inner)
            }
            #[getter]
            fn n_particles(&self) -> usize {
                ParticleFilter::n_particles(&self.inner)
            }

            /// (bytes of distinct map tiles, distinct tiles, tile references) over all particles.
            fn map_memory(&self) -> (usize, usize, usize) {
                ParticleFilter::map_memory(&self.inner)
            }

            /// Frees the particles' maps once the run's map is written. Poses, weights and paths
            /// stay readable; the filter then refuses scans (ConfigError).
            fn release_maps(&mut self) -> PyResult<()> {
                guard(concat!(stringify!($class), ".release_maps"), || {
                    ParticleFilter::release_maps(&mut self.inner).py_err()
                })
            }

            /// Whether release_maps was called.
            #[getter]
            fn maps_released(&self) -> bool {
                ParticleFilter::maps_released(&self.inner)
            }
        }
    };
}

filter_pymethods!(ClamFilter {
    #[new]
    #[pyo3(signature = (initial_pose, mapping_model, weight_model, *, n_particles=100, resolution=0.2, origin=(0.0, 0.0),
        n_levels=10, levels="midpoints", belief_floor=1e-12, tile_size=32, extent=None, scan_update="batch",
        batch_kernel="windowed", hits_first=false, weight_stride=1, map_stride=1, tempering=1.0, tempering_beams=None, resample_threshold=0.5, init_sigma=(0.0, 0.0, 0.0),
        motion="gaussian", motion_params=None, linear_update=0.0, angular_update=0.0, proposal="odometry",
        proposal_pose="sample", match_stride=3, lattice_step=(0.05, 0.025), motion_outlier=0.0, scan_match_weight="crm",
        match_range=MatchRangeArg::Name("z_max".to_owned()), hit_means=false, front_end=None, match_min_score=0.0, match_climb="score", degeneracy="off", seed=0, prior_map=None, initial_cov=None))]
    fn new(
        initial_pose: PyReadonlyArray1<'_, f64>,
        mapping_model: &SensorModel,
        weight_model: &SensorModel,
        n_particles: usize,
        resolution: f64,
        origin: (f64, f64),
        n_levels: usize,
        levels: &str,
        belief_floor: f64,
        tile_size: usize,
        extent: Option<(i64, i64, i64, i64)>,
        scan_update: &str,
        batch_kernel: &str,
        hits_first: bool,
        weight_stride: usize,
        map_stride: usize,
        tempering: f64,
        tempering_beams: Option<f64>,
        resample_threshold: f64,
        init_sigma: (f64, f64, f64),
        motion: &str,
        motion_params: Option<Vec<f64>>,
        linear_update: f64,
        angular_update: f64,
        proposal: &str,
        proposal_pose: &str,
        match_stride: usize,
        lattice_step: (f64, f64),
        motion_outlier: f64,
        scan_match_weight: &str,
        match_range: MatchRangeArg,
        hit_means: bool,
        front_end: Option<(f64, f64)>,
        match_min_score: f64,
        match_climb: &str,
        degeneracy: &str,
        seed: u64,
        prior_map: Option<PyRef<'_, CrmMap>>,
        initial_cov: Option<PyReadonlyArray2<'_, f64>>,
    ) -> PyResult<Self> {
        guard("ClamFilter.new", || {
        let geometry = GridGeometry::new([origin.0, origin.1], resolution).py_err()?;
        let extent = extent
            .map(|(ix0, iy0, nx, ny)| CellRect::checked(ix0, iy0, nx, ny).py_err())
            .transpose()?;
        let crm = CrmConfig {
            geometry,
            n_levels,
            placement: LevelPlacement::parse(levels).py_err()?,
            prior_mean: None,
            belief_floor,
            tile_size,
            extent,
        };
        let pose_rule = ProposalPose::parse(proposal_pose).py_err()?;
        let scan_match_weight = ScanMatchWeight::parse(scan_match_weight).py_err()?;
        let match_range = match_range.parse()?;
        let match_climb = MatchClimb::parse(match_climb).py_err()?;
        let degeneracy = Degeneracy::parse(degeneracy).py_err()?;
        let proposal = match (proposal, pose_rule) {
            ("odometry", ProposalPose::Sample) => ClamProposal::Odometry,
            ("odometry", ProposalPose::Match) => {
                return Err(shape_err(
                    "proposal_pose=\"match\" needs proposal=\"likelihood_mode\" (the odometry proposal has no match)",
                ))
            }
            ("likelihood_mode", rule) => match ClamProposal::likelihood_mode_with(rule) {
                ClamProposal::LikelihoodMode {
                    step, iterations, ..
                } => ClamProposal::LikelihoodMode {
                    step,
                    iterations,
                    match_stride,
                    lattice: [lattice_step.0, lattice_step.0, lattice_step.1],
                    pose: rule,
                    motion_outlier,
                },
                other => other,
            },
            ("scan_match", rule) => {
                if motion_outlier != 0.0 {
                    return Err(shape_err(
                        "motion_outlier applies to proposal=\"likelihood_mode\" only",
                    ));
                }
                let defaults = ScanMatchSettings::default();
                ClamProposal::ScanMatch(ScanMatchSettings {
                    matcher: MatcherParams {
                        beam_stride: match_stride,
                        ..defaults.matcher
                    },
                    lattice: ProposalParams {
                        pose: rule,
                        range: [lattice_step.0, lattice_step.0, lattice_step.1],
                        min_score: match_min_score,
                        ..defaults.lattice
                    },
                    weight: scan_match_weight,
                    match_range,
                    hit_means,
                    climb: match_climb,
                    degeneracy,
                    front_end: front_end.map(|(linear, angular)| CorrelativeSettings {
                        linear_window: linear,
                        angular_window: angular,
                        ..CorrelativeSettings::default()
                    }),
                    ..defaults
                })
            }
            (other, _) => {
                return Err(shape_err(format!(
                    "unknown proposal {other:?}; expected odometry, likelihood_mode or scan_match"
                )))
            }
        };
        let cfg = ClamConfig {
            n_particles,
            motion: motion_model(motion, motion_params)?,
            trigger: UpdateTrigger {
                linear: linear_update,
                angular: angular_update,
            },
            crm,
            mapping_model: mapping_model.inner,
            weight_model: weight_model.inner,
            scan_update: ScanUpdateMode::parse(scan_update).py_err()?,
            batch_kernel: BatchKernel::parse(batch_kernel).py_err()?,
            hits_first,
            weight_stride,
            map_stride,
            tempering,
            tempering_beams,
            resample_threshold,
            init_sigma: [init_sigma.0, init_sigma.1, init_sigma.2],
            proposal,
            seed,
            defer_map_updates: true,
        };
        let initial = pose3(&initial_pose)?;
        let inner = match (prior_map, initial_cov) {
            (None, None) => RbpfClam::new(cfg, initial),
            (Some(map), Some(cov)) => {
                let c = cov.as_array();
                if c.shape() != [3, 3] {
                    return Err(shape_err(format!(
                        "initial_cov must have shape (3, 3), got {:?}",
                        c.shape()
                    )));
                }
                let cov = [0, 1, 2].map(|i| [0, 1, 2].map(|j| c[[i, j]]));
                let prior = ClamPrior {
                    map: map.core().clone(),
                    cov,
                };
                RbpfClam::with_prior(cfg, initial, prior)
            }
            _ => {
                return Err(shape_err(
                    "a prior map needs its initial_cov (and the covariance its prior map)",
                ))
            }
        };
        Ok(Self {
            inner: inner.py_err()?,
        })
        })
    }

    /// The best particle's map (a copy-on-write copy).
    fn best_map(&self) -> CrmMap {
        CrmMap::from_core(
            self.inner.best_map().clone(),
            self.inner.config().crm.tile_size,
        )
    }

    /// (processed scans the correlative front end searched, those whose odometry increment it
    /// corrected).
    fn front_end_counts(&self) -> (usize, usize) {
        let c = self.inner.front_end_counts();
        (c.searched, c.corrected)
    }

    /// Processed scans the scan-match proposal found degenerate (0 unless `degeneracy` is
    /// "remap").
    fn degenerate_scans(&self) -> usize {
        self.inner.degenerate_scans()
    }

    /// A map with the filter's grid and levels and nothing mapped yet (loop closing rebuilds
    /// the map into it with `map_scan`).
    fn empty_map(&self) -> PyResult<CrmMap> {
        guard("ClamFilter.empty_map", || {
            Ok(CrmMap::from_core(
                self.inner.empty_map().py_err()?,
                self.inner.config().crm.tile_size,
            ))
        })
    }

    /// Maps one scan taken at robot pose `pose` into `map` as a particle's map takes a
    /// processed scan (the filter's mapping model and options).
    fn map_scan(
        &self,
        py: Python<'_>,
        mut map: PyRefMut<'_, CrmMap>,
        pose: PyReadonlyArray1<'_, f64>,
        angles: PyReadonlyArray1<'_, f64>,
        ranges: PyReadonlyArray1<'_, f64>,
        laser_offset: PyReadonlyArray1<'_, f64>,
    ) -> PyResult<()> {
        guard("ClamFilter.map_scan", || {
            let scan = ScanInput {
                odom: [0.0; 3],
                angles: slice1(&angles, "angles")?,
                ranges: slice1(&ranges, "ranges")?,
                laser_offset: pose3(&laser_offset)?,
            };
            let pose = pose3(&pose)?;
            let inner = &self.inner;
            let core = map.core_mut();
            py.allow_threads(|| inner.map_scan(core, pose, &scan))
                .py_err()
        })
    }

    /// Loop closing's correction: every particle's map becomes a copy of `map`, and every pose
    /// moves by the rigid `correction` (x, y, theta; new = correction ∘ old).
    fn reanchor(&mut self, map: PyRef<'_, CrmMap>, correction: PyReadonlyArray1<'_, f64>) -> PyResult<()> {
        guard("ClamFilter.reanchor", || {
            let c = pose3(&correction)?;
            self.inner.reanchor(map.core().clone(), c).py_err()
        })
    }
});

/// RBPF-OGM: the GMapping-style baseline (log-odds maps, scan matching, improved proposal).
#[pyclass(module = "crlam._native")]
pub struct OgmFilter {
    inner: RbpfOgm,
}

filter_pymethods!(OgmFilter {
    #[new]
    #[pyo3(signature = (initial_pose, *, n_particles=30, resolution=0.05, usable_range=30.0, motion="thrun", motion_params=None,
        linear_update=0.0, angular_update=0.0, resample_threshold=0.5, init_sigma=(0.0, 0.0, 0.0), proposal_pose="sample",
        map_model="log_odds", motion_draws="per_update", weight_smoothing=3.0, seed=0))]
    fn new(
        initial_pose: PyReadonlyArray1<'_, f64>,
        n_particles: usize,
        resolution: f64,
        usable_range: f64,
        motion: &str,
        motion_params: Option<Vec<f64>>,
        linear_update: f64,
        angular_update: f64,
        resample_threshold: f64,
        init_sigma: (f64, f64, f64),
        proposal_pose: &str,
        map_model: &str,
        motion_draws: &str,
        weight_smoothing: f64,
        seed: u64,
    ) -> PyResult<Self> {
        guard("OgmFilter.new", || {
        let defaults = OgmFilterConfig::default();
        let motion = match (motion, &motion_params) {
            ("thrun", None) => OgmFilterConfig::default_motion(),
            _ => motion_model(motion, motion_params)?,
        };
        let cfg = OgmFilterConfig {
            n_particles,
            motion,
            motion_draws: MotionDraws::parse(motion_draws).py_err()?,
            trigger: UpdateTrigger {
                linear: linear_update,
                angular: angular_update,
            },
            resample_threshold,
            weight_smoothing,
            geometry: GridGeometry::new([0.0, 0.0], resolution).py_err()?,
            log_odds: LogOddsParams {
                z_max: usable_range,
                ..defaults.log_odds
            },
            // Readings arrive with no-returns as inf; every finite one is usable up to usable_range.
            max_range: 1e6,
            init_sigma: [init_sigma.0, init_sigma.1, init_sigma.2],
            proposal: ProposalParams {
                pose: ProposalPose::parse(proposal_pose).py_err()?,
                ..defaults.proposal
            },
            seed,
            ..defaults
        };
        let cfg = match map_model {
            "log_odds" => cfg,
            // GMapping's fullnessThreshold.
            "hit_rate" => cfg.with_hit_rate_map(0.1).py_err()?,
            "gmapping" => cfg.with_gmapping_map(0.1).py_err()?,
            other => {
                return Err(crlam_core::error::config_err(
                    "map_model",
                    format!("unknown value {other:?}; expected log_odds, hit_rate or gmapping"),
                ))
                .py_err()
            }
        };
        Ok(Self {
            inner: RbpfOgm::new(cfg, pose3(&initial_pose)?).py_err()?,
        })
        })
    }

    /// The best particle's log-odds map (a copy-on-write copy).
    fn best_map(&self) -> LogOddsMap {
        LogOddsMap::from_core(self.inner.best_map().clone())
    }
});
