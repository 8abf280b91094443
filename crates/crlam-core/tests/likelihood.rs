//! crm-spec section 7, items 12–14: the predictive scan likelihood is a proper distribution,
//! bounded below under the mixture, and ordered correctly on converged maps.

use crlam_core::crm::update::{cause_sweep, update_ray};
use crlam_core::crm::{level_values, CrmConfig, CrmMap, CrmScratch, LevelPlacement, ScanOptions};
use crlam_core::grid::GridGeometry;
use crlam_core::pose::compose;
use crlam_core::sensor::{SensorModel, SensorModelKind};
use crlam_core::sim::WorldRaster;

fn eta(model: &SensorModel, mhat: &[f64], d: &[f64], z: f64) -> f64 {
    let like: Vec<f64> = d.iter().map(|&x| model.on_ray(z, x)).collect();
    let mut s = Vec::new();
    cause_sweep(mhat, &like, model.infinity(z), &mut s, None)
}

fn ray(n: usize) -> (Vec<f64>, Vec<f64>) {
    let d: Vec<f64> = (0..n).map(|l| 0.2 * l as f64 + 0.1).collect();
    let mhat: Vec<f64> = (0..n)
        .map(|l| 0.05 + 0.9 * (((l * 37) % 17) as f64 / 16.0))
        .collect();
    (d, mhat)
}

#[test]
fn item12_predictive_likelihood_is_proper() {
    let (d, mhat) = ray(40);
    for kind in [SensorModelKind::Ijrr, SensorModelKind::Mixture] {
        let model = SensorModel::with_defaults(kind, 8.0, 0.2);
        let h = model.sigma_hit / 10.0;
        let n = (8.0 / h) as usize;
        let cont: f64 = (0..n)
            .map(|i| eta(&model, &mhat, &d, (i as f64 + 0.5) * h))
            .sum::<f64>()
            * h;
        let total = cont + eta(&model, &mhat, &d, f64::INFINITY);
        assert!((total - 1.0).abs() < 1e-3, "{kind:?}: total mass {total}");
    }
}

#[test]
fn item13_mixture_lower_bounds() {
    let (d, mhat) = ray(40);
    let model = SensorModel::with_defaults(SensorModelKind::Mixture, 8.0, 0.2);
    for z in [0.01, 1.0, 3.3, 7.99] {
        assert!(eta(&model, &mhat, &d, z) >= model.w_rand / model.z_max * (1.0 - 1e-12));
    }
    assert!(eta(&model, &mhat, &d, f64::INFINITY) >= model.w_max * (1.0 - 1e-12));
}

#[test]
fn item14_ordering_on_a_converged_ray() {
    // 25 cells, wall at 2.5 m, 20 ijrr updates (Appendix A numbers).
    let mu = level_values(10, LevelPlacement::Midpoints).unwrap();
    let mut ijrr = SensorModel::with_defaults(SensorModelKind::Ijrr, 8.0, 0.2);
    ijrr.sigma_hit = 0.06;
    let d: Vec<f64> = (0..25).map(|l| 0.2 * l as f64 + 0.1).collect();
    let wall = d[12];
    let mut b = vec![0.1; 25 * 10];
    for _ in 0..20 {
        let like: Vec<f64> = d.iter().map(|&x| ijrr.on_ray(wall, x)).collect();
        update_ray(&mut b, &mu, &like, ijrr.infinity(wall), 1e-12);
    }
    let mhat: Vec<f64> = b
        .chunks(10)
        .map(|p| p.iter().zip(&mu).map(|(a, m)| a * m).sum())
        .collect();
    let mut mix = SensorModel::with_defaults(SensorModelKind::Mixture, 8.0, 0.2);
    mix.sigma_hit = 0.06;
    let at = eta(&mix, &mhat, &d, wall);
    assert!(at > eta(&mix, &mhat, &d, wall - 0.5) && at > eta(&mix, &mhat, &d, wall + 0.5));
    assert!(at > eta(&mix, &mhat, &d, f64::INFINITY));
}

#[test]
fn item14_true_pose_beats_displaced_poses_on_a_converged_map() {
    let n = 200; // 10 m x 10 m at 0.05 m
    let mut occ = vec![0u8; n * n];
    for i in 0..n {
        for t in 0..3 {
            occ[t * n + i] = 1;
            occ[(n - 1 - t) * n + i] = 1;
            occ[i * n + t] = 1;
            occ[i * n + n - 1 - t] = 1;
        }
    }
    for y in 60..90 {
        for x in 120..140 {
            occ[y * n + x] = 1;
        }
    }
    let world = WorldRaster::new(GridGeometry::new([0.0, 0.0], 0.05).unwrap(), n, n, &occ).unwrap();
    let angles: Vec<f64> = (0..360)
        .map(|i| i as f64 * std::f64::consts::PI / 180.0)
        .collect();
    let truth = [4.1, 5.2, 0.3];
    let mut ranges = vec![0.0; 360];
    world.cast(&[truth], &angles, 8.0, &mut ranges).unwrap();
    let mut map =
        CrmMap::new(&CrmConfig::new(GridGeometry::new([0.0, 0.0], 0.2).unwrap())).unwrap();
    let ijrr = SensorModel::with_defaults(SensorModelKind::Ijrr, 8.0, 0.2);
    let mix = SensorModel::with_defaults(SensorModelKind::Mixture, 8.0, 0.2);
    let mut sc = CrmScratch::default();
    let o = ScanOptions::default();
    for k in 0..20 {
        // Views from a few nearby poses so the map converges around the truth.
        let p = compose(
            truth,
            [
                0.05 * (k % 5) as f64 - 0.1,
                0.04 * (k % 3) as f64 - 0.04,
                0.0,
            ],
        );
        let mut r = vec![0.0; 360];
        world.cast(&[p], &angles, 8.0, &mut r).unwrap();
        map.update_scan(p, &angles, &r, &ijrr, &o, &mut sc).unwrap();
    }
    let ll = |p: [f64; 3], sc: &mut CrmScratch| {
        map.scan_log_likelihood(p, &angles, &ranges, &mix, &o, sc)
            .unwrap()
            .0
    };
    let at = ll(truth, &mut sc);
    for off in [
        [0.3, 0.0, 0.0],
        [0.0, -0.3, 0.0],
        [0.0, 0.0, 0.1],
        [0.0, 0.0, -0.1],
    ] {
        let other = ll(compose(truth, off), &mut sc);
        assert!(
            at > other,
            "true pose {at:.1} vs displaced {off:?} {other:.1}"
        );
    }
}
