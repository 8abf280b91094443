//! RBPF-CLAM's scan-match proposal: GMapping's improved proposal searched on the scan's
//! endpoints against the particle's confidence-rich map, and the paper's closed-form CRM
//! predictive likelihood as the weight, once per particle.
//!
//! The likelihood-mode proposal ([`super::ClamProposal::LikelihoodMode`]) climbs and samples the CRM likelihood
//! itself: some 40-60 full scan likelihoods per particle, each walking every cell of every
//! beam. Here the search reads only a window of cells around each beam's endpoint:
//! 1. start from the odometry guess (`Sample`) or a motion-model sample (`Match`);
//! 2. hill-climb GMapping's endpoint score on the map's expected occupancy (a cell is occupied
//!    when m̂ > `occupied_above`, see [`super::MatchSurface::around_crm`]), or with
//!    [`MatchClimb::Posterior`] the endpoint log-likelihood × the motion density, the function
//!    the lattice of step 3 evaluates;
//! 3. evaluate GMapping's endpoint likelihood × the motion density on the 3×3×3 lattice around
//!    the match, fit a Gaussian, draw the new pose from it (or keep the match);
//! 4. weight: the importance weight of the new pose x under the paper's target, with the CRM
//!    predictive log-likelihood of the scan (`weight_model`, every `weight_stride`-th beam):
//!    log p(z | x, m) + log p(x | x', u) − log q(x), divided by the tempering τ. The readings
//!    the matcher uses beyond z_max (`match_range`, none by default) are part of z: the CRM,
//!    updated only below z_max, scores the readings below it, GMapping's endpoint likelihood
//!    the ones beyond (see [`MatchRange::Full`]). The proposal q
//!    is fitted to the endpoint likelihood, not to the CRM's, so the weight must correct for
//!    the draw: a draw that lands off the CRM's peak loses weight. With `Match` (no draw, q a
//!    point mass at the match) it is the target's height at the match.
//!
//! A scan with no matching beam (score ≤ `min_score`, e.g. the first scans in a new room) falls
//! back to the paper's proposal: a motion-model sample weighed by the CRM likelihood there.
//!
//! With [`Degeneracy::Remap`], on a scan that leaves a direction free ([`super::degeneracy`]:
//! a featureless corridor's axis) the match of step 2 keeps its start's coordinate along that
//! direction, and the CRM likelihood of step 4 is read at the drawn pose moved back along it to
//! the odometry's prediction (the motion and proposal densities stay at the drawn pose).
//!
//! With [`ScanMatchWeight::Endpoint`] the weight is instead GMapping's: the log of the lattice
//! normaliser of the endpoint likelihood × motion density (the endpoint log-likelihood at the
//! motion-model pose when nothing matched), divided by τ; no CRM likelihood is evaluated.

use crate::crm::{CrmMap, CrmScratch};
use crate::error::Result;
use crate::pose::{between, compose, wrap, Pose};
use crate::rbpf::clam_config::ClamConfig;
pub use crate::rbpf::clam_config::{
    Degeneracy, MatchClimb, MatchRange, ScanMatchSettings, ScanMatchWeight, NO_RETURN_TOLERANCE,
};
use crate::rbpf::clam_particle::weigh_at_pose;
use crate::rbpf::common::{ProposalPose, ScanInput};
use crate::rbpf::correlative::{
    self, depth_for_window, field_rect, CorrelativeMatch, CorrelativeSettings, LikelihoodField,
};
use crate::rbpf::degeneracy;
use crate::rbpf::hit_means::HitMeans;
use crate::rbpf::motion_prior::MotionPrior;
use crate::rbpf::proposal::Proposed;
use crate::rbpf::scanmatch::{PreparedScan, ScanMatcher};
use crate::rng::Rng;

/// Standard deviations (m, m, rad) added in quadrature to the motion density the lattice uses,
/// so that a robot standing still (zero variance under Thrun's model) still has a proper prior.
const MOTION_FLOOR: [f64; 3] = [0.01, 0.01, 0.01];

/// The scan's beams as the matcher uses them: every `matcher.beam_stride`-th reading that
/// `settings.match_range` selects (the paper's: below the weight and mapping models' z_max, where
/// the maps are), with `largest` the largest finite reading given to the filter so far (the
/// no-return rule of [`MatchRange::Full`]).
pub(crate) fn prepare_scan(
    cfg: &ClamConfig,
    settings: &ScanMatchSettings,
    scan: &ScanInput,
    largest: f64,
) -> Result<PreparedScan> {
    let z_max = cfg.weight_model.z_max.min(cfg.mapping_model.z_max);
    let mut prepared = PreparedScan::select(
        scan.angles,
        scan.ranges,
        scan.laser_offset,
        settings.match_range.selection(z_max, largest),
        settings.matcher.beam_stride,
    )?;
    if settings.degeneracy == Degeneracy::Remap {
        let points: Vec<[f64; 2]> = prepared.near_endpoints().collect();
        prepared.free_direction = degeneracy::free_direction(&points);
    }
    Ok(prepared)
}

/// Relative gain in the endpoint score that the climb from the correlative match must show over
/// the climb from the odometry's guess before it replaces the guess: a tie keeps the odometry.
const CLIMB_GAIN: f64 = 0.01;

/// The odometry increment the particles start from, after the correlative search of
/// `front_end` around `compose(prev, u)` on `map` (the best particle's map, `hits` its hit
/// means, `prev` its pose), and the search's result (`None` when the scan has no endpoint below
/// z_max to search with).
///
/// The search's pose lies on a lattice of whole cells and heading steps, and its field is
/// coarser than the endpoint matcher's, so it does not replace the guess by itself: when it is
/// confident ([`CorrelativeMatch::is_confident`]), GMapping's hill climb runs from both the guess
/// and the match on the best particle's map, and the increment becomes the one to the climb
/// from the match only when that climb scores higher by more than [`CLIMB_GAIN`]. Where the
/// odometry is good both climbs end at the same pose and the increment is `u` unchanged.
#[allow(clippy::too_many_arguments)]
pub(crate) fn corrected_increment(
    cfg: &ClamConfig,
    settings: &ScanMatchSettings,
    front_end: &CorrelativeSettings,
    prepared: &PreparedScan,
    prev: Pose,
    map: &CrmMap,
    hits: Option<&HitMeans>,
    u: Pose,
) -> Result<(Pose, Option<CorrelativeMatch>)> {
    let endpoints: Vec<[f64; 2]> = prepared.near_endpoints().collect();
    if endpoints.is_empty() {
        return Ok((u, None));
    }
    let guess = compose(prev, u);
    let g = *map.geometry();
    let z_max = cfg.weight_model.z_max.min(cfg.mapping_model.z_max);
    let rect = field_rect(&g, guess, z_max, front_end)?;
    let mut means = vec![0.0; rect.n_cells()];
    map.means_into(rect, &mut means)?;
    let occupied: Vec<bool> = means.iter().map(|&m| m > settings.occupied_above).collect();
    let w = (front_end.linear_window / g.resolution).ceil() as i64;
    let field = LikelihoodField::new(g, rect, &occupied, depth_for_window(w))?;
    let found = correlative::search(&field, &endpoints, guess, front_end)?;
    if !found.is_confident(front_end) {
        return Ok((u, Some(found)));
    }
    let matcher = ScanMatcher {
        params: settings.matcher,
    };
    let surface = crate::rbpf::match_surface::MatchSurface::around_crm(
        map,
        hits,
        prepared,
        guess,
        settings.matcher.kernel_size,
        settings.matcher.free_test,
        settings.occupied_above,
    );
    let (_, from_guess) = matcher.optimize(&surface, prepared, guess)?;
    let (climbed, from_match) = matcher.optimize(&surface, prepared, found.pose)?;
    let increment = if from_match > from_guess * (1.0 + CLIMB_GAIN) {
        // Along a direction the scan leaves free the search says nothing: the guess stays.
        let climbed = match prepared.free_direction {
            Some(d) => degeneracy::along_to(climbed, guess, degeneracy::to_world(d, climbed[2])),
            None => climbed,
        };
        between(prev, climbed)
    } else {
        u
    };
    Ok((increment, Some(found)))
}

/// Proposes a particle's new pose by scan matching and weighs it (see the module documentation).
///
/// `rngs` holds one random stream per particle that starts from `prev` on `map`: with
/// [`ProposalPose::Sample`] the children of one parent right after a resampling share the map,
/// the pose and so the whole search (the climb and the lattice, a pure function of the three),
/// and each draws and weighs its own pose; the results are those of one call per child. With
/// [`ProposalPose::Match`] the climb starts from each particle's own motion draw, so `rngs` must
/// hold one stream. Returns one proposal per stream, in order.
#[allow(clippy::too_many_arguments)]
pub(crate) fn propose_by_scan_match(
    cfg: &ClamConfig,
    settings: &ScanMatchSettings,
    prepared: &PreparedScan,
    prev: Pose,
    map: &mut CrmMap,
    hits: Option<&HitMeans>,
    u: Pose,
    n_steps: usize,
    scan: &ScanInput,
    rngs: &mut [Rng],
    sc: &mut CrmScratch,
) -> Result<Vec<Proposed>> {
    let matcher = ScanMatcher {
        params: settings.matcher,
    };
    let params = &settings.lattice;
    // With `Match` nothing is drawn after the climb, so it starts from a motion-model sample (as
    // in GMapping): from the odometry guess, the children of one parent would stay copies.
    let start = match params.pose {
        ProposalPose::Sample => compose(prev, u),
        ProposalPose::Match => {
            let [rng] = rngs else {
                return Err(crate::error::CrlamError::Config {
                    field: "proposal_pose",
                    reason:
                        "a kept match climbs from each particle's own draw: one particle per call"
                            .into(),
                });
            };
            cfg.motion.sample(prev, u, n_steps, rng)
        }
    };
    let prior = MotionPrior::new(&cfg.motion, prev, u, n_steps, MOTION_FLOOR);
    // The direction the scan leaves free, in the world at a pose's heading (where the scan
    // lies along the map's walls), and the prediction the weight reads the scan at along it.
    let predicted = compose(prev, u);
    let free = prepared.free_direction;
    let along_prediction = |pose: Pose, anchor: Pose| match free {
        Some(d) => degeneracy::along_to(pose, anchor, degeneracy::to_world(d, pose[2])),
        None => pose,
    };
    let weigh_pose = |pose: Pose| along_prediction(pose, predicted);
    // What the endpoint model says, read while the surface borrows the map.
    let outcomes = {
        let surface = crate::rbpf::match_surface::MatchSurface::around_crm(
            map,
            hits,
            prepared,
            start,
            settings.matcher.kernel_size,
            settings.matcher.free_test,
            settings.occupied_above,
        );
        let (matched, score) = match settings.climb {
            MatchClimb::Score => matcher.optimize(&surface, prepared, start)?,
            MatchClimb::Posterior => {
                let (matched, _) = matcher
                    .optimize_posterior(&surface, prepared, start, |x| prior.log_density(x))?;
                (matched, matcher.score(&surface, prepared, matched)?)
            }
        };
        // Solution remapping: along a direction the scan leaves free, the match keeps its
        // start's coordinate.
        let (matched, score) = match free {
            Some(_) => {
                let remapped = along_prediction(matched, start);
                (remapped, matcher.score(&surface, prepared, remapped)?)
            }
            None => (matched, score),
        };
        let fit = if score > params.min_score {
            Some(matcher.fit_proposal(
                &surface,
                prepared,
                matched,
                |x| prior.log_density(x),
                params,
            )?)
        } else {
            None
        };
        let mut outcomes = Vec::with_capacity(rngs.len());
        for rng in rngs.iter_mut() {
            let outcome = match &fit {
                Some(fit) => {
                    let (pose, mean, log_q) = match params.pose {
                        ProposalPose::Sample => {
                            let draw = fit.draw(rng);
                            (
                                draw.pose,
                                draw.mean,
                                gaussian_log_density(draw.pose, draw.mean, &draw.covariance),
                            )
                        }
                        ProposalPose::Match => (matched, matched, 0.0),
                    };
                    let log_eta = fit.log_normalizer();
                    Outcome::Matched {
                        pose,
                        mean,
                        log_q,
                        log_eta,
                    }
                }
                None => {
                    // Nothing to match against: the paper's proposal.
                    let pose = match params.pose {
                        ProposalPose::Sample => cfg.motion.sample(prev, u, n_steps, rng),
                        ProposalPose::Match => start,
                    };
                    let endpoint_ll = matcher.evaluate(&surface, prepared, pose)?.log_likelihood;
                    Outcome::Unmatched { pose, endpoint_ll }
                }
            };
            // The returns beyond z_max that the matcher used are part of the measurement: the
            // weight scores them with the endpoint model (the CRM scores those below z_max).
            let far_ll = match (settings.weight, &outcome) {
                (
                    ScanMatchWeight::Crm,
                    Outcome::Matched { pose, .. } | Outcome::Unmatched { pose, .. },
                ) => matcher.far_log_likelihood(&surface, prepared, weigh_pose(*pose))?,
                (ScanMatchWeight::Endpoint, _) => 0.0,
            };
            outcomes.push((outcome, far_ll));
        }
        outcomes
    };
    let tau = cfg.tempering;
    outcomes
        .into_iter()
        .map(|(outcome, far_ll)| {
            Ok(match (outcome, settings.weight) {
                (Outcome::Unmatched { pose, .. }, ScanMatchWeight::Crm) => Proposed {
                    pose,
                    mean: pose,
                    dlogw: (weigh_at_pose(cfg, map, weigh_pose(pose), scan, sc)? + far_ll) / tau,
                },
                (Outcome::Unmatched { pose, endpoint_ll }, ScanMatchWeight::Endpoint) => Proposed {
                    pose,
                    mean: pose,
                    dlogw: endpoint_ll / tau,
                },
                (
                    Outcome::Matched {
                        pose, mean, log_q, ..
                    },
                    ScanMatchWeight::Crm,
                ) => {
                    let ll = weigh_at_pose(cfg, map, weigh_pose(pose), scan, sc)? + far_ll;
                    Proposed {
                        pose,
                        mean,
                        dlogw: (ll + prior.log_density(pose) - log_q) / tau,
                    }
                }
                (
                    Outcome::Matched {
                        pose,
                        mean,
                        log_eta,
                        ..
                    },
                    ScanMatchWeight::Endpoint,
                ) => Proposed {
                    pose,
                    mean,
                    dlogw: log_eta / tau,
                },
            })
        })
        .collect()
}

/// What the endpoint search gave one particle.
enum Outcome {
    /// A match: the new pose, the proposal's mean, log q(pose) (0 when the match is kept) and
    /// the log of the lattice normaliser.
    Matched {
        pose: Pose,
        mean: Pose,
        log_q: f64,
        log_eta: f64,
    },
    /// No beam matched: a motion-model pose and the endpoint log-likelihood there.
    Unmatched { pose: Pose, endpoint_ll: f64 },
}

/// log N(x; mean, cov) over (x, y, θ), the heading residual wrapped to (−π, π]; −∞ would need a
/// singular covariance, which the proposal's regularisation rules out (0 is returned then).
fn gaussian_log_density(x: Pose, mean: Pose, cov: &[[f64; 3]; 3]) -> f64 {
    let Some(l) = crate::rbpf::scanmatch::cholesky3(cov) else {
        return 0.0;
    };
    let d = [x[0] - mean[0], x[1] - mean[1], wrap(x[2] - mean[2])];
    // Forward substitution: L y = d, so dᵀ Σ⁻¹ d = |y|².
    let mut y = [0.0; 3];
    for r in 0..3 {
        let s: f64 = (0..r).map(|c| l[r][c] * y[c]).sum();
        y[r] = (d[r] - s) / l[r][r];
    }
    let log_det_half: f64 = (0..3).map(|i| l[i][i].ln()).sum();
    -0.5 * (y[0] * y[0] + y[1] * y[1] + y[2] * y[2])
        - log_det_half
        - 1.5 * (2.0 * std::f64::consts::PI).ln()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rbpf::scanmatch::MatcherParams;

    /// The children of one parent search once and draw each with its own stream: the same
    /// proposals, bit for bit, as one search per child; a kept match takes one particle a call.
    #[test]
    fn children_of_one_parent_share_the_search_and_keep_their_own_draws() {
        let (cfg, map, angles, ranges) = crate::rbpf::proposal::tests::room_scan(8.0);
        let scan = ScanInput {
            odom: [0.0; 3],
            angles: &angles,
            ranges: &ranges,
            laser_offset: [0.0; 3],
        };
        let mut settings = ScanMatchSettings::default();
        let prepared = prepare_scan(&cfg, &settings, &scan, 2.5).unwrap();
        let (prev, u) = ([0.04, -0.02, 0.02], [0.03, 0.02, -0.01]);
        let stream = |k: u64| Rng::stream(3, 7, k);
        let mut sc = CrmScratch::default();
        let propose = |settings: &ScanMatchSettings, rngs: &mut [Rng], sc: &mut CrmScratch| {
            let mut m = map.clone();
            propose_by_scan_match(
                &cfg, settings, &prepared, prev, &mut m, None, u, 1, &scan, rngs, sc,
            )
        };
        let mut together: Vec<Rng> = (0..4).map(stream).collect();
        let shared = propose(&settings, &mut together, &mut sc).unwrap();
        assert_eq!(shared.len(), 4);
        for (k, s) in shared.iter().enumerate() {
            let alone = propose(&settings, &mut [stream(k as u64)], &mut sc).unwrap();
            assert_eq!(alone.len(), 1);
            assert_eq!((alone[0].pose, alone[0].mean), (s.pose, s.mean));
            assert_eq!(alone[0].dlogw.to_bits(), s.dlogw.to_bits());
        }
        // A match was fitted (the means are its mean, not the poses) and each child drew its own pose.
        assert!(shared
            .iter()
            .all(|s| s.mean == shared[0].mean && s.pose != s.mean));
        assert!(shared.windows(2).all(|w| w[0].pose != w[1].pose));
        settings.lattice.pose = ProposalPose::Match;
        assert!(propose(&settings, &mut [stream(0), stream(1)], &mut sc).is_err());
        assert_eq!(
            propose(&settings, &mut [stream(0)], &mut sc).unwrap().len(),
            1
        );
    }

    /// A straight corridor along x (walls 0.1 m thick at y = ±1.25 m, longer than the laser's
    /// 8 m reach) mapped from scans along its axis, and the scan at the origin: its walls fix y
    /// and the heading, nothing fixes x.
    fn corridor() -> (CrmMap, PreparedScan) {
        let (_, map, angles, ranges) = corridor_scan();
        let prepared = PreparedScan::select(
            &angles,
            &ranges,
            [0.0; 3],
            crate::rbpf::prepared_scan::BeamSelection::below(8.0),
            1,
        )
        .unwrap();
        (map, prepared)
    }

    /// [`corridor`]'s filter settings, map and scan (its beam angles and readings).
    fn corridor_scan() -> (ClamConfig, CrmMap, Vec<f64>, Vec<f64>) {
        use crate::crm::CrmConfig;
        use crate::grid::GridGeometry;
        use crate::rbpf::clam_config::scan_opts;
        use crate::sim::WorldRaster;
        let (nx, ny, res) = (800usize, 60usize, 0.05);
        let world_geometry = GridGeometry::new([-20.0, -1.5], res).unwrap();
        let mut occupied = vec![0u8; nx * ny];
        for iy in 0..ny {
            let y = -1.5 + (iy as f64 + 0.5) * res;
            if (y.abs() - 1.275).abs() < 0.05 {
                occupied[iy * nx..(iy + 1) * nx].fill(1);
            }
        }
        let world = WorldRaster::new(world_geometry, nx, ny, &occupied).unwrap();
        let angles: Vec<f64> = (0..181)
            .map(|i| -std::f64::consts::FRAC_PI_2 + i as f64 * std::f64::consts::PI / 180.0)
            .collect();
        let cast = |pose: Pose| {
            let mut ranges = vec![0.0; angles.len()];
            world.cast(&[pose], &angles, 8.0, &mut ranges).unwrap();
            ranges
        };
        let cfg = ClamConfig::paper(
            CrmConfig::new(GridGeometry::new([0.0, 0.0], 0.1).unwrap()),
            8.0,
        );
        let mut map = CrmMap::new(&cfg.crm).unwrap();
        let mut sc = CrmScratch::default();
        for k in -6..=6 {
            let pose = [0.5 * k as f64, 0.0, 0.0];
            let ranges = cast(pose);
            map.update_scan(
                pose,
                &angles,
                &ranges,
                &cfg.mapping_model,
                &scan_opts(&cfg, 1),
                &mut sc,
            )
            .unwrap();
        }
        let ranges = cast([0.0; 3]);
        (cfg, map, angles, ranges)
    }

    /// Along the corridor's axis, which the scan leaves free, the remapped proposal keeps the
    /// odometry's prediction (GMapping's climb slides along it); across it the scan still
    /// decides.
    #[test]
    fn remapping_keeps_the_prediction_along_the_corridor() {
        let (cfg, map, angles, ranges) = corridor_scan();
        let scan = ScanInput {
            odom: [0.0; 3],
            angles: &angles,
            ranges: &ranges,
            laser_offset: [0.0; 3],
        };
        let (prev, u) = ([0.0; 3], [0.4, 0.15, 0.04]);
        let run = |degeneracy: Degeneracy| {
            let settings = ScanMatchSettings {
                degeneracy,
                ..ScanMatchSettings::default()
            };
            let prepared = prepare_scan(&cfg, &settings, &scan, 8.0).unwrap();
            let mut rngs: Vec<Rng> = (0..6).map(|k| Rng::stream(5, 1, k)).collect();
            let mut m = map.clone();
            let mut sc = CrmScratch::default();
            let out = propose_by_scan_match(
                &cfg, &settings, &prepared, prev, &mut m, None, u, 1, &scan, &mut rngs, &mut sc,
            )
            .unwrap();
            (prepared.free_direction, out)
        };
        let (free, remapped) = run(Degeneracy::Remap);
        let d = free.expect("the corridor's scan is degenerate");
        assert!(d[0].abs() > 0.99, "{d:?}");
        let (none, plain) = run(Degeneracy::Off);
        assert!(none.is_none());
        // The children share one search: one proposal mean each way.
        let (mr, mp) = (remapped[0].mean, plain[0].mean);
        assert!(remapped.iter().all(|r| r.mean == mr) && plain.iter().all(|r| r.mean == mp));
        // Along the axis: the remapped match stays at the prediction (the lattice's Gaussian
        // fit may move its mean by millimetres), GMapping's climb slides.
        let along = |m: Pose| (m[0] - u[0]).abs();
        assert!(along(mr) < 0.005, "{mr:?}");
        assert!(along(mp) > 2.0 * along(mr), "{mp:?} against {mr:?}");
        // Across it and in heading the scan decides either way: both pull y from the guess's
        // 0.15 m towards the scan's pose, to within millimetres of each other.
        assert!(
            mr[1] < 0.1 && (mr[1] - mp[1]).abs() < 0.005,
            "{mr:?} {mp:?}"
        );
        assert!((mr[2] - mp[2]).abs() < 1e-3, "{mr:?} {mp:?}");
        // The draws keep their own spread, and every weight is finite.
        assert!(remapped.windows(2).all(|w| w[0].pose != w[1].pose));
        assert!(remapped.iter().all(|r| r.dlogw.is_finite()));
    }

    /// The surface the default scan-match settings read for `prepared` near `pose` on `map`.
    fn default_surface<'a>(
        map: &'a CrmMap,
        prepared: &PreparedScan,
        pose: Pose,
    ) -> crate::rbpf::match_surface::MatchSurface<'a> {
        let settings = ScanMatchSettings::default();
        crate::rbpf::match_surface::MatchSurface::around_crm(
            map,
            None,
            prepared,
            pose,
            settings.matcher.kernel_size,
            settings.matcher.free_test,
            settings.occupied_above,
        )
    }

    /// The posterior climb corrects what the scan fixes (across the corridor, the heading) as
    /// the likelihood alone does, and keeps what the scan leaves free (along the corridor) where
    /// the motion density puts it; GMapping's score climb slides along the corridor.
    #[test]
    fn the_posterior_climb_keeps_the_odometry_where_the_scan_leaves_the_pose_free() {
        let (map, prepared) = corridor();
        let matcher = ScanMatcher {
            params: MatcherParams::default(),
        };
        // The odometry's guess: 0.4 m along the corridor, 0.15 m across and 0.04 rad off the
        // pose the scan was taken from; the motion model's spread 2 cm along the corridor (the
        // direction of travel), 0.2 m across, 0.1 rad.
        let guess = [0.4, 0.15, 0.04];
        let surface = default_surface(&map, &prepared, guess);
        let prior = MotionPrior::from_sigma(guess, 0.0, [0.02, 0.2, 0.1], [0.0; 3]);
        let (climbed, value) = matcher
            .optimize_posterior(&surface, &prepared, guess, |x| prior.log_density(x))
            .unwrap();
        let (alone, _) = matcher
            .optimize_posterior(&surface, &prepared, guess, |_| 0.0)
            .unwrap();
        let (scored, _) = matcher.optimize(&surface, &prepared, guess).unwrap();
        assert!(
            (climbed[0] - guess[0]).abs() < 0.01,
            "along the corridor: {climbed:?}"
        );
        assert!(
            (scored[0] - guess[0]).abs() > 0.03,
            "the score climb: {scored:?}"
        );
        // Across the corridor and in heading the scan decides: the wall cells' centres put the
        // likelihood's peak a few centimetres off the scan's pose, the same with the motion density.
        assert!(alone[1].abs() < 0.1 && alone[2].abs() < 0.02, "{alone:?}");
        for i in 1..3 {
            assert!(
                (climbed[i] - alone[i]).abs() < 0.01,
                "{climbed:?} against {alone:?}"
            );
        }
        // The value is the objective at the climb's end, and no neighbour at the last step
        // improves on it.
        let objective = |x: Pose| {
            matcher
                .evaluate(&surface, &prepared, x)
                .unwrap()
                .log_likelihood
                + prior.log_density(x)
        };
        assert_eq!(value.to_bits(), objective(climbed).to_bits());
        let step = 0.05 / 32.0;
        for d in [
            [step, 0.0, 0.0],
            [-step, 0.0, 0.0],
            [0.0, step, 0.0],
            [0.0, -step, 0.0],
            [0.0, 0.0, step],
            [0.0, 0.0, -step],
        ] {
            let x = [climbed[0] + d[0], climbed[1] + d[1], climbed[2] + d[2]];
            assert!(objective(x) <= value, "{d:?} improves on {climbed:?}");
        }
    }

    /// Where the scan matches nothing (an unmapped area: the likelihood is flat) the posterior
    /// climb goes to the motion density's mean; GMapping's score climb does not move.
    #[test]
    fn with_a_flat_likelihood_the_posterior_climb_ends_at_the_motion_mean() {
        let (_, prepared) = corridor();
        let empty = CrmMap::new(&crate::crm::CrmConfig::new(
            crate::grid::GridGeometry::new([0.0, 0.0], 0.1).unwrap(),
        ))
        .unwrap();
        let matcher = ScanMatcher {
            params: MatcherParams::default(),
        };
        let (start, mean) = ([0.3, -0.2, 0.1], [0.0, 0.0, 0.0]);
        let surface = default_surface(&empty, &prepared, start);
        let prior = MotionPrior::from_sigma(mean, 0.0, [0.1, 0.1, 0.05], [0.0; 3]);
        let (climbed, _) = matcher
            .optimize_posterior(&surface, &prepared, start, |x| prior.log_density(x))
            .unwrap();
        for i in 0..3 {
            assert!((climbed[i] - mean[i]).abs() < 2e-3, "{climbed:?}");
        }
        let (scored, _) = matcher.optimize(&surface, &prepared, start).unwrap();
        assert_eq!(scored, start);
    }

    #[test]
    fn match_climbs_parse_by_name() {
        assert_eq!(MatchClimb::parse("score").unwrap(), MatchClimb::Score);
        assert_eq!(
            MatchClimb::parse("posterior").unwrap(),
            MatchClimb::Posterior
        );
        assert!(MatchClimb::parse("Posterior").is_err());
        assert_eq!(ScanMatchSettings::default().climb, MatchClimb::Score);
    }

    #[test]
    fn gaussian_log_density_matches_the_closed_form() {
        // Diagonal: a product of three normals.
        let cov = [[0.04, 0.0, 0.0], [0.0, 0.01, 0.0], [0.0, 0.0, 0.0025]];
        let (x, m) = ([0.3, -0.1, 3.1], [0.1, 0.0, -3.1]);
        let d = [0.2, -0.1, wrap(6.2)];
        let expected: f64 = (0..3)
            .map(|i| {
                -0.5 * d[i] * d[i] / cov[i][i] - 0.5 * (2.0 * std::f64::consts::PI * cov[i][i]).ln()
            })
            .sum();
        assert!((gaussian_log_density(x, m, &cov) - expected).abs() < 1e-12);
        // Correlated: against Σ⁻¹ computed by hand for a 2×2 block.
        let cov = [[0.05, 0.02, 0.0], [0.02, 0.03, 0.0], [0.0, 0.0, 0.01]];
        let (dx, dy) = (0.1, -0.05);
        let det2 = 0.05 * 0.03 - 0.02 * 0.02;
        let q = (0.03 * dx * dx - 2.0 * 0.02 * dx * dy + 0.05 * dy * dy) / det2;
        let expected = -0.5 * q - 0.5 * ((2.0 * std::f64::consts::PI).powi(3) * det2 * 0.01).ln();
        let got = gaussian_log_density([dx, dy, 0.0], [0.0; 3], &cov);
        assert!((got - expected).abs() < 1e-12, "{got} vs {expected}");
    }
}
