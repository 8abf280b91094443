//! UCRMI at a candidate node (crm-spec 6.3–6.4): the CRMI of the candidate's virtual scan mixed
//! with the pose information the scan brings to a particle set propagated along the edge.
//!
//! Node state is a [`ParticleBelief`]. Evaluating the edge parent → candidate:
//! 1. propagates every parent particle along the edge (per-edge noise Q, [`EdgeTransition`]);
//! 2. casts the virtual scan from the particles' weighted mean against the map mean (first cell
//!    above the hit threshold, else a no-return);
//! 3. weighs each particle by the scan's predictive log-likelihood under the shared CRM
//!    (`weight_model`), evaluated at the particle's own pose;
//! 4. estimates the new pose entropy with the corrected Boers estimator (crm-spec 6.2);
//! 5. I_p = H_parent − H_new (bits, not clipped), I_m = CRMI at the candidate (bits),
//!    ΔI = α I_m + (1 − α) I_p;
//! 6. resamples (systematic) when N_eff < n/2 and stores the set and H_new as the node's belief.
//!
//! The map update on commit is the same virtual scan, applied at the particle mean with the
//! CRMI mapping model (crm-spec 6.4 step 9).

use rayon::prelude::*;

use crate::crm::CrmMap;
use crate::error::{config_err, Result};
use crate::info::crmi::{
    commit_virtual_scan, virtual_scan, Crmi, CrmiConfig, CrmiScratch, VirtualScan,
};
use crate::info::entropy::{
    edge_particle_entropy, pose_information_gain, root_entropy, sample_root_particles, ucrmi_mix,
    EdgeMotionNoise, EdgeTransition, ROOT_COV_DIAG, UCRMI_ALPHA,
};
use crate::info::shared_likelihood::SharedMapLikelihood;
use crate::info::{Candidate, Evaluation, InfoUnits, InformationFunction};
use crate::rbpf::common::weighted_mean_pose;
use crate::resample::{effective_sample_size, normalize_log_weights, systematic_resample};
use crate::rng::Rng;
use crate::sensor::{SensorModel, SensorModelKind};

/// A node's pose belief: particles with normalised log-weights and the set's entropy.
#[derive(Clone, Debug, PartialEq)]
pub struct ParticleBelief {
    /// (x, y, θ) per particle (m, m, rad).
    pub particles: Vec<[f64; 3]>,
    /// Normalised log-weights.
    pub log_weights: Vec<f64>,
    /// Differential entropy of the set (nats; may be negative).
    pub entropy_nats: f64,
    /// The map and pose gains (bits) of the evaluation that produced this belief (0 at a root).
    pub map_gain_bits: f64,
    pub pose_gain_bits: f64,
    /// Whether that evaluation resampled.
    pub resampled: bool,
}

impl ParticleBelief {
    /// Normalised weights.
    pub fn weights(&self) -> Vec<f64> {
        normalize_log_weights(&self.log_weights)
    }

    /// Weighted mean pose (circular mean heading).
    pub fn mean_pose(&self) -> [f64; 3] {
        weighted_mean_pose(&self.particles, &self.weights())
    }
}

/// Settings of UCRMI.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UcrmiConfig {
    /// The CRMI half (its `model` is the mapping model; its beams are the virtual scan's).
    pub crmi: CrmiConfig,
    /// α in I_c = α I_m + (1 − α) I_p (0.5 in the paper).
    pub alpha: f64,
    /// Particles per node (100).
    pub n_particles: usize,
    /// Per-edge motion noise Q.
    pub noise: EdgeMotionNoise,
    /// Root covariance diagonal Σ_0 (m², m², rad²).
    pub root_cov_diag: [f64; 3],
    /// The model of the particles' scan likelihoods (the RBPF weight model, `mixture`).
    pub weight_model: SensorModel,
    /// Resample when N_eff < this fraction of the particle count.
    pub resample_threshold: f64,
}

impl UcrmiConfig {
    /// The spec's defaults for a sensor range `z_max` (m) and grid resolution (m).
    pub fn new(z_max: f64, resolution: f64) -> Self {
        Self {
            crmi: CrmiConfig::new(z_max, resolution),
            alpha: UCRMI_ALPHA,
            n_particles: 100,
            noise: EdgeMotionNoise::default(),
            root_cov_diag: ROOT_COV_DIAG,
            weight_model: SensorModel::with_defaults(SensorModelKind::Mixture, z_max, resolution),
            resample_threshold: 0.5,
        }
    }

    pub fn validate(&self) -> Result<()> {
        self.crmi.validate()?;
        self.noise.validate()?;
        self.weight_model.validate()?;
        if !(0.0..=1.0).contains(&self.alpha) {
            return Err(config_err(
                "alpha",
                format!("must be in [0, 1], got {}", self.alpha),
            ));
        }
        if self.n_particles == 0 {
            return Err(config_err("n_particles", "must be >= 1"));
        }
        crate::limits::check_particles("UCRMI n_particles", self.n_particles)?;
        if !(0.0..=1.0).contains(&self.resample_threshold) {
            return Err(config_err(
                "resample_threshold",
                format!("must be in [0, 1], got {}", self.resample_threshold),
            ));
        }
        root_entropy(self.root_cov_diag).map(|_| ())
    }
}

/// UCRMI of candidates on a shared [`CrmMap`], with particle sets as node beliefs.
#[derive(Clone, Debug)]
pub struct Ucrmi {
    cfg: UcrmiConfig,
    crmi: Crmi,
}

impl Ucrmi {
    pub fn new(cfg: UcrmiConfig) -> Result<Self> {
        cfg.validate()?;
        let mut crmi_cfg = cfg.crmi;
        crmi_cfg.units = InfoUnits::Bits;
        Ok(Self {
            cfg,
            crmi: Crmi::new(crmi_cfg)?,
        })
    }

    pub fn config(&self) -> &UcrmiConfig {
        &self.cfg
    }

    /// The root belief: `n_particles` draws from N(pose, diag(Σ_0)) with equal weights and the
    /// Gaussian entropy ½ ln((2πe)³|Σ_0|) (crm-spec 6.4 Root).
    pub fn root_belief(&self, pose: [f64; 3], seed: u64) -> Result<ParticleBelief> {
        let n = self.cfg.n_particles;
        let mut rng = Rng::stream(seed, 0, 0);
        let particles = sample_root_particles(pose, self.cfg.root_cov_diag, n, &mut rng)?;
        Ok(ParticleBelief {
            particles,
            log_weights: vec![-(n as f64).ln(); n],
            entropy_nats: root_entropy(self.cfg.root_cov_diag)?,
            map_gain_bits: 0.0,
            pose_gain_bits: 0.0,
            resampled: false,
        })
    }

    /// Gains of candidates that each start from their own root belief at their own pose (a
    /// surface: "how much would a robot that is here, with the root uncertainty, gain"), in
    /// parallel; candidate i uses the seed `candidate_seed(seed, i)` for both its root and its
    /// evaluation, so the result equals the serial loop.
    pub fn gains_from_roots(
        &self,
        map: &CrmMap,
        candidates: &[Candidate],
        seed: u64,
    ) -> Result<Vec<f64>> {
        candidates
            .par_iter()
            .enumerate()
            .map(|(i, c)| {
                let s = crate::info::candidate_seed(seed, i as u64);
                let root = self.root_belief(c.pose, s)?;
                self.evaluate(map, &root, c, s).map(|e| e.gain)
            })
            .collect()
    }

    /// Virtual-scan log-likelihood of each child under the shared map.
    fn child_log_likelihoods(
        &self,
        map: &CrmMap,
        children: &[[f64; 3]],
        scan: &VirtualScan,
        mean_heading: f64,
    ) -> Result<Vec<f64>> {
        // The scan's beams are fixed in the robot frame of the mean pose; each particle sees them
        // rotated by its own heading.
        let rel: Vec<f64> = scan
            .angles
            .iter()
            .map(|a| a + scan.pose[2] - mean_heading)
            .collect();
        // One window of cell means serves every particle's beams.
        let res = map.geometry().resolution;
        let visits = (children.len() * rel.len()) as f64 * (self.cfg.weight_model.z_max / res);
        let shared = SharedMapLikelihood::new(map, &self.cfg.weight_model, children, visits)?;
        // Particles are independent (no random draws here), so the parallel map equals the
        // serial one whatever the thread count.
        shared.scan_log_likelihoods(children, &rel, &scan.ranges)
    }
}

impl InformationFunction for Ucrmi {
    type Map = CrmMap;
    type Belief = ParticleBelief;
    type Update = VirtualScan;

    fn name(&self) -> &'static str {
        "ucrmi"
    }

    fn units(&self) -> InfoUnits {
        InfoUnits::Bits
    }

    fn evaluate(
        &self,
        map: &CrmMap,
        parent: &ParticleBelief,
        candidate: &Candidate,
        seed: u64,
    ) -> Result<Evaluation<ParticleBelief, VirtualScan>> {
        map.check_ray_reach(self.cfg.crmi.model.z_max.max(self.cfg.weight_model.z_max))?;
        let n = parent.particles.len();
        if n == 0 || parent.log_weights.len() != n {
            return Err(crate::error::CrlamError::Shape(format!(
                "parent belief has {n} particles and {} weights",
                parent.log_weights.len()
            )));
        }
        let to = [candidate.pose[0], candidate.pose[1]];
        let edge = EdgeTransition::new(candidate.parent, to, self.cfg.noise, None)?;
        let mut rng = Rng::new(seed);
        let children: Vec<[f64; 3]> = parent
            .particles
            .iter()
            .map(|&p| edge.sample(p, &mut rng))
            .collect();
        let w_parent = normalize_log_weights(&parent.log_weights);
        let mean = weighted_mean_pose(&children, &w_parent);
        // The beams point as the candidate's (world frame), cast from the particle mean.
        let angles = self.crmi.beam_angles(candidate.pose);
        let scan_pose = [mean[0], mean[1], candidate.pose[2]];
        let scan = virtual_scan(
            map,
            scan_pose,
            &angles,
            self.cfg.crmi.model.z_max,
            self.cfg.crmi.hit_threshold,
        );
        let log_lik = self.child_log_likelihoods(map, &children, &scan, mean[2])?;
        let h_new = edge_particle_entropy(
            &parent.particles,
            &parent.log_weights,
            &children,
            &log_lik,
            &edge,
        )?;
        let i_p = pose_information_gain(parent.entropy_nats, h_new);
        let mut sc = CrmiScratch::default();
        let i_m = self.crmi.gain_with(map, candidate.pose, &mut sc)?;
        let gain = ucrmi_mix(i_m, i_p, self.cfg.alpha)?;
        // Posterior weights w_parent · e^ℓ; resample when degenerate.
        let log_w: Vec<f64> = parent
            .log_weights
            .iter()
            .zip(&log_lik)
            .map(|(a, b)| a + b)
            .collect();
        let w = normalize_log_weights(&log_w);
        let resampled = effective_sample_size(&w) < self.cfg.resample_threshold * n as f64;
        let (particles, log_weights) = if resampled {
            let idx = systematic_resample(&w, rng.uniform());
            (
                idx.iter().map(|&i| children[i]).collect(),
                vec![-(n as f64).ln(); n],
            )
        } else {
            (children, w.iter().map(|x| x.ln()).collect())
        };
        Ok(Evaluation {
            gain,
            belief: ParticleBelief {
                particles,
                log_weights,
                entropy_nats: h_new,
                map_gain_bits: i_m,
                pose_gain_bits: i_p,
                resampled,
            },
            update: scan,
        })
    }

    fn commit(&self, map: &mut CrmMap, update: &VirtualScan) -> Result<()> {
        commit_virtual_scan(map, update, &self.cfg.crmi.model)
    }
}
