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

use std::sync::Arc;

use rayon::prelude::*;

use crate::error::{config_err, Result};
use crate::mcl::baseline::{DistanceField, Measurement};
use crate::mcl::climb::{endpoints, EndpointField};
use crate::mcl::cluster::{clusters, clusters_with_labels, Cluster};
pub use crate::mcl::config::MclConfig;
use crate::mcl::field::MeanField;
use crate::mcl::kld::KldSettings;
use crate::mcl::likelihood::{select_beams, ScanFit};
use crate::mcl::weighing::{adaptive_tempering, climb_settings, set_spread, ScanWeigher};
use crate::pose::{between, compose, covariance_factor, draw_pose, Pose};
use crate::rbpf::{OdometryTracker, ScanInput};
use crate::resample::{effective_sample_size, normalize_log_weights};
use crate::rng::Rng;

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
    pub(super) cfg: MclConfig,
    pub(super) field: Arc<MeanField>,
    pub(super) poses: Vec<Pose>,
    pub(super) log_w: Vec<f64>,
    pub(super) tracker: OdometryTracker,
    pub(super) step: u64,
    pub(super) started: bool,
    pub(super) estimate: Pose,
    pub(super) estimate_odom: Pose,
    /// (w_slow, w_fast) in the fit's linear units; `None` before the first fit.
    pub(super) averages: Option<(f64, f64)>,
    pub(super) beams: (usize, Vec<usize>),
    pub(super) last: Option<MclStep>,
    /// The endpoint score of the climb (`spread_climb`), built at the first spread scan (a
    /// localizer that tracks from a known pose and never loses it does without).
    pub(super) endpoint_field: Option<EndpointField>,
    /// The likelihood field's distances (AMCL's likelihood-field model only).
    pub(super) distance_field: Option<Arc<DistanceField>>,
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
            distance_field: None,
        };
        if let Measurement::LikelihoodField(p) = m.cfg.measurement {
            m.distance_field = Some(Arc::new(DistanceField::new(&m.field, p.max_dist)));
        }
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

    /// The fit of a scan seen from the sensor pose `sensor` under this localizer's measurement
    /// model with the model's own hit σ, on the beams its rule keeps (`beam_stride`,
    /// `max_beams`): what a particle there would be weighed with (before tempering).
    pub fn scan_fit(&self, sensor: Pose, angles: &[f64], ranges: &[f64]) -> Result<ScanFit> {
        let beams = select_beams(angles.len(), self.cfg.beam_stride, self.cfg.max_beams);
        let sigma = self
            .cfg
            .measurement
            .sigma_hit()
            .unwrap_or(self.cfg.likelihood.model.sigma_hit);
        ScanWeigher::new(
            &self.cfg,
            &self.field,
            self.distance_field.as_deref(),
            sigma,
        )
        .fit(sensor, angles, ranges, &beams)
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
        let base = cfg
            .measurement
            .sigma_hit()
            .unwrap_or(cfg.likelihood.model.sigma_hit);
        let sigma_hit = (cfg.anneal * spread).min(cfg.sigma_max).max(base);
        let weigher = ScanWeigher::new(cfg, field, self.distance_field.as_deref(), sigma_hit);
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
                    cfg.likelihood.model.z_min,
                    cfg.likelihood.model.z_max,
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
                let fit = weigher.fit(sensor, scan.angles, scan.ranges, beams)?;
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
}

#[cfg(test)]
#[path = "filter_tests.rs"]
mod keep_tests;
