//! The localizer on a simulated world: convergence from a uniform start, tracking, kidnapping,
//! the KLD bounds and independence from the thread count.

use std::sync::Arc;

use crate::grid::{CellRect, GridGeometry};
use crate::mcl::kld::KldSettings;
use crate::mcl::{LikelihoodSettings, Mcl, MclConfig, MclInit, MclStep, MeanField};
use crate::motion::MotionModel;
use crate::pose::{between, compose, wrap, Pose};
use crate::rbpf::{ScanInput, UpdateTrigger};
use crate::rng::Rng;
use crate::sensor::{SensorModel, SensorModelKind};
use crate::sim::WorldRaster;

const RES: f64 = 0.1;
const NX: usize = 140;
const NY: usize = 90;

/// A 14 m × 9 m floor with an outer wall, an inner wall with a door and boxes placed without
/// symmetry, as a raster and as a map (m̂ 0.9 on walls, 0.05 elsewhere).
fn world() -> (Vec<u8>, Arc<MeanField>) {
    let mut occ = vec![0u8; NX * NY];
    let mut set = |x0: usize, y0: usize, x1: usize, y1: usize| {
        for y in y0..y1 {
            for x in x0..x1 {
                occ[y * NX + x] = 1;
            }
        }
    };
    set(0, 0, NX, 2);
    set(0, NY - 2, NX, NY);
    set(0, 0, 2, NY);
    set(NX - 2, 0, NX, NY);
    // Inner wall at x = 9 m with a door between y = 3 and 4.5 m.
    set(90, 0, 92, 30);
    set(90, 45, 92, NY);
    set(20, 20, 35, 28);
    set(55, 60, 60, 80);
    set(110, 15, 125, 20);
    set(70, 30, 74, 34);
    let mean: Vec<f64> = occ
        .iter()
        .map(|&o| if o != 0 { 0.9 } else { 0.05 })
        .collect();
    let g = GridGeometry::new([0.0, 0.0], RES).unwrap();
    let rect = CellRect {
        ix0: 0,
        iy0: 0,
        nx: NX as i64,
        ny: NY as i64,
    };
    let field = MeanField::from_means(g, rect, mean, 0.5, 0.2, 80).unwrap();
    (occ, Arc::new(field))
}

fn angles() -> Vec<f64> {
    (0..60)
        .map(|i| -std::f64::consts::PI + 2.0 * std::f64::consts::PI * i as f64 / 60.0)
        .collect()
}

/// A loop through both rooms: positions along a polyline, heading along the motion.
fn path(n: usize) -> Vec<Pose> {
    let corners: [[f64; 2]; 9] = [
        [3.0, 2.0],
        [7.5, 2.0],
        [7.5, 3.7],
        [11.5, 3.7],
        [11.5, 7.0],
        [7.5, 7.0],
        [7.5, 5.0],
        [4.0, 5.0],
        [3.0, 2.0],
    ];
    let seg: Vec<f64> = corners
        .windows(2)
        .map(|w| (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]))
        .collect();
    let total: f64 = seg.iter().sum();
    (0..n)
        .map(|k| {
            let mut s = total * k as f64 / n as f64;
            let mut i = 0;
            while s > seg[i] {
                s -= seg[i];
                i += 1;
            }
            let (a, b) = (corners[i], corners[i + 1]);
            let f = s / seg[i];
            [
                a[0] + f * (b[0] - a[0]),
                a[1] + f * (b[1] - a[1]),
                (b[1] - a[1]).atan2(b[0] - a[0]),
            ]
        })
        .collect()
}

/// Scans at the true poses and odometry drifting from them.
struct Log {
    truth: Vec<Pose>,
    odom: Vec<Pose>,
    ranges: Vec<Vec<f64>>,
}

fn simulate(occ: &[u8], truth: Vec<Pose>, seed: u64) -> Log {
    let raster =
        WorldRaster::new(GridGeometry::new([0.0, 0.0], RES).unwrap(), NX, NY, occ).unwrap();
    let a = angles();
    let mut flat = vec![0.0; truth.len() * a.len()];
    raster.cast(&truth, &a, 8.0, &mut flat).unwrap();
    let mut rng = Rng::new(seed);
    let mut odom = vec![[0.0, 0.0, 0.0]];
    for k in 1..truth.len() {
        let d = between(truth[k - 1], truth[k]);
        let noisy = [
            d[0] * (1.0 + 0.05 * rng.normal()),
            d[1] + 0.01 * rng.normal(),
            d[2] + 0.02 * rng.normal(),
        ];
        odom.push(compose(odom[k - 1], noisy));
    }
    let ranges = flat
        .chunks(a.len())
        .map(|r| {
            r.iter()
                .map(|&z| {
                    if z.is_finite() {
                        z + 0.01 * rng.normal()
                    } else {
                        z
                    }
                })
                .collect()
        })
        .collect();
    Log {
        truth,
        odom,
        ranges,
    }
}

fn config(n_min: usize, n_max: usize) -> MclConfig {
    let mut model = SensorModel::with_defaults(SensorModelKind::Mixture, 8.0, RES);
    model.sigma_hit = 0.05;
    MclConfig {
        measurement: crate::mcl::Measurement::Crm,
        likelihood: LikelihoodSettings {
            model,
            tail_tolerance: 1e-6,
            skip_no_returns: false,
        },
        motion: MotionModel::Thrun {
            alpha: [0.05, 0.05, 0.05, 0.05],
        },
        trigger: UpdateTrigger::every_scan(),
        spread_trigger: UpdateTrigger::every_scan(),
        spread_limit: 0.5,
        kld: KldSettings {
            n_min,
            n_max,
            ..KldSettings::default()
        },
        alpha_slow: 0.001,
        alpha_fast: 0.1,
        tempering: 10.0,
        min_neff: 0.0,
        sigma_max: 0.0,
        anneal: 0.0,
        beam_stride: 1,
        max_beams: 0,
        resample_threshold: 0.5,
        min_cluster: 0,
        min_bin: 0,
        place_xy: 0.0,
        place_theta: std::f64::consts::FRAC_PI_2,
        spread_max: 0,
        spread_climb: false,
        keep_ratio: 1e-3,
        seed: 7,
    }
}

fn run(f: &mut Mcl, log: &Log, from: usize, to: usize) -> Vec<MclStep> {
    let a = angles();
    (from..to)
        .map(|k| {
            f.process(&ScanInput {
                odom: log.odom[k],
                angles: &a,
                ranges: &log.ranges[k],
                laser_offset: [0.0; 3],
            })
            .unwrap()
        })
        .collect()
}

fn error(p: Pose, q: Pose) -> (f64, f64) {
    ((p[0] - q[0]).hypot(p[1] - q[1]), wrap(p[2] - q[2]).abs())
}

#[test]
fn global_localization_converges_from_a_uniform_start() {
    let (occ, field) = world();
    let log = simulate(&occ, path(150), 1);
    let mut f = Mcl::new(config(200, 4000), field, MclInit::Global).unwrap();
    assert_eq!(f.poses().len(), 4000);
    let steps = run(&mut f, &log, 0, 80);
    let last = steps.last().unwrap();
    let (dxy, dth) = error(last.estimate, log.truth[79]);
    assert!(dxy < 0.15 && dth < 0.05, "final error {dxy} m, {dth} rad");
    // Converged: one heavy cluster, and KLD has cut the count far below the start.
    assert!(
        last.cluster.weight > 0.95 && last.n_after < 1500,
        "{last:?}"
    );
    for s in &steps {
        assert!((200..=4000).contains(&s.n_after));
    }
}

#[test]
fn a_spread_set_may_hold_spread_max_particles() {
    let (occ, field) = world();
    let log = simulate(&occ, path(150), 1);
    let cfg = MclConfig {
        spread_max: 6000,
        ..config(200, 2000)
    };
    let mut f = Mcl::new(cfg, field.clone(), MclInit::Global).unwrap();
    assert_eq!(f.poses().len(), 6000);
    let steps = run(&mut f, &log, 0, 80);
    assert!(steps.iter().all(|s| s.n_after <= 6000));
    // Gathered: n_max bounds the set again.
    let last = steps.last().unwrap();
    assert!(
        last.cluster.weight > 0.95 && last.n_after <= 2000,
        "{last:?}"
    );
    // A known start is not spread: it draws n_max.
    let init = MclInit::Pose {
        mean: log.truth[0],
        cov: [[0.01, 0.0, 0.0], [0.0, 0.01, 0.0], [0.0, 0.0, 0.01]],
    };
    let g = Mcl::new(
        MclConfig {
            spread_max: 6000,
            ..config(200, 2000)
        },
        field,
        init,
    )
    .unwrap();
    assert_eq!(g.poses().len(), 2000);
}

#[test]
fn a_spread_set_keeps_places_and_still_converges() {
    let (occ, field) = world();
    let log = simulate(&occ, path(150), 1);
    let cfg = MclConfig {
        min_cluster: 30,
        place_xy: 2.0,
        spread_max: 6000,
        ..config(200, 2000)
    };
    let mut f = Mcl::new(cfg, field, MclInit::Global).unwrap();
    let steps = run(&mut f, &log, 0, 80);
    // While spread, the resampling floors many places of 2 m x 90° (a few hundred on this
    // 14 m x 9 m floor at the start), never beyond the spread bound.
    assert!(steps[0].resampled && steps[0].n_kept > 20, "{:?}", steps[0]);
    assert!(steps.iter().all(|s| s.n_after <= 6000));
    let last = steps.last().unwrap();
    let (dxy, dth) = error(last.estimate, log.truth[79]);
    assert!(dxy < 0.15 && dth < 0.05, "final error {dxy} m, {dth} rad");
    assert!(
        last.cluster.weight > 0.95 && last.n_after <= 2000,
        "{last:?}"
    );
}

#[test]
fn tracks_from_a_known_pose_with_its_covariance() {
    let (occ, field) = world();
    let log = simulate(&occ, path(120), 2);
    // The odometry frame is the log's own; the map frame starts at the truth.
    let start = log.truth[0];
    let cov = [[0.04, 0.0, 0.0], [0.0, 0.04, 0.0], [0.0, 0.0, 0.01]];
    let mut f = Mcl::new(config(100, 1000), field, MclInit::Pose { mean: start, cov }).unwrap();
    // Particles drawn from the covariance.
    let p = f.poses();
    let var_x = p.iter().map(|q| (q[0] - start[0]).powi(2)).sum::<f64>() / p.len() as f64;
    assert!((var_x - 0.04).abs() < 0.008, "{var_x}");
    let steps = run(&mut f, &log, 0, 120);
    for (k, s) in steps.iter().enumerate().skip(5) {
        let (dxy, dth) = error(s.estimate, log.truth[k]);
        assert!(dxy < 0.15 && dth < 0.06, "scan {k}: {dxy} m, {dth} rad");
    }
}

#[test]
fn a_kidnapped_robot_is_found_again() {
    let (occ, field) = world();
    // At scan 100 the robot is carried to another part of its loop, unseen by the odometry.
    let loop_poses = path(200);
    let truth: Vec<Pose> = (0..160)
        .map(|k| {
            if k < 100 {
                loop_poses[k]
            } else {
                loop_poses[(k + 60) % 200]
            }
        })
        .collect();
    let mut log = simulate(&occ, truth, 3);
    // Odometry: before the jump as simulated; after it, the increments of the new truth from the
    // old odometry pose (the wheels did not see the carry).
    for k in 100..160 {
        let d = between(log.truth[k - 1], log.truth[k]);
        let d = if k == 100 { [0.0, 0.0, 0.0] } else { d };
        log.odom[k] = compose(log.odom[k - 1], d);
    }
    let start = log.truth[0];
    let cov = [[0.01, 0.0, 0.0], [0.0, 0.01, 0.0], [0.0, 0.0, 0.005]];
    let mut cfg = config(300, 3000);
    cfg.alpha_fast = 0.2;
    let mut f = Mcl::new(cfg, field, MclInit::Pose { mean: start, cov }).unwrap();
    let before = run(&mut f, &log, 0, 100);
    assert!(error(before[99].estimate, log.truth[99]).0 < 0.15);
    let after = run(&mut f, &log, 100, 160);
    assert!(
        after.iter().any(|s| s.n_injected > 0),
        "recovery never injected"
    );
    let lost = error(after[0].estimate, log.truth[100]).0;
    assert!(
        lost > 1.0,
        "the jump should lose the estimate first ({lost} m)"
    );
    let (dxy, dth) = error(after[59].estimate, log.truth[159]);
    assert!(dxy < 0.2 && dth < 0.1, "not recovered: {dxy} m, {dth} rad");
}

#[test]
fn results_do_not_depend_on_the_thread_count() {
    let (occ, field) = world();
    let log = simulate(&occ, path(150), 4);
    let go = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let mut f = Mcl::new(config(100, 1500), field.clone(), MclInit::Global).unwrap();
            let steps = run(&mut f, &log, 0, 20);
            (steps, f.poses().to_vec())
        })
    };
    let (s1, p1) = go(1);
    let (s2, p2) = go(2);
    assert_eq!(p1, p2);
    for (a, b) in s1.iter().zip(&s2) {
        assert_eq!(a.estimate, b.estimate);
        assert_eq!(a.n_after, b.n_after);
    }
}

#[test]
fn unprocessed_scans_carry_the_estimate_by_odometry() {
    let (occ, field) = world();
    let log = simulate(&occ, path(400), 5);
    let mut cfg = config(100, 500);
    cfg.trigger = UpdateTrigger {
        linear: 0.5,
        angular: 0.5,
    };
    let cov = [[0.01, 0.0, 0.0], [0.0, 0.01, 0.0], [0.0, 0.0, 0.005]];
    let mut f = Mcl::new(
        cfg,
        field,
        MclInit::Pose {
            mean: log.truth[0],
            cov,
        },
    )
    .unwrap();
    let steps = run(&mut f, &log, 0, 40);
    assert!(steps[0].processed);
    let skipped = steps.iter().position(|s| !s.processed).unwrap();
    let last = steps[..skipped].iter().rposition(|s| s.processed).unwrap();
    let want = compose(
        steps[last].estimate,
        between(log.odom[last], log.odom[skipped]),
    );
    assert_eq!(steps[skipped].estimate, want);
}

#[test]
fn bad_settings_and_covariances_are_refused() {
    let (_, field) = world();
    let cov_bad = [[0.01, 0.5, 0.0], [0.0, 0.01, 0.0], [0.0, 0.0, 0.005]];
    let init = MclInit::Pose {
        mean: [1.0, 1.0, 0.0],
        cov: cov_bad,
    };
    assert!(Mcl::new(config(10, 100), field.clone(), init).is_err());
    let neg = [[-1.0, 0.0, 0.0], [0.0, 0.01, 0.0], [0.0, 0.0, 0.005]];
    let init = MclInit::Pose {
        mean: [1.0, 1.0, 0.0],
        cov: neg,
    };
    assert!(Mcl::new(config(10, 100), field.clone(), init).is_err());
    let mut cfg = config(10, 100);
    cfg.alpha_fast = 0.0005;
    assert!(Mcl::new(cfg, field.clone(), MclInit::Global).is_err());
    let mut cfg = config(10, 100);
    cfg.tempering = 0.0;
    assert!(Mcl::new(cfg, field, MclInit::Global).is_err());
}

/// Particles within 0.1 m and 0.05 rad of `truth`.
fn near(f: &Mcl, truth: Pose) -> usize {
    f.poses()
        .iter()
        .filter(|&&p| {
            let (dxy, dth) = error(p, truth);
            dxy < 0.1 && dth < 0.05
        })
        .count()
}

/// A localizer of `config(n_min, n_max)` with the climb of a spread set on or off.
fn with_climb(
    climb: bool,
    n_min: usize,
    n_max: usize,
    field: &Arc<MeanField>,
    init: MclInit,
) -> Mcl {
    let cfg = MclConfig {
        spread_climb: climb,
        ..config(n_min, n_max)
    };
    Mcl::new(cfg, field.clone(), init).unwrap()
}

#[test]
fn the_climb_puts_particles_of_a_spread_set_on_the_true_pose() {
    let (occ, field) = world();
    let log = simulate(&occ, path(150), 1);
    let with = |climb: bool| {
        let mut f = with_climb(climb, 200, 4000, &field, MclInit::Global);
        run(&mut f, &log, 0, 1);
        near(&f, log.truth[0])
    };
    // 4,000 particles over about 100 m² and 2π: about one per 0.16 m² rad, so hardly any lies
    // within 0.1 m and 0.05 rad of the truth; those in its basin climb onto it.
    let (plain, climbed) = (with(false), with(true));
    assert!(plain <= 2 && climbed >= 20, "{plain} {climbed}");
}

#[test]
fn a_gathered_set_does_not_climb() {
    let (occ, field) = world();
    let log = simulate(&occ, path(120), 2);
    let init = MclInit::Pose {
        mean: log.truth[0],
        cov: [[0.01, 0.0, 0.0], [0.0, 0.01, 0.0], [0.0, 0.0, 0.003]],
    };
    let plain = |climb: bool| {
        let mut f = with_climb(climb, 200, 1000, &field, init);
        run(&mut f, &log, 0, 20);
        f.poses().to_vec()
    };
    // A start of 0.1 m and 0.05 rad is not spread (spread_limit 0.5): the same draws, the same
    // particles.
    assert_eq!(plain(false), plain(true));
}

#[test]
fn global_localization_with_the_climb_converges_with_few_particles() {
    let (occ, field) = world();
    let log = simulate(&occ, path(150), 1);
    let last_error = |climb: bool| {
        let mut f = with_climb(climb, 100, 300, &field, MclInit::Global);
        let steps = run(&mut f, &log, 0, 80);
        let last = *steps.last().unwrap();
        (error(last.estimate, log.truth[79]), last)
    };
    // 300 particles over the floor: about one per 2 m² rad. Moved by the odometry's noise alone
    // none reaches the true pose and the set settles elsewhere; climbing, it converges.
    let ((dxy, dth), last) = last_error(true);
    assert!(dxy < 0.15 && dth < 0.05, "final error {dxy} m, {dth} rad");
    assert!(last.cluster.weight > 0.95, "{last:?}");
    let ((dxy, _), _) = last_error(false);
    assert!(dxy > 1.0, "without the climb: {dxy} m");
}
