//! GPVR and UGPVR: the GP-variance-reduction information functions of the IIG planner
//! (planner-spec 5.1–5.4, 3.5; tests in `tests/info_gp.rs`).
//!
//! A virtual scan's hit and free points are the GP test points; their nearest lattice nodes are
//! the training inputs. The posterior variances at the test points are fused into the per-node
//! variance map (BCM in information form) and the gain is the drop of Σ ln Var over the scan's
//! node ids, in nats. UGPVR replaces the training–test kernel by its expectation over the
//! uncertain training positions (Gauss–Hermite), with the pose covariance propagated along the
//! edge (planner-spec 3.9). Occupancy probabilities are read for ray casting only.

use super::gp_kernel::posterior_prefix;
pub use super::gp_kernel::{
    bcm_fuse, cholesky_lower, gauss_hermite, posterior_variances, ExpectedKernel, FreePoints,
    Fusion, GpHyper, Matern, Mode, UgpvrKernel, GH_ORDER, GH_PAIR_THRESHOLD,
};
use super::lattice::{march_beam, BeamAngles, OccupancyLattice};
use super::posecov::{
    check_covariance, propagate_covariance, xy_block, Cov3, EdgeNoise, PoseJacobian,
};
use super::{Candidate, Evaluation, InfoUnits, InformationFunction};
use crate::error::{config_err, CrlamError, Result};
use crate::grid::check_pose;

/// The map of GPVR/UGPVR: the occupancy lattice (read by the ray casting only, never changed)
/// and the GP variance of every node (prior 1).
#[derive(Clone, Debug, PartialEq)]
pub struct GpVarianceMap {
    lattice: OccupancyLattice,
    var: Vec<f64>,
}

impl GpVarianceMap {
    /// Every node at the prior variance 1.
    pub fn new(lattice: OccupancyLattice) -> Self {
        let var = vec![1.0; lattice.len()];
        Self { lattice, var }
    }

    /// Given variances (one per node, each finite and > 0).
    pub fn with_variances(lattice: OccupancyLattice, var: Vec<f64>) -> Result<Self> {
        if var.len() != lattice.len() {
            return Err(CrlamError::Shape(format!(
                "{} variances for {} nodes",
                var.len(),
                lattice.len()
            )));
        }
        if let Some(&v) = var.iter().find(|v| !(v.is_finite() && **v > 0.0)) {
            return Err(CrlamError::NonFinite {
                field: "variance",
                value: v,
            });
        }
        Ok(Self { lattice, var })
    }

    /// The occupancy lattice (ray casting only).
    pub fn lattice(&self) -> &OccupancyLattice {
        &self.lattice
    }

    /// Variance per node (index as the lattice).
    pub fn variances(&self) -> &[f64] {
        &self.var
    }

    /// Σ ln Var over all nodes. A committed scan lowers it by at most its gain (the gain counts
    /// a node once per test point on it).
    pub fn total_log_variance(&self) -> f64 {
        self.var.iter().map(|v| v.ln()).sum()
    }

    /// Sets the variances of an update `(node id, Var)` in order; checks everything first.
    fn apply(&mut self, update: &[(usize, f64)]) -> Result<()> {
        for &(id, v) in update {
            if id >= self.var.len() {
                return Err(CrlamError::OutOfBounds(format!(
                    "node {id} of {}",
                    self.var.len()
                )));
            }
            if !(v.is_finite() && v > 0.0) {
                return Err(CrlamError::NonFinite {
                    field: "variance",
                    value: v,
                });
            }
        }
        for &(id, v) in update {
            self.var[id] = v;
        }
        Ok(())
    }
}

/// Options shared by GPVR and UGPVR.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GpvrOptions {
    /// Kernel hyperparameters.
    pub hyper: GpHyper,
    /// Beams per virtual scan (1..=64).
    pub n_beams: usize,
    /// Maximum range (m), in (0, 100].
    pub z_max: f64,
    /// Occupancy above which a ray-march step is a hit.
    pub p_occ: f64,
    /// World-frame beam directions (`Reference`: 9 distinct for 10 beams).
    pub beam_angles: BeamAngles,
    /// Where the free test points lie.
    pub free_points: FreePoints,
    /// Which test points update the variance map.
    pub fusion: Fusion,
}

impl Default for GpvrOptions {
    fn default() -> Self {
        Self::preset(Mode::Reference)
    }
}

impl GpvrOptions {
    /// 10 beams, 5 m, p_occ 0.65, the reference hyperparameters, and the mode's switches.
    pub fn preset(mode: Mode) -> Self {
        let reference = mode == Mode::Reference;
        Self {
            hyper: GpHyper::reference(),
            n_beams: 10,
            z_max: 5.0,
            p_occ: 0.65,
            beam_angles: [BeamAngles::Distinct, BeamAngles::Reference][reference as usize],
            free_points: [FreePoints::Robot, FreePoints::WorldOrigin][reference as usize],
            fusion: [Fusion::AllPoints, Fusion::HitsOnly][reference as usize],
        }
    }

    /// Checks every field (hyperparameters, beams, range, threshold).
    pub fn validate(&self) -> Result<()> {
        self.hyper.validate()?;
        if !(1..=64).contains(&self.n_beams) {
            return Err(config_err("n_beams", "must be in 1..=64"));
        }
        if !(self.z_max.is_finite() && self.z_max > 0.0 && self.z_max <= 100.0) {
            return Err(config_err("z_max", "must be in (0, 100] m"));
        }
        if !(0.0..=1.0).contains(&self.p_occ) {
            return Err(config_err("p_occ", "must be in [0, 1]"));
        }
        Ok(())
    }
}

/// The test points of a virtual scan (planner-spec 5.2 steps 1–3).
#[derive(Clone, Debug, PartialEq)]
pub struct ScanPoints {
    /// Test points (m): the hits in beam order, then the free points.
    pub test: Vec<[f64; 2]>,
    /// Nearest lattice node of each test point (duplicates allowed); the training inputs are
    /// these nodes' positions.
    pub ids: Vec<usize>,
    /// Number of hits (the first entries of `test`).
    pub n_hits: usize,
}

/// Free points per beam of range `r` (m): N = min(⌈6.25 r⌉, 15), at least 1.
fn free_count(r: f64) -> usize {
    ((6.25 * r).ceil() as usize).clamp(1, 15)
}

fn scan_points(opts: &GpvrOptions, lat: &OccupancyLattice, pose: [f64; 3]) -> ScanPoints {
    let o = [pose[0], pose[1]];
    let hits: Vec<[f64; 2]> = opts
        .beam_angles
        .angles(opts.n_beams, pose[2])
        .into_iter()
        .filter_map(|a| march_beam(lat, o, a, opts.z_max, opts.p_occ).hit)
        .collect();
    let mut test = hits.clone();
    match opts.free_points {
        FreePoints::WorldOrigin => {
            let n_of = |h: &[f64; 2]| free_count(h[0].hypot(h[1]));
            test.extend(hits.iter().map(|h| {
                let n = n_of(h) as f64;
                [h[0] / n, h[1] / n]
            }));
            let n_last = hits.last().map_or(0, n_of);
            for m in 2..n_last {
                let (f, n) = (m as f64, n_last as f64);
                test.extend(hits.iter().map(|h| [h[0] * f / n, h[1] * f / n]));
            }
        }
        FreePoints::Robot => {
            for h in &hits {
                let (dx, dy) = (h[0] - o[0], h[1] - o[1]);
                let n = free_count(dx.hypot(dy));
                test.extend((1..n).map(|k| {
                    let f = k as f64 / n as f64;
                    [o[0] + f * dx, o[1] + f * dy]
                }));
            }
        }
    }
    let ids = test.iter().map(|p| lat.nearest(p[0], p[1])).collect();
    ScanPoints {
        test,
        ids,
        n_hits: hits.len(),
    }
}

/// Gain (nats) and update of one virtual scan. Fused test points are applied sequentially in
/// order (a node seen twice is fused twice); the gain is Σ ln Var_old − Σ ln Var_new over every
/// test id with multiplicity, as the reference does (unfused ids contribute only if a fused
/// point shares their node).
fn evaluate_scan(
    opts: &GpvrOptions,
    map: &GpVarianceMap,
    pose: [f64; 3],
    expected: Option<&ExpectedKernel>,
) -> Result<(f64, Vec<(usize, f64)>)> {
    check_pose(pose)?;
    let scan = scan_points(opts, &map.lattice, pose);
    if scan.n_hits == 0 {
        return Ok((0.0, Vec::new()));
    }
    let n_fused = match opts.fusion {
        Fusion::HitsOnly => scan.n_hits,
        Fusion::AllPoints => scan.test.len(),
    };
    let train: Vec<[f64; 2]> = scan
        .ids
        .iter()
        .map(|&id| map.lattice.node_position(id))
        .collect();
    let k = opts.hyper.eval();
    let test = &scan.test;
    let s2 = match expected {
        None => posterior_prefix(&opts.hyper, &train, 1.0, n_fused, |i, j| {
            k.at(train[i], test[j])
        })?,
        Some(e) => posterior_prefix(&opts.hyper, &train, e.train_scale, n_fused, |i, j| {
            e.eval_with(&k, train[i], test[j])
        })?,
    };
    // (id, Var before the scan, Var after the fusions so far)
    let mut touched: Vec<(usize, f64, f64)> = Vec::new();
    for (&id, &s) in scan.ids.iter().zip(&s2) {
        let slot = match touched.iter().position(|t| t.0 == id) {
            Some(p) => p,
            None => {
                touched.push((id, map.var[id], map.var[id]));
                touched.len() - 1
            }
        };
        touched[slot].2 = bcm_fuse(touched[slot].2, s);
    }
    let gain = touched
        .iter()
        .map(|&(id, old, new)| {
            let mult = scan.ids.iter().filter(|&&x| x == id).count();
            mult as f64 * (old / new).ln()
        })
        .sum();
    let update = touched
        .into_iter()
        .filter(|t| t.2 != t.1)
        .map(|t| (t.0, t.2))
        .collect();
    Ok((gain, update))
}

/// GPVR (planner-spec 5.2): map-only, gain in nats.
#[derive(Clone, Debug, PartialEq)]
pub struct Gpvr {
    opts: GpvrOptions,
}

impl Gpvr {
    /// Validated constructor.
    pub fn new(opts: GpvrOptions) -> Result<Self> {
        opts.validate()?;
        Ok(Self { opts })
    }

    /// The reference preset (figure parity).
    pub fn reference() -> Self {
        Self {
            opts: GpvrOptions::preset(Mode::Reference),
        }
    }

    /// The clean preset.
    pub fn clean() -> Self {
        Self {
            opts: GpvrOptions::preset(Mode::Clean),
        }
    }

    /// The options in use.
    pub fn options(&self) -> &GpvrOptions {
        &self.opts
    }

    /// The test points and node ids of the virtual scan at `pose` (diagnostics).
    pub fn scan_points(&self, map: &GpVarianceMap, pose: [f64; 3]) -> Result<ScanPoints> {
        check_pose(pose)?;
        Ok(scan_points(&self.opts, &map.lattice, pose))
    }
}

impl InformationFunction for Gpvr {
    type Map = GpVarianceMap;
    type Belief = ();
    /// (node id, new Var) pairs.
    type Update = Vec<(usize, f64)>;

    fn name(&self) -> &'static str {
        "gpvr"
    }

    fn units(&self) -> InfoUnits {
        InfoUnits::Nats
    }

    fn evaluate(
        &self,
        map: &GpVarianceMap,
        _parent: &(),
        candidate: &Candidate,
        _seed: u64,
    ) -> Result<Evaluation<(), Vec<(usize, f64)>>> {
        let (gain, update) = evaluate_scan(&self.opts, map, candidate.pose, None)?;
        Ok(Evaluation {
            gain,
            belief: (),
            update,
        })
    }

    fn commit(&self, map: &mut GpVarianceMap, update: &Vec<(usize, f64)>) -> Result<()> {
        map.apply(update)
    }
}

/// Options of UGPVR: GPVR's plus the expected kernel and the pose propagation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UgpvrOptions {
    /// Everything GPVR has.
    pub gp: GpvrOptions,
    /// Expected-kernel mode.
    pub kernel: UgpvrKernel,
    /// θ-coupling of the edge propagation (planner-spec 3.9).
    pub jacobian: PoseJacobian,
    /// Per-edge motion noise Q.
    pub noise: EdgeNoise,
}

impl Default for UgpvrOptions {
    fn default() -> Self {
        Self::preset(Mode::Reference)
    }
}

impl UgpvrOptions {
    /// GPVR's preset plus `reference_half`/`reference` or `expected`/`unicycle`, default noise.
    pub fn preset(mode: Mode) -> Self {
        let reference = mode == Mode::Reference;
        Self {
            gp: GpvrOptions::preset(mode),
            kernel: [UgpvrKernel::Expected, UgpvrKernel::ReferenceHalf][reference as usize],
            jacobian: [PoseJacobian::Unicycle, PoseJacobian::Reference][reference as usize],
            noise: EdgeNoise::default(),
        }
    }
}

/// UGPVR (planner-spec 5.3): GPVR with the expected kernel over the candidate's position
/// covariance. The belief is the pose covariance (m², m², rad²).
#[derive(Clone, Debug, PartialEq)]
pub struct Ugpvr {
    opts: UgpvrOptions,
}

impl Ugpvr {
    /// Validated constructor.
    pub fn new(opts: UgpvrOptions) -> Result<Self> {
        opts.gp.validate()?;
        Ok(Self { opts })
    }

    /// The reference preset (figure parity).
    pub fn reference() -> Self {
        Self {
            opts: UgpvrOptions::preset(Mode::Reference),
        }
    }

    /// The clean preset.
    pub fn clean() -> Self {
        Self {
            opts: UgpvrOptions::preset(Mode::Clean),
        }
    }

    /// The options in use.
    pub fn options(&self) -> &UgpvrOptions {
        &self.opts
    }

    /// The candidate's covariance: the parent's propagated along parent → candidate
    /// (planner-spec 3.9). A zero-length edge (`Candidate::at`, e.g. the root) propagates
    /// nothing and returns the parent's covariance as is.
    pub fn propagate(&self, parent: &Cov3, candidate: &Candidate) -> Cov3 {
        let to = [candidate.pose[0], candidate.pose[1]];
        if to == candidate.parent {
            return *parent;
        }
        propagate_covariance(
            parent,
            candidate.parent,
            to,
            &self.opts.noise,
            self.opts.jacobian,
        )
    }
}

impl InformationFunction for Ugpvr {
    type Map = GpVarianceMap;
    type Belief = Cov3;
    /// (node id, new Var) pairs.
    type Update = Vec<(usize, f64)>;

    fn name(&self) -> &'static str {
        "ugpvr"
    }

    fn units(&self) -> InfoUnits {
        InfoUnits::Nats
    }

    fn evaluate(
        &self,
        map: &GpVarianceMap,
        parent: &Cov3,
        candidate: &Candidate,
        _seed: u64,
    ) -> Result<Evaluation<Cov3, Vec<(usize, f64)>>> {
        check_covariance("pose_covariance", parent)?;
        check_pose(candidate.pose)?;
        check_pose([candidate.parent[0], candidate.parent[1], 0.0])?;
        let sigma = self.propagate(parent, candidate);
        let expected = ExpectedKernel::new(self.opts.kernel, xy_block(&sigma))?;
        let (gain, update) = evaluate_scan(&self.opts.gp, map, candidate.pose, expected.as_ref())?;
        Ok(Evaluation {
            gain,
            belief: sigma,
            update,
        })
    }

    fn commit(&self, map: &mut GpVarianceMap, update: &Vec<(usize, f64)>) -> Result<()> {
        map.apply(update)
    }
}
