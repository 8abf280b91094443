//! The windowed batch kernel (pass counts far before the reading, `crm::windowed`) against the
//! full sweep of every cell: same maps to f32 storage precision, same weights to 1e-10, same
//! counters; and the shared mean cache, which must not change any result.

use crlam_core::crm::{
    BatchKernel, CrmConfig, CrmMap, CrmScratch, LevelPlacement, ScanOptions, ScanStats,
};
use crlam_core::grid::{CellRect, GridGeometry};
use crlam_core::sensor::{SensorModel, SensorModelKind};
use crlam_core::sim::WorldRaster;
use crlam_core::simd::{with_level, SimdLevel};

/// A 16 m x 16 m room (0.05 m raster) with two pillars.
fn room() -> (GridGeometry, Vec<u8>, usize) {
    let n = 320;
    let mut occ = vec![0u8; n * n];
    for i in 0..n {
        for t in 0..3 {
            occ[t * n + i] = 1;
            occ[(n - 1 - t) * n + i] = 1;
            occ[i * n + t] = 1;
            occ[i * n + n - 1 - t] = 1;
        }
    }
    for (cx, cy, h) in [(100usize, 120usize, 12usize), (230, 200, 20)] {
        for y in cy - h..cy + h {
            for x in cx - h..cx + h {
                occ[y * n + x] = 1;
            }
        }
    }
    (GridGeometry::new([-8.0, -8.0], 0.05).unwrap(), occ, n)
}

/// Poses along an arc and the exact scans of `n_beams` over 270° at `z_max`, with a few
/// readings turned into no-returns, zeros and out-of-range values.
fn scans(n_scans: usize, n_beams: usize, z_max: f64) -> (Vec<[f64; 3]>, Vec<f64>, Vec<Vec<f64>>) {
    let (g, occ, n) = room();
    let world = WorldRaster::new(g, n, n, &occ).unwrap();
    let fov = 270f64.to_radians();
    let angles: Vec<f64> = (0..n_beams)
        .map(|i| -fov / 2.0 + fov * i as f64 / (n_beams - 1) as f64)
        .collect();
    let poses: Vec<[f64; 3]> = (0..n_scans)
        .map(|k| {
            let a = 0.09 * k as f64;
            [3.0 * a.cos() - 1.0, 3.0 * a.sin(), a + 1.4]
        })
        .collect();
    let mut flat = vec![0.0; n_scans * n_beams];
    world.cast(&poses, &angles, z_max, &mut flat).unwrap();
    let mut ranges: Vec<Vec<f64>> = flat.chunks(n_beams).map(|c| c.to_vec()).collect();
    for (k, r) in ranges.iter_mut().enumerate() {
        for (b, z) in r.iter_mut().enumerate() {
            match (b * 7 + k) % 53 {
                0 => *z = f64::INFINITY,
                1 => *z = 0.0,
                2 => *z = z_max + 3.0,
                3 => *z = 0.04,
                _ => {}
            }
        }
    }
    (poses, angles, ranges)
}

/// The CRM grid of the comparisons. Its origin is off the room's 0.05 m raster: with walls on
/// that raster, a simulated range can equal a chord midpoint to 1e-16, where the mixture's short
/// term switches on (ε(z; d) = 0 for z > d), and rounding would then decide a real difference.
fn crm_grid() -> GridGeometry {
    GridGeometry::new([0.0123, -0.0271], 0.2).unwrap()
}

fn opts(kernel: BatchKernel, stride: usize) -> ScanOptions {
    ScanOptions {
        kernel,
        beam_stride: stride,
        ..ScanOptions::default()
    }
}

/// Largest difference between two maps' pmf entries over `rect`.
fn max_diff(a: &CrmMap, b: &CrmMap, rect: CellRect) -> f32 {
    a.beliefs(rect)
        .unwrap()
        .iter()
        .zip(b.beliefs(rect).unwrap())
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max)
}

/// Every cell the scans of [`scans`] at 8 m can reach (poses within 4 m of the origin).
const ROOM: CellRect = CellRect {
    ix0: -65,
    iy0: -65,
    nx: 130,
    ny: 130,
};

/// Counters that must agree between the kernels (all of them).
fn same_counts(a: &ScanStats, b: &ScanStats) -> bool {
    a == b
}

#[test]
fn windowed_updates_equal_the_full_sweep_for_every_level_placement() {
    let (poses, angles, ranges) = scans(40, 361, 8.0);
    for placement in [
        LevelPlacement::Midpoints,
        LevelPlacement::Endpoints,
        LevelPlacement::R1Right,
    ] {
        let g = crm_grid();
        let mut cfg = CrmConfig::new(g);
        cfg.placement = placement;
        let model = SensorModel::with_defaults(SensorModelKind::Ijrr, 8.0, 0.2);
        let mut full = CrmMap::new(&cfg).unwrap();
        let mut win = CrmMap::new(&cfg).unwrap();
        let mut sc = CrmScratch::default();
        for (k, (pose, r)) in poses.iter().zip(&ranges).enumerate() {
            let stride = 1 + k % 2;
            let a = full
                .update_scan(
                    *pose,
                    &angles,
                    r,
                    &model,
                    &opts(BatchKernel::FullRay, stride),
                    &mut sc,
                )
                .unwrap();
            let b = win
                .update_scan(
                    *pose,
                    &angles,
                    r,
                    &model,
                    &opts(BatchKernel::Windowed, stride),
                    &mut sc,
                )
                .unwrap();
            assert!(
                same_counts(&a, &b),
                "{placement:?} scan {k}: {a:?} vs {b:?}"
            );
        }
        let d = max_diff(&full, &win, ROOM);
        assert!(d < 2e-6, "{placement:?}: largest pmf difference {d}");
        // The maps really learned: walls and free space are confident, so the test compares
        // converged beliefs and not a near-uniform map.
        let (m, _, _) = win.derived(ROOM).unwrap();
        let (lo, hi) = m
            .iter()
            .fold((1.0f64, 0.0f64), |(a, b), &x| (a.min(x), b.max(x)));
        assert!(
            hi > 0.85 && lo < 0.15,
            "{placement:?}: means in [{lo}, {hi}]"
        );
    }
}

#[test]
fn windowed_weights_and_updates_equal_the_full_sweep() {
    let (poses, angles, ranges) = scans(40, 541, 8.0);
    let g = crm_grid();
    let cfg = CrmConfig::new(g);
    let ijrr = SensorModel::with_defaults(SensorModelKind::Ijrr, 8.0, 0.2);
    let mix = SensorModel::with_defaults(SensorModelKind::Mixture, 8.0, 0.2);
    let mut full = CrmMap::new(&cfg).unwrap();
    let mut win = CrmMap::new(&cfg).unwrap();
    let mut sc = CrmScratch::default();
    for (k, (pose, r)) in poses.iter().zip(&ranges).enumerate() {
        let (wstride, mstride) = [(1, 1), (3, 1), (1, 2), (2, 3)][k % 4];
        let (la, ua, sa) = full
            .weigh_and_update_scan(
                *pose,
                &angles,
                r,
                &mix,
                wstride,
                &ijrr,
                &opts(BatchKernel::FullRay, mstride),
                &mut sc,
            )
            .unwrap();
        let (lb, ub, sb) = win
            .weigh_and_update_scan(
                *pose,
                &angles,
                r,
                &mix,
                wstride,
                &ijrr,
                &opts(BatchKernel::Windowed, mstride),
                &mut sc,
            )
            .unwrap();
        assert_eq!(ua, ub);
        assert!(same_counts(&sa, &sb), "scan {k}: {sa:?} vs {sb:?}");
        // Per beam the two agree to ~1e-15 relative; the sum over beams to 1e-10 absolute.
        assert!(
            (la - lb).abs() < 1e-10 * la.abs().max(1.0),
            "scan {k}: {la} vs {lb}"
        );
        // A pose 5 cm away weighs differently by far more than the tolerance: the comparison
        // is not vacuous.
        let (lc, _, _) = win
            .clone()
            .weigh_and_update_scan(
                [pose[0] + 0.05, pose[1], pose[2]],
                &angles,
                r,
                &mix,
                wstride,
                &ijrr,
                &opts(BatchKernel::Windowed, mstride),
                &mut sc,
            )
            .unwrap();
        if k > 5 {
            assert!((lc - lb).abs() > 1e-2, "scan {k}: {lc} vs {lb}");
        }
    }
    let d = max_diff(&full, &win, ROOM);
    assert!(d < 2e-6, "largest pmf difference {d}");
}

#[test]
fn long_rays_fall_back_to_the_full_sweep_where_reach_underflows() {
    // 60 m rays on 0.2 m cells: behind the learned walls the reach underflows, and no-returns
    // over unknown cells have η = 0.5^300; the windowed kernel hands those beams to the sweep.
    let (poses, angles, ranges) = scans(12, 181, 60.0);
    let g = crm_grid();
    let cfg = CrmConfig::new(g);
    let ijrr = SensorModel::with_defaults(SensorModelKind::Ijrr, 60.0, 0.2);
    let mix = SensorModel::with_defaults(SensorModelKind::Mixture, 60.0, 0.2);
    let mut full = CrmMap::new(&cfg).unwrap();
    let mut win = CrmMap::new(&cfg).unwrap();
    let mut sc = CrmScratch::default();
    for (pose, r) in poses.iter().zip(&ranges) {
        let (la, _, sa) = full
            .weigh_and_update_scan(
                *pose,
                &angles,
                r,
                &mix,
                1,
                &ijrr,
                &opts(BatchKernel::FullRay, 1),
                &mut sc,
            )
            .unwrap();
        let (lb, _, sb) = win
            .weigh_and_update_scan(
                *pose,
                &angles,
                r,
                &mix,
                1,
                &ijrr,
                &opts(BatchKernel::Windowed, 1),
                &mut sc,
            )
            .unwrap();
        assert_eq!(sa, sb);
        assert!((la - lb).abs() < 1e-10 * la.abs().max(1.0), "{la} vs {lb}");
    }
    let wide = CellRect {
        ix0: -60,
        iy0: -60,
        nx: 120,
        ny: 120,
    };
    assert!(max_diff(&full, &win, wide) < 2e-6);
}

#[test]
fn shared_mean_cache_changes_nothing() {
    // Copies of a map share its mean cache until they write; scanning through a filled cache
    // must give the bits a lone map gives, and a copy that wrote must not see stale means.
    let (poses, angles, ranges) = scans(12, 361, 8.0);
    let g = crm_grid();
    let cfg = CrmConfig::new(g);
    let ijrr = SensorModel::with_defaults(SensorModelKind::Ijrr, 8.0, 0.2);
    let mix = SensorModel::with_defaults(SensorModelKind::Mixture, 8.0, 0.2);
    let o = opts(BatchKernel::Windowed, 1);
    let mut sc = CrmScratch::default();
    let mut parent = CrmMap::new(&cfg).unwrap();
    for (pose, r) in poses.iter().zip(&ranges).take(6) {
        parent
            .update_scan(*pose, &angles, r, &ijrr, &o, &mut sc)
            .unwrap();
    }
    let mut copies: Vec<CrmMap> = (0..3).map(|_| parent.clone()).collect();
    let run = |m: &mut CrmMap, k: usize, dx: f64, sc: &mut CrmScratch| {
        let p = poses[k];
        m.weigh_and_update_scan(
            [p[0] + dx, p[1], p[2]],
            &angles,
            &ranges[k],
            &mix,
            1,
            &ijrr,
            &o,
            sc,
        )
        .unwrap()
        .0
    };
    // Reference: a map with the same content that shares nothing.
    let lone = |k: usize, dx: f64, sc: &mut CrmScratch| {
        let mut m = CrmMap::new(&cfg).unwrap();
        m.set_beliefs(
            ROOM,
            &parent
                .beliefs(ROOM)
                .unwrap()
                .iter()
                .map(|&x| x as f64)
                .collect::<Vec<_>>(),
        )
        .unwrap();
        let ll = run(&mut m, k, dx, sc);
        (m, ll)
    };
    for (i, c) in copies.iter_mut().enumerate() {
        let ll = run(c, 6, 0.03 * i as f64, &mut sc);
        let (m, want) = lone(6, 0.03 * i as f64, &mut sc);
        assert_eq!(ll.to_bits(), want.to_bits(), "copy {i}");
        assert_eq!(
            c.beliefs(ROOM).unwrap(),
            m.beliefs(ROOM).unwrap(),
            "copy {i}"
        );
    }
    // A copy that wrote scans again from its own beliefs.
    let ll = run(&mut copies[0], 7, 0.0, &mut sc);
    let mut m = lone(6, 0.0, &mut sc).0;
    let want = run(&mut m, 7, 0.0, &mut sc);
    assert_eq!(ll.to_bits(), want.to_bits());
}

#[test]
fn weighing_alone_equals_the_fused_weight_bit_for_bit() {
    // `weigh_scan` walks far phases, windows and tails sixteen beams at a time in lanes; the
    // fused weight + update walks every beam alone. Both must give the same bits, on a map whose
    // walls have converged (reach drops behind them, so tails end by the stop rule) and with
    // no-returns, out-of-range and short readings among the beams.
    let (poses, angles, ranges) = scans(24, 1079, 8.0);
    let g = crm_grid();
    let cfg = CrmConfig::new(g);
    let ijrr = SensorModel::with_defaults(SensorModelKind::Ijrr, 8.0, 0.2);
    let mix = SensorModel::with_defaults(SensorModelKind::Mixture, 8.0, 0.2);
    let o = opts(BatchKernel::Windowed, 1);
    let mut sc = CrmScratch::default();
    let mut map = CrmMap::new(&cfg).unwrap();
    for (pose, r) in poses.iter().zip(&ranges).take(16) {
        map.update_scan(*pose, &angles, r, &ijrr, &o, &mut sc)
            .unwrap();
    }
    // Every level the CPU runs (the lanes at AVX-512 and AVX2, the scalar kernel alone at
    // scalar), each against the fused weight at the scalar level.
    for level in SimdLevel::ALL {
        if !level.supported() {
            eprintln!("weighing_alone_equals_the_fused_weight: skipped: {level} not supported by this CPU");
            continue;
        }
        for k in 16..24 {
            for (dx, dth) in [(0.0, 0.0), (0.07, -0.01), (-0.13, 0.02)] {
                let p = [poses[k][0] + dx, poses[k][1], poses[k][2] + dth];
                let alone = with_level(level, || {
                    map.clone()
                        .weigh_scan(p, &angles, &ranges[k], &mix, 1, &ijrr, &o, &mut sc)
                        .unwrap()
                });
                let fused = with_level(SimdLevel::Scalar, || {
                    map.clone()
                        .weigh_and_update_scan(p, &angles, &ranges[k], &mix, 1, &ijrr, &o, &mut sc)
                        .unwrap()
                });
                assert_eq!(
                    alone.0.to_bits(),
                    fused.0.to_bits(),
                    "{level}: scan {k}, offset {dx}"
                );
                assert_eq!(alone.1, fused.1);
            }
        }
    }
}
