//! The shared-map scan likelihood (UCRMI's particle weights) equals the general
//! `CrmMap::scan_log_likelihood` (crm-spec 4.1) on every kind of beam.

use crlam_core::crm::{CrmConfig, CrmMap, CrmScratch, ScanOptions};
use crlam_core::grid::GridGeometry;
use crlam_core::info::lattice::OccupancyLattice;
use crlam_core::info::prior::crm_from_lattice;
use crlam_core::info::shared_likelihood::SharedMapLikelihood;
use crlam_core::rng::Rng;
use crlam_core::sensor::{CauseKernel, SensorModel, SensorModelKind};

/// A 12 m × 12 m fixed-extent lattice (0.2 m) with random walls, half-known patches and open
/// space, so that beams see every kind of cell.
fn lattice_map(seed: u64) -> CrmMap {
    let g = GridGeometry::new([-1.0, -2.0], 0.2).unwrap();
    let n = 60;
    let mut rng = Rng::new(seed);
    let p: Vec<f64> = (0..n * n)
        .map(|_| match (rng.uniform() * 10.0) as u32 {
            0 => 0.85,
            1 | 2 => 0.5,
            3 => 0.05,
            _ => 0.3,
        })
        .collect();
    crm_from_lattice(&OccupancyLattice::new(g, n, n, p).unwrap(), 10).unwrap()
}

/// A growing (unbounded) map with a few scans written into it.
fn growing_map() -> CrmMap {
    let cfg = CrmConfig::new(GridGeometry::new([0.0, 0.0], 0.2).unwrap());
    let mut m = CrmMap::new(&cfg).unwrap();
    let model = SensorModel::with_defaults(SensorModelKind::Ijrr, 5.0, 0.2);
    let angles: Vec<f64> = (0..36).map(|i| i as f64 * 0.17).collect();
    let ranges: Vec<f64> = (0..36).map(|i| 1.0 + (i % 7) as f64 * 0.5).collect();
    m.update_scan(
        [1.0, 1.0, 0.3],
        &angles,
        &ranges,
        &model,
        &ScanOptions::default(),
        &mut CrmScratch::default(),
    )
    .unwrap();
    m
}

/// Readings of every kind: ordinary hits, very short ones, near and at z_max, no-returns
/// (∞, NaN) and dropped ones (negative).
fn readings(rng: &mut Rng, n: usize, z_max: f64) -> Vec<f64> {
    (0..n)
        .map(|i| match i % 9 {
            0 => f64::INFINITY,
            1 => z_max,
            2 => z_max - 0.01,
            3 => 0.03,
            4 => f64::NAN,
            5 => -0.5,
            _ => 0.1 + rng.uniform() * (z_max - 0.1),
        })
        .collect()
}

fn check_equal(map: &CrmMap, model: &SensorModel, poses: &[[f64; 3]], seed: u64) {
    let mut rng = Rng::new(seed);
    let angles: Vec<f64> = (0..27).map(|i| -3.1 + i as f64 * 0.23).collect();
    let ranges = readings(&mut rng, angles.len(), model.z_max);
    // A large visit estimate forces the window; zero forces the per-cell fallback.
    for visits in [1e12, 0.0] {
        let shared = SharedMapLikelihood::new(map, model, poses, visits).unwrap();
        let fast = shared
            .scan_log_likelihoods(poses, &angles, &ranges)
            .unwrap();
        for (p, f) in poses.iter().zip(&fast) {
            let (exact, _) = map
                .scan_log_likelihood(
                    *p,
                    &angles,
                    &ranges,
                    model,
                    &ScanOptions::default(),
                    &mut CrmScratch::default(),
                )
                .unwrap();
            assert!(
                *f == exact || (f - exact).abs() <= 1e-12 * exact.abs().max(1.0),
                "pose {p:?}, {:?}: {f} vs {exact}",
                model.kind
            );
        }
    }
}

fn poses(rng: &mut Rng, n: usize, lo: [f64; 2], hi: [f64; 2]) -> Vec<[f64; 3]> {
    (0..n)
        .map(|_| {
            [
                lo[0] + rng.uniform() * (hi[0] - lo[0]),
                lo[1] + rng.uniform() * (hi[1] - lo[1]),
                (rng.uniform() - 0.5) * 6.0,
            ]
        })
        .collect()
}

#[test]
fn mixture_equals_the_general_likelihood_inside_and_at_the_edge_of_a_fixed_extent() {
    let mut rng = Rng::new(3);
    for seed in 0..4 {
        let map = lattice_map(seed);
        // Poses inside, near the border (rays leave the extent: hits beyond it become
        // no-returns) and outside the extent.
        let mut ps = poses(&mut rng, 30, [0.0, -1.0], [10.0, 9.0]);
        ps.extend(poses(&mut rng, 10, [-0.9, -1.9], [-0.5, 9.9]));
        ps.extend(poses(&mut rng, 5, [-4.0, -4.0], [-1.5, -2.5]));
        for z_max in [5.0, 8.0] {
            let model = SensorModel::with_defaults(SensorModelKind::Mixture, z_max, 0.2);
            check_equal(&map, &model, &ps, seed);
        }
    }
}

#[test]
fn ijrr_and_non_default_weights_equal_the_general_likelihood() {
    let mut rng = Rng::new(5);
    let map = lattice_map(9);
    let ps = poses(&mut rng, 25, [0.0, -1.0], [10.0, 9.0]);
    let ijrr = SensorModel::with_defaults(SensorModelKind::Ijrr, 5.0, 0.2);
    check_equal(&map, &ijrr, &ps, 1);
    let mut m = SensorModel::with_defaults(SensorModelKind::Mixture, 5.0, 0.2);
    (m.w_hit, m.w_short, m.w_max, m.w_rand) = (0.85, 0.0, 0.1, 0.05);
    check_equal(&map, &m, &ps, 2);
    (m.w_hit, m.w_short, m.w_max, m.w_rand) = (0.5, 0.3, 0.2 - 1e-9, 1e-9);
    m.lambda_short = 2.0;
    m.sigma_hit = 0.02;
    check_equal(&map, &m, &ps, 3);
}

#[test]
fn models_outside_the_fast_path_and_growing_maps_agree_too() {
    let mut rng = Rng::new(7);
    let ps = poses(&mut rng, 20, [-2.0, -2.0], [4.0, 4.0]);
    let grow = growing_map();
    let mixture = SensorModel::with_defaults(SensorModelKind::Mixture, 5.0, 0.2);
    check_equal(&grow, &mixture, &ps, 4);
    let mut chord = mixture;
    chord.kernel = CauseKernel::Chord;
    check_equal(&grow, &chord, &ps, 5);
    let authors = SensorModel::with_defaults(SensorModelKind::AuthorsCode, 5.0, 0.2);
    check_equal(&lattice_map(2), &authors, &ps, 6);
}

#[test]
fn bad_input_is_an_error_not_a_panic() {
    let map = lattice_map(0);
    let model = SensorModel::with_defaults(SensorModelKind::Mixture, 5.0, 0.2);
    assert!(SharedMapLikelihood::new(&map, &model, &[[f64::NAN, 0.0, 0.0]], 1e6).is_err());
    let shared = SharedMapLikelihood::new(&map, &model, &[[1.0, 1.0, 0.0]], 1e6).unwrap();
    let mut sc = CrmScratch::default();
    assert!(shared
        .scan_log_likelihood([1.0, 1.0, 0.0], &[0.0, 1.0], &[1.0], &mut sc)
        .is_err());
    assert!(shared
        .scan_log_likelihood([1.0, 1.0, 0.0], &[f64::NAN], &[1.0], &mut sc)
        .is_err());
    assert!(shared
        .scan_log_likelihood([1.0, f64::INFINITY, 0.0], &[0.0], &[1.0], &mut sc)
        .is_err());
    let mut bad = model;
    bad.sigma_hit = -1.0;
    assert!(SharedMapLikelihood::new(&map, &bad, &[[1.0, 1.0, 0.0]], 1e6).is_err());
}

#[test]
fn window_means_equal_the_per_cell_means() {
    use crlam_core::grid::CellRect;
    // Rectangles across tile borders, partly outside storage, on a fixed and a growing map.
    for map in [lattice_map(4), growing_map()] {
        for rect in [
            CellRect {
                ix0: -5,
                iy0: -7,
                nx: 80,
                ny: 45,
            },
            CellRect {
                ix0: 31,
                iy0: 30,
                nx: 3,
                ny: 2,
            },
            CellRect {
                ix0: 0,
                iy0: 0,
                nx: 1,
                ny: 1,
            },
        ] {
            let mut out = vec![f64::NAN; rect.n_cells()];
            map.means_into(rect, &mut out).unwrap();
            for iy in 0..rect.ny {
                for ix in 0..rect.nx {
                    let want = map.mean_at(rect.ix0 + ix, rect.iy0 + iy);
                    let got = out[(iy * rect.nx + ix) as usize];
                    assert_eq!(got.to_bits(), want.to_bits(), "{rect:?} ({ix}, {iy})");
                }
            }
        }
        let r = CellRect {
            ix0: 0,
            iy0: 0,
            nx: 4,
            ny: 4,
        };
        assert!(map.means_into(r, &mut [0.0; 3]).is_err());
    }
}
