//! RBPF-CLAM end to end on a synthetic room: it beats raw odometry, and its result does not
//! depend on the number of threads.

use crlam_core::crm::CrmConfig;
use crlam_core::grid::GridGeometry;
use crlam_core::motion::MotionModel;
use crlam_core::pose::{between, compose, wrap, Pose};
use crlam_core::rbpf::{
    ClamConfig, ClamProposal, MatchRange, ProposalPose, RbpfClam, ScanInput, ScanMatchSettings,
    ScanMatchWeight,
};
use crlam_core::rng::Rng;
use crlam_core::sim::WorldRaster;

const RES_WORLD: f64 = 0.05;
const N: usize = 240; // 12 m x 12 m

fn world() -> Vec<u8> {
    let mut occ = vec![0u8; N * N];
    let mut set = |x0: usize, y0: usize, x1: usize, y1: usize| {
        for y in y0..y1 {
            for x in x0..x1 {
                occ[y * N + x] = 1;
            }
        }
    };
    set(0, 0, N, 4);
    set(0, N - 4, N, N);
    set(0, 0, 4, N);
    set(N - 4, 0, N, N);
    set(60, 60, 90, 80);
    set(150, 40, 170, 110);
    set(80, 160, 140, 170);
    set(190, 170, 200, 200);
    occ
}

/// A loop around the room's middle: true poses, noisy odometry, exact ranges.
struct Run {
    truth: Vec<Pose>,
    odom: Vec<Pose>,
    angles: Vec<f64>,
    ranges: Vec<Vec<f64>>,
}

fn simulate(n_scans: usize) -> Run {
    simulate_to(n_scans, 8.0)
}

/// [`simulate`] with readings up to `max_range` (m); none beyond (`inf`).
fn simulate_to(n_scans: usize, max_range: f64) -> Run {
    let occ = world();
    let w = WorldRaster::new(
        GridGeometry::new([0.0, 0.0], RES_WORLD).unwrap(),
        N,
        N,
        &occ,
    )
    .unwrap();
    let angles: Vec<f64> = (0..180)
        .map(|i| -std::f64::consts::FRAC_PI_2 + i as f64 * std::f64::consts::PI / 180.0)
        .collect();
    let (cx, cy, r) = (6.0, 6.5, 3.8);
    let truth: Vec<Pose> = (0..n_scans)
        .map(|k| {
            let a = 2.0 * std::f64::consts::PI * k as f64 / n_scans as f64;
            [
                cx + r * a.cos(),
                cy + r * a.sin(),
                a + std::f64::consts::FRAC_PI_2,
            ]
        })
        .collect();
    let mut rng = Rng::new(11);
    let noise = MotionModel::Gaussian {
        sigma: [0.02, 0.02, 0.01],
    };
    let mut odom = vec![truth[0]];
    for k in 1..n_scans {
        let u = between(truth[k - 1], truth[k]);
        odom.push(noise.sample(odom[k - 1], u, 1, &mut rng));
    }
    let mut flat = vec![0.0; n_scans * angles.len()];
    w.cast(&truth, &angles, max_range, &mut flat).unwrap();
    let ranges = flat.chunks(angles.len()).map(|c| c.to_vec()).collect();
    Run {
        truth,
        odom,
        angles,
        ranges,
    }
}

fn pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
}

fn config(proposal: ClamProposal) -> ClamConfig {
    let mut cfg = ClamConfig::paper(
        CrmConfig::new(GridGeometry::new([0.0, 0.0], 0.1).unwrap()),
        8.0,
    );
    cfg.n_particles = 30;
    cfg.motion = MotionModel::Gaussian {
        sigma: [0.02, 0.02, 0.01],
    };
    cfg.tempering = 10.0;
    cfg.proposal = proposal;
    cfg.seed = 5;
    cfg
}

fn run_filter(run: &Run, cfg: ClamConfig) -> Vec<Pose> {
    let mut f = RbpfClam::new(cfg, run.truth[0]).unwrap();
    run.odom
        .iter()
        .zip(&run.ranges)
        .map(|(o, r)| {
            let s = ScanInput {
                odom: *o,
                angles: &run.angles,
                ranges: r,
                laser_offset: [0.0; 3],
            };
            f.process(&s).unwrap().estimate
        })
        .collect()
}

fn mean_position_error(est: &[Pose], truth: &[Pose]) -> f64 {
    est.iter()
        .zip(truth)
        .map(|(a, b)| (a[0] - b[0]).hypot(a[1] - b[1]))
        .sum::<f64>()
        / est.len() as f64
}

#[test]
fn clam_beats_raw_odometry_with_every_proposal() {
    let run = simulate(150);
    let odo_err = mean_position_error(&run.odom, &run.truth);
    for (proposal, n_particles) in [
        (ClamProposal::Odometry, 30),
        (ClamProposal::likelihood_mode(), 8),
        (ClamProposal::likelihood_mode_with(ProposalPose::Match), 8),
        (scan_match(ProposalPose::Sample), 8),
        (scan_match(ProposalPose::Match), 8),
        (endpoint_weighed(scan_match(ProposalPose::Sample)), 8),
    ] {
        let t = std::time::Instant::now();
        let est = run_filter(
            &run,
            ClamConfig {
                n_particles,
                ..config(proposal)
            },
        );
        let err = mean_position_error(&est, &run.truth);
        eprintln!(
            "{proposal:?}: {err:.3} m vs odometry {odo_err:.3} m in {:.1} s",
            t.elapsed().as_secs_f64()
        );
        assert!(
            err < 0.5 * odo_err,
            "{proposal:?}: filter {err:.3} m vs odometry {odo_err:.3} m"
        );
    }
}

/// `proposal` (a scan match) weighed by GMapping's endpoint model instead of the CRM likelihood.
fn endpoint_weighed(proposal: ClamProposal) -> ClamProposal {
    match proposal {
        ClamProposal::ScanMatch(s) => ClamProposal::ScanMatch(ScanMatchSettings {
            weight: ScanMatchWeight::Endpoint,
            ..s
        }),
        other => other,
    }
}

fn scan_match(pose: ProposalPose) -> ClamProposal {
    let mut settings = ScanMatchSettings::default();
    settings.lattice.pose = pose;
    ClamProposal::ScanMatch(settings)
}

#[test]
fn scan_match_is_thread_independent_and_records_its_means() {
    let run = simulate(40);
    let (one, two) = (pool(1), pool(2));
    for pose in [ProposalPose::Sample, ProposalPose::Match] {
        let cfg = || config(scan_match(pose));
        assert_eq!(
            one.install(|| run_filter(&run, cfg())),
            two.install(|| run_filter(&run, cfg()))
        );
        let mut f = RbpfClam::new(cfg(), run.truth[0]).unwrap();
        feed_processed(&run, &mut f, |_| {});
        // Drawn poses keep their proposal means (the lineage's poses without the draw's jitter).
        let means = f.best_path_means();
        assert_eq!(means.is_some(), pose == ProposalPose::Sample);
        if let Some(m) = means {
            let path = f.best_path();
            assert_eq!(m.len(), path.len());
            assert!(m.iter().zip(&path).skip(1).any(|(a, b)| a != b));
        }
    }
}

#[test]
fn scan_match_settings_are_validated() {
    let bad = ScanMatchSettings {
        occupied_above: 1.0,
        ..Default::default()
    };
    let mut cfg = config(ClamProposal::ScanMatch(bad));
    assert!(RbpfClam::new(cfg.clone(), [0.0; 3]).is_err());
    let mut bad = ScanMatchSettings::default();
    bad.matcher.beam_stride = 0;
    cfg.proposal = ClamProposal::ScanMatch(bad);
    assert!(RbpfClam::new(cfg, [0.0; 3]).is_err());
}

#[test]
fn tempering_divides_the_weights_and_leaves_the_proposal_alone() {
    // Three steps of the likelihood-mode proposal with τ = 1 and τ = 4, no resampling: the
    // same proposed poses, and log-weight differences scaled by exactly 1/τ (all particles start
    // at one pose with one map, so their weights only differ from the second step on).
    let run = simulate(40);
    let step = |tempering: f64| {
        let mut cfg = config(ClamProposal::likelihood_mode());
        cfg.n_particles = 6;
        cfg.tempering = tempering;
        cfg.resample_threshold = 0.0;
        let mut f = RbpfClam::new(cfg, run.truth[0]).unwrap();
        for k in 0..4 {
            f.process(&ScanInput {
                odom: run.odom[k],
                angles: &run.angles,
                ranges: &run.ranges[k],
                laser_offset: [0.0; 3],
            })
            .unwrap();
        }
        f.particles()
            .iter()
            .map(|p| (p.pose, p.log_w))
            .collect::<Vec<_>>()
    };
    let (plain, tempered) = (step(1.0), step(4.0));
    let spread = plain.iter().map(|p| p.1).fold(f64::NEG_INFINITY, f64::max)
        - plain.iter().map(|p| p.1).fold(f64::INFINITY, f64::min);
    assert!(
        spread > 1e-3,
        "the weights must differ for the test to mean anything"
    );
    for (a, b) in plain.iter().zip(&tempered) {
        assert_eq!(a.0, b.0, "the proposal must not depend on the tempering");
        let (da, db) = (a.1 - plain[0].1, b.1 - tempered[0].1);
        assert!(
            (da - 4.0 * db).abs() < 1e-9 * da.abs().max(1.0),
            "{da} vs 4 x {db}"
        );
    }
}

#[test]
fn tempering_beams_scales_the_tempering_with_the_beam_count() {
    let run = simulate(30);
    let cfg = |tempering: f64, tempering_beams: Option<f64>| ClamConfig {
        tempering,
        tempering_beams,
        ..config(ClamProposal::Odometry)
    };
    // The workload's scans have 180 beams: τ = 2 per 90 beams is τ = 4 for each of them.
    assert_eq!(cfg(2.0, Some(90.0)).tempering_for(180), 4.0);
    assert_eq!(
        run_filter(&run, cfg(4.0, None)),
        run_filter(&run, cfg(2.0, Some(90.0)))
    );
    assert_ne!(
        run_filter(&run, cfg(4.0, None)),
        run_filter(&run, cfg(2.0, None))
    );
    // The beams that weigh count: every second beam halves them.
    let strided = ClamConfig {
        weight_stride: 2,
        ..cfg(2.0, Some(90.0))
    };
    assert_eq!(strided.tempering_for(180), 2.0);
    assert_eq!(strided.tempering_for(181), 2.0 * 91.0 / 90.0);
    for bad in [0.5, f64::NAN, f64::INFINITY] {
        assert!(
            RbpfClam::new(cfg(1.0, Some(bad)), [0.0; 3]).is_err(),
            "{bad}"
        );
    }
}

#[test]
fn same_seed_same_trajectory_with_one_and_two_threads() {
    let run = simulate(40);
    let (one, two) = (pool(1), pool(2));
    let a = one.install(|| run_filter(&run, config(ClamProposal::Odometry)));
    let b = two.install(|| run_filter(&run, config(ClamProposal::Odometry)));
    assert_eq!(a, b);
    let c = two.install(|| run_filter(&run, config(ClamProposal::Odometry)));
    assert_eq!(b, c);
}

#[test]
fn proposal_pose_match_keeps_the_climb_result_and_is_thread_independent() {
    let run = simulate(30);
    let cfg = || {
        let mut c = config(ClamProposal::likelihood_mode_with(ProposalPose::Match));
        c.n_particles = 6;
        c.resample_threshold = 0.0;
        c
    };
    let (one, two) = (pool(1), pool(2));
    assert_eq!(
        one.install(|| run_filter(&run, cfg())),
        two.install(|| run_filter(&run, cfg()))
    );
    // All particles start at one pose with one map; the climbs start from different
    // motion-model samples, so the particles must not stay identical copies.
    let mut f = RbpfClam::new(cfg(), run.truth[0]).unwrap();
    let mut g = RbpfClam::new(
        config(ClamProposal::likelihood_mode_with(ProposalPose::Sample)),
        run.truth[0],
    )
    .unwrap();
    for k in 0..3 {
        let s = ScanInput {
            odom: run.odom[k],
            angles: &run.angles,
            ranges: &run.ranges[k],
            laser_offset: [0.0; 3],
        };
        f.process(&s).unwrap();
        g.process(&s).unwrap();
    }
    let poses: Vec<Pose> = f.particles().iter().map(|p| p.pose).collect();
    assert!(
        poses.iter().any(|p| p != &poses[0]),
        "match: particles stayed identical: {poses:?}"
    );
    // Both pose rules stay near the truth.
    for p in f.particles().iter().chain(g.particles()) {
        let d = between(run.truth[2], p.pose);
        assert!(
            d[0].hypot(d[1]) < 0.2,
            "pose {:?} far from the truth",
            p.pose
        );
    }
}

#[test]
fn bad_inputs_are_errors() {
    let cfg = ClamConfig {
        n_particles: 0,
        ..config(ClamProposal::Odometry)
    };
    assert!(RbpfClam::new(cfg, [0.0; 3]).is_err());
    for lattice in [
        [0.01, 0.01, 0.0],
        [0.01, f64::NAN, 0.005],
        [-0.01, 0.01, 0.005],
    ] {
        let mut proposal = ClamProposal::likelihood_mode();
        if let ClamProposal::LikelihoodMode { lattice: l, .. } = &mut proposal {
            *l = lattice;
        }
        assert!(
            RbpfClam::new(config(proposal), [0.0; 3]).is_err(),
            "{lattice:?}"
        );
    }
    for eps in [1.0, -1e-3, f64::NAN] {
        let mut proposal = ClamProposal::likelihood_mode();
        if let ClamProposal::LikelihoodMode { motion_outlier, .. } = &mut proposal {
            *motion_outlier = eps;
        }
        assert!(RbpfClam::new(config(proposal), [0.0; 3]).is_err(), "{eps}");
    }
    let mut f = RbpfClam::new(config(ClamProposal::Odometry), [1.0, 1.0, 0.0]).unwrap();
    let s = ScanInput {
        odom: [f64::NAN, 0.0, 0.0],
        angles: &[0.0],
        ranges: &[1.0],
        laser_offset: [0.0; 3],
    };
    assert!(f.process(&s).is_err());
    let s = ScanInput {
        odom: [0.0; 3],
        angles: &[0.0, 1.0],
        ranges: &[1.0],
        laser_offset: [0.0; 3],
    };
    assert!(f.process(&s).is_err());
    let _ = compose([0.0; 3], [0.0; 3]);
}

/// Feeds every scan of `run` to `f`; calls `at_processed` after each processed scan and returns
/// the true poses of the processed scans.
fn feed_processed(
    run: &Run,
    f: &mut RbpfClam,
    mut at_processed: impl FnMut(&RbpfClam),
) -> Vec<Pose> {
    let mut truth = Vec::new();
    for ((o, r), t) in run.odom.iter().zip(&run.ranges).zip(&run.truth) {
        let s = ScanInput {
            odom: *o,
            angles: &run.angles,
            ranges: r,
            laser_offset: [0.0; 3],
        };
        if f.process(&s).unwrap().processed {
            at_processed(f);
            truth.push(*t);
        }
    }
    truth
}

#[test]
fn best_path_is_the_history_of_the_best_particle() {
    let run = simulate(80);
    let mut f = RbpfClam::new(config(ClamProposal::Odometry), run.truth[0]).unwrap();
    let mut poses_at_step: Vec<Vec<Pose>> = Vec::new();
    let truth_at_step = feed_processed(&run, &mut f, |f| {
        poses_at_step.push(f.particles().iter().map(|p| p.pose).collect())
    });
    let path = f.best_path();
    assert_eq!(path.len(), f.n_processed());
    assert!(
        f.n_resamples() > 0,
        "the test needs resampling to branch the paths"
    );
    assert_eq!(*path.last().unwrap(), f.particles()[f.best_index()].pose);
    // The ancestor of the final best particle survived every resampling, so its pose at step k
    // is among the particle poses kept at step k.
    for (k, p) in path.iter().enumerate() {
        assert!(poses_at_step[k].contains(p), "step {k}: {p:?}");
    }
    let odo_err = mean_position_error(&run.odom, &run.truth);
    let path_err = mean_position_error(&path, &truth_at_step);
    assert!(
        path_err < 0.5 * odo_err,
        "path {path_err:.3} m vs odometry {odo_err:.3} m"
    );
}

#[test]
fn best_path_means_are_the_proposal_means_of_the_best_lineage() {
    let run = simulate(80);
    let truth_processed = |f: &mut RbpfClam| feed_processed(&run, f, |_| {});
    // Only a drawn improved proposal records means.
    for proposal in [
        ClamProposal::Odometry,
        ClamProposal::likelihood_mode_with(ProposalPose::Match),
    ] {
        let mut f = RbpfClam::new(config(proposal), run.truth[0]).unwrap();
        truth_processed(&mut f);
        assert_eq!(f.best_path_means(), None);
    }
    let mut f = RbpfClam::new(config(ClamProposal::likelihood_mode()), run.truth[0]).unwrap();
    let truth = truth_processed(&mut f);
    let path = f.best_path();
    let means = f.best_path_means().expect("likelihood_mode records means");
    assert_eq!(means.len(), path.len());
    // The first scan is not proposed: its mean is the pose.
    assert_eq!(means[0], path[0]);
    // Every later pose is a draw around its mean: distinct, and within a few floor sigmas
    // (0.1 x lattice spacing = 5 mm, 2.5 mrad) plus the fitted spread.
    let mut gaps = Vec::new();
    for (k, (m, p)) in means.iter().zip(&path).enumerate().skip(1) {
        assert_ne!(m, p, "step {k}");
        let gap = (m[0] - p[0]).hypot(m[1] - p[1]);
        assert!(
            gap < 0.1 && wrap(m[2] - p[2]).abs() < 0.05,
            "step {k}: {gap}"
        );
        gaps.push(gap);
    }
    let mean_gap = gaps.iter().sum::<f64>() / gaps.len() as f64;
    assert!(
        mean_gap > 1e-3,
        "draws should scatter around the means: {mean_gap}"
    );
    let err_means = mean_position_error(&means, &truth);
    let err_path = mean_position_error(&path, &truth);
    assert!(
        err_means < err_path + 0.01,
        "means {err_means:.4} m vs drawn path {err_path:.4} m"
    );
}

#[test]
fn deferred_map_updates_change_nothing_bit_for_bit() {
    // Maps updated only once resampling keeps them (the default) against every map updated while
    // weighing: the same estimates, weights, poses and maps, with steps that resample and steps
    // that do not, for both proposals.
    let run = simulate(60);
    for proposal in [ClamProposal::Odometry, ClamProposal::likelihood_mode()] {
        let go = |defer: bool| {
            let mut cfg = config(proposal);
            cfg.n_particles = 12;
            cfg.tempering = 3.0;
            cfg.defer_map_updates = defer;
            let mut f = RbpfClam::new(cfg, run.truth[0]).unwrap();
            let mut steps = Vec::new();
            for (o, r) in run.odom.iter().zip(&run.ranges) {
                let s = ScanInput {
                    odom: *o,
                    angles: &run.angles,
                    ranges: r,
                    laser_offset: [0.0; 3],
                };
                steps.push(f.process(&s).unwrap());
            }
            (f, steps)
        };
        let (fa, sa) = go(true);
        let (fb, sb) = go(false);
        let n_resampled = sa.iter().filter(|s| s.resampled).count();
        assert!(
            n_resampled > 3 && n_resampled + 3 < sa.len(),
            "{proposal:?}: {n_resampled} resamplings"
        );
        for (a, b) in sa.iter().zip(&sb) {
            assert_eq!(a.resampled, b.resampled);
            for i in 0..3 {
                assert_eq!(
                    a.estimate[i].to_bits(),
                    b.estimate[i].to_bits(),
                    "{proposal:?}"
                );
            }
        }
        let rect = crlam_core::grid::CellRect {
            ix0: -10,
            iy0: -10,
            nx: 140,
            ny: 120,
        };
        for (p, q) in fa.particles().iter().zip(fb.particles()) {
            assert_eq!(p.log_w.to_bits(), q.log_w.to_bits());
            assert_eq!(p.pose, q.pose);
            assert_eq!(p.map.beliefs(rect).unwrap(), q.map.beliefs(rect).unwrap());
        }
    }
}

/// One odometry increment slips by 0.4 m (a wheel slip). Under the motion model alone (σ 2 cm)
/// the climb's target keeps the pose near the bad guess; with `motion_outlier` the motion density
/// has a floor of log ε, the scan's likelihood gain is far above it, and the climb moves the pose
/// back.
#[test]
fn motion_outlier_lets_the_climb_leave_a_slipped_odometry_guess() {
    let clean = simulate(150);
    let mut run = simulate(150);
    let slip = 70;
    for o in &mut run.odom[slip..] {
        // The same offset for every later reading: only the increment into `slip` is wrong.
        let h = run.truth[slip - 1][2];
        *o = [o[0] + 0.4 * h.cos(), o[1] + 0.4 * h.sin(), o[2]];
    }
    let with = |run: &Run, motion_outlier: f64| {
        let mut proposal = ClamProposal::likelihood_mode();
        if let ClamProposal::LikelihoodMode {
            motion_outlier: eps,
            ..
        } = &mut proposal
        {
            *eps = motion_outlier;
        }
        let est = run_filter(
            run,
            ClamConfig {
                n_particles: 8,
                ..config(proposal)
            },
        );
        let after = slip + 5;
        mean_position_error(&est[after..], &run.truth[after..])
    };
    let (plain, robust) = (with(&run, 0.0), with(&run, 1e-3));
    let no_slip = with(&clean, 1e-3);
    eprintln!("after the slip: plain {plain:.3} m, robust {robust:.3} m; robust without it {no_slip:.3} m");
    // The robust prior is back at its error without the slip; the plain one carries the slip.
    assert!(robust < no_slip + 0.03, "robust prior: {robust:.3} m");
    assert!(plain > no_slip + 0.15, "plain prior: {plain:.3} m");
}

#[test]
fn weighed_set_is_the_set_behind_the_estimate() {
    use crlam_core::rbpf::{mode_seeking_pose, weighted_mean_pose, ModeBandwidth};
    let run = simulate(80);
    let mut f = RbpfClam::new(config(ClamProposal::Odometry), run.truth[0]).unwrap();
    let mut checked = 0;
    let mut resampled_seen = 0;
    let mut last_resamples = 0;
    feed_processed(&run, &mut f, |f| {
        let set = f.weighed_set();
        assert_eq!(set.poses.len(), 30);
        assert!((set.weights.iter().sum::<f64>() - 1.0).abs() < 1e-9);
        let mean = weighted_mean_pose(&set.poses, &set.weights);
        let est = f.estimate();
        assert!((mean[0] - est[0]).abs() < 1e-12 && (mean[1] - est[1]).abs() < 1e-12);
        assert!(wrap(mean[2] - est[2]).abs() < 1e-12);
        let inf = ModeBandwidth {
            xy: f64::INFINITY,
            theta: f64::INFINITY,
        };
        let m = mode_seeking_pose(&set.poses, &set.weights, inf).unwrap();
        assert!((m[0] - est[0]).abs() < 1e-12 && wrap(m[2] - est[2]).abs() < 1e-12);
        // Lag 0 of the lineage smoother is the weighted mean too.
        let lag0 = f.ancestor_means(0, false).unwrap();
        assert!((lag0[0][0] - est[0]).abs() < 1e-12 && wrap(lag0[0][2] - est[2]).abs() < 1e-12);
        // A resampling draws the new set from the weighed one.
        if f.n_resamples() > last_resamples {
            last_resamples = f.n_resamples();
            resampled_seen += 1;
            for p in f.particles() {
                assert!(set.poses.contains(&p.pose));
            }
        }
        checked += 1;
    });
    assert!(checked > 10 && resampled_seen > 0);
    // The full smoother reaches back to the first processed scan, where every particle sat at
    // the initial pose; the odometry proposal records no proposal means.
    let smoothed = f.ancestor_means(usize::MAX, false).unwrap();
    assert_eq!(smoothed.len(), f.n_processed());
    let first = smoothed.last().unwrap();
    assert!(
        (first[0] - run.truth[0][0]).abs() < 1e-12 && (first[1] - run.truth[0][1]).abs() < 1e-12
    );
    assert!(f.ancestor_means(3, true).is_none());
}

/// The scan-match proposal with the endpoint matcher reading `range`.
fn scan_match_range(range: MatchRange) -> ClamProposal {
    ClamProposal::ScanMatch(ScanMatchSettings {
        match_range: range,
        ..ScanMatchSettings::default()
    })
}

#[test]
fn a_full_range_matcher_never_matches_a_no_return() {
    // Nothing returns from beyond z_max (8 m). A laser reports a no-return as inf or as one fixed
    // reading, its maximum (FLASER logs: 81.83 m on Intel, 8 m here): either way the full-range
    // matcher sees what the paper's sees, so the filters agree to the bit.
    let run = simulate(40);
    let paper = run_filter(&run, config(scan_match_range(MatchRange::ZMax)));
    for saturated in [f64::INFINITY, 8.0, 81.83] {
        let mut r = Run {
            ranges: run.ranges.clone(),
            ..simulate(40)
        };
        for z in r.ranges.iter_mut().flatten() {
            if !z.is_finite() {
                *z = saturated;
            }
        }
        assert!(r.ranges.iter().flatten().any(|z| *z == saturated));
        for range in [MatchRange::Full, MatchRange::Metres(30.0)] {
            assert_eq!(
                run_filter(&r, config(scan_match_range(range))),
                paper,
                "no-returns at {saturated} m, {range:?}"
            );
        }
    }
}

#[test]
fn a_full_range_matcher_uses_the_returns_beyond_z_max() {
    // Readings up to 12 m, maps and weights at 8 m: the far returns change the search, and the
    // filter still beats odometry by far.
    let run = simulate_to(150, 12.0);
    assert!(run.ranges.iter().flatten().any(|z| (8.5..12.0).contains(z)));
    let odo_err = mean_position_error(&run.odom, &run.truth);
    let cfg = |range| ClamConfig {
        n_particles: 8,
        ..config(scan_match_range(range))
    };
    let full = run_filter(&run, cfg(MatchRange::Full));
    assert_ne!(full, run_filter(&run, cfg(MatchRange::ZMax)));
    let err = mean_position_error(&full, &run.truth);
    assert!(
        err < 0.5 * odo_err,
        "full range {err:.3} m vs odometry {odo_err:.3} m"
    );
}

#[test]
fn a_filter_with_a_prior_map_continues_where_the_saved_run_ended() {
    use crlam_core::rbpf::ClamPrior;
    let run = simulate(160);
    // The first half maps; its best map and final estimate start the second half.
    let half = 80;
    let cfg = config(ClamProposal::Odometry);
    let mut first = RbpfClam::new(cfg.clone(), run.truth[0]).unwrap();
    for k in 0..half {
        let s = ScanInput {
            odom: run.odom[k],
            angles: &run.angles,
            ranges: &run.ranges[k],
            laser_offset: [0.0; 3],
        };
        first.process(&s).unwrap();
    }
    let cov = [[0.01, 0.0, 0.0], [0.0, 0.01, 0.0], [0.0, 0.0, 0.003]];
    let prior = ClamPrior {
        map: first.best_map().clone(),
        cov,
    };
    let start = first.estimate();
    let mut second = RbpfClam::with_prior(cfg.clone(), start, prior.clone()).unwrap();
    // The particles are drawn from the covariance around the saved estimate, all with its map.
    let xs: Vec<f64> = second
        .particles()
        .iter()
        .map(|p| p.pose[0] - start[0])
        .collect();
    let var = xs.iter().map(|x| x * x).sum::<f64>() / xs.len() as f64;
    assert!(var > 0.002 && var < 0.03, "{var}");
    // The first scan is weighed against that map (and counted as processed), and the second half
    // tracks the truth with the odometry of its own frame.
    let mut est = Vec::new();
    for k in half..run.odom.len() {
        let s = ScanInput {
            odom: run.odom[k],
            angles: &run.angles,
            ranges: &run.ranges[k],
            laser_offset: [0.0; 3],
        };
        let step = second.process(&s).unwrap();
        assert!(step.processed);
        est.push(step.estimate);
    }
    assert_eq!(second.n_processed(), run.odom.len() - half);
    let err = mean_position_error(&est, &run.truth[half..]);
    assert!(err < 0.15, "{err}");
    // A prior map on another grid is refused.
    let mut other = cfg;
    other.crm = CrmConfig::new(GridGeometry::new([0.0, 0.0], 0.2).unwrap());
    assert!(RbpfClam::with_prior(other, start, prior).is_err());
}

#[test]
fn released_maps_free_the_tiles_keep_the_paths_and_refuse_scans() {
    let run = simulate(40);
    let mut f = RbpfClam::new(config(ClamProposal::Odometry), run.truth[0]).unwrap();
    feed_processed(&run, &mut f, |_| {});
    let (bytes_before, _, _) = f.map_memory();
    assert!(bytes_before > 0);
    let path = f.best_path();
    let estimate = f.estimate();
    f.release_maps().unwrap();
    assert!(f.maps_released());
    assert_eq!(
        f.map_memory().0,
        0,
        "every particle's map tiles are dropped"
    );
    assert_eq!(f.best_path(), path);
    assert_eq!(f.estimate(), estimate);
    let s = ScanInput {
        odom: run.odom[0],
        angles: &run.angles,
        ranges: &run.ranges[0],
        laser_offset: [0.0; 3],
    };
    let err = f.process(&s).unwrap_err().to_string();
    assert!(err.contains("released"), "{err}");
    let map = f.empty_map().unwrap();
    assert!(f.reanchor(map, [0.0; 3]).is_err());
}
