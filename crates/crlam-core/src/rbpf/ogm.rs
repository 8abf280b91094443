//! RBPF-OGM: the GMapping-style baseline (Grisetti, Stachniss, Burgard 2007) that RBPF-CLAM is
//! compared against.
//!
//! Per particle: a pose, a log-weight and its own log-odds grid ([`LogOddsGrid`], tiles shared
//! copy-on-write with its relatives). Per processed scan, for every particle (in parallel, each
//! with its own random stream, so results do not depend on the thread count):
//!
//! 1. draw x̃ from the motion model from the particle pose (the scan matcher's starting point);
//!    with [`MotionDraws::PerScan`] the particle was already moved by a draw at every scan since
//!    the last processed one, as GMapping does, and x̃ is that pose;
//! 2. hill-climb the scan score on the particle's map from x̃ ([`ScanMatcher::optimize`]);
//! 3. if the score exceeds `min_score`: evaluate likelihood × motion prior on a lattice around the
//!    match, fit a Gaussian, draw the new pose from it (or, with `ProposalPose::Match`, keep the
//!    match, as GMapping's released code does), and add log η = log Σ_k L_k p_k ΔV to the
//!    log-weight (the improved proposal, paper Eqs. 9–11); otherwise keep x̃ and add log L(x̃)
//!    (the plain motion proposal's weight);
//! 4. integrate the scan into the particle's map at the new pose.
//!
//! Then weights are normalised, N_eff computed, and if N_eff < threshold·n the particles are
//! resampled systematically (children share their parent's map tiles).
//!
//! GMapping's weight smoothing ("ogain") is kept: weights are normalised as
//! exp((ℓ − ℓ_max) / (ogain · n)) for N_eff, resampling and the estimate; ogain = 0 uses the
//! textbook weights exp(ℓ − ℓ_max).

use rayon::prelude::*;

use super::common::{weighted_mean_pose, FilterStep, OdometryTracker, ProposalPose, ScanInput};
use super::estimate::WeighedSet;
use super::lineage::{NodeId, PathTree, NO_NODE};
use super::motion_prior::MotionPrior;
pub use super::ogm_config::{MotionDraws, OgmFilterConfig};
use super::scanmatch::{PreparedScan, ScanMatcher};
use crate::error::Result;
use crate::grid::check_pose;
use crate::ogm::LogOddsGrid;
use crate::pose::{between, compose, wrap, Pose};
use crate::resample::{effective_sample_size, normalize_log_weights, systematic_resample};
use crate::rng::Rng;

/// Random-stream step reserved for the initial particle spread; processed scans use 1, 2, ...
const INIT_STEP: u64 = 0;
/// Random-stream index reserved for the resampling offset u0 (particle indices are smaller).
const RESAMPLE_INDEX: u64 = u64::MAX;
/// Mixed into the seed of the per-scan motion draws ([`MotionDraws::PerScan`]), whose streams
/// are indexed by raw scan rather than by processed scan.
const PER_SCAN_DOMAIN: u64 = 0x6D6F_7469_6F6E_5F73;

/// One particle: pose, log-weight (normalised: the weights exp(ℓ) sum to 1) and map.
#[derive(Clone, Debug)]
pub struct OgmParticle {
    /// The pose at the last processed scan; with [`MotionDraws::PerScan`], moved by the motion
    /// draws of the scans since.
    pub pose: Pose,
    /// The pose at the last processed scan (the motion prior's origin).
    pub anchor: Pose,
    pub log_w: f64,
    pub map: LogOddsGrid,
    /// The particle's pose at the last processed scan in the filter's [`PathTree`].
    pub path: NodeId,
}

/// Map memory summed over particles. A tile shared by k particles is counted k times in
/// `allocated_tiles` and `bytes_allocated`, and also in `shared_tiles`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct OgmMemoryStats {
    pub n_particles: usize,
    pub allocated_tiles: usize,
    pub shared_tiles: usize,
    pub bytes_allocated: usize,
}

/// Everything a particle needs for one processed scan (shared, read-only).
struct StepContext<'a> {
    cfg: &'a OgmFilterConfig,
    matcher: &'a ScanMatcher,
    prepared: &'a PreparedScan,
    u: Pose,
    n_steps: usize,
    map_angles: &'a [f64],
    map_ranges: &'a [f64],
    laser_offset: Pose,
    step: u64,
    /// Per-step variances (along, across, heading) summed since the last processed scan, when
    /// the particles have already been moved by per-scan draws; `None` with per-update draws.
    drawn_variance: Option<[f64; 3]>,
}

/// What one particle's step did.
struct ParticleStep {
    /// The scan match was accepted (else the motion-model sample was kept).
    accepted: bool,
    /// The mean of the distribution the new pose was drawn from (the fitted Gaussian's mean, or
    /// the pose itself when nothing was fitted or the match is kept).
    mean: Pose,
}

/// Steps 1–4 of the module doc for one particle.
fn advance_particle(ctx: &StepContext, index: usize, p: &mut OgmParticle) -> Result<ParticleStep> {
    let mut rng = Rng::stream(ctx.cfg.seed, ctx.step, index as u64);
    let prev = p.anchor;
    let start = match ctx.drawn_variance {
        None => ctx.cfg.motion.sample(prev, ctx.u, ctx.n_steps, &mut rng),
        Some(_) => p.pose,
    };
    let surface = ctx.matcher.surface(&p.map, ctx.prepared, start);
    let (matched, score) = ctx.matcher.optimize(&surface, ctx.prepared, start)?;
    let accepted = score > ctx.cfg.proposal.min_score;
    let (pose, mean, delta_log_w) = if accepted {
        let prior = match ctx.drawn_variance {
            None => MotionPrior::new(
                &ctx.cfg.motion,
                prev,
                ctx.u,
                ctx.n_steps,
                ctx.cfg.motion_floor,
            ),
            Some(var) => MotionPrior::from_sigma(
                compose(prev, ctx.u),
                prev[2],
                var.map(f64::sqrt),
                ctx.cfg.motion_floor,
            ),
        };
        let draw = ctx.matcher.improved_proposal(
            &surface,
            ctx.prepared,
            matched,
            |x| prior.log_density(x),
            &ctx.cfg.proposal,
            &mut rng,
        )?;
        let (pose, mean) = match ctx.cfg.proposal.pose {
            ProposalPose::Sample => (draw.pose, draw.mean),
            ProposalPose::Match => (matched, matched),
        };
        (pose, mean, draw.log_normalizer)
    } else {
        let fit = ctx.matcher.evaluate(&surface, ctx.prepared, start)?;
        (start, start, fit.log_likelihood)
    };
    p.pose = pose;
    p.anchor = pose;
    p.log_w += delta_log_w;
    p.map.update_scan(
        compose(pose, ctx.laser_offset),
        ctx.map_angles,
        ctx.map_ranges,
    )?;
    Ok(ParticleStep { accepted, mean })
}

/// The GMapping-style RBPF.
///
/// If `process` returns an error after validation (only possible when a map cannot grow, i.e.
/// a pose far outside any sensible area), some particles may already have been updated: the
/// filter should then be discarded.
#[derive(Clone, Debug)]
pub struct RbpfOgm {
    cfg: OgmFilterConfig,
    matcher: ScanMatcher,
    particles: Vec<OgmParticle>,
    tracker: OdometryTracker,
    initialized: bool,
    /// Processed scans after the first one (the step of the random streams).
    step: u64,
    /// Processed scans, the first one included.
    n_processed: usize,
    /// Estimate at the last processed scan.
    estimate: Pose,
    /// Poses and normalised (resampling) weights of the last processed scan, before resampling.
    weighed: WeighedSet,
    n_resamples: usize,
    last_match_failures: usize,
    paths: PathTree,
    /// [`MotionDraws::PerScan`]: the odometry of the previous scan, the scans seen after the
    /// first (the step of the per-scan streams), and the per-step variances summed since the
    /// last processed scan.
    previous_odom: Option<Pose>,
    raw_step: u64,
    drawn_variance: [f64; 3],
    /// [`Self::release_maps`] was called: the particles hold empty maps and take no more scans.
    maps_released: bool,
}

/// The particles' poses with uniform weights.
fn uniform_set(particles: &[OgmParticle]) -> WeighedSet {
    let n = particles.len();
    WeighedSet {
        poses: particles.iter().map(|p| p.pose).collect(),
        weights: vec![1.0 / n as f64; n],
        nodes: particles.iter().map(|p| p.path).collect(),
    }
}

impl RbpfOgm {
    /// A filter with every particle at `initial_pose` (spread by `init_sigma`) and empty maps.
    pub fn new(cfg: OgmFilterConfig, initial_pose: Pose) -> Result<Self> {
        cfg.validate()?;
        check_pose(initial_pose)?;
        let map = LogOddsGrid::new(cfg.geometry, cfg.log_odds, cfg.tile_size, None)?;
        let n = cfg.n_particles;
        let particles = (0..n)
            .map(|i| {
                let mut rng = Rng::stream(cfg.seed, INIT_STEP, i as u64);
                let s = cfg.init_sigma;
                let pose = [
                    initial_pose[0] + s[0] * rng.normal(),
                    initial_pose[1] + s[1] * rng.normal(),
                    wrap(initial_pose[2] + s[2] * rng.normal()),
                ];
                OgmParticle {
                    pose,
                    anchor: pose,
                    log_w: -(n as f64).ln(),
                    map: map.clone(),
                    path: NO_NODE,
                }
            })
            .collect::<Vec<_>>();
        let cfg_draws = cfg.proposal.pose == ProposalPose::Sample;
        let weighed = uniform_set(&particles);
        Ok(Self {
            matcher: ScanMatcher::new(cfg.matcher)?,
            cfg,
            particles,
            tracker: OdometryTracker::default(),
            initialized: false,
            step: 0,
            n_processed: 0,
            estimate: initial_pose,
            weighed,
            n_resamples: 0,
            last_match_failures: 0,
            previous_odom: None,
            raw_step: 0,
            drawn_variance: [0.0; 3],
            maps_released: false,
            // Only drawn poses have a mean distinct from the pose.
            paths: if cfg_draws {
                PathTree::recording_means()
            } else {
                PathTree::default()
            },
        })
    }

    pub fn config(&self) -> &OgmFilterConfig {
        &self.cfg
    }

    /// Feeds one scan. The first scan only builds the maps; later scans are processed when the
    /// trigger fires, else the estimate is carried forward by odometry.
    pub fn process(&mut self, scan: &ScanInput) -> Result<FilterStep> {
        super::common::check_maps_kept(self.maps_released)?;
        scan.validate()?;
        // Everything that can refuse the input happens before the tracker records the scan.
        let prepared = PreparedScan::new(
            scan.angles,
            scan.ranges,
            scan.laser_offset,
            self.cfg.log_odds.z_max,
            self.cfg.matcher.beam_stride,
        )?;
        let (angles, ranges) = self.mapping_beams(scan);
        let (u, n_steps, fires) = self.tracker.observe(scan.odom, &self.cfg.trigger);
        if self.initialized && self.cfg.motion_draws == MotionDraws::PerScan {
            self.draw_scan_motion(scan.odom);
        }
        self.previous_odom = Some(scan.odom);
        if !self.initialized {
            self.initialize(scan, &angles, &ranges)?;
            let poses: Vec<Pose> = self.particles.iter().map(|p| p.pose).collect();
            self.advance_paths(poses);
            self.weighed = uniform_set(&self.particles);
            self.tracker.processed(scan.odom);
            self.n_processed += 1;
            return Ok(FilterStep {
                processed: true,
                estimate: self.estimate,
                neff: self.particles.len() as f64,
                resampled: false,
            });
        }
        if !fires {
            return Ok(FilterStep {
                processed: false,
                estimate: compose(self.estimate, u),
                neff: f64::NAN,
                resampled: false,
            });
        }
        self.step += 1;
        let ctx = StepContext {
            cfg: &self.cfg,
            matcher: &self.matcher,
            prepared: &prepared,
            u,
            n_steps,
            map_angles: &angles,
            map_ranges: &ranges,
            laser_offset: scan.laser_offset,
            step: self.step,
            drawn_variance: (self.cfg.motion_draws == MotionDraws::PerScan)
                .then_some(self.drawn_variance),
        };
        let steps: Vec<ParticleStep> = self
            .particles
            .par_iter_mut()
            .enumerate()
            .map(|(i, p)| advance_particle(&ctx, i, p))
            .collect::<Result<_>>()?;
        self.last_match_failures = steps.iter().filter(|s| !s.accepted).count();
        self.drawn_variance = [0.0; 3];
        self.tracker.processed(scan.odom);
        self.n_processed += 1;
        self.advance_paths(steps.into_iter().map(|s| s.mean).collect());
        let (neff, resampled) = self.reweight_and_resample();
        Ok(FilterStep {
            processed: true,
            estimate: self.estimate,
            neff,
            resampled,
        })
    }

    /// [`MotionDraws::PerScan`]: moves every particle by a motion-model draw on the odometry
    /// step from the previous scan to this one, and adds the step's variances to the prior's.
    fn draw_scan_motion(&mut self, odom: Pose) {
        let Some(previous) = self.previous_odom else {
            return;
        };
        let d = between(previous, odom);
        self.raw_step += 1;
        let (seed, step, motion) = (
            self.cfg.seed ^ PER_SCAN_DOMAIN,
            self.raw_step,
            self.cfg.motion,
        );
        for (i, p) in self.particles.iter_mut().enumerate() {
            let mut rng = Rng::stream(seed, step, i as u64);
            p.pose = motion.sample(p.pose, d, 1, &mut rng);
        }
        let v = MotionPrior::step_variance(&self.cfg.motion, d);
        for k in 0..3 {
            self.drawn_variance[k] += v[k];
        }
    }

    /// The beams used for mapping: finite readings below `max_range` (GMapping skips the rest;
    /// readings between the usable range and `max_range` are cropped by the grid update).
    fn mapping_beams(&self, scan: &ScanInput) -> (Vec<f64>, Vec<f64>) {
        scan.angles
            .iter()
            .zip(scan.ranges)
            .filter(|(_, z)| z.is_finite() && **z < self.cfg.max_range)
            .map(|(a, z)| (*a, *z))
            .unzip()
    }

    /// Integrates the first scan. With no initial spread all particles share one map.
    fn initialize(&mut self, scan: &ScanInput, angles: &[f64], ranges: &[f64]) -> Result<()> {
        let offset = scan.laser_offset;
        if self.cfg.init_sigma.iter().all(|s| *s == 0.0) {
            let first = &mut self.particles[0];
            first
                .map
                .update_scan(compose(first.pose, offset), angles, ranges)?;
            let map = first.map.clone();
            for p in &mut self.particles[1..] {
                p.map = map.clone();
            }
        } else {
            self.particles
                .par_iter_mut()
                .map(|p| {
                    p.map
                        .update_scan(compose(p.pose, offset), angles, ranges)
                        .map(|_| ())
                })
                .collect::<Result<Vec<()>>>()?;
        }
        self.initialized = true;
        self.estimate = self.mean_pose(&vec![
            1.0 / self.particles.len() as f64;
            self.particles.len()
        ]);
        Ok(())
    }

    /// Normalised weights used for N_eff, resampling and the estimate (smoothed if configured).
    fn resampling_weights(&self) -> Vec<f64> {
        let n = self.particles.len() as f64;
        let scale = if self.cfg.weight_smoothing > 0.0 {
            1.0 / (self.cfg.weight_smoothing * n)
        } else {
            1.0
        };
        let lw: Vec<f64> = self.particles.iter().map(|p| p.log_w * scale).collect();
        normalize_log_weights(&lw)
    }

    /// Normalises the log-weights, resamples when N_eff is low, updates the estimate.
    fn reweight_and_resample(&mut self) -> (f64, bool) {
        // Keep log-weights normalised (log Σ exp = 0) so they never drift towards −∞.
        // Subtracting the log-sum-exp (not taking ln of the normalised weights) keeps particles
        // whose weight underflows at a finite log-weight.
        let m = self
            .particles
            .iter()
            .map(|p| p.log_w)
            .fold(f64::NEG_INFINITY, f64::max);
        if m.is_finite() {
            let lse = m + self
                .particles
                .iter()
                .map(|p| (p.log_w - m).exp())
                .sum::<f64>()
                .ln();
            for p in &mut self.particles {
                p.log_w -= lse;
            }
        }
        let mut w = self.resampling_weights();
        let neff = effective_sample_size(&w);
        self.weighed = WeighedSet {
            poses: self.particles.iter().map(|p| p.pose).collect(),
            weights: w.clone(),
            nodes: self.particles.iter().map(|p| p.path).collect(),
        };
        let n = self.particles.len();
        let resampled = neff < self.cfg.resample_threshold * n as f64;
        if resampled {
            let u0 = Rng::stream(self.cfg.seed, self.step, RESAMPLE_INDEX).uniform();
            let parents = systematic_resample(&w, u0);
            let log_n = -(n as f64).ln();
            self.particles = parents
                .iter()
                .map(|&i| OgmParticle {
                    log_w: log_n,
                    ..self.particles[i].clone()
                })
                .collect();
            self.n_resamples += 1;
            w = vec![1.0 / n as f64; n];
        }
        self.estimate = self.mean_pose(&w);
        (neff, resampled)
    }

    fn mean_pose(&self, w: &[f64]) -> Pose {
        let poses: Vec<Pose> = self.particles.iter().map(|p| p.pose).collect();
        weighted_mean_pose(&poses, w)
    }

    /// Weighted mean pose (circular heading) at the last processed scan.
    pub fn estimate(&self) -> Pose {
        self.estimate
    }

    /// The particle set of the last processed scan before resampling (the estimate itself is
    /// the mean of the set after it).
    pub fn weighed_set(&self) -> &WeighedSet {
        &self.weighed
    }

    /// Smoothed means of the weighed set's lineages for lags 0..=max_lag processed scans
    /// (see [`PathTree::ancestor_means`]).
    pub fn ancestor_means(&self, max_lag: usize, proposal_means: bool) -> Option<Vec<Pose>> {
        let w = &self.weighed;
        self.paths
            .ancestor_means(&w.nodes, &w.weights, max_lag, proposal_means)
    }

    /// Appends each particle's pose and proposal mean (`means[i]` for particle i) to the paths.
    fn advance_paths(&mut self, means: Vec<Pose>) {
        self.paths.advance(
            self.particles
                .iter_mut()
                .zip(means)
                .map(|(p, mean)| (&mut p.path, p.pose, mean)),
        );
    }

    /// The best particle's pose at every processed scan, first to last (GMapping's trajectory).
    pub fn best_path(&self) -> Vec<Pose> {
        self.paths.path(self.particles[self.best_index()].path)
    }

    /// The proposal means along the best particle's path (see [`PathTree`]): `None` when the
    /// proposal keeps the match.
    pub fn best_path_means(&self) -> Option<Vec<Pose>> {
        self.paths.mean_path(self.particles[self.best_index()].path)
    }

    /// Index of the highest-weight particle (the lowest index among ties).
    pub fn best_index(&self) -> usize {
        let mut best = 0;
        for (i, p) in self.particles.iter().enumerate() {
            if p.log_w > self.particles[best].log_w {
                best = i;
            }
        }
        best
    }

    /// The particles (pose, normalised log-weight, map).
    pub fn particles(&self) -> &[OgmParticle] {
        &self.particles
    }

    pub fn poses(&self) -> Vec<Pose> {
        self.particles.iter().map(|p| p.pose).collect()
    }

    /// Accumulated log-likelihoods since the last resampling, normalised (log Σ exp = 0), before
    /// the weight smoothing.
    pub fn log_weights(&self) -> Vec<f64> {
        self.particles.iter().map(|p| p.log_w).collect()
    }

    /// Normalised weights after the weight smoothing: the ones behind N_eff, resampling and the
    /// estimate (uniform right after resampling).
    pub fn weights(&self) -> Vec<f64> {
        self.resampling_weights()
    }

    /// The map of the highest-weight particle.
    pub fn best_map(&self) -> &LogOddsGrid {
        &self.particles[self.best_index()].map
    }

    /// Number of resampling events so far.
    pub fn n_resamples(&self) -> usize {
        self.n_resamples
    }

    /// Processed scans, the first one included.
    pub fn n_processed(&self) -> usize {
        self.n_processed
    }

    /// Particles whose scan match was rejected at the last processed scan (they used the plain
    /// motion proposal).
    pub fn last_match_failures(&self) -> usize {
        self.last_match_failures
    }

    /// Map memory summed over particles.
    /// (bytes of distinct map tiles, distinct tiles, tile references) over all particles: the
    /// memory the maps really take with copy-on-write sharing.
    pub fn map_memory(&self) -> (usize, usize, usize) {
        crate::rbpf::common::distinct_tile_memory(self.particles.iter().map(|p| p.map.grid()))
    }

    /// Frees every particle's map once a run's map has been written (see
    /// [`crate::rbpf::RbpfClam::release_maps`]): poses, weights and paths stay; the filter
    /// refuses further scans.
    pub fn release_maps(&mut self) -> Result<()> {
        let empty = LogOddsGrid::new(
            self.cfg.geometry,
            self.cfg.log_odds,
            self.cfg.tile_size,
            None,
        )?;
        for p in &mut self.particles {
            p.map = empty.clone();
        }
        self.maps_released = true;
        Ok(())
    }

    /// Whether [`Self::release_maps`] was called.
    pub fn maps_released(&self) -> bool {
        self.maps_released
    }

    pub fn memory_stats(&self) -> OgmMemoryStats {
        let mut s = OgmMemoryStats {
            n_particles: self.particles.len(),
            ..Default::default()
        };
        for p in &self.particles {
            let t = p.map.tile_stats();
            s.allocated_tiles += t.n_allocated;
            s.shared_tiles += t.n_shared;
            s.bytes_allocated += t.bytes_allocated;
        }
        s
    }
}

crate::rbpf::common::impl_particle_filter!(RbpfOgm);
