//! Monte Carlo localization on a fixed confidence-rich map (Thrun, Burgard, Fox, *Probabilistic
//! Robotics*, Table 8.3, with KLD sampling, Fox 2003): AMCL's algorithm with the CRM predictive
//! likelihood as the measurement model.
//!
//! Per processed scan: move every particle by a draw of the odometry motion model, multiply its
//! weight by the scan's likelihood (tempered: Σ log η / τ), form the clusters of the weighted set
//! and report the heaviest one's mean; then, when N_eff falls below the threshold or recovery
//! asks for random particles, draw a new set by KLD sampling: particles are drawn one by one,
//! multinomially from the weights or, with probability p = max(0, 1 − w_fast / w_slow), uniformly
//! over the map's free space, until the particles drawn from the weights reach Fox's bound for the
//! number of histogram bins they occupy (within [n_min, n_max]), or the set reaches n_max. The
//! random particles come on top of the bound, a share p of the set: AMCL counts their bins too,
//! and then a dip of the fit to a few percent of random particles, each in a bin of its own, sends
//! a tracking filter to n_max.
//!
//! Recovery (Augmented MCL): w_slow and w_fast follow a measure of how well the scans fit the map
//! with rates α_slow < α_fast, and the random share is max(0, 1 − w_fast / w_slow). AMCL's measure
//! is the mean likelihood of the scan over the particles; with the CRM likelihood that mean is
//! ruled by the scene (a beam to a near wall has a likelihood many times that of a beam to a far
//! one, the reach through free cells decaying with distance), so moving from a corridor into a
//! hall reads as a lost robot. The measure here is the share of the scan the map explains: per
//! beam the posterior probability that a cell the map holds occupied (not the mixture's noise
//! terms, nor a cell of unknown occupancy, which would explain any reading) returned it
//! ([`super::likelihood::BeamEta::explained`]), averaged over the beams and over the particles
//! with their posterior weights. It is near its usual level wherever the robot is placed right,
//! and falls when the scans stop fitting (a kidnapping, a wrong convergence). Both averages start
//! at the first scan's value (AMCL starts them at 0, which delays any recovery until w_slow has
//! grown over ~1/α_slow scans).
//!
//! Determinism: particle j's motion draw at processed scan k comes from
//! `Rng::stream(seed, 3k, j)`, the i-th draw of the resampling from `Rng::stream(seed, 3k + 1, i)`
//! and the initial particles from `Rng::stream(seed, 0, j)`; weights are computed per particle
//! and combined in index order, so the results do not depend on the number of threads.

use std::collections::HashMap;
use std::sync::Arc;

use rayon::prelude::*;

use crate::error::{config_err, Result};
use crate::mcl::climb::{endpoints, ClimbSettings, EndpointField};
use crate::mcl::cluster::{clusters, clusters_with_labels, Cluster};
use crate::mcl::field::MeanField;
use crate::mcl::kld::{BinCounter, KldSettings};
use crate::mcl::likelihood::{scan_log_likelihood, select_beams, LikelihoodSettings, ScanFit};
use crate::motion::MotionModel;
use crate::pose::{between, compose, covariance_factor, draw_pose, wrap, Pose};
use crate::rbpf::{OdometryTracker, ScanInput, UpdateTrigger};
use crate::resample::{effective_sample_size, normalize_log_weights};
use crate::rng::Rng;
use crate::sensor::SensorModel;

/// Settings of the localizer.
#[derive(Clone, Debug, PartialEq)]
pub struct MclConfig {
    pub likelihood: LikelihoodSettings,
    pub motion: MotionModel,
    pub trigger: UpdateTrigger,
    /// The trigger while the set is spread (its spread, as for the annealing of the hit term,
    /// above `spread_limit`): scans of nearly the same view are not independent evidence, and a
    /// spread set that weighs each of them as such collapses onto whichever place fits best by
    /// chance. AMCL processes every scan this way (update_min_d 0.25 m, update_min_a 0.2 rad).
    pub spread_trigger: UpdateTrigger,
    /// Spread (m) above which the set counts as spread.
    pub spread_limit: f64,
    pub kld: KldSettings,
    /// Rate of the long-term average of the fit (AMCL's `recovery_alpha_slow`); 0 with
    /// `alpha_fast` 0 turns recovery off.
    pub alpha_slow: f64,
    /// Rate of the short-term average (`recovery_alpha_fast`), above `alpha_slow`.
    pub alpha_fast: f64,
    /// Weight tempering τ: a scan multiplies the weights by exp(Σ log η / τ).
    pub tempering: f64,
    /// Annealing of the hit term: a scan is weighed with σ_hit = clamp(`anneal` · s, σ, `sigma_max`)
    /// where σ is the model's and s the spread of the weighted set at the last scan: of its
    /// heaviest cluster when that holds at least half the weight, else of the whole set (the RMS
    /// distance of the particles from their mean position plus 1 m times their circular heading
    /// spread in radians; a set split in several places has the spread of all). A few random
    /// particles of recovery that gain some weight do not widen it. Particles spread over metres
    /// (a global start) are weighed with a wide hit term, which a particle decimetres from the
    /// true pose still fits; once they gather, σ returns to the model's. `sigma_max` ≤ σ turns
    /// it off.
    pub sigma_max: f64,
    pub anneal: f64,
    /// Smallest share of the effective sample size a scan may leave while the set is spread (see
    /// `spread_limit`): when the weights at τ would bring N_eff below `min_neff` times its value
    /// before the scan (the particle count right after resampling), the scan is tempered more (τ
    /// raised until they do not). A gathered set keeps τ. 0 turns this off.
    pub min_neff: f64,
    /// Every n-th beam of a scan.
    pub beam_stride: usize,
    /// At most this many of those, spread evenly (0: all).
    pub max_beams: usize,
    /// Resample when N_eff < threshold · n (1: at every processed scan) or when recovery injects.
    pub resample_threshold: f64,
    /// Smallest particle count of a competing hypothesis: when, at a resampling, more than one
    /// cluster holds at least `keep_ratio` times the heaviest cluster's weight, each of those
    /// keeps at least `min_cluster` particles (extra draws from within it, as long as the set is
    /// below `n_max`) and the particles of every cluster share its weight (each gets the
    /// cluster's weight over its count), so the clusters' weights pass through the resampling
    /// unchanged. A hypothesis the scans have not yet ruled out is then neither lost to the
    /// random draw nor decided by it, and the second-heaviest cluster's weight stays a measure
    /// of the evidence against it (the convergence rule's odds). With one such cluster the
    /// resampling is AMCL's (equal weights), and so it is while recovery injects random
    /// particles (they come and go; a place they find competes once it holds on without them).
    /// 0 turns this off.
    pub min_cluster: usize,
    /// See `min_cluster`: the weight, relative to the heaviest cluster's, down to which a
    /// cluster counts as a competing hypothesis (in (0, 1]).
    pub keep_ratio: f64,
    /// Smallest particle count of a pose bin (the KLD histogram's boxes) while the set is spread
    /// (above `spread_limit`): at a resampling without random particles, every bin holding at
    /// least `keep_ratio` times the heaviest bin's weight first gets `min_bin` draws from within
    /// it (heaviest bins first, up to `n_max`), then KLD sampling draws the rest, and the
    /// particles of every bin share its weight, so the bins' weights pass through the
    /// resampling unchanged. While the set is spread a cluster is a whole corridor or room (its
    /// bins touch), and the `min_cluster` floor cannot keep a place inside it; this floor keeps
    /// the few particles near each place the scans have not yet ruled out. 0 turns this off.
    pub min_bin: usize,
    /// Size (m) of a place while the set is spread: when it is above 0 (and `min_cluster` is on,
    /// `min_bin` off), a resampling of a spread set without random particles keeps the
    /// `min_cluster` floor per place instead of per cluster. A place is a cell of `place_xy` ×
    /// `place_xy` metres and `place_theta` radians of the pose space (a fixed grid); every place
    /// holding at least `keep_ratio` times the heaviest place's weight first gets `min_cluster`
    /// draws from within it by weight (heaviest places first, up to `n_max`), then KLD sampling
    /// draws the rest, and the particles of every place share its weight, so the places' weights
    /// pass through the resampling unchanged. While the set is spread AMCL's clusters join whole
    /// rooms and corridors (their bins touch), so a floor per cluster cannot keep a place inside
    /// one; a place of bounded size keeps the best particles near each pose the scans have not
    /// yet ruled out. Once one cluster remains, the floor is per cluster again. 0: off.
    pub place_xy: f64,
    /// Heading extent (rad) of a place (see `place_xy`); sectors count from −π.
    pub place_theta: f64,
    /// Largest particle count while the set is spread (above `spread_limit`) and recovery does
    /// not inject: a global start draws this many, and KLD sampling may keep up to this many
    /// until the set gathers (then `kld.n_max` again). A set spread over a building asks KLD for
    /// far more than AMCL's 5,000 (one per occupied bin and more); with too few, a place has no
    /// particle near enough to its true pose to win. 0: `kld.n_max` throughout.
    pub spread_max: usize,
    /// The scan-matched proposal while the set is spread (above `spread_limit`): after its
    /// motion draw, each particle climbs to the nearby pose where the scan's endpoints fit the
    /// map best, and is weighed there ([`super::climb`]). The climb starts with steps of half
    /// a KLD bin (the spacing of a spread set) and halves them until the step along x and y is
    /// at most the map's cell. A gathered set moves by the motion model alone.
    pub spread_climb: bool,
    pub seed: u64,
}

impl MclConfig {
    pub fn validate(&self) -> Result<()> {
        self.likelihood.validate()?;
        self.motion.validate()?;
        self.trigger.validate()?;
        self.spread_trigger.validate()?;
        if !(self.spread_limit.is_finite() && self.spread_limit >= 0.0) {
            return Err(config_err("spread_limit", "must be finite and >= 0"));
        }
        self.kld.validate()?;
        let unit = |v: f64| v.is_finite() && (0.0..=1.0).contains(&v);
        if !(unit(self.alpha_slow) && unit(self.alpha_fast)) {
            return Err(config_err(
                "recovery_alpha",
                "alpha_slow and alpha_fast must be in [0, 1]",
            ));
        }
        if self.alpha_slow > 0.0 && self.alpha_fast <= self.alpha_slow {
            return Err(config_err(
                "recovery_alpha",
                format!(
                    "alpha_fast ({}) must exceed alpha_slow ({})",
                    self.alpha_fast, self.alpha_slow
                ),
            ));
        }
        if !(self.tempering.is_finite() && self.tempering > 0.0) {
            return Err(config_err(
                "tempering",
                format!("must be > 0, got {}", self.tempering),
            ));
        }
        if self.beam_stride == 0 {
            return Err(config_err("beam_stride", "must be >= 1"));
        }
        if !(self.sigma_max.is_finite()
            && self.sigma_max >= 0.0
            && self.anneal.is_finite()
            && self.anneal >= 0.0)
        {
            return Err(config_err(
                "sigma_max",
                "sigma_max and anneal must be finite and >= 0",
            ));
        }
        if !(self.min_neff.is_finite() && (0.0..1.0).contains(&self.min_neff)) {
            return Err(config_err(
                "min_neff",
                format!("must be in [0, 1), got {}", self.min_neff),
            ));
        }
        if !unit(self.resample_threshold) {
            return Err(config_err("resample_threshold", "must be in [0, 1]"));
        }
        if self.spread_max > 10_000_000 {
            return Err(config_err(
                "spread_max",
                format!("must be at most 10,000,000, got {}", self.spread_max),
            ));
        }
        if !(self.place_xy.is_finite() && self.place_xy >= 0.0) {
            return Err(config_err(
                "place_xy",
                format!("must be finite and >= 0 (0: off), got {}", self.place_xy),
            ));
        }
        if self.place_xy > 0.0 && !(self.place_theta.is_finite() && self.place_theta > 0.0) {
            return Err(config_err(
                "place_theta",
                format!("must be finite and > 0, got {}", self.place_theta),
            ));
        }
        if !(self.keep_ratio.is_finite() && self.keep_ratio > 0.0 && self.keep_ratio <= 1.0) {
            return Err(config_err(
                "keep_ratio",
                format!("must be in (0, 1], got {}", self.keep_ratio),
            ));
        }
        Ok(())
    }

    /// True when recovery can inject particles.
    pub fn recovery(&self) -> bool {
        self.alpha_slow > 0.0
    }
}

/// How the particles start.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum MclInit {
    /// `n_max` particles drawn from N(mean, cov) (cov: 3 × 3, symmetric, positive semidefinite;
    /// m², m·rad, rad²).
    Pose { mean: Pose, cov: [[f64; 3]; 3] },
    /// `n_max` particles uniformly over the map's free space, uniform headings.
    Global,
}

/// What one call of [`Mcl::process`] did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MclStep {
    /// Whether the scan was processed (the update trigger fired) or only carried by odometry.
    pub processed: bool,
    /// The heaviest cluster's mean (processed scans), else the last one composed with the
    /// odometry since.
    pub estimate: Pose,
    /// Particles weighed at this scan (before resampling).
    pub n_particles: usize,
    /// Particles after this scan (after resampling, if any).
    pub n_after: usize,
    /// Effective sample size of the weights (before resampling); NaN when not processed.
    pub neff: f64,
    pub resampled: bool,
    /// Particles drawn from the free space by recovery.
    pub n_injected: usize,
    /// max(0, 1 − w_fast / w_slow) at this scan.
    pub inject_probability: f64,
    /// The scan's fit: the share the map explains (see the module documentation), in [0, 1];
    /// NaN when no beam was used.
    pub fit: f64,
    /// Beams the likelihood used.
    pub n_beams: usize,
    /// The tempering the scan was weighed with (τ, or more to keep N_eff at `min_neff`).
    pub tempering: f64,
    /// The σ_hit the scan was weighed with (see [`MclConfig::sigma_max`]).
    pub sigma_hit: f64,
    /// Spread of the weighted set (see [`MclConfig::sigma_max`]): m.
    pub set_spread: f64,
    /// The heaviest cluster of the weighted set, and how many clusters there were.
    pub cluster: Cluster,
    pub n_clusters: usize,
    /// The weight of the second-heaviest cluster (0 with one cluster).
    pub second_weight: f64,
    /// Clusters that kept at least `min_cluster` particles through this scan's resampling
    /// (0 when it did not resample or when only one cluster was competing); while a spread set
    /// is floored per place (`place_xy`) or per bin (`min_bin`), the places or bins floored.
    pub n_kept: usize,
}

/// The localizer: particles over a fixed map.
#[derive(Debug)]
pub struct Mcl {
    cfg: MclConfig,
    field: Arc<MeanField>,
    poses: Vec<Pose>,
    log_w: Vec<f64>,
    tracker: OdometryTracker,
    step: u64,
    started: bool,
    estimate: Pose,
    estimate_odom: Pose,
    /// (w_slow, w_fast) in the fit's linear units; `None` before the first fit.
    averages: Option<(f64, f64)>,
    beams: (usize, Vec<usize>),
    last: Option<MclStep>,
    /// The endpoint score of the climb (`spread_climb`), built at the first spread scan (a
    /// localizer that tracks from a known pose and never loses it does without).
    endpoint_field: Option<EndpointField>,
}

impl Mcl {
    /// A localizer on `field` with particles placed by `init`.
    pub fn new(cfg: MclConfig, field: Arc<MeanField>, init: MclInit) -> Result<Self> {
        cfg.validate()?;
        let mut m = Self {
            cfg,
            field,
            poses: Vec::new(),
            log_w: Vec::new(),
            tracker: OdometryTracker::default(),
            step: 0,
            started: false,
            estimate: [0.0; 3],
            estimate_odom: [0.0; 3],
            averages: None,
            beams: (usize::MAX, Vec::new()),
            last: None,
            endpoint_field: None,
        };
        m.reset(init)?;
        Ok(m)
    }

    /// Places the particles anew (uniform weights); the recovery averages restart. The odometry
    /// tracking goes on: the next scan is processed with the odometry since the last one.
    pub fn reset(&mut self, init: MclInit) -> Result<()> {
        let n = match init {
            MclInit::Global => self.cfg.kld.n_max.max(self.cfg.spread_max),
            MclInit::Pose { .. } => self.cfg.kld.n_max,
        };
        let seed = self.cfg.seed;
        // A reset after some scans draws from streams of its own step.
        let stream_step = if self.step == 0 { 0 } else { 3 * self.step + 2 };
        self.poses = match init {
            MclInit::Pose { mean, cov } => {
                crate::grid::check_pose(mean)?;
                let l = covariance_factor(&cov)?;
                (0..n)
                    .map(|j| draw_pose(mean, &l, &mut Rng::stream(seed, stream_step, j as u64)))
                    .collect()
            }
            MclInit::Global => {
                if self.field.n_free() == 0 {
                    return Err(config_err(
                        "map",
                        format!(
                            "no free cell (m̂ <= {}) to place particles on",
                            self.field.free_threshold()
                        ),
                    ));
                }
                (0..n)
                    .map(|j| {
                        let mut rng = Rng::stream(seed, stream_step, j as u64);
                        // n_free > 0 was checked above.
                        self.field.sample_free(&mut rng).unwrap_or([0.0; 3])
                    })
                    .collect()
            }
        };
        self.log_w = vec![0.0; n];
        self.averages = None;
        let w = vec![1.0 / n as f64; n];
        self.estimate = clusters(&self.poses, &w, &self.cfg.kld)
            .first()
            .map(|c| c.mean)
            .unwrap_or([0.0; 3]);
        Ok(())
    }

    pub fn config(&self) -> &MclConfig {
        &self.cfg
    }

    pub fn field(&self) -> &MeanField {
        &self.field
    }

    pub fn poses(&self) -> &[Pose] {
        &self.poses
    }

    /// Normalised weights of the current particles.
    pub fn weights(&self) -> Vec<f64> {
        normalize_log_weights(&self.log_w)
    }

    pub fn estimate(&self) -> Pose {
        self.estimate
    }

    pub fn n_processed(&self) -> u64 {
        self.step
    }

    /// (w_slow, w_fast) of the recovery, once a scan has been weighed.
    pub fn averages(&self) -> Option<(f64, f64)> {
        self.averages
    }

    /// The last processed scan's summary.
    pub fn last_step(&self) -> Option<MclStep> {
        self.last
    }

    /// The clusters of the current set with its current weights, heaviest first.
    pub fn clusters(&self) -> Vec<Cluster> {
        clusters(&self.poses, &self.weights(), &self.cfg.kld)
    }

    /// Feeds one scan; processes it when the update trigger fires.
    pub fn process(&mut self, scan: &ScanInput) -> Result<MclStep> {
        scan.validate()?;
        let spread = self.spread();
        let trigger = if spread > self.cfg.spread_limit {
            self.cfg.spread_trigger
        } else {
            self.cfg.trigger
        };
        let (u, n_steps, fires) = self.tracker.observe(scan.odom, &trigger);
        let first = !self.started;
        self.started = true;
        if !fires {
            let carried = compose(self.estimate, between(self.estimate_odom, scan.odom));
            let n = self.poses.len();
            return Ok(MclStep {
                processed: false,
                estimate: carried,
                n_particles: n,
                n_after: n,
                neff: f64::NAN,
                resampled: false,
                n_injected: 0,
                inject_probability: 0.0,
                fit: f64::NAN,
                n_beams: 0,
                tempering: f64::NAN,
                sigma_hit: f64::NAN,
                set_spread: f64::NAN,
                cluster: self.last.map(|s| s.cluster).unwrap_or(Cluster {
                    weight: 1.0,
                    count: n,
                    mean: carried,
                    cov_xy: [0.0; 3],
                    std_theta: 0.0,
                }),
                n_clusters: self.last.map(|s| s.n_clusters).unwrap_or(1),
                second_weight: self.last.map(|s| s.second_weight).unwrap_or(0.0),
                n_kept: 0,
            });
        }
        self.step += 1;
        let step = self.step;
        let cfg = &self.cfg;
        if self.beams.0 != scan.angles.len() {
            self.beams = (
                scan.angles.len(),
                select_beams(scan.angles.len(), cfg.beam_stride, cfg.max_beams),
            );
        }
        let beams = &self.beams.1;
        let field = &*self.field;
        // The hit term of this scan, widened while the particles are spread.
        let base = cfg.likelihood.model.sigma_hit;
        let sigma_hit = (cfg.anneal * spread).min(cfg.sigma_max).max(base);
        let likelihood = LikelihoodSettings {
            model: SensorModel {
                sigma_hit,
                ..cfg.likelihood.model
            },
            ..cfg.likelihood
        };
        // The climb of a spread set, on the endpoint score at this scan's σ.
        if cfg.spread_climb && spread > cfg.spread_limit && self.endpoint_field.is_none() {
            self.endpoint_field = Some(EndpointField::new(field));
        }
        let climb = match self.endpoint_field.as_mut() {
            Some(e) if spread > cfg.spread_limit => {
                e.set_sigma(sigma_hit);
                let points = endpoints(
                    scan.angles,
                    scan.ranges,
                    beams,
                    likelihood.model.z_min,
                    likelihood.model.z_max,
                );
                Some((&*e, climb_settings(cfg, field), points))
            }
            _ => None,
        };
        // Move (not at the first scan: nothing moved yet), climb while spread and weigh,
        // particle by particle.
        let moved: Vec<Result<(Pose, ScanFit)>> = self
            .poses
            .par_iter()
            .enumerate()
            .map(|(j, &p)| {
                let pose = if first {
                    p
                } else {
                    let mut rng = Rng::stream(cfg.seed, 3 * step, j as u64);
                    cfg.motion.sample(p, u, n_steps, &mut rng)
                };
                let pose = match &climb {
                    Some((e, settings, points)) => {
                        e.climb(settings, pose, scan.laser_offset, points)
                    }
                    None => pose,
                };
                let sensor = compose(pose, scan.laser_offset);
                let fit = scan_log_likelihood(
                    field,
                    &likelihood,
                    sensor,
                    scan.angles,
                    scan.ranges,
                    beams,
                )?;
                Ok((pose, fit))
            })
            .collect();
        let moved = moved.into_iter().collect::<Result<Vec<_>>>()?;
        let n = moved.len();
        let n_beams = moved.first().map(|m| m.1.n_beams).unwrap_or(0);
        let ll: Vec<f64> = moved.iter().map(|m| m.1.log_likelihood).collect();
        // Only a spread set is tempered further: a gathered one keeps τ, so that the random
        // particles of recovery, which add nothing to N_eff, do not flatten its weights.
        let min_neff = if spread > cfg.spread_limit {
            cfg.min_neff
        } else {
            0.0
        };
        let tempering = adaptive_tempering(&self.log_w, &ll, cfg.tempering, min_neff);
        for (j, m) in moved.iter().enumerate() {
            self.poses[j] = m.0;
            self.log_w[j] += m.1.log_likelihood / tempering;
        }
        let w = normalize_log_weights(&self.log_w);
        // The share of the scan the map explains, over the posterior.
        let fit = if n_beams > 0 {
            w.iter()
                .zip(&moved)
                .map(|(w, m)| w * m.1.explained)
                .sum::<f64>()
                / n_beams as f64
        } else {
            f64::NAN
        };
        let inject_probability = self.update_averages(fit);
        let neff = effective_sample_size(&w);
        let (found, labels) = clusters_with_labels(&self.poses, &w, &self.cfg.kld);
        let cluster = found[0];
        let second_weight = found.get(1).map(|c| c.weight).unwrap_or(0.0);
        let weighed_spread = set_spread(&self.poses, &w);
        self.estimate = cluster.mean;
        self.estimate_odom = scan.odom;
        self.tracker.processed(scan.odom);
        let resample = neff < self.cfg.resample_threshold * n as f64 || inject_probability > 0.0;
        let (n_injected, n_kept) = if resample {
            let spread_set = spread > self.cfg.spread_limit && inject_probability == 0.0;
            let kld = KldSettings {
                n_max: if spread_set {
                    self.cfg.kld.n_max.max(self.cfg.spread_max)
                } else {
                    self.cfg.kld.n_max
                },
                ..self.cfg.kld
            };
            if spread_set && self.cfg.min_bin > 0 {
                let keys: Vec<_> = self.poses.iter().map(|p| kld.bin_of(p)).collect();
                (0, self.resample_floored(&w, &kld, &keys, self.cfg.min_bin))
            } else if spread_set && self.cfg.min_cluster > 0 && self.cfg.place_xy > 0.0 {
                let keys: Vec<_> = self.poses.iter().map(|p| self.place_of(p)).collect();
                (
                    0,
                    self.resample_floored(&w, &kld, &keys, self.cfg.min_cluster),
                )
            } else {
                self.resample(&w, inject_probability, &found, &labels, &kld)
            }
        } else {
            // Keep the log-weights bounded (they are only relative).
            let mx = self.log_w.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            if mx.is_finite() {
                self.log_w.iter_mut().for_each(|l| *l -= mx);
            }
            (0, 0)
        };
        let out = MclStep {
            processed: true,
            estimate: self.estimate,
            n_particles: n,
            n_after: self.poses.len(),
            neff,
            resampled: resample,
            n_injected,
            inject_probability,
            fit,
            n_beams,
            tempering,
            sigma_hit,
            set_spread: weighed_spread,
            cluster,
            n_clusters: found.len(),
            second_weight,
            n_kept,
        };
        self.last = Some(out);
        Ok(out)
    }

    /// The spread of the set at the last scan: of its heaviest cluster when that holds at least
    /// half the weight and no other cluster competes with it (see `min_cluster`), else of the
    /// whole set (before the first scan: of the initial set). Several competing places make a
    /// spread set: its scans are weighed as such (the spread trigger, `min_neff`, the wide hit
    /// term) until one place remains.
    fn spread(&self) -> f64 {
        match self.last {
            Some(s) if s.cluster.weight >= 0.5 && !self.competing(&s) => {
                s.cluster.spread_xy() + s.cluster.std_theta
            }
            Some(s) => s.set_spread,
            None => {
                let n = self.poses.len();
                let w = vec![1.0 / n as f64; n];
                match clusters(&self.poses, &w, &self.cfg.kld).first() {
                    Some(c) if c.weight >= 0.5 => c.spread_xy() + c.std_theta,
                    _ => set_spread(&self.poses, &w),
                }
            }
        }
    }

    /// Whether, at the step `s`, a second cluster competed with the heaviest (`min_cluster` on,
    /// recovery not injecting, and the second's weight at least `keep_ratio` times the
    /// heaviest's).
    fn competing(&self, s: &MclStep) -> bool {
        self.cfg.min_cluster > 0
            && s.inject_probability == 0.0
            && s.second_weight >= self.cfg.keep_ratio * s.cluster.weight
    }

    /// Updates w_slow and w_fast with the scan's fit; returns the probability of a random particle.
    fn update_averages(&mut self, fit: f64) -> f64 {
        if !self.cfg.recovery() || !fit.is_finite() {
            return 0.0;
        }
        let (a_slow, a_fast) = (self.cfg.alpha_slow, self.cfg.alpha_fast);
        let (slow, fast) = match self.averages {
            None => (fit, fit),
            Some((s, f)) => (s + a_slow * (fit - s), f + a_fast * (fit - f)),
        };
        self.averages = Some((slow, fast));
        if slow > 0.0 {
            (1.0 - fast / slow).max(0.0)
        } else {
            0.0
        }
    }

    /// KLD sampling from the weights `w` with random particles at `inject` probability, then the
    /// floor of `min_cluster` particles for every competing cluster of `found` (`labels`: each
    /// particle's cluster); returns how many were injected and how many clusters were kept.
    fn resample(
        &mut self,
        w: &[f64],
        inject: f64,
        found: &[Cluster],
        labels: &[usize],
        kld: &KldSettings,
    ) -> (usize, usize) {
        let kld = *kld;
        let mut cumulative = Vec::with_capacity(w.len());
        let mut s = 0.0;
        for &x in w {
            s += x;
            cumulative.push(s);
        }
        let total = s;
        let draw_step = 3 * self.step + 1;
        let mut out = Vec::with_capacity(kld.n_min.max(self.poses.len()));
        // The particle each draw copied (None: a random one).
        let mut origin: Vec<Option<usize>> = Vec::with_capacity(out.capacity());
        let mut bins = BinCounter::default();
        let (mut injected, mut drawn) = (0, 0);
        while out.len() < kld.n_max {
            let mut rng = Rng::stream(self.cfg.seed, draw_step, out.len() as u64);
            let random = inject > 0.0 && rng.uniform() < inject;
            match random.then(|| self.field.sample_free(&mut rng)).flatten() {
                Some(p) => {
                    injected += 1;
                    out.push(p);
                    origin.push(None);
                }
                None => {
                    let u = rng.uniform() * total;
                    let i = cumulative.partition_point(|&c| c <= u).min(w.len() - 1);
                    let pose = self.poses[i];
                    drawn += 1;
                    let k = bins.add(&kld, &pose);
                    out.push(pose);
                    origin.push(Some(i));
                    if drawn >= kld.limit(k) {
                        break;
                    }
                }
            }
        }
        // While recovery injects, the set is AMCL's: its random particles come and go, and a
        // place they find competes once it holds on without them.
        let n_kept = if injected == 0 {
            self.keep_clusters(w, found, labels, &mut out, &mut origin, kld.n_max)
        } else {
            0
        };
        self.log_w = if n_kept > 1 {
            cluster_log_weights(&origin, found, labels, injected)
        } else {
            vec![0.0; out.len()]
        };
        self.poses = out;
        (injected, if n_kept > 1 { n_kept } else { 0 })
    }

    /// The place (see [`MclConfig::place_xy`]) of a pose: its cell of `place_xy` m and its
    /// heading sector of `place_theta` rad counted from −π (the last sector, possibly narrower,
    /// ends at π).
    fn place_of(&self, p: &Pose) -> (i64, i64, i64) {
        let (s, t) = (self.cfg.place_xy, self.cfg.place_theta);
        let n_t = ((2.0 * std::f64::consts::PI / t).ceil() as i64).max(1);
        (
            (p[0] / s).floor() as i64,
            (p[1] / s).floor() as i64,
            (((wrap(p[2]) + std::f64::consts::PI) / t).floor() as i64).clamp(0, n_t - 1),
        )
    }

    /// The resampling of a spread set with a floor per cell of the pose space (`keys[j]`:
    /// particle j's cell; the `min_bin` floor per pose bin, or the `min_cluster` floor per
    /// place): every cell holding at least `keep_ratio` times the heaviest cell's weight first
    /// gets `floor` draws from within it by weight (heaviest cells first, while they fit in
    /// `n_max`), then KLD sampling draws the rest up to its bound or `n_max`; every particle
    /// weighs its cell's weight over the cell's new count. Returns the number of floored cells.
    fn resample_floored(
        &mut self,
        w: &[f64],
        kld: &KldSettings,
        keys: &[(i64, i64, i64)],
        floor: usize,
    ) -> usize {
        let cfg = &self.cfg;
        let kld = *kld;
        let mut index: HashMap<(i64, i64, i64), usize> = HashMap::new();
        let mut members: Vec<Vec<usize>> = Vec::new();
        let mut bin_w: Vec<f64> = Vec::new();
        let mut label = Vec::with_capacity(w.len());
        for (j, key) in keys.iter().enumerate() {
            let n = index.len();
            let b = *index.entry(*key).or_insert(n);
            if b == members.len() {
                members.push(Vec::new());
                bin_w.push(0.0);
            }
            members[b].push(j);
            bin_w[b] += w[j];
            label.push(b);
        }
        let best = bin_w.iter().copied().fold(0.0, f64::max);
        // Bins by weight, heaviest first (ties by first member: never by hashing).
        let mut order: Vec<usize> = (0..bin_w.len())
            .filter(|&b| bin_w[b] > 0.0 && bin_w[b] >= cfg.keep_ratio * best)
            .collect();
        order.sort_by(|&a, &b| {
            bin_w[b]
                .total_cmp(&bin_w[a])
                .then(members[a][0].cmp(&members[b][0]))
        });
        let draw_step = 3 * self.step + 1;
        let mut out: Vec<Pose> = Vec::with_capacity(kld.n_max);
        let mut origin: Vec<usize> = Vec::with_capacity(kld.n_max);
        let mut counter = BinCounter::default();
        let mut stream = kld.n_max as u64;
        let mut floored = 0;
        for &b in &order {
            if out.len() + floor > kld.n_max {
                break;
            }
            floored += 1;
            for _ in 0..floor {
                let mut rng = Rng::stream(cfg.seed, draw_step, stream);
                stream += 1;
                let mut u = rng.uniform() * bin_w[b];
                let m = &members[b];
                let mut pick = m[m.len() - 1];
                for &j in m {
                    if u < w[j] {
                        pick = j;
                        break;
                    }
                    u -= w[j];
                }
                counter.add(&kld, &self.poses[pick]);
                out.push(self.poses[pick]);
                origin.push(pick);
            }
        }
        let mut cumulative = Vec::with_capacity(w.len());
        let mut s = 0.0;
        for &x in w {
            s += x;
            cumulative.push(s);
        }
        let mut k = 0u64;
        while out.len() < kld.n_max && out.len() < kld.limit(counter.len()) {
            let mut rng = Rng::stream(cfg.seed, draw_step, k);
            k += 1;
            let u = rng.uniform() * s;
            let i = cumulative.partition_point(|&c| c <= u).min(w.len() - 1);
            counter.add(&kld, &self.poses[i]);
            out.push(self.poses[i]);
            origin.push(i);
        }
        let mut count = vec![0usize; bin_w.len()];
        for &i in &origin {
            count[label[i]] += 1;
        }
        self.log_w = origin
            .iter()
            .map(|&i| {
                let b = label[i];
                (bin_w[b] / count[b] as f64).max(f64::MIN_POSITIVE).ln()
            })
            .collect();
        self.poses = out;
        floored
    }

    /// Tops up every competing cluster (weight at least `keep_ratio` times the heaviest's) to
    /// `min_cluster` particles with draws from within it by weight, while the set is below
    /// `n_max`; heaviest clusters first. Returns the number of competing clusters (0 when
    /// `min_cluster` is 0; nothing is drawn when there is one).
    fn keep_clusters(
        &self,
        w: &[f64],
        found: &[Cluster],
        labels: &[usize],
        out: &mut Vec<Pose>,
        origin: &mut Vec<Option<usize>>,
        n_max: usize,
    ) -> usize {
        let cfg = &self.cfg;
        let best = found.first().map(|c| c.weight).unwrap_or(0.0);
        let n_comp = found
            .iter()
            .take_while(|c| c.weight > 0.0 && c.weight >= cfg.keep_ratio * best)
            .count();
        if cfg.min_cluster == 0 {
            return 0;
        }
        if n_comp < 2 {
            return n_comp;
        }
        let mut count = vec![0usize; n_comp];
        for &i in origin.iter().flatten() {
            if let Some(c) = count.get_mut(labels[i]) {
                *c += 1;
            }
        }
        let mut members: Vec<Vec<usize>> = vec![Vec::new(); n_comp];
        for (j, &l) in labels.iter().enumerate() {
            if let Some(m) = members.get_mut(l) {
                m.push(j);
            }
        }
        // Streams of their own: the KLD loop uses indices below n_max.
        let draw_step = 3 * self.step + 1;
        let mut extra = n_max as u64;
        for (c, m) in members.iter().enumerate() {
            let total: f64 = m.iter().map(|&j| w[j]).sum();
            while count[c] < cfg.min_cluster && out.len() < n_max && total > 0.0 {
                let mut rng = Rng::stream(cfg.seed, draw_step, extra);
                extra += 1;
                let mut u = rng.uniform() * total;
                let mut pick = m[m.len() - 1];
                for &j in m {
                    if u < w[j] {
                        pick = j;
                        break;
                    }
                    u -= w[j];
                }
                out.push(self.poses[pick]);
                origin.push(Some(pick));
                count[c] += 1;
            }
        }
        n_comp
    }
}

/// The climb of a spread set: first steps of half a KLD bin, halved until the step along x and
/// y is at most the map's cell; at most 40 moves (240 evaluations of the score).
fn climb_settings(cfg: &MclConfig, field: &MeanField) -> ClimbSettings {
    let step_xy = 0.5 * cfg.kld.bin_xy;
    let cell = field.geometry().resolution;
    let mut refinements = 0;
    while refinements < 16 && step_xy / f64::from(1u32 << refinements) > cell {
        refinements += 1;
    }
    ClimbSettings {
        step_xy,
        step_theta: 0.5 * cfg.kld.bin_theta,
        refinements,
        max_moves: 40,
    }
}

/// Log-weights after a resampling that keeps every cluster's weight: each of the `injected`
/// random particles weighs 1/n as in AMCL's resampling (n: the new set's size), and the
/// particles copied from cluster c share its weight W_c, scaled to the rest of the mass:
/// (1 − injected / n) · W_c / (particles copied from c).
fn cluster_log_weights(
    origin: &[Option<usize>],
    found: &[Cluster],
    labels: &[usize],
    injected: usize,
) -> Vec<f64> {
    let mut count = vec![0usize; found.len()];
    for &i in origin.iter().flatten() {
        count[labels[i]] += 1;
    }
    let n = origin.len().max(1) as f64;
    let drawn_share = 1.0 - injected as f64 / n;
    origin
        .iter()
        .map(|o| match o {
            None => -n.ln(),
            Some(i) => {
                let c = labels[*i];
                (drawn_share * found[c].weight / count[c].max(1) as f64)
                    .max(f64::MIN_POSITIVE)
                    .ln()
            }
        })
        .collect()
}

/// The tempering of a scan: `base`, or, when the weights `prior + ll / base` would have an
/// effective sample size below `min_neff` times that of `prior`, the smallest τ > base (to
/// 0.1 %, by bisection on log τ; N_eff grows with τ towards the prior's) at which they have it.
fn adaptive_tempering(prior: &[f64], ll: &[f64], base: f64, min_neff: f64) -> f64 {
    let n = ll.len();
    if min_neff <= 0.0 || n == 0 {
        return base;
    }
    let target = min_neff * effective_sample_size(&normalize_log_weights(prior));
    let neff = |tau: f64| {
        let lw: Vec<f64> = prior.iter().zip(ll).map(|(p, l)| p + l / tau).collect();
        effective_sample_size(&normalize_log_weights(&lw))
    };
    if neff(base) >= target {
        return base;
    }
    let mut hi = base * 2.0;
    while neff(hi) < target {
        if hi > base * 1e12 {
            return hi;
        }
        hi *= 2.0;
    }
    let mut lo = hi / 2.0;
    while hi / lo > 1.001 {
        let mid = (lo * hi).sqrt();
        if neff(mid) >= target {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    hi
}

/// The weighted set's RMS distance from its mean position plus 1 m times its circular heading
/// spread sqrt(−2 ln R) (rad).
fn set_spread(poses: &[Pose], w: &[f64]) -> f64 {
    let (mut x, mut y, mut c, mut s) = (0.0, 0.0, 0.0, 0.0);
    for (p, &wi) in poses.iter().zip(w) {
        x += wi * p[0];
        y += wi * p[1];
        c += wi * p[2].cos();
        s += wi * p[2].sin();
    }
    let var: f64 = poses
        .iter()
        .zip(w)
        .map(|(p, &wi)| wi * ((p[0] - x).powi(2) + (p[1] - y).powi(2)))
        .sum();
    let r = c.hypot(s).clamp(1e-300, 1.0);
    var.max(0.0).sqrt() + (-2.0 * r.ln()).max(0.0).sqrt()
}

#[cfg(test)]
mod keep_tests {
    use super::*;
    use crate::grid::{CellRect, GridGeometry};
    use crate::mcl::kld::KldSettings;
    use crate::rbpf::UpdateTrigger;
    use crate::sensor::SensorModelKind;

    fn filter(min_cluster: usize) -> Mcl {
        let g = GridGeometry::new([0.0, 0.0], 0.1).unwrap();
        let rect = CellRect {
            ix0: 0,
            iy0: 0,
            nx: 100,
            ny: 100,
        };
        let field = MeanField::from_means(g, rect, vec![0.05; 10_000], 0.5, 0.2, 10).unwrap();
        let cfg = MclConfig {
            likelihood: LikelihoodSettings {
                model: SensorModel::with_defaults(SensorModelKind::Mixture, 8.0, 0.1),
                tail_tolerance: 1e-6,
                skip_no_returns: false,
            },
            motion: MotionModel::gmapping(),
            trigger: UpdateTrigger::every_scan(),
            spread_trigger: UpdateTrigger::every_scan(),
            spread_limit: 0.5,
            kld: KldSettings {
                n_min: 50,
                n_max: 2000,
                ..KldSettings::default()
            },
            alpha_slow: 0.0,
            alpha_fast: 0.0,
            tempering: 1.0,
            min_neff: 0.0,
            sigma_max: 0.0,
            anneal: 0.0,
            beam_stride: 1,
            max_beams: 0,
            resample_threshold: 0.5,
            min_cluster,
            keep_ratio: 1e-3,
            min_bin: 0,
            place_xy: 0.0,
            place_theta: std::f64::consts::FRAC_PI_2,
            spread_max: 0,
            spread_climb: false,
            seed: 3,
        };
        let init = MclInit::Pose {
            mean: [5.0, 5.0, 0.0],
            cov: [[0.01, 0.0, 0.0], [0.0, 0.01, 0.0], [0.0, 0.0, 0.01]],
        };
        Mcl::new(cfg, Arc::new(field), init).unwrap()
    }

    /// 990 particles at A hold 0.998 of the weight, 10 at B 0.0015 and 10 at C 1e-6.
    fn three_places(f: &mut Mcl) -> Vec<f64> {
        let mut poses = Vec::new();
        let mut w = Vec::new();
        for i in 0..1010 {
            let (place, weight) = match i {
                0..=989 => ([2.0, 2.0, 0.0], 0.998 / 990.0),
                990..=999 => ([8.0, 8.0, 1.0], 0.0015 / 10.0),
                _ => ([2.0, 8.0, -2.0], 1e-6 / 10.0),
            };
            poses.push([place[0] + 0.001 * (i % 7) as f64, place[1], place[2]]);
            w.push(weight);
        }
        let s: f64 = w.iter().sum();
        let w: Vec<f64> = w.iter().map(|v| v / s).collect();
        f.poses = poses;
        f.log_w = w.iter().map(|v| v.ln()).collect();
        w
    }

    fn weight_near(f: &Mcl, x: f64, y: f64) -> (f64, usize) {
        let w = f.weights();
        let near: Vec<usize> = (0..f.poses.len())
            .filter(|&j| (f.poses[j][0] - x).hypot(f.poses[j][1] - y) < 0.5)
            .collect();
        (near.iter().map(|&j| w[j]).sum(), near.len())
    }

    /// Resamples `f` with weights `w` and no injection, floored per AMCL cluster; returns the
    /// number of clusters, the particles injected and the clusters kept.
    fn resample_by_cluster(f: &mut Mcl, w: &[f64]) -> (usize, usize, usize) {
        let (found, labels) = clusters_with_labels(&f.poses, w, &f.cfg.kld);
        let kld = f.cfg.kld;
        let (injected, kept) = f.resample(w, 0.0, &found, &labels, &kld);
        (found.len(), injected, kept)
    }

    #[test]
    fn competing_clusters_keep_their_particles_and_weights() {
        let mut f = filter(30);
        let w = three_places(&mut f);
        let (n_clusters, injected, kept) = resample_by_cluster(&mut f, &w);
        assert_eq!(n_clusters, 3);
        assert_eq!((injected, kept), (0, 2));
        let (wa, na) = weight_near(&f, 2.0, 2.0);
        let (wb, nb) = weight_near(&f, 8.0, 8.0);
        // B keeps at least min_cluster particles and its weight; C (below keep_ratio) is left to
        // the draw, which almost surely loses it.
        assert!(nb >= 30 && na >= 50, "{na} {nb}");
        let total = wa + wb;
        assert!(
            (wb / total - 0.0015 / (0.998 + 0.0015)).abs() < 1e-9,
            "{wb} {wa}"
        );
    }

    #[test]
    fn without_the_floor_the_draw_decides() {
        let mut f = filter(0);
        let w = three_places(&mut f);
        let (_, _, kept) = resample_by_cluster(&mut f, &w);
        assert_eq!(kept, 0);
        // AMCL's resampling: equal weights, B holds about its share of the draws (0-3 of them).
        let (_, nb) = weight_near(&f, 8.0, 8.0);
        assert!(nb < 5, "{nb}");
        assert!(f.log_w.iter().all(|&l| l == 0.0));
    }

    #[test]
    fn the_bin_floor_keeps_every_plausible_bin_and_its_weight() {
        let mut f = filter(0);
        f.cfg.min_bin = 5;
        let w = three_places(&mut f);
        // A, B and C are one pose bin each; C is below keep_ratio times A.
        let kld = f.cfg.kld;
        let keys: Vec<_> = f.poses.iter().map(|p| kld.bin_of(p)).collect();
        let floored = f.resample_floored(&w, &kld, &keys, 5);
        assert_eq!(floored, 2);
        let (wa, na) = weight_near(&f, 2.0, 2.0);
        let (wb, nb) = weight_near(&f, 8.0, 8.0);
        assert!(nb >= 5 && na >= 5, "{na} {nb}");
        // The bins' weights pass through unchanged (C, if drawn at all, keeps its own).
        assert!((wb / wa - 0.0015 / 0.998).abs() < 1e-12, "{wa} {wb}");
        assert!(f.poses.len() <= f.cfg.kld.n_max);
    }

    /// One room: 990 particles at A (2, 2) hold 0.998 of the weight, 10 at B (6, 2) 0.0015,
    /// and a chain of particles 0.25 m apart between them (1e-9 each) joins their pose bins, so
    /// AMCL's clusters make one cluster of the room, as they do while a set is spread.
    fn one_room(f: &mut Mcl) -> Vec<f64> {
        let mut poses = Vec::new();
        let mut w = Vec::new();
        for i in 0..1000 {
            let (x, weight) = if i < 990 {
                (2.0, 0.998 / 990.0)
            } else {
                (6.0, 0.0015 / 10.0)
            };
            poses.push([x + 0.001 * (i % 7) as f64, 2.0, 0.0]);
            w.push(weight);
        }
        for k in 1..16 {
            poses.push([2.0 + 0.25 * k as f64, 2.0, 0.0]);
            w.push(1e-9);
        }
        let s: f64 = w.iter().sum();
        let w: Vec<f64> = w.iter().map(|v| v / s).collect();
        f.poses = poses;
        f.log_w = w.iter().map(|v| v.ln()).collect();
        w
    }

    #[test]
    fn places_split_a_room_that_is_one_cluster() {
        let mut f = filter(30);
        f.cfg.place_xy = 2.0;
        assert_eq!(f.place_of(&[2.0, 2.0, 0.0]), (1, 1, 2));
        assert_eq!(f.place_of(&[-0.1, 3.9, -3.0]), (-1, 1, 0));
        // Sectors count from −π: a heading just below π lies in the last of the four.
        assert_eq!(f.place_of(&[0.0, 0.0, 3.1]), (0, 0, 3));
        let w = one_room(&mut f);
        let (found, _) = clusters_with_labels(&f.poses, &w, &f.cfg.kld);
        assert_eq!(found.len(), 1, "the chain joins A and B");
        let kld = f.cfg.kld;
        let keys: Vec<_> = f.poses.iter().map(|p| f.place_of(p)).collect();
        // A's and B's places are floored; the chain's middle place (1e-9 x 5) is not.
        let floored = f.resample_floored(&w, &kld, &keys, 30);
        assert_eq!(floored, 2);
        let (wa, na) = weight_near(&f, 2.0, 2.0);
        let (wb, nb) = weight_near(&f, 6.0, 2.0);
        assert!(nb >= 30 && na >= 30, "{na} {nb}");
        // The places' weights pass through unchanged.
        assert!((wb / wa - 0.0015 / 0.998).abs() < 1e-6, "{wa} {wb}");
        assert!(f.poses.len() <= kld.n_max);
    }

    #[test]
    fn the_cluster_floor_cannot_keep_a_place_inside_one_cluster() {
        let mut f = filter(30);
        let w = one_room(&mut f);
        let (_, _, kept) = resample_by_cluster(&mut f, &w);
        // One cluster: AMCL's resampling, B keeps about its share of the draws (0-3 of them).
        assert_eq!(kept, 0);
        let (_, nb) = weight_near(&f, 6.0, 2.0);
        assert!(nb < 10, "{nb}");
    }

    #[test]
    fn place_settings_are_checked() {
        let mut f = filter(30);
        f.cfg.place_xy = f64::NAN;
        assert!(f.cfg.validate().is_err());
        f.cfg.place_xy = 2.0;
        f.cfg.place_theta = 0.0;
        assert!(f.cfg.validate().is_err());
        f.cfg.place_theta = 1.0;
        assert!(f.cfg.validate().is_ok());
    }
}
