//! Tests of the localizer's CRM likelihood.

use super::*;
use crate::crm::{CrmConfig, CrmMap, CrmScratch};
use crate::grid::{CellRect, GridGeometry};
use crate::mcl::hit_table::HIT_TABLE_ERROR;

/// A map learned from scans of a square room, and its field over the room.
fn room() -> (CrmMap, MeanField, SensorModel, Vec<f64>) {
    let g = GridGeometry::new([0.0, 0.0], 0.1).unwrap();
    let mut map = CrmMap::new(&CrmConfig::new(g)).unwrap();
    let ijrr = SensorModel::with_defaults(SensorModelKind::Ijrr, 8.0, 0.1);
    let angles: Vec<f64> = (0..90).map(|i| -1.5 + 3.0 * i as f64 / 89.0).collect();
    let mut sc = CrmScratch::default();
    // Walls of a 6 m x 4 m room around (3, 2); scans from the centre, turning.
    let wall = |x: f64, y: f64, a: f64| {
        let (c, s) = (a.cos(), a.sin());
        let mut t = f64::INFINITY;
        for (p, u, lo, hi) in [(x, c, 0.0, 6.0), (y, s, 0.0, 4.0)] {
            if u > 0.0 {
                t = t.min((hi - p) / u);
            } else if u < 0.0 {
                t = t.min((lo - p) / u);
            }
        }
        t
    };
    for k in 0..40 {
        let pose = [3.0 + 0.02 * k as f64, 2.0, 0.16 * k as f64];
        let ranges: Vec<f64> = angles
            .iter()
            .map(|a| wall(pose[0], pose[1], pose[2] + a))
            .collect();
        map.update_scan(
            pose,
            &angles,
            &ranges,
            &ijrr,
            &ScanOptions::default(),
            &mut sc,
        )
        .unwrap();
    }
    let rect = CellRect {
        ix0: -5,
        iy0: -5,
        nx: 70,
        ny: 50,
    };
    let field = MeanField::from_crm(&map, rect, 0.25, 20).unwrap();
    let mix = SensorModel::with_defaults(SensorModelKind::Mixture, 8.0, 0.1);
    let pose = [2.5, 1.7, 0.3];
    let ranges = angles
        .iter()
        .map(|a| wall(pose[0], pose[1], pose[2] + a))
        .collect();
    (map, field, mix, ranges)
}

#[test]
fn field_likelihood_equals_the_maps() {
    let (map, field, mix, ranges) = room();
    let angles: Vec<f64> = (0..90).map(|i| -1.5 + 3.0 * i as f64 / 89.0).collect();
    let mut sc = CrmScratch::default();
    for pose in [[2.5, 1.7, 0.3], [1.0, 3.0, -2.0], [5.0, 0.5, 1.2]] {
        let (want, n) = map
            .scan_log_likelihood(
                pose,
                &angles,
                &ranges,
                &mix,
                &ScanOptions::default(),
                &mut sc,
            )
            .unwrap();
        let beams: Vec<usize> = (0..angles.len()).collect();
        for tol in [1.0 / (1u64 << 60) as f64, 1e-6, 1e-3] {
            let s = LikelihoodSettings {
                model: mix,
                tail_tolerance: tol,
                skip_no_returns: false,
            };
            let fit = scan_log_likelihood(&field, &s, pose, &angles, &ranges, &beams).unwrap();
            let got = fit.log_likelihood;
            assert_eq!(fit.n_beams, n);
            assert!(fit.explained > 0.5 * n as f64 || pose[0] != 2.5, "{fit:?}");
            // Each beam's log η is low by less than twice the tolerance (the tail and the hit
            // window), and within the hit table's
            // error where it is used (plus rounding).
            let table = if tol >= HIT_TABLE_ERROR {
                HIT_TABLE_ERROR
            } else {
                0.0
            };
            let err = want - got;
            assert!(
                err > -(n as f64) * table - 1e-9 && err < n as f64 * (2.0 * tol + table) + 1e-9,
                "tol {tol}: {got} vs {want}"
            );
        }
    }
}

#[test]
fn every_vector_level_gives_the_same_likelihood() {
    use crate::simd::SimdLevel;
    let (_, field, mix, ranges) = room();
    let angles: Vec<f64> = (0..90).map(|i| -1.5 + 3.0 * i as f64 / 89.0).collect();
    let s = LikelihoodSettings {
        model: mix,
        tail_tolerance: 1e-6,
        skip_no_returns: false,
    };
    let beams = select_beams(90, 1, 0);
    for pose in [
        [2.5, 1.7, 0.3],
        [1.0, 3.0, -2.0],
        [5.0, 0.5, 1.2],
        [-3.0, 9.0, 0.0],
    ] {
        let at = |level| {
            scan_log_likelihood_at(level, &field, &s, pose, &angles, &ranges, &beams).unwrap()
        };
        let scalar = at(SimdLevel::Scalar);
        assert_eq!(scalar, at(SimdLevel::Avx2));
        assert_eq!(scalar, at(SimdLevel::Avx512));
    }
}

#[test]
fn the_true_pose_is_likelier_than_shifted_ones() {
    let (_, field, mix, ranges) = room();
    let angles: Vec<f64> = (0..90).map(|i| -1.5 + 3.0 * i as f64 / 89.0).collect();
    let s = LikelihoodSettings {
        model: mix,
        tail_tolerance: 1e-6,
        skip_no_returns: false,
    };
    let beams = select_beams(90, 1, 0);
    let ll = |p: Pose| {
        scan_log_likelihood(&field, &s, p, &angles, &ranges, &beams)
            .unwrap()
            .log_likelihood
    };
    let truth = ll([2.5, 1.7, 0.3]);
    for d in [[0.2, 0.0, 0.0], [0.0, -0.2, 0.0], [0.0, 0.0, 0.1]] {
        assert!(truth > ll([2.5 + d[0], 1.7 + d[1], 0.3 + d[2]]) + 5.0);
    }
}

#[test]
fn beam_selection() {
    assert_eq!(select_beams(5, 1, 0), vec![0, 1, 2, 3, 4]);
    assert_eq!(select_beams(10, 3, 0), vec![0, 3, 6, 9]);
    assert_eq!(select_beams(181, 1, 3), vec![0, 90, 180]);
    assert_eq!(select_beams(10, 1, 1), vec![0]);
    assert_eq!(select_beams(4, 1, 10).len(), 4);
}

#[test]
fn settings_are_checked() {
    let mix = SensorModel::with_defaults(SensorModelKind::Mixture, 8.0, 0.1);
    let ok = LikelihoodSettings {
        model: mix,
        tail_tolerance: 1e-6,
        skip_no_returns: false,
    };
    assert!(ok.validate().is_ok());
    let ijrr = LikelihoodSettings {
        model: SensorModel::with_defaults(SensorModelKind::Ijrr, 8.0, 0.1),
        ..ok
    };
    assert!(ijrr.validate().is_err());
    assert!(LikelihoodSettings {
        tail_tolerance: 0.0,
        ..ok
    }
    .validate()
    .is_err());
    let mut no_rand = mix;
    no_rand.w_rand = 0.0;
    no_rand.w_hit = 0.8;
    assert!(LikelihoodSettings {
        model: no_rand,
        ..ok
    }
    .validate()
    .is_err());
}

/// Any sensor pose (huge, tiny, non-finite) and any scan (any length, any readings, any
/// beam list) give a result or an error, never a panic: a particle drawn from a huge initial
/// covariance sits at cells near i64::MAX, where the window test once wrapped around and
/// let the walk index the stored values out of bounds.
#[test]
fn any_pose_and_scan_gives_a_result_or_an_error() {
    use proptest::prelude::*;
    use proptest::test_runner::{Config, TestRunner};
    let (_, field, mix, _) = room();
    let coord = prop_oneof![
        -10.0f64..20.0,
        -1e300f64..1e300,
        Just(f64::MAX),
        Just(f64::MIN),
        Just(9.3e18),
        Just(-9.3e18),
        Just(f64::NAN),
        Just(f64::INFINITY),
    ];
    let reading = prop_oneof![0.0f64..10.0, proptest::num::f64::ANY];
    let scan = (0usize..400).prop_flat_map(move |n| {
        (
            proptest::collection::vec(-4.0f64..4.0, n),
            proptest::collection::vec(reading.clone(), n),
            proptest::collection::vec(0usize..n.max(1) + 3, 0..n + 2),
        )
    });
    let mut runner = TestRunner::new(Config {
        cases: 300,
        failure_persistence: None,
        ..Config::default()
    });
    for kernel in [CauseKernel::Midpoint, CauseKernel::Chord] {
        let mut model = mix;
        model.kernel = kernel;
        let s = LikelihoodSettings {
            model,
            tail_tolerance: 1e-6,
            skip_no_returns: false,
        };
        runner
            .run(
                &(coord.clone(), coord.clone(), -1e300f64..1e300, scan.clone()),
                |(x, y, yaw, (angles, ranges, beams))| {
                    if let Ok(fit) =
                        scan_log_likelihood(&field, &s, [x, y, yaw], &angles, &ranges, &beams)
                    {
                        prop_assert!(fit.n_beams <= beams.len());
                    }
                    Ok(())
                },
            )
            .unwrap();
    }
}

/// The stated error on random maps and scans: with any field of means (random m̂ per cell,
/// walls of random confidence), any sensor pose in or near the map and any readings (in range,
/// short, no-returns), the localizer's likelihood at tail tolerance `tol` (with the hit table)
/// is low by at most `n_beams · (2 tol + HIT_TABLE_ERROR)` (the tail and the hit window) and
/// high by at most
/// `n_beams · HIT_TABLE_ERROR` against the same likelihood to rounding (tolerance 2^-60, no
/// table), and is the same, bit for bit, at every vector level.
#[test]
fn the_tolerance_bounds_the_error_on_random_maps_and_scans() {
    use proptest::prelude::*;
    use proptest::test_runner::{Config, TestRunner};
    let mut runner = TestRunner::new(Config {
        cases: 60,
        failure_persistence: None,
        ..Config::default()
    });
    let case = (
        proptest::collection::vec(0.0f64..1.0, 40 * 30),
        proptest::collection::vec((0usize..40, 0usize..30, 0.5f64..1.0), 0..30),
        (0.3f64..3.7, 0.3f64..2.7, -3.2f64..3.2),
        proptest::collection::vec(prop_oneof![0.02f64..5.0, Just(f64::INFINITY)], 1..60),
        prop_oneof![Just(CauseKernel::Midpoint), Just(CauseKernel::Chord)],
    );
    runner
        .run(&case, |(noise, walls, pose, ranges, kernel)| {
            let g = GridGeometry::new([0.0, 0.0], 0.1).unwrap();
            let rect = CellRect {
                ix0: 0,
                iy0: 0,
                nx: 40,
                ny: 30,
            };
            // Mostly free cells of low m̂, some walls of high m̂.
            let mut mean: Vec<f64> = noise.iter().map(|u| 0.2 * u * u).collect();
            for (ix, iy, m) in walls {
                mean[iy * 40 + ix] = m;
            }
            let field = MeanField::from_means(g, rect, mean, 0.3, 0.25, 60).unwrap();
            let mut model = SensorModel::with_defaults(SensorModelKind::Mixture, 5.0, 0.1);
            model.kernel = kernel;
            let n = ranges.len();
            let angles: Vec<f64> = (0..n).map(|i| -1.5 + 3.0 * i as f64 / n as f64).collect();
            let beams: Vec<usize> = (0..n).collect();
            let at = |tol: f64| {
                let s = LikelihoodSettings {
                    model,
                    tail_tolerance: tol,
                    skip_no_returns: false,
                };
                scan_log_likelihood(
                    &field,
                    &s,
                    [pose.0, pose.1, pose.2],
                    &angles,
                    &ranges,
                    &beams,
                )
                .unwrap()
            };
            let exact = at(1.0 / (1u64 << 60) as f64);
            // Every vector level stops its lanes' far phases where the scalar loop stops
            // (walls of random confidence make many stop): the same likelihood bit for bit.
            for tol in [1e-6, 0.01] {
                let s = LikelihoodSettings {
                    model,
                    tail_tolerance: tol,
                    skip_no_returns: false,
                };
                let at_level = |level| {
                    scan_log_likelihood_at(
                        level,
                        &field,
                        &s,
                        [pose.0, pose.1, pose.2],
                        &angles,
                        &ranges,
                        &beams,
                    )
                    .unwrap()
                };
                let scalar = at_level(crate::simd::SimdLevel::Scalar);
                prop_assert_eq!(scalar, at_level(crate::simd::SimdLevel::Avx2));
                prop_assert_eq!(scalar, at_level(crate::simd::SimdLevel::Avx512));
            }
            for tol in [1e-6, 1e-3, 0.01] {
                let fast = at(tol);
                prop_assert_eq!(fast.n_beams, exact.n_beams);
                let err = exact.log_likelihood - fast.log_likelihood;
                let nb = fast.n_beams as f64;
                prop_assert!(
                    err > -nb * HIT_TABLE_ERROR - 1e-9
                        && err <= nb * (2.0 * tol + HIT_TABLE_ERROR) + 1e-9,
                    "tol {}: error {} over {} beams",
                    tol,
                    err,
                    fast.n_beams
                );
            }
            Ok(())
        })
        .unwrap();
}
