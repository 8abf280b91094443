//! RBPF-CLAM (crm-spec 4.3, the paper's Algorithm 1 corrected).
//!
//! Each particle has a pose, a log-weight and its own confidence-rich map. Per processed scan:
//! propose a pose, weight it by the closed-form predictive likelihood of the scan under the
//! particle's *pre-update* beliefs (`weight_model`, default `mixture`), then update its map at that
//! pose (`mapping_model`, default `ijrr`). Resampling (systematic, when N_eff < threshold·n)
//! makes children share their parent's map tiles copy-on-write.
//!
//! Determinism: every random draw of particle j at step k comes from `Rng::stream(seed, k, j)`,
//! and particles are processed independently, so the result does not depend on the number of
//! threads.

use rayon::prelude::*;

use crate::crm::{with_thread_scratch, CrmConfig, CrmMap, CrmScratch};
use crate::error::{config_err, Result};
use crate::pose::{between, compose, covariance_factor, draw_pose, wrap, Pose};
use crate::rbpf::clam_config::scan_opts;
pub use crate::rbpf::clam_config::{ClamConfig, ClamProposal};
use crate::rbpf::clam_match::{corrected_increment, prepare_scan, propose_by_scan_match};
use crate::rbpf::clam_particle::weigh_at_pose;
pub use crate::rbpf::clam_particle::ClamParticle;
use crate::rbpf::common::{
    weighted_mean_pose, FilterStep, OdometryTracker, ProposalPose, ScanInput,
};
use crate::rbpf::estimate::WeighedSet;
use crate::rbpf::hit_means::HitMeans;
use crate::rbpf::lineage::{PathTree, NO_NODE};
use crate::rbpf::proposal::propose;
use crate::rbpf::scanmatch::PreparedScan;
use crate::resample::{effective_sample_size, normalize_log_weights, systematic_resample};
use crate::rng::Rng;

/// What a filter continuing a saved run starts from: the saved map (given to every particle)
/// and the covariance of the saved estimate (m², m·rad, rad²) that spreads the particles.
#[derive(Clone, Debug)]
pub struct ClamPrior {
    pub map: CrmMap,
    pub cov: [[f64; 3]; 3],
}

/// A prior map must have the configuration's grid and levels.
fn check_prior_map(cfg: &CrmConfig, map: &CrmMap) -> Result<()> {
    let g = map.geometry();
    if g.resolution != cfg.geometry.resolution || g.origin != cfg.geometry.origin {
        return Err(config_err(
            "prior_map",
            format!(
                "its grid (resolution {} m, origin {:?}) differs from the filter's ({} m, {:?})",
                g.resolution, g.origin, cfg.geometry.resolution, cfg.geometry.origin
            ),
        ));
    }
    let levels = crate::crm::level_values(cfg.n_levels, cfg.placement)?;
    if map.levels() != levels.as_slice() || map.placement() != cfg.placement {
        return Err(config_err(
            "prior_map",
            format!(
                "its {} {} levels differ from the filter's {} {}",
                map.levels().len(),
                map.placement().name(),
                levels.len(),
                cfg.placement.name()
            ),
        ));
    }
    Ok(())
}

/// The RBPF-CLAM filter.
#[derive(Debug)]
pub struct RbpfClam {
    cfg: ClamConfig,
    particles: Vec<ClamParticle>,
    tracker: OdometryTracker,
    step: u64,
    initial: Pose,
    started: bool,
    /// The particles started with a saved map: the first scan is weighed, not only mapped.
    from_prior: bool,
    estimate: Pose,
    estimate_odom: Pose,
    weighed: WeighedSet,
    best: usize,
    n_resamples: usize,
    n_processed: usize,
    paths: PathTree,
    /// The largest finite reading of every scan given so far (−∞ before any): the no-return rule
    /// of a full-range matcher ([`crate::rbpf::MatchRange::Full`]).
    largest_reading: f64,
    /// Each particle's parent in the last resampling, while the children are still copies of it
    /// (until the next processed scan); each particle its own index otherwise. Systematic
    /// resampling keeps the children of one parent next to each other.
    parents: Vec<usize>,
    /// What the correlative front end did (see [`FrontEndCounts`]).
    front_end: FrontEndCounts,
    /// Processed scans the scan-match proposal found degenerate (see
    /// [`crate::rbpf::degeneracy`]; only looked for with [`crate::rbpf::Degeneracy::Remap`]).
    degenerate_scans: usize,
    /// [`Self::release_maps`] was called: the particles hold empty maps and take no more scans.
    maps_released: bool,
}

/// Processed scans the correlative front end searched, and those whose odometry increment its
/// match replaced.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FrontEndCounts {
    pub searched: usize,
    pub corrected: usize,
}

/// The particles' poses with uniform weights.
fn uniform_set(particles: &[ClamParticle]) -> WeighedSet {
    let n = particles.len();
    WeighedSet {
        poses: particles.iter().map(|p| p.pose).collect(),
        weights: vec![1.0 / n as f64; n],
        nodes: particles.iter().map(|p| p.path).collect(),
    }
}

/// How the maps of a step are brought up to date once resampling has decided which to keep.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum PendingUpdate {
    /// Every map was updated while weighing.
    None,
    /// The particles were only weighed: the maps resampling keeps are updated with the mapping
    /// model at their poses (a map update does not depend on the weight, so this is the fused
    /// call's update bit for bit, without walking the weight's part again).
    Deferred,
}

impl RbpfClam {
    /// A filter whose particles start at `initial` (spread by `init_sigma`) with prior maps.
    pub fn new(cfg: ClamConfig, initial: Pose) -> Result<Self> {
        Self::build(cfg, initial, None)
    }

    /// A filter that continues a saved run: every particle starts with `prior`'s map, at a draw
    /// from N(`initial`, `prior.cov`), and the first scan is weighed against that map like any
    /// later one (a filter from [`Self::new`] only maps its first scan).
    pub fn with_prior(cfg: ClamConfig, initial: Pose, prior: ClamPrior) -> Result<Self> {
        Self::build(cfg, initial, Some(prior))
    }

    fn build(cfg: ClamConfig, initial: Pose, prior: Option<ClamPrior>) -> Result<Self> {
        cfg.validate()?;
        let from_prior = prior.is_some();
        let (map, factor) = match prior {
            None => (CrmMap::new(&cfg.crm)?, None),
            Some(p) => {
                check_prior_map(&cfg.crm, &p.map)?;
                (p.map, Some(covariance_factor(&p.cov)?))
            }
        };
        // A continued run starts without hit means: its matcher reads the saved map's cell
        // centres until the new scans record where the walls are.
        let hits = match &cfg.proposal {
            ClamProposal::ScanMatch(s) if s.hit_means => {
                Some(HitMeans::new(cfg.crm.geometry, cfg.crm.tile_size)?)
            }
            _ => None,
        };
        let n = cfg.n_particles;
        let particles = (0..n)
            .map(|j| {
                let mut rng = Rng::stream(cfg.seed, 0, j as u64);
                let pose = match &factor {
                    Some(l) => draw_pose(initial, l, &mut rng),
                    None => {
                        let s = cfg.init_sigma;
                        [
                            initial[0] + s[0] * rng.normal(),
                            initial[1] + s[1] * rng.normal(),
                            wrap(initial[2] + s[2] * rng.normal()),
                        ]
                    }
                };
                ClamParticle {
                    pose,
                    log_w: -(n as f64).ln(),
                    map: map.clone(),
                    hits: hits.clone(),
                    path: NO_NODE,
                }
            })
            .collect::<Vec<_>>();
        // Only a drawn improved proposal has a mean worth a path of its own: the odometry
        // proposal's mean is dead reckoning, and `Match` keeps the mode itself.
        let drawn = match &cfg.proposal {
            ClamProposal::Odometry => false,
            ClamProposal::LikelihoodMode { pose, .. } => *pose == ProposalPose::Sample,
            ClamProposal::ScanMatch(s) => s.lattice.pose == ProposalPose::Sample,
        };
        let paths = if drawn {
            PathTree::recording_means()
        } else {
            PathTree::default()
        };
        let weighed = uniform_set(&particles);
        Ok(Self {
            cfg,
            particles,
            tracker: OdometryTracker::default(),
            step: 0,
            initial,
            started: false,
            from_prior,
            estimate: initial,
            estimate_odom: [0.0; 3],
            weighed,
            best: 0,
            n_resamples: 0,
            n_processed: 0,
            paths,
            largest_reading: f64::NEG_INFINITY,
            parents: (0..n).collect(),
            front_end: FrontEndCounts::default(),
            degenerate_scans: 0,
            maps_released: false,
        })
    }

    pub fn config(&self) -> &ClamConfig {
        &self.cfg
    }

    pub fn particles(&self) -> &[ClamParticle] {
        &self.particles
    }

    /// Index of the highest-weight particle (its map is the one reported, crm-spec B7).
    pub fn best_index(&self) -> usize {
        self.best
    }

    pub fn best_map(&self) -> &CrmMap {
        &self.particles[self.best].map
    }

    pub fn estimate(&self) -> Pose {
        self.estimate
    }

    /// Normalised weights of the current particles (uniform right after resampling).
    pub fn weights(&self) -> Vec<f64> {
        let logw: Vec<f64> = self.particles.iter().map(|p| p.log_w).collect();
        normalize_log_weights(&logw)
    }

    /// The set the last estimate was taken from (before resampling).
    pub fn weighed_set(&self) -> &WeighedSet {
        &self.weighed
    }

    /// Smoothed means of the weighed set's lineages for lags 0..=max_lag processed scans
    /// (see [`PathTree::ancestor_means`]; element 0 is the weighted mean).
    pub fn ancestor_means(&self, max_lag: usize, proposal_means: bool) -> Option<Vec<Pose>> {
        let w = &self.weighed;
        self.paths
            .ancestor_means(&w.nodes, &w.weights, max_lag, proposal_means)
    }

    /// What the correlative front end did so far.
    pub fn front_end_counts(&self) -> FrontEndCounts {
        self.front_end
    }

    /// Processed scans the scan-match proposal found degenerate (0 unless it looks for them).
    pub fn degenerate_scans(&self) -> usize {
        self.degenerate_scans
    }

    pub fn n_resamples(&self) -> usize {
        self.n_resamples
    }

    pub fn n_processed(&self) -> usize {
        self.n_processed
    }

    /// The best particle's pose at every processed scan, first to last (GMapping's trajectory).
    pub fn best_path(&self) -> Vec<Pose> {
        self.paths.path(self.particles[self.best].path)
    }

    /// The proposal means along the best particle's path (see [`PathTree`]): `None` unless the
    /// proposal is the likelihood mode with drawn poses.
    pub fn best_path_means(&self) -> Option<Vec<Pose>> {
        self.paths.mean_path(self.particles[self.best].path)
    }

    /// (bytes of distinct map tiles over all particles, distinct tiles, tile references): what the
    /// particle maps really occupy thanks to copy-on-write sharing.
    pub fn map_memory(&self) -> (usize, usize, usize) {
        crate::rbpf::common::distinct_tile_memory(
            self.particles.iter().map(|p| p.map.grid()).chain(
                self.particles
                    .iter()
                    .filter_map(|p| p.hits.as_ref().map(|h| h.grid())),
            ),
        )
    }

    /// A map with the filter's grid and levels and nothing mapped yet (what loop closing
    /// rebuilds the map into, scan by scan with [`Self::map_scan`]).
    pub fn empty_map(&self) -> Result<CrmMap> {
        CrmMap::new(&self.cfg.crm)
    }

    /// Maps `scan` taken at robot pose `pose` into `map` exactly as a particle's map takes a
    /// processed scan (the mapping model, its map stride and scan options); `scan.odom` is not
    /// read.
    pub fn map_scan(&self, map: &mut CrmMap, pose: Pose, scan: &ScanInput) -> Result<()> {
        scan.validate()?;
        crate::grid::check_pose(pose)?;
        check_prior_map(&self.cfg.crm, map)?;
        let sensor = compose(pose, scan.laser_offset);
        let opts = scan_opts(&self.cfg, self.cfg.map_stride);
        with_thread_scratch(|sc| {
            map.update_scan(
                sensor,
                scan.angles,
                scan.ranges,
                &self.cfg.mapping_model,
                &opts,
                sc,
            )
        })?;
        Ok(())
    }

    /// Loop closing's correction: every particle's map becomes `map` (the map rebuilt at a pose
    /// graph's corrected poses) and every pose the filter holds (the particles', the estimate,
    /// the weighed set) moves by the rigid `correction` (world frame: new = correction ∘ old).
    ///
    /// Weights, the path tree (the poses as they were proposed) and the odometry reference stay.
    /// Hit means, where kept, restart empty: the rebuilt map's cell centres stand until new
    /// scans record where the walls are (as when continuing a saved run).
    pub fn reanchor(&mut self, map: CrmMap, correction: Pose) -> Result<()> {
        crate::rbpf::common::check_maps_kept(self.maps_released)?;
        crate::grid::check_pose(correction)?;
        check_prior_map(&self.cfg.crm, &map)?;
        let hits = match self.particles.first().and_then(|p| p.hits.as_ref()) {
            Some(_) => Some(HitMeans::new(
                self.cfg.crm.geometry,
                self.cfg.crm.tile_size,
            )?),
            None => None,
        };
        for p in &mut self.particles {
            p.pose = compose(correction, p.pose);
            p.map = map.clone();
            p.hits = hits.clone();
        }
        for q in &mut self.weighed.poses {
            *q = compose(correction, *q);
        }
        self.estimate = compose(correction, self.estimate);
        self.initial = compose(correction, self.initial);
        Ok(())
    }

    /// Frees every particle's map and hit means once a run's map has been written: the
    /// particles keep their poses, weights and paths (every trajectory stays readable), but hold
    /// empty maps, so the filter refuses further scans and corrections. The last grid to go
    /// frees the tile pool the particle maps shared.
    pub fn release_maps(&mut self) -> Result<()> {
        let empty = CrmMap::new(&self.cfg.crm)?;
        for p in &mut self.particles {
            p.map = empty.clone();
            p.hits = None;
        }
        self.maps_released = true;
        Ok(())
    }

    /// Whether [`Self::release_maps`] was called.
    pub fn maps_released(&self) -> bool {
        self.maps_released
    }

    /// Feeds one scan; processes it when the update trigger fires.
    pub fn process(&mut self, scan: &ScanInput) -> Result<FilterStep> {
        crate::rbpf::common::check_maps_kept(self.maps_released)?;
        scan.validate()?;
        self.largest_reading = scan
            .ranges
            .iter()
            .filter(|z| z.is_finite())
            .fold(self.largest_reading, |m, &z| m.max(z));
        let (u, n_steps, fires) = self.tracker.observe(scan.odom, &self.cfg.trigger);
        if !self.started && !self.from_prior {
            self.started = true;
            self.integrate_first(scan)?;
            return Ok(FilterStep {
                processed: true,
                estimate: self.estimate,
                neff: self.cfg.n_particles as f64,
                resampled: false,
            });
        }
        // With a prior map the first scan is processed as any other (no motion yet: the
        // tracker's first increment is zero).
        self.started = true;
        if !fires {
            let carried = compose(self.estimate, between(self.estimate_odom, scan.odom));
            return Ok(FilterStep {
                processed: false,
                estimate: carried,
                neff: f64::NAN,
                resampled: false,
            });
        }
        self.step += 1;
        // The scan's tempering (it depends on the beam count with `tempering_beams`); every
        // weight below divides by `cfg.tempering`.
        let scan_cfg = ClamConfig {
            tempering: self.cfg.tempering_for(scan.angles.len()),
            ..self.cfg.clone()
        };
        let cfg = &scan_cfg;
        let step = self.step;
        let pending = if cfg.defer_map_updates {
            PendingUpdate::Deferred
        } else {
            PendingUpdate::None
        };
        // The matcher's view of the scan, shared by every particle.
        let prepared: Option<PreparedScan> = match &cfg.proposal {
            ClamProposal::ScanMatch(settings) => {
                Some(prepare_scan(cfg, settings, scan, self.largest_reading)?)
            }
            _ => None,
        };
        if prepared
            .as_ref()
            .is_some_and(|p| p.free_direction.is_some())
        {
            self.degenerate_scans += 1;
        }
        // The correlative front end: one wide search on the best particle's map; a confident
        // match corrects the increment every particle starts from.
        let u = match (&cfg.proposal, &prepared) {
            (ClamProposal::ScanMatch(settings), Some(prepared)) => match &settings.front_end {
                Some(front_end) => {
                    let best = &self.particles[self.best];
                    let (corrected, found) = corrected_increment(
                        cfg,
                        settings,
                        front_end,
                        prepared,
                        best.pose,
                        &best.map,
                        best.hits.as_ref(),
                        u,
                    )?;
                    if found.is_some() {
                        self.front_end.searched += 1;
                        if corrected != u {
                            self.front_end.corrected += 1;
                        }
                    }
                    corrected
                }
                None => u,
            },
            _ => u,
        };
        // The scan-match proposal from the odometry guess searches once for the children of one
        // parent (same map, same pose) right after a resampling; every other proposal, and each
        // child's draw, weight and map update, per particle.
        let share_search = matches!(
            &cfg.proposal,
            ClamProposal::ScanMatch(settings) if settings.lattice.pose == ProposalPose::Sample
        );
        let mut groups: Vec<(usize, &mut [ClamParticle])> = Vec::new();
        let mut rest: &mut [ClamParticle] = &mut self.particles;
        let mut first = 0;
        while !rest.is_empty() {
            let len = if share_search {
                self.parents[first..]
                    .iter()
                    .take_while(|&&q| q == self.parents[first])
                    .count()
            } else {
                1
            };
            let (group, tail) = std::mem::take(&mut rest).split_at_mut(len);
            groups.push((first, group));
            rest = tail;
            first += len;
        }
        // Each particle's proposal mean, for the path tree, in particle order.
        let results: Vec<Result<Vec<Pose>>> = groups
            .into_par_iter()
            .map(|(first, group)| {
                with_thread_scratch(|sc| {
                    let mut rngs: Vec<Rng> = (first..first + group.len())
                        .map(|j| Rng::stream(cfg.seed, step, j as u64))
                        .collect();
                    if let (ClamProposal::ScanMatch(settings), Some(prepared)) =
                        (&cfg.proposal, &prepared)
                    {
                        let leader = &mut group[0];
                        let proposals = propose_by_scan_match(
                            cfg,
                            settings,
                            prepared,
                            leader.pose,
                            &mut leader.map,
                            leader.hits.as_ref(),
                            u,
                            n_steps,
                            scan,
                            &mut rngs,
                            sc,
                        )?;
                        let mut means = Vec::with_capacity(group.len());
                        for (p, proposed) in group.iter_mut().zip(proposals) {
                            p.pose = proposed.pose;
                            p.log_w += proposed.dlogw;
                            if pending == PendingUpdate::None {
                                update_map_at_pose(cfg, p, scan, sc)?;
                            }
                            means.push(proposed.mean);
                        }
                        return Ok(means);
                    }
                    let (p, rng) = (&mut group[0], &mut rngs[0]);
                    if cfg.proposal == ClamProposal::Odometry {
                        // Weight and map update share one walk of every beam (same pre-scan
                        // beliefs); a deferred update weighs alone, with the same weight.
                        let mean = compose(p.pose, u);
                        let pose = cfg.motion.sample(p.pose, u, n_steps, rng);
                        let ll = if pending == PendingUpdate::Deferred {
                            weigh_at_pose(cfg, &mut p.map, pose, scan, sc)?
                        } else {
                            let sensor = compose(pose, scan.laser_offset);
                            fused_update(cfg, &mut p.map, sensor, scan, sc)?
                        };
                        p.pose = pose;
                        p.log_w += ll / cfg.tempering;
                        return Ok(vec![mean]);
                    }
                    let proposed = propose(cfg, p, u, n_steps, scan, rng, sc)?;
                    p.pose = proposed.pose;
                    p.log_w += proposed.dlogw;
                    if pending == PendingUpdate::None {
                        update_map_at_pose(cfg, p, scan, sc)?;
                    }
                    Ok(vec![proposed.mean])
                })
            })
            .collect();
        let means: Vec<Pose> = results
            .into_iter()
            .collect::<Result<Vec<Vec<Pose>>>>()?
            .into_iter()
            .flatten()
            .collect();
        self.paths.advance(
            self.particles
                .iter_mut()
                .zip(means)
                .map(|(p, mean)| (&mut p.path, p.pose, mean)),
        );
        let step_out = self.reweight_and_resample(pending, scan)?;
        self.tracker.processed(scan.odom);
        self.estimate_odom = scan.odom;
        self.n_processed += 1;
        Ok(step_out)
    }

    fn integrate_first(&mut self, scan: &ScanInput) -> Result<()> {
        let cfg = &self.cfg;
        let results: Vec<Result<()>> = self
            .particles
            .par_iter_mut()
            .map(|p| with_thread_scratch(|sc| update_map_at_pose(cfg, p, scan, sc)))
            .collect();
        results.into_iter().collect::<Result<Vec<()>>>()?;
        self.paths.advance(
            self.particles
                .iter_mut()
                .map(|p| (&mut p.path, p.pose, p.pose)),
        );
        self.weighed = uniform_set(&self.particles);
        self.estimate = if self.cfg.init_sigma == [0.0; 3] {
            self.initial
        } else {
            weighted_mean_pose(&self.weighed.poses, &self.weighed.weights)
        };
        self.tracker.processed(scan.odom);
        self.estimate_odom = scan.odom;
        self.n_processed += 1;
        Ok(())
    }

    /// Updates the maps of the particles marked in `keep` that `pending` left behind.
    fn update_kept_maps(
        &mut self,
        pending: PendingUpdate,
        scan: &ScanInput,
        keep: &[bool],
    ) -> Result<()> {
        if pending == PendingUpdate::None {
            return Ok(());
        }
        let cfg = &self.cfg;
        let results: Vec<Result<()>> = self
            .particles
            .par_iter_mut()
            .zip(keep.par_iter())
            .filter(|(_, &k)| k)
            .map(|(p, _)| with_thread_scratch(|sc| update_map_at_pose(cfg, p, scan, sc)))
            .collect();
        results.into_iter().collect()
    }

    fn reweight_and_resample(
        &mut self,
        pending: PendingUpdate,
        scan: &ScanInput,
    ) -> Result<FilterStep> {
        let logw: Vec<f64> = self.particles.iter().map(|p| p.log_w).collect();
        let w = normalize_log_weights(&logw);
        let neff = effective_sample_size(&w);
        let poses: Vec<Pose> = self.particles.iter().map(|p| p.pose).collect();
        self.estimate = weighted_mean_pose(&poses, &w);
        self.weighed = WeighedSet {
            poses,
            weights: w.clone(),
            nodes: self.particles.iter().map(|p| p.path).collect(),
        };
        let best = w
            .iter()
            .enumerate()
            .fold(0, |b, (i, &x)| if x > w[b] { i } else { b });
        let n = self.particles.len();
        // Keep log-weights bounded: subtract the max (weights are only relative).
        let mx = logw.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let resampled = neff < self.cfg.resample_threshold * n as f64;
        if resampled {
            let u0 = Rng::stream(self.cfg.seed, self.step, u64::MAX).uniform();
            let idx = systematic_resample(&w, u0);
            let mut keep = vec![false; n];
            for &i in &idx {
                keep[i] = true;
            }
            self.update_kept_maps(pending, scan, &keep)?;
            // Children are clones: their maps share every tile with the parent until written.
            let new: Vec<ClamParticle> = idx
                .iter()
                .map(|&i| {
                    let mut c = self.particles[i].clone();
                    c.log_w = -(n as f64).ln();
                    c
                })
                .collect();
            self.best = idx.iter().position(|&i| i == best).unwrap_or(0);
            self.particles = new;
            self.parents = idx;
            self.n_resamples += 1;
        } else {
            self.parents = (0..n).collect();
            self.update_kept_maps(pending, scan, &vec![true; n])?;
            for p in &mut self.particles {
                p.log_w = if mx.is_finite() {
                    p.log_w - mx
                } else {
                    -(n as f64).ln()
                };
            }
            self.best = best;
        }
        Ok(FilterStep {
            processed: true,
            estimate: self.estimate,
            neff,
            resampled,
        })
    }
}

/// The odometry proposal's weight and map update in one walk; returns Σ log η.
fn fused_update(
    cfg: &ClamConfig,
    map: &mut CrmMap,
    sensor: Pose,
    scan: &ScanInput,
    sc: &mut CrmScratch,
) -> Result<f64> {
    let opts = scan_opts(cfg, cfg.map_stride);
    let (ll, _, _) = map.weigh_and_update_scan(
        sensor,
        scan.angles,
        scan.ranges,
        &cfg.weight_model,
        cfg.weight_stride,
        &cfg.mapping_model,
        &opts,
        sc,
    )?;
    Ok(ll)
}

/// Updates the particle's map with the scan taken at its current pose (`mapping_model`).
fn update_map_at_pose(
    cfg: &ClamConfig,
    p: &mut ClamParticle,
    scan: &ScanInput,
    sc: &mut CrmScratch,
) -> Result<()> {
    let sensor = compose(p.pose, scan.laser_offset);
    let opts = scan_opts(cfg, cfg.map_stride);
    p.map.update_scan(
        sensor,
        scan.angles,
        scan.ranges,
        &cfg.mapping_model,
        &opts,
        sc,
    )?;
    if let Some(hits) = &mut p.hits {
        let model = &cfg.mapping_model;
        hits.record_scan(
            sensor,
            scan.angles,
            scan.ranges,
            model.z_min,
            model.z_max,
            cfg.map_stride,
        )?;
    }
    Ok(())
}

crate::rbpf::common::impl_particle_filter!(RbpfClam);
