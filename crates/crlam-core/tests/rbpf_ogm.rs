//! RBPF-OGM (the GMapping-style baseline) on a synthetic room with boxes: it beats raw odometry,
//! its result does not depend on the number of threads, its scan matcher recovers a known
//! offset, and its configuration is validated.

use std::time::Instant;

use crlam_core::error::CrlamError;
use crlam_core::grid::GridGeometry;
use crlam_core::motion::MotionModel;
use crlam_core::ogm::{LogOddsGrid, LogOddsParams};
use crlam_core::pose::{between, compose, wrap, Pose};
use crlam_core::rbpf::{
    FilterStep, FreeTest, MatchSurface, MatcherParams, MotionDraws, OgmFilterConfig, PreparedScan,
    ProposalPose, RbpfOgm, ScanFit, ScanInput, ScanMatcher, UpdateTrigger,
};
use crlam_core::rng::Rng;
use crlam_core::sim::WorldRaster;

const RES: f64 = 0.05;
const NX: usize = 260; // 13 m
const NY: usize = 180; // 9 m
const Z_MAX: f64 = 10.0;
const LASER: Pose = [0.1, 0.0, 0.0];

/// A 12 m × 8 m room (walls 0.2 m thick, lower-left inner corner at (0.5, 0.5)) with boxes and
/// wall protrusions, none on the robot's path.
fn world() -> Vec<u8> {
    let mut occ = vec![0u8; NX * NY];
    let mut rect = |x0: f64, y0: f64, x1: f64, y1: f64| {
        let c = |v: f64| (v / RES).round() as usize;
        for y in c(y0)..c(y1) {
            for x in c(x0)..c(x1) {
                occ[y * NX + x] = 1;
            }
        }
    };
    rect(0.3, 0.3, 12.7, 0.5);
    rect(0.3, 8.5, 12.7, 8.7);
    rect(0.3, 0.3, 0.5, 8.7);
    rect(12.5, 0.3, 12.7, 8.7);
    rect(5.5, 3.8, 7.5, 5.2); // centre block
    rect(0.5, 0.5, 1.3, 1.1); // corner boxes
    rect(11.6, 7.7, 12.5, 8.5);
    rect(4.2, 7.6, 4.6, 8.5); // protrusions
    rect(8.6, 0.5, 9.0, 1.3);
    rect(2.5, 4.2, 2.9, 4.6); // pillar inside the loop
    occ
}

fn angles() -> Vec<f64> {
    (0..180)
        .map(|i| -std::f64::consts::FRAC_PI_2 + i as f64 * std::f64::consts::PI / 179.0)
        .collect()
}

/// True poses on an ellipse around the centre block, noisy odometry, noisy ranges.
struct Run {
    truth: Vec<Pose>,
    odom: Vec<Pose>,
    angles: Vec<f64>,
    ranges: Vec<Vec<f64>>,
}

fn truth_on_ellipse(n: usize, turns: f64) -> Vec<Pose> {
    let (cx, cy, rx, ry) = (6.5, 4.5, 4.3, 2.6);
    (0..n)
        .map(|k| {
            let s = turns * 2.0 * std::f64::consts::PI * k as f64 / n as f64;
            let (dx, dy) = (-rx * s.sin(), ry * s.cos());
            [cx + rx * s.cos(), cy + ry * s.sin(), dy.atan2(dx)]
        })
        .collect()
}

fn cast(truth: &[Pose], angles: &[f64], occ: &[u8]) -> Vec<Vec<f64>> {
    let g = GridGeometry::new([0.0, 0.0], RES).unwrap();
    let w = WorldRaster::new(g, NX, NY, occ).unwrap();
    let sensors: Vec<Pose> = truth.iter().map(|p| compose(*p, LASER)).collect();
    let mut flat = vec![0.0; truth.len() * angles.len()];
    w.cast(&sensors, angles, Z_MAX, &mut flat).unwrap();
    flat.chunks(angles.len()).map(|c| c.to_vec()).collect()
}

fn simulate(n: usize, turns: f64) -> Run {
    let occ = world();
    let angles = angles();
    let truth = truth_on_ellipse(n, turns);
    let mut rng = Rng::new(11);
    let noise = MotionModel::Gaussian {
        sigma: [0.01, 0.005, 0.008],
    };
    let mut odom = vec![[0.0; 3]];
    for k in 1..n {
        let u = between(truth[k - 1], truth[k]);
        odom.push(noise.sample(odom[k - 1], u, 1, &mut rng));
    }
    let mut ranges = cast(&truth, &angles, &occ);
    for scan in &mut ranges {
        for z in scan.iter_mut().filter(|z| z.is_finite()) {
            *z += 0.01 * rng.normal();
        }
    }
    Run {
        truth,
        odom,
        angles,
        ranges,
    }
}

fn config() -> OgmFilterConfig {
    OgmFilterConfig {
        log_odds: LogOddsParams::new(Z_MAX - 0.5),
        max_range: Z_MAX,
        trigger: UpdateTrigger {
            linear: 0.25,
            angular: 0.25,
        },
        seed: 7,
        ..Default::default()
    }
}

/// Feeds scan `k` of the run to the filter.
fn process_scan(f: &mut RbpfOgm, run: &Run, k: usize) -> FilterStep {
    f.process(&ScanInput {
        odom: run.odom[k],
        angles: &run.angles,
        ranges: &run.ranges[k],
        laser_offset: LASER,
    })
    .unwrap()
}

fn run_filter(run: &Run, cfg: OgmFilterConfig) -> (RbpfOgm, Vec<FilterStep>) {
    let mut f = RbpfOgm::new(cfg, run.truth[0]).unwrap();
    let steps = (0..run.odom.len())
        .map(|k| process_scan(&mut f, run, k))
        .collect();
    (f, steps)
}

fn position_error(a: Pose, b: Pose) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

/// Odometry expressed in the world frame (it starts at the first true pose).
fn odometry_in_world(run: &Run) -> Vec<Pose> {
    run.odom
        .iter()
        .map(|o| compose(run.truth[0], between(run.odom[0], *o)))
        .collect()
}

#[test]
fn beats_raw_odometry_on_a_loop() {
    let run = simulate(240, 1.15);
    let t0 = Instant::now();
    let (f, steps) = run_filter(&run, config());
    let secs = t0.elapsed().as_secs_f64();
    let n_proc = steps.iter().filter(|s| s.processed).count();
    let odo = odometry_in_world(&run);
    let n = run.truth.len() as f64;
    let e_filter: f64 = steps
        .iter()
        .zip(&run.truth)
        .map(|(s, t)| position_error(s.estimate, *t))
        .sum::<f64>()
        / n;
    let e_odom: f64 = odo
        .iter()
        .zip(&run.truth)
        .map(|(o, t)| position_error(*o, *t))
        .sum::<f64>()
        / n;
    let last = run.truth.len() - 1;
    let final_filter = position_error(steps[last].estimate, run.truth[last]);
    let final_odom = position_error(odo[last], run.truth[last]);
    let heading = wrap(steps[last].estimate[2] - run.truth[last][2]).abs();
    eprintln!(
        "ogm: {n_proc} processed scans in {secs:.2} s ({:.1} scans/s); mean err {e_filter:.3} m \
         vs odometry {e_odom:.3} m; final {final_filter:.3} m vs {final_odom:.3} m, heading \
         {heading:.4} rad; resamples {}; memory {:?}",
        n_proc as f64 / secs,
        f.n_resamples(),
        f.memory_stats()
    );
    assert!(
        e_odom > 0.2,
        "odometry drift too small for the test: {e_odom}"
    );
    assert!(e_filter < 0.5 * e_odom, "{e_filter} vs {e_odom}");
    assert!(
        final_filter < 0.5 * final_odom,
        "{final_filter} vs {final_odom}"
    );
    assert!(e_filter < 0.1 && heading < 0.05);
    assert_eq!(f.n_processed(), n_proc);
    // The best particle's path: one pose per processed scan, ending at that particle's pose,
    // as close to the truth as the weighted-mean estimate.
    let path = f.best_path();
    assert_eq!(path.len(), n_proc);
    assert_eq!(*path.last().unwrap(), f.particles()[f.best_index()].pose);
    let truth_processed: Vec<Pose> = steps
        .iter()
        .zip(&run.truth)
        .filter(|(s, _)| s.processed)
        .map(|(_, t)| *t)
        .collect();
    let e_path = path
        .iter()
        .zip(&truth_processed)
        .map(|(p, t)| position_error(*p, *t))
        .sum::<f64>()
        / n_proc as f64;
    assert!(e_path < 0.1, "best path {e_path} m");
    // The proposal means of the same lineage: the first scan's is its pose, later ones are the
    // fitted Gaussians' means the poses were drawn around.
    let means = f.best_path_means().expect("drawn poses record their means");
    assert_eq!(means.len(), n_proc);
    assert_eq!(means[0], path[0]);
    assert!(means.iter().zip(&path).skip(1).any(|(m, p)| m != p));
    let e_means = means
        .iter()
        .zip(&truth_processed)
        .map(|(p, t)| position_error(*p, *t))
        .sum::<f64>()
        / n_proc as f64;
    eprintln!("best path {e_path:.4} m, its proposal means {e_means:.4} m");
    assert!(e_means < 0.1, "best path means {e_means} m");
}

#[test]
fn hit_rate_cells_also_beat_raw_odometry() {
    // GMapping's counting cells and not-occupied match test (`with_hit_rate_map`), with either
    // motion draw schedule (GMapping's is per scan).
    let run = simulate(240, 1.15);
    for (draws, means) in [
        (MotionDraws::PerUpdate, false),
        (MotionDraws::PerScan, false),
        (MotionDraws::PerScan, true),
    ] {
        let mut cfg = if means {
            config().with_gmapping_map(0.1).unwrap()
        } else {
            config().with_hit_rate_map(0.1).unwrap()
        };
        assert_eq!(cfg.log_odds.hit_means, means);
        cfg.motion_draws = draws;
        assert_eq!(cfg.matcher.free_test, FreeTest::NotOccupied);
        assert_eq!((cfg.log_odds.l_occ, cfg.log_odds.l_free), (9.0, -1.0));
        let (f, steps) = run_filter(&run, cfg);
        let odo = odometry_in_world(&run);
        let mean_error = |poses: &mut dyn Iterator<Item = Pose>| {
            poses
                .zip(&run.truth)
                .map(|(p, t)| position_error(p, *t))
                .sum::<f64>()
                / run.truth.len() as f64
        };
        let e_filter = mean_error(&mut steps.iter().map(|s| s.estimate));
        let e_odom = mean_error(&mut odo.iter().copied());
        eprintln!(
            "ogm hit-rate cells (hit means {means}), {draws:?}: mean err {e_filter:.3} m vs odometry {e_odom:.3} m"
        );
        assert!(e_odom > 0.2 && e_filter < 0.5 * e_odom && e_filter < 0.1);
        // Every processed scan's cells count: the best map holds a wall cell hit far more often
        // than the ±100 clamp of the default cells would allow.
        let g = f.best_map().grid();
        let max = (0..200)
            .flat_map(|iy| (0..200).map(move |ix| (ix, iy)))
            .map(|(ix, iy)| g.get(ix, iy)[0])
            .fold(f32::MIN, f32::max);
        assert!(max > 100.0, "largest cell value {max}");
    }
}

#[test]
fn unprocessed_scans_carry_the_estimate_by_odometry() {
    let run = simulate(30, 0.1);
    let (_, steps) = run_filter(&run, config());
    assert!(steps[0].processed);
    let mut last = (steps[0].estimate, run.odom[0]);
    let mut skipped = 0;
    for (s, o) in steps.iter().zip(&run.odom).skip(1) {
        if s.processed {
            last = (s.estimate, *o);
            assert!(s.neff >= 1.0 - 1e-9);
        } else {
            skipped += 1;
            assert!(s.neff.is_nan() && !s.resampled);
            let want = compose(last.0, between(last.1, *o));
            for (w, e) in want.iter().zip(s.estimate) {
                assert!((w - e).abs() < 1e-12);
            }
        }
    }
    assert!(skipped > 0);
}

#[test]
fn proposal_pose_match_keeps_the_match_with_the_same_weights() {
    let run = simulate(240, 1.15);
    let mut matched = config();
    matched.proposal.pose = ProposalPose::Match;
    // First step after the initial scan: one map, one start pose, the same random streams, so
    // the same motion samples, the same matches and the same lattice normalisers; only the
    // final draw differs.
    let first_two = Run {
        truth: run.truth[..2].to_vec(),
        odom: run.odom[..2].to_vec(),
        angles: run.angles.clone(),
        ranges: run.ranges[..2].to_vec(),
    };
    let mut every = config();
    every.trigger = UpdateTrigger::every_scan();
    let (fs, _) = run_filter(&first_two, every.clone());
    every.proposal.pose = ProposalPose::Match;
    let (fm, _) = run_filter(&first_two, every);
    assert_eq!(fs.n_processed(), 2);
    assert_eq!(fs.log_weights(), fm.log_weights());
    assert!(fs.poses().iter().zip(fm.poses()).all(|(a, b)| *a != b));
    // Over the whole loop the match rule tracks as well as the draw; its poses are its means,
    // so it records none.
    let (f, steps) = run_filter(&run, matched);
    assert_eq!(f.best_path_means(), None);
    let odo = odometry_in_world(&run);
    let n = run.truth.len() as f64;
    let mean = |est: &mut dyn Iterator<Item = Pose>| {
        est.zip(&run.truth)
            .map(|(e, t)| position_error(e, *t))
            .sum::<f64>()
            / n
    };
    let e_filter = mean(&mut steps.iter().map(|s| s.estimate));
    let e_odom = mean(&mut odo.iter().copied());
    assert!(
        e_filter < 0.1 && e_filter < 0.5 * e_odom,
        "{e_filter} vs {e_odom}"
    );
    assert!(f.n_processed() > 10);
}

#[test]
fn result_does_not_depend_on_the_thread_count() {
    let run = simulate(40, 0.2);
    // Per-update draws on every scan, and per-scan draws with a trigger that leaves scans
    // between the processed ones (their draws use their own streams).
    for (draws, trigger) in [
        (MotionDraws::PerUpdate, UpdateTrigger::every_scan()),
        (
            MotionDraws::PerScan,
            UpdateTrigger {
                linear: 0.1,
                angular: 0.1,
            },
        ),
    ] {
        let mut cfg = config();
        cfg.trigger = trigger;
        cfg.motion_draws = draws;
        cfg.weight_smoothing = 0.0; // textbook weights: resampling happens, and is compared too
        let go = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| run_filter(&run, cfg.clone()))
        };
        let (f1, s1) = go(1);
        let (f2, s2) = go(2);
        for (a, b) in s1.iter().zip(&s2) {
            for i in 0..3 {
                assert_eq!(a.estimate[i].to_bits(), b.estimate[i].to_bits());
            }
            assert_eq!(a.resampled, b.resampled);
        }
        let bits = |f: &RbpfOgm| {
            f.log_weights()
                .iter()
                .chain(f.poses().iter().flatten())
                .map(|v| v.to_bits())
                .collect::<Vec<_>>()
        };
        assert_eq!(bits(&f1), bits(&f2));
        assert!(f1.n_resamples() > 0, "{draws:?}");
        assert!(s1.iter().any(|s| !s.processed) || draws == MotionDraws::PerUpdate);
    }
}

#[test]
fn per_scan_draws_add_step_variances() {
    // No matchable beam (every reading a no-return), so every particle keeps its motion sample
    // and the spread at the processed scan is the motion model's alone. Ten steps of 0.1 m
    // straight ahead, processed after 1 m: GMapping's model gives σx = srr·1 m = 0.1 m for one
    // draw on the whole increment, and √10 · srr·0.1 m ≈ 0.032 m for ten per-scan draws.
    let spread_x = |draws: MotionDraws| {
        let cfg = OgmFilterConfig {
            n_particles: 2000,
            motion: MotionModel::gmapping(),
            motion_draws: draws,
            log_odds: LogOddsParams::new(2.0),
            max_range: 2.0,
            trigger: UpdateTrigger {
                linear: 0.99,
                angular: 10.0,
            },
            seed: 3,
            ..Default::default()
        };
        let mut f = RbpfOgm::new(cfg, [0.0; 3]).unwrap();
        let angles = [-0.5, 0.0, 0.5];
        let ranges = [f64::INFINITY; 3];
        let mut processed = vec![];
        for k in 0..=10 {
            let step = f
                .process(&ScanInput {
                    odom: [0.1 * k as f64, 0.0, 0.0],
                    angles: &angles,
                    ranges: &ranges,
                    laser_offset: [0.0; 3],
                })
                .unwrap();
            processed.push(step.processed);
        }
        // The first scan and the tenth step only.
        assert_eq!(processed.iter().filter(|p| **p).count(), 2, "{processed:?}");
        assert!(processed[0] && processed[10]);
        let xs: Vec<f64> = f.poses().iter().map(|p| p[0]).collect();
        let n = xs.len() as f64;
        let mean = xs.iter().sum::<f64>() / n;
        let sd = (xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
        // Unbiased: the odometry's 1 m, within 4 standard errors.
        assert!(
            (mean - 1.0).abs() < 4.0 * sd / n.sqrt(),
            "mean {mean}, sd {sd}"
        );
        sd
    };
    let per_update = spread_x(MotionDraws::PerUpdate);
    let per_scan = spread_x(MotionDraws::PerScan);
    // 2000 samples estimate a standard deviation to about 1.6 %.
    assert!(
        (per_update / 0.1 - 1.0).abs() < 0.06,
        "per update {per_update}"
    );
    assert!(
        (per_scan / (0.1 / 10f64.sqrt()) - 1.0).abs() < 0.06,
        "per scan {per_scan}"
    );
}

#[test]
fn neff_is_in_range_and_resampling_keeps_n_particles() {
    let run = simulate(40, 0.2);
    let mut cfg = config();
    cfg.n_particles = 12;
    cfg.trigger = UpdateTrigger::every_scan();
    cfg.weight_smoothing = 0.0;
    cfg.resample_threshold = 1.0; // resample whenever the weights are not uniform
    let mut f = RbpfOgm::new(cfg, run.truth[0]).unwrap();
    let mut resampled = 0;
    for k in 0..run.odom.len() {
        let s = process_scan(&mut f, &run, k);
        assert!(s.neff >= 1.0 - 1e-9 && s.neff <= 12.0 + 1e-9, "{}", s.neff);
        assert_eq!(f.particles().len(), 12);
        if k == 0 {
            // The first scan is integrated once and every particle shares its tiles.
            let mem = f.memory_stats();
            assert!(mem.allocated_tiles > 0 && mem.shared_tiles == mem.allocated_tiles);
        }
        let sum: f64 = f.log_weights().iter().map(|l| l.exp()).sum();
        assert!((sum - 1.0).abs() < 1e-9);
        resampled += usize::from(s.resampled);
        assert!(f.best_index() < 12);
    }
    assert!(resampled > 0 && resampled == f.n_resamples());
    assert!(f.best_map().tile_stats().n_allocated > 0);
}

/// A map built from exact scans at known poses along the loop.
fn reference_map(
    truth: &[Pose],
    angles: &[f64],
    ranges: &[Vec<f64>],
    params: LogOddsParams,
) -> LogOddsGrid {
    let g = GridGeometry::new([0.0, 0.0], RES).unwrap();
    let mut m = LogOddsGrid::new(g, params, 32, None).unwrap();
    for (p, r) in truth.iter().zip(ranges) {
        m.update_scan(compose(*p, LASER), angles, r).unwrap();
    }
    m
}

#[test]
fn scan_matcher_recovers_a_known_offset() {
    let occ = world();
    let angles = angles();
    let truth = truth_on_ellipse(40, 1.0);
    let ranges = cast(&truth, &angles, &occ);
    // The crm-spec log-odds cells with the observed-free test, and GMapping's counting cells with
    // its not-occupied test.
    let hit_rate = LogOddsParams::hit_rate(Z_MAX - 0.5, 0.1).unwrap();
    let gmapping = LogOddsParams {
        hit_means: true,
        ..hit_rate
    };
    let mut at_truth = vec![];
    for (params, free_test) in [
        (LogOddsParams::new(Z_MAX - 0.5), FreeTest::Observed),
        (hit_rate, FreeTest::NotOccupied),
        (gmapping, FreeTest::NotOccupied),
    ] {
        at_truth.push(recovers_known_offsets(
            &truth, &angles, &ranges, params, free_test,
        ));
    }
    // Same cells, same matches; with the hit means the distances at the truth are those to where
    // the walls were hit, not to cell centres, so the likelihood there is higher.
    assert_eq!(at_truth[1].matched, at_truth[2].matched);
    assert!(
        at_truth[2].log_likelihood > at_truth[1].log_likelihood,
        "{at_truth:?}"
    );
}

fn recovers_known_offsets(
    truth: &[Pose],
    angles: &[f64],
    ranges: &[Vec<f64>],
    params: LogOddsParams,
    free_test: FreeTest,
) -> ScanFit {
    let map = reference_map(truth, angles, ranges, params);
    let matcher = ScanMatcher::new(MatcherParams {
        free_test,
        ..Default::default()
    })
    .unwrap();
    let tiles = MatchSurface::tiles(&map, free_test);
    let mut first = None;
    for k in [3usize, 17, 29] {
        let p = truth[k];
        let scan = PreparedScan::new(angles, &ranges[k], LASER, Z_MAX - 0.5, 1).unwrap();
        let at_truth = matcher.evaluate(&tiles, &scan, p).unwrap();
        first.get_or_insert(at_truth);
        assert!(at_truth.matched > scan.len() * 3 / 4);
        for off in [[0.1, 0.0, 0.05], [0.0, -0.1, -0.05], [-0.07, 0.07, 0.05]] {
            let start = [p[0] + off[0], p[1] + off[1], wrap(p[2] + off[2])];
            let (found, score) = matcher.optimize(&tiles, &scan, start).unwrap();
            let before = matcher.evaluate(&tiles, &scan, start).unwrap().score;
            assert!(score > before);
            assert!(
                position_error(found, p) < RES && wrap(found[2] - p[2]).abs() < 0.01,
                "scan {k} offset {off:?}: found {found:?}, truth {p:?}"
            );
            // The likelihood peaks at the truth, not at the offset start.
            let l_start = matcher
                .evaluate(&tiles, &scan, start)
                .unwrap()
                .log_likelihood;
            assert!(at_truth.log_likelihood > l_start);
        }
    }
    first.unwrap()
}

/// The dense patch of cell classes is only a faster way to read the grid: matches, scores and
/// likelihoods are the same to the bit with and without it, also when the climb starts far
/// enough off that some reads fall outside the patch.
#[test]
fn hit_mean_matching_equals_a_brute_force_window_search() {
    // The matcher's window search over GMapping's cells (visit order, lower-bound skips, one
    // read per occupied cell) against the plain definition: every cell of the 3x3 window that is
    // occupied, with its companion around the free point not occupied, at the distance from the
    // endpoint to the mean of its hits; the smallest wins.
    let occ = world();
    let angles = angles();
    let truth = truth_on_ellipse(40, 1.0);
    let ranges = cast(&truth, &angles, &occ);
    let params = LogOddsParams {
        hit_means: true,
        ..LogOddsParams::hit_rate(Z_MAX - 0.5, 0.1).unwrap()
    };
    let map = reference_map(&truth, &angles, &ranges, params);
    let mp = MatcherParams {
        free_test: FreeTest::NotOccupied,
        ..Default::default()
    };
    let matcher = ScanMatcher::new(mp).unwrap();
    let surface = MatchSurface::tiles(&map, FreeTest::NotOccupied);
    let g = *map.grid().geometry();
    let back = std::f64::consts::SQRT_2 * g.resolution;
    let mut rng = Rng::stream(11, 0, 0);
    let mut compared = 0;
    for k in [5usize, 20, 33] {
        let scan = PreparedScan::new(&angles, &ranges[k], LASER, Z_MAX - 0.5, 1).unwrap();
        for _ in 0..15 {
            let t = truth[k];
            let p = [
                t[0] + 0.08 * rng.normal(),
                t[1] + 0.08 * rng.normal(),
                wrap(t[2] + 0.04 * rng.normal()),
            ];
            let fit = matcher.evaluate(&surface, &scan, p).unwrap();
            let (s, c) = p[2].sin_cos();
            let (mut loglik, mut score, mut matched) = (0.0, 0.0, 0);
            for end in scan.endpoints() {
                let ray = [end[0] - LASER[0], end[1] - LASER[1]];
                let len = ray[0].hypot(ray[1]);
                let dir = [ray[0] / len, ray[1] / len];
                let e = [
                    p[0] + c * end[0] - s * end[1],
                    p[1] + s * end[0] + c * end[1],
                ];
                let f = [
                    e[0] - back * (c * dir[0] - s * dir[1]),
                    e[1] - back * (s * dir[0] + c * dir[1]),
                ];
                let (ix, iy) = g.cell_of(e[0], e[1]);
                let (fx, fy) = g.cell_of(f[0], f[1]);
                let mut best = f64::INFINITY;
                for dy in -1..=1 {
                    for dx in -1..=1 {
                        let occupied = map.log_odds(ix + dx, iy + dy) > 0.0;
                        let free = map.log_odds(fx + dx, fy + dy) <= 0.0;
                        if occupied && free {
                            let centre = g.cell_center(ix + dx, iy + dy);
                            let m = map.hit_mean_offset(ix + dx, iy + dy);
                            let d2 = (e[0] - centre[0] - m[0]).powi(2)
                                + (e[1] - centre[1] - m[1]).powi(2);
                            best = best.min(d2);
                        }
                    }
                }
                if best.is_finite() {
                    matched += 1;
                    loglik -= best / mp.likelihood_sigma;
                    score += (-best / mp.score_sigma).exp();
                } else {
                    loglik += mp.null_likelihood / mp.likelihood_sigma;
                }
            }
            assert_eq!(fit.matched, matched);
            assert!((fit.log_likelihood - loglik).abs() < 1e-9 * loglik.abs().max(1.0));
            assert!((fit.score - score).abs() < 1e-9 * score.max(1.0));
            compared += usize::from(matched > 0);
        }
    }
    assert!(compared > 30, "only {compared} poses matched anything");
}

#[test]
fn match_surface_patch_changes_no_result() {
    let occ = world();
    let angles = angles();
    let truth = truth_on_ellipse(40, 1.0);
    let ranges = cast(&truth, &angles, &occ);
    let map = reference_map(&truth, &angles, &ranges, LogOddsParams::new(Z_MAX - 0.5));
    let tiles = MatchSurface::tiles(&map, FreeTest::Observed);
    let mut patched = 0;
    for stride in [1usize, 3] {
        let matcher = ScanMatcher::new(Default::default()).unwrap();
        for k in [3usize, 17, 29] {
            let p = truth[k];
            let scan = PreparedScan::new(&angles, &ranges[k], LASER, Z_MAX - 0.5, stride).unwrap();
            for off in [[0.1, 0.0, 0.05], [-0.6, 0.9, -0.2], [1.5, -1.2, 0.4]] {
                let start = [p[0] + off[0], p[1] + off[1], wrap(p[2] + off[2])];
                let near =
                    MatchSurface::around_within(&map, &scan, p, 1, FreeTest::Observed, 10_000);
                patched += usize::from(near.has_patch());
                let a = matcher.optimize(&tiles, &scan, start).unwrap();
                let b = matcher.optimize(&near, &scan, start).unwrap();
                assert_eq!(a.0.map(f64::to_bits), b.0.map(f64::to_bits));
                assert_eq!(a.1.to_bits(), b.1.to_bits());
                let fa = matcher.evaluate(&tiles, &scan, start).unwrap();
                let fb = matcher.evaluate(&near, &scan, start).unwrap();
                assert_eq!(fa, fb);
            }
        }
    }
    assert!(patched > 0, "no patch was built: the test compares nothing");
}

fn field_of(e: CrlamError) -> &'static str {
    match e {
        CrlamError::Config { field, .. } => field,
        other => panic!("expected a config error, got {other:?}"),
    }
}

#[test]
fn config_validation_names_the_field() {
    assert!(OgmFilterConfig::default().validate().is_ok());
    let bad = |f: fn(&mut OgmFilterConfig)| {
        let mut c = OgmFilterConfig::default();
        f(&mut c);
        field_of(RbpfOgm::new(c, [0.0; 3]).unwrap_err())
    };
    assert_eq!(bad(|c| c.n_particles = 0), "n_particles");
    assert_eq!(bad(|c| c.resample_threshold = 1.5), "resample_threshold");
    assert_eq!(bad(|c| c.weight_smoothing = f64::NAN), "weight_smoothing");
    assert_eq!(bad(|c| c.geometry.resolution = 0.0), "resolution");
    assert_eq!(bad(|c| c.tile_size = 48), "tile_size");
    assert_eq!(bad(|c| c.max_range = 5.0), "max_range");
    assert_eq!(bad(|c| c.log_odds.l_free = 0.1), "l_free");
    assert_eq!(bad(|c| c.matcher.beam_stride = 0), "matcher.beam_stride");
    assert_eq!(bad(|c| c.matcher.score_sigma = -1.0), "matcher.score_sigma");
    assert_eq!(bad(|c| c.proposal.half_steps = 0), "proposal.half_steps");
    assert_eq!(bad(|c| c.proposal.range[2] = 0.0), "proposal.range");
    assert_eq!(bad(|c| c.motion_floor[0] = 0.0), "motion_floor");
    assert_eq!(bad(|c| c.init_sigma[1] = -0.1), "init_sigma");
    assert_eq!(
        bad(|c| c.motion = MotionModel::Thrun {
            alpha: [0.1, -0.1, 0.0, 0.0]
        }),
        "motion"
    );
    assert_eq!(
        bad(|c| c.trigger = UpdateTrigger {
            linear: -1.0,
            angular: 0.0
        }),
        "update_trigger"
    );
}

#[test]
fn bad_input_is_an_error_not_a_panic() {
    let mut f = RbpfOgm::new(config(), [1.0, 1.0, 0.0]).unwrap();
    assert!(RbpfOgm::new(config(), [f64::NAN, 0.0, 0.0]).is_err());
    let a = angles();
    let r = vec![1.0; 179];
    let scan = ScanInput {
        odom: [0.0; 3],
        angles: &a,
        ranges: &r,
        laser_offset: LASER,
    };
    assert!(matches!(f.process(&scan), Err(CrlamError::Shape(_))));
    let r = vec![f64::NAN; 180];
    let scan = ScanInput {
        odom: [f64::INFINITY, 0.0, 0.0],
        angles: &a,
        ranges: &r,
        laser_offset: LASER,
    };
    assert!(f.process(&scan).is_err());
    // NaN readings are ignored, not fatal, and an empty scan leaves the filter on odometry.
    for k in 0..3 {
        let scan = ScanInput {
            odom: [0.3 * k as f64, 0.0, 0.0],
            angles: &a,
            ranges: &r,
            laser_offset: LASER,
        };
        let s = f.process(&scan).unwrap();
        assert!(s.estimate.iter().all(|v| v.is_finite()));
    }
    assert_eq!(f.last_match_failures(), f.particles().len());
}

/// Throughput figure (not a check): 30 particles × 180 beams, every scan processed. Run with
/// `cargo test --release -p crlam-core --test rbpf_ogm -- --ignored --nocapture`.
#[test]
#[ignore]
fn throughput_every_scan() {
    let run = simulate(240, 1.15);
    let cfg = OgmFilterConfig {
        trigger: UpdateTrigger::every_scan(),
        ..config()
    };
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let t0 = Instant::now();
        let (f, steps) = pool.install(|| run_filter(&run, cfg.clone()));
        let secs = t0.elapsed().as_secs_f64();
        let err = steps
            .iter()
            .zip(&run.truth)
            .map(|(s, t)| position_error(s.estimate, *t))
            .sum::<f64>()
            / steps.len() as f64;
        eprintln!(
            "{threads} thread(s): {} scans in {secs:.2} s = {:.1} scans/s; mean err {err:.3} m; \
             resamples {}",
            steps.len(),
            steps.len() as f64 / secs,
            f.n_resamples()
        );
    }
}

#[test]
fn weights_are_the_smoothed_ones_behind_neff_and_the_estimate() {
    let run = simulate(30, 0.2);
    let mut cfg = config();
    cfg.n_particles = 10;
    cfg.trigger = UpdateTrigger::every_scan();
    cfg.init_sigma = [0.05, 0.05, 0.02];
    assert_eq!(cfg.weight_smoothing, 3.0);
    let mut f = RbpfOgm::new(cfg, run.truth[0]).unwrap();
    let mut unresampled = 0;
    for k in 0..run.odom.len() {
        let s = process_scan(&mut f, &run, k);
        let w = f.weights();
        assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        if s.resampled {
            assert!(w.iter().all(|x| (x - 0.1).abs() < 1e-12));
            continue;
        }
        // Not resampled: the current set is the weighed set, and N_eff is taken from these
        // weights, which are flatter than the stored log-likelihoods (divided by ogain · n).
        assert_eq!(w, f.weighed_set().weights);
        let neff = 1.0 / w.iter().map(|x| x * x).sum::<f64>();
        assert!((neff - s.neff).abs() < 1e-9 * neff);
        let lw = f.log_weights();
        let m = lw.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
        let z: f64 = lw.iter().map(|l| ((l - m) / 30.0).exp()).sum();
        for (x, l) in w.iter().zip(&lw) {
            assert!((x - ((l - m) / 30.0).exp() / z).abs() < 1e-12);
        }
        unresampled += 1;
    }
    assert!(unresampled > 0);
}

#[test]
fn released_maps_free_the_tiles_keep_the_paths_and_refuse_scans() {
    let run = simulate(30, 0.5);
    let (mut f, _) = run_filter(&run, config());
    assert!(f.map_memory().0 > 0);
    let path = f.best_path();
    f.release_maps().unwrap();
    assert!(f.maps_released());
    assert_eq!(
        f.map_memory().0,
        0,
        "every particle's map tiles are dropped"
    );
    assert_eq!(f.best_path(), path);
    let err = f
        .process(&ScanInput {
            odom: run.odom[0],
            angles: &run.angles,
            ranges: &run.ranges[0],
            laser_offset: LASER,
        })
        .unwrap_err();
    assert!(matches!(err, CrlamError::Config { .. }), "{err}");
}
