//! crm-spec section 7, items 1–10 (and 16): invariants of the single-beam CRM update.

use crlam_core::crm::update::{apply_factor, cause_sweep, cause_sweep_log, mean, update_ray};
use crlam_core::crm::{
    level_values, CrmConfig, CrmMap, CrmScratch, LevelPlacement, ScanOptions, ScanUpdateMode,
};
use crlam_core::grid::GridGeometry;
use crlam_core::sensor::{SensorModel, SensorModelKind};

/// SplitMix64: a tiny deterministic generator for test inputs.
struct Rng(u64);
impl Rng {
    fn next_f64(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }
    fn pmf(&mut self, k: usize) -> Vec<f64> {
        let v: Vec<f64> = (0..k).map(|_| 0.05 + self.next_f64()).collect();
        let s: f64 = v.iter().sum();
        v.into_iter().map(|x| x / s).collect()
    }
}

fn midpoints() -> Vec<f64> {
    level_values(10, LevelPlacement::Midpoints).unwrap()
}

fn uniform_ray(n: usize, k: usize) -> Vec<f64> {
    vec![1.0 / k as f64; n * k]
}

fn means(b: &[f64], mu: &[f64]) -> Vec<f64> {
    b.chunks(mu.len()).map(|p| mean(mu, p)).collect()
}

/// Cause distances of a ray of `n` cells of 0.2 m starting at the centre of the robot cell.
fn distances(n: usize) -> Vec<f64> {
    (0..n)
        .map(|l| {
            if l == 0 {
                0.05
            } else {
                0.2 * l as f64 + 0.1 - 0.1
            }
        })
        .map(|d| d + 0.1)
        .collect()
}

fn ijrr(sigma: f64, z_max: f64) -> SensorModel {
    let mut m = SensorModel::with_defaults(SensorModelKind::Ijrr, z_max, 0.2);
    m.sigma_hit = sigma;
    m
}

fn likelihoods(model: &SensorModel, d: &[f64], z: f64) -> (Vec<f64>, f64) {
    (
        d.iter().map(|&x| model.on_ray(z, x)).collect(),
        model.infinity(z),
    )
}

/// Brute-force enumeration over all K^N joint configurations: (η, posterior marginals).
fn enumerate(beliefs: &[f64], mu: &[f64], like: &[f64], like_inf: f64) -> (f64, Vec<f64>) {
    let (n, k) = (like.len(), mu.len());
    let mut post = vec![0.0; n * k];
    let mut eta = 0.0;
    let total = k.pow(n as u32);
    for code in 0..total {
        let mut c = code;
        let idx: Vec<usize> = (0..n)
            .map(|_| {
                let i = c % k;
                c /= k;
                i
            })
            .collect();
        let prior: f64 = (0..n).map(|l| beliefs[l * k + idx[l]]).product();
        let mut reach = 1.0;
        let mut pz = 0.0;
        for l in 0..n {
            let m = mu[idx[l]];
            pz += reach * m * like[l];
            reach *= 1.0 - m;
        }
        pz += reach * like_inf;
        eta += prior * pz;
        for l in 0..n {
            post[l * k + idx[l]] += prior * pz;
        }
    }
    for x in post.iter_mut() {
        *x /= eta;
    }
    (eta, post)
}

#[test]
fn item1_normalisation_and_raw_factor_sums() {
    let mut rng = Rng(1);
    let mu = midpoints();
    for _ in 0..200 {
        let n = 1 + (rng.next_f64() * 30.0) as usize;
        let beliefs: Vec<f64> = (0..n).flat_map(|_| rng.pmf(10)).collect();
        let like: Vec<f64> = (0..n).map(|_| rng.next_f64() * 3.0).collect();
        let like_inf = rng.next_f64();
        let mhat = means(&beliefs, &mu);
        let mut alpha = vec![0.0; n];
        let mut s = Vec::new();
        cause_sweep(&mhat, &like, like_inf, &mut s, Some(&mut alpha));
        for l in 0..n {
            let p = &beliefs[l * 10..(l + 1) * 10];
            let raw: f64 = (0..10)
                .map(|i| p[i] * (1.0 + alpha[l] * (mu[i] - mhat[l])))
                .sum();
            assert!((raw - 1.0).abs() < 1e-12, "raw factor sum {raw}");
        }
        let mut b = beliefs.clone();
        update_ray(&mut b, &mu, &like, like_inf, 1e-12);
        for p in b.chunks(10) {
            assert!((p.iter().sum::<f64>() - 1.0).abs() < 1e-12);
            assert!(p.iter().all(|&x| x >= 1e-12 * (1.0 - 1e-9)));
        }
    }
}

#[test]
fn item2_uniform_prior() {
    let mu = midpoints();
    let p = vec![0.1; 10];
    assert!((mean(&mu, &p) - 0.5).abs() < 1e-15);
    let h: f64 = p.iter().map(|x| -x * x.log2()).sum();
    assert!((h - 10f64.log2()).abs() < 1e-12);
}

#[test]
fn item3_mean_shift_is_exact() {
    let mut rng = Rng(3);
    let mu = midpoints();
    for _ in 0..100 {
        let n = 8;
        let beliefs: Vec<f64> = (0..n).flat_map(|_| rng.pmf(10)).collect();
        let like: Vec<f64> = (0..n).map(|_| rng.next_f64()).collect();
        let mhat = means(&beliefs, &mu);
        let mut alpha = vec![0.0; n];
        let mut s = Vec::new();
        cause_sweep(&mhat, &like, 0.3, &mut s, Some(&mut alpha));
        for l in 0..n {
            let mut p = beliefs[l * 10..(l + 1) * 10].to_vec();
            let var = mu.iter().zip(&p).map(|(m, q)| m * m * q).sum::<f64>() - mhat[l] * mhat[l];
            assert!(apply_factor(&mut p, &mu, alpha[l], mhat[l], 0.0));
            assert!((mean(&mu, &p) - (mhat[l] + alpha[l] * var)).abs() < 1e-12);
        }
    }
}

#[test]
fn item4_and_11_brute_force_enumeration() {
    let mut rng = Rng(4);
    for _ in 0..300 {
        let n = 1 + (rng.next_f64() * 4.0) as usize;
        let k = 2 + (rng.next_f64() * 3.0) as usize;
        let mu: Vec<f64> = (0..k).map(|i| (i as f64 + 0.5) / k as f64).collect();
        let beliefs: Vec<f64> = (0..n).flat_map(|_| rng.pmf(k)).collect();
        let like: Vec<f64> = (0..n).map(|_| 0.01 + rng.next_f64() * 2.0).collect();
        let like_inf = 0.01 + rng.next_f64();
        let (eta_bf, post) = enumerate(&beliefs, &mu, &like, like_inf);
        // Item 11: η equals the explicit cause sum Σ π_l L_l + π_∞ L_∞.
        let mhat = means(&beliefs, &mu);
        let (mut reach, mut explicit) = (1.0, 0.0);
        for l in 0..n {
            explicit += reach * mhat[l] * like[l];
            reach *= 1.0 - mhat[l];
        }
        explicit += reach * like_inf;
        let mut b = beliefs.clone();
        let eta = update_ray(&mut b, &mu, &like, like_inf, 0.0);
        assert!((eta - eta_bf).abs() < 1e-12 * eta_bf.max(1.0));
        assert!((eta - explicit).abs() < 1e-12 * eta.max(1.0));
        for (a, e) in b.iter().zip(&post) {
            assert!((a - e).abs() < 1e-12, "{a} vs {e}");
        }
    }
}

#[test]
fn item5_consistency_identity() {
    let mut rng = Rng(5);
    let mu = midpoints();
    let n = 12;
    let beliefs: Vec<f64> = (0..n).flat_map(|_| rng.pmf(10)).collect();
    let like: Vec<f64> = (0..n).map(|_| rng.next_f64()).collect();
    let like_inf = 0.2;
    let mhat = means(&beliefs, &mu);
    let mut s_next = Vec::new();
    let eta = cause_sweep(&mhat, &like, like_inf, &mut s_next, None);
    let (mut f, mut reach) = (0.0, 1.0);
    for l in 0..n {
        let p = &beliefs[l * 10..(l + 1) * 10];
        let lhs: f64 = (0..10)
            .map(|i| p[i] * (f + reach * (mu[i] * like[l] + (1.0 - mu[i]) * s_next[l])))
            .sum();
        assert!((lhs - eta).abs() < 1e-12 * eta);
        f += reach * mhat[l] * like[l];
        reach *= 1.0 - mhat[l];
    }
}

fn hit_ray(n_cells: usize, hit: usize, sigma: f64) -> (SensorModel, Vec<f64>, f64) {
    let model = ijrr(sigma, 8.0);
    let d = distances(n_cells);
    (model, d.clone(), d[hit])
}

#[test]
fn item6_free_space_beam() {
    let mu = midpoints();
    let (model, d, z) = hit_ray(40, 12, 0.06);
    let (like, like_inf) = likelihoods(&model, &d, z);
    let mut b = uniform_ray(40, 10);
    update_ray(&mut b, &mu, &like, like_inf, 1e-12);
    let m = means(&b, &mu);
    for (l, &v) in m.iter().enumerate().take(11) {
        assert!(v < 0.5, "cell {l} must decrease");
        assert!((v - 0.335).abs() < 1e-3, "cell {l}: {v}");
    }
    assert!((m[12] - 0.665).abs() < 2e-3, "hit cell {}", m[12]);
    for l in 0..40 {
        if d[l] > z + 6.0 * 0.06 + 0.2 {
            assert!((m[l] - 0.5).abs() < 1e-9, "far cell {l} changed: {}", m[l]);
        }
    }
    for _ in 0..19 {
        update_ray(&mut b, &mu, &likelihoods(&model, &d, z).0, like_inf, 1e-12);
    }
    let m = means(&b, &mu);
    assert!((m[5] - 0.061).abs() < 2e-3, "free after 20: {}", m[5]);
    assert!((m[12] - 0.939).abs() < 2e-3, "wall after 20: {}", m[12]);
}

#[test]
fn item7_no_return_beam() {
    let mu = midpoints();
    let model = ijrr(0.06, 8.0);
    let d = distances(40);
    let (like, like_inf) = likelihoods(&model, &d, f64::INFINITY);
    let mut b = uniform_ray(40, 10);
    let eta = update_ray(&mut b, &mu, &like, like_inf, 1e-12);
    assert_eq!(eta, 0.5f64.powi(40));
    assert!(means(&b, &mu).iter().all(|&v| v < 0.5));
    for _ in 0..19 {
        update_ray(&mut b, &mu, &like, like_inf, 1e-12);
    }
    for v in means(&b, &mu) {
        assert!((v - 0.061).abs() < 2e-3, "{v}");
    }
}

#[test]
fn item8_monotone_in_evidence() {
    let mu = midpoints();
    let (model, d, z) = hit_ray(30, 10, 0.06);
    let (like, like_inf) = likelihoods(&model, &d, z);
    let mut one = uniform_ray(30, 10);
    update_ray(&mut one, &mu, &like, like_inf, 1e-12);
    let mut two = one.clone();
    update_ray(&mut two, &mu, &like, like_inf, 1e-12);
    let (m1, m2) = (means(&one, &mu), means(&two, &mu));
    for l in 0..8 {
        assert!(m2[l] < m1[l] && m1[l] < 0.5);
    }
    assert!(m2[10] > m1[10] && m1[10] > 0.5);
}

#[test]
fn item9_cells_behind_a_confident_wall_do_not_change() {
    let mu = midpoints();
    // The invariant needs a reading that causes in front of the wall can explain: under the
    // pure-hit `ijrr` model a reading far behind the wall (or a no-return) can only be explained
    // by passing it, and then the exact posterior does change the cells behind.
    let mut mix = SensorModel::with_defaults(SensorModelKind::Mixture, 8.0, 0.2);
    mix.sigma_hit = 0.06;
    let model = ijrr(0.06, 8.0);
    let d = distances(40);
    let cases = [
        (model, d[5]),
        (model, d[10]),
        (model, d[11]),
        (mix, d[30]),
        (mix, f64::INFINITY),
        (mix, d[3]),
    ];
    let mut b = uniform_ray(40, 10);
    for l in 10..20 {
        let p = &mut b[l * 10..(l + 1) * 10];
        p.fill(0.0);
        p[9] = 1.0;
    }
    for (model, z) in cases {
        let (like, like_inf) = likelihoods(&model, &d, z);
        let before = b.clone();
        let mut after = b.clone();
        update_ray(&mut after, &mu, &like, like_inf, 0.0);
        for l in 21..40 {
            for i in 0..10 {
                assert!(
                    (after[l * 10 + i] - before[l * 10 + i]).abs() < 1e-9,
                    "z={z} cell {l}"
                );
            }
        }
    }
}

#[test]
fn item10_mixture_cannot_learn_a_far_wall_but_ijrr_can() {
    let mu = midpoints();
    let d = distances(40);
    let z = d[30];
    let mut mix = SensorModel::with_defaults(SensorModelKind::Mixture, 8.0, 0.2);
    mix.sigma_hit = 0.06;
    let (like, like_inf) = likelihoods(&mix, &d, z);
    let mut b = uniform_ray(40, 10);
    for _ in 0..20 {
        update_ray(&mut b, &mu, &like, like_inf, 1e-12);
    }
    for v in means(&b, &mu) {
        assert!((v - 0.5).abs() < 1e-3, "mixture learned something: {v}");
    }
    let model = ijrr(0.06, 8.0);
    let (like, like_inf) = likelihoods(&model, &d, z);
    let mut b = uniform_ray(40, 10);
    for _ in 0..20 {
        update_ray(&mut b, &mu, &like, like_inf, 1e-12);
    }
    let m = means(&b, &mu);
    assert!((m[10] - 0.061).abs() < 2e-3 && (m[30] - 0.939).abs() < 2e-3);
}

#[test]
fn item16_log_and_linear_eta_agree_on_rays() {
    let mut rng = Rng(16);
    let mu = midpoints();
    let model = SensorModel::with_defaults(SensorModelKind::Mixture, 8.0, 0.2);
    let d = distances(40);
    for _ in 0..50 {
        let b: Vec<f64> = (0..40).flat_map(|_| rng.pmf(10)).collect();
        let mhat = means(&b, &mu);
        let z = rng.next_f64() * 8.0;
        let (like, like_inf) = likelihoods(&model, &d, z);
        let ll: Vec<f64> = d.iter().map(|&x| model.log_on_ray(z, x)).collect();
        let mut s = Vec::new();
        let eta = cause_sweep(&mhat, &like, like_inf, &mut s, None);
        let le = cause_sweep_log(&mhat, &ll, like_inf.ln(), &mut s, None);
        assert!((le.exp() - eta).abs() < 1e-12 * eta);
    }
}

fn beam_map(model: SensorModelKind) -> (CrmMap, SensorModel) {
    let g = GridGeometry::new([0.0, 0.0], 0.2).unwrap();
    let map = CrmMap::new(&CrmConfig::new(g)).unwrap();
    let mut m = SensorModel::with_defaults(model, 8.0, 0.2);
    if model != SensorModelKind::AuthorsCode {
        m.sigma_hit = 0.06;
    }
    (map, m)
}

#[test]
fn map_level_beam_matches_the_ray_level_numbers() {
    let (mut map, model) = beam_map(SensorModelKind::Ijrr);
    let mut sc = CrmScratch::default();
    let z = 12.0 * 0.2 + 0.1 - 0.1;
    for _ in 0..20 {
        map.update_scan(
            [0.1, 0.1, 0.0],
            &[0.0],
            &[z],
            &model,
            &ScanOptions::default(),
            &mut sc,
        )
        .unwrap();
    }
    assert!((map.mean_at(5, 0) - 0.061).abs() < 2e-3);
    assert!(
        (map.mean_at(12, 0) - 0.939).abs() < 5e-3,
        "{}",
        map.mean_at(12, 0)
    );
    assert!((map.mean_at(20, 0) - 0.5).abs() < 1e-6);
}

#[test]
fn authors_code_learns_walls_at_any_range() {
    for wall in [5i64, 15, 30] {
        let (mut map, model) = beam_map(SensorModelKind::AuthorsCode);
        let mut sc = CrmScratch::default();
        let z = 0.2 * wall as f64 + 0.1 - 0.1 + 0.05;
        for _ in 0..20 {
            map.update_scan(
                [0.1, 0.1, 0.0],
                &[0.0],
                &[z],
                &model,
                &ScanOptions::default(),
                &mut sc,
            )
            .unwrap();
        }
        let free = map.mean_at(wall / 2, 0);
        let w = map.mean_at(wall, 0);
        assert!(free < 0.15, "wall {wall}: free {free}");
        assert!(w > 0.85, "wall {wall}: wall {w}");
    }
}

#[test]
fn batch_equals_sequential_for_disjoint_beams_and_differs_little_otherwise() {
    let (mut a, model) = beam_map(SensorModelKind::Ijrr);
    let mut b = a.clone();
    let mut sc = CrmScratch::default();
    let angles: Vec<f64> = (0..180).map(|i| -1.5 + i as f64 * (3.0 / 179.0)).collect();
    let ranges: Vec<f64> = angles.iter().map(|a| 3.0 + a.sin()).collect();
    let seq = ScanOptions {
        mode: ScanUpdateMode::Sequential,
        ..Default::default()
    };
    let sa = a
        .update_scan(
            [0.0, 0.0, 0.3],
            &angles,
            &ranges,
            &model,
            &ScanOptions::default(),
            &mut sc,
        )
        .unwrap();
    let sb = b
        .update_scan([0.0, 0.0, 0.3], &angles, &ranges, &model, &seq, &mut sc)
        .unwrap();
    assert_eq!(sa.n_used, 180);
    assert_eq!(sa.n_cell_updates, sb.n_cell_updates);
    // Far from the sensor, cells are crossed by one beam: identical.
    let (ix, iy) = map_cell(&a, 2.5 * 0.3f64.cos(), 2.5 * 0.3f64.sin());
    assert!((a.mean_at(ix, iy) - b.mean_at(ix, iy)).abs() < 1e-6);
    let (m0a, m0b) = (a.mean_at(0, 0), b.mean_at(0, 0));
    assert!(m0a < 0.2 && m0b < 0.2);
}

fn map_cell(m: &CrmMap, x: f64, y: f64) -> (i64, i64) {
    m.geometry().cell_of(x, y)
}

#[test]
fn copies_share_tiles_until_written() {
    let (mut a, model) = beam_map(SensorModelKind::Ijrr);
    let mut sc = CrmScratch::default();
    let angles: Vec<f64> = (0..90).map(|i| i as f64 * 0.07).collect();
    let ranges = vec![5.0; 90];
    a.update_scan(
        [0.0, 0.0, 0.0],
        &angles,
        &ranges,
        &model,
        &ScanOptions::default(),
        &mut sc,
    )
    .unwrap();
    let mut b = a.clone();
    let st = b.tile_stats();
    assert_eq!(st.n_shared, st.n_allocated);
    b.update_scan(
        [30.0, 0.0, 0.0],
        &angles,
        &ranges,
        &model,
        &ScanOptions::default(),
        &mut sc,
    )
    .unwrap();
    assert_eq!(a.tile_stats().n_allocated, st.n_allocated);
    assert_eq!(b.tile_stats().n_shared, st.n_allocated);
}

#[test]
fn bad_inputs_are_errors_not_panics() {
    let (mut a, model) = beam_map(SensorModelKind::Ijrr);
    let mut sc = CrmScratch::default();
    let o = ScanOptions::default();
    assert!(a
        .update_scan([f64::NAN, 0.0, 0.0], &[0.0], &[1.0], &model, &o, &mut sc)
        .is_err());
    assert!(a
        .update_scan([0.0, 0.0, 0.0], &[0.0, 1.0], &[1.0], &model, &o, &mut sc)
        .is_err());
    a.update_scan([0.0, 0.0, 0.0], &[0.0], &[1.0], &model, &o, &mut sc)
        .unwrap();
    assert!(a
        .update_scan([1e6, 0.0, 0.0], &[0.0], &[1.0], &model, &o, &mut sc)
        .is_err());
    assert!(a
        .update_scan([1e300, 0.0, 0.0], &[0.0], &[1.0], &model, &o, &mut sc)
        .is_err());
    let st = a
        .update_scan(
            [0.0, 0.0, 0.0],
            &[0.0, 0.1, 0.2],
            &[f64::NAN, -1.0, 0.0],
            &model,
            &o,
            &mut sc,
        )
        .unwrap();
    assert_eq!((st.n_used, st.n_no_return, st.n_dropped_short), (1, 1, 2));
    let mut cfg = CrmConfig::new(GridGeometry::new([0.0, 0.0], 0.2).unwrap());
    cfg.extent = Some(crlam_core::grid::CellRect {
        ix0: 0,
        iy0: 0,
        nx: 10,
        ny: 10,
    });
    let mut fixed = CrmMap::new(&cfg).unwrap();
    assert!(fixed
        .update_scan([-1.0, 0.5, 0.0], &[0.0], &[1.0], &model, &o, &mut sc)
        .is_err());
    let st = fixed
        .update_scan([1.0, 1.0, 0.0], &[0.0], &[5.0], &model, &o, &mut sc)
        .unwrap();
    assert_eq!(
        st.n_no_return, 1,
        "a hit beyond the fixed extent is a no-return over the truncated ray"
    );
}

#[test]
fn fused_weigh_and_update_equals_likelihood_then_update() {
    let g = GridGeometry::new([0.0, 0.0], 0.2).unwrap();
    let mut rng = Rng(42);
    for fixed in [false, true] {
        let mut cfg = CrmConfig::new(g);
        if fixed {
            cfg.extent = Some(crlam_core::grid::CellRect {
                ix0: -20,
                iy0: -20,
                nx: 40,
                ny: 40,
            });
        }
        let mut a = CrmMap::new(&cfg).unwrap();
        let ijrr = SensorModel::with_defaults(SensorModelKind::Ijrr, 8.0, 0.2);
        let mix = SensorModel::with_defaults(SensorModelKind::Mixture, 8.0, 0.2);
        let angles: Vec<f64> = (0..120).map(|i| -2.0 + i as f64 * 4.0 / 119.0).collect();
        let mut sc = CrmScratch::default();
        for k in 0..6 {
            let pose = [
                rng.next_f64() - 0.5,
                rng.next_f64() - 0.5,
                rng.next_f64() * 6.0,
            ];
            let ranges: Vec<f64> = (0..120)
                .map(|i| {
                    if (i + k) % 7 == 0 {
                        f64::INFINITY
                    } else if i % 11 == 0 {
                        0.0
                    } else {
                        0.5 + 7.0 * rng.next_f64()
                    }
                })
                .collect();
            let mut b = a.clone();
            let opts = ScanOptions {
                beam_stride: 2,
                ..ScanOptions::default()
            };
            let (ll_sep, used_sep) = a
                .scan_log_likelihood(
                    pose,
                    &angles,
                    &ranges,
                    &mix,
                    &ScanOptions {
                        beam_stride: 3,
                        ..opts
                    },
                    &mut sc,
                )
                .unwrap();
            let st_sep = a
                .update_scan(pose, &angles, &ranges, &ijrr, &opts, &mut sc)
                .unwrap();
            let (ll, used, st) = b
                .weigh_and_update_scan(pose, &angles, &ranges, &mix, 3, &ijrr, &opts, &mut sc)
                .unwrap();
            assert_eq!(used, used_sep);
            assert!(
                (ll - ll_sep).abs() < 1e-9 * ll_sep.abs().max(1.0),
                "{ll} vs {ll_sep}"
            );
            assert_eq!(st, st_sep);
            let r = crlam_core::grid::CellRect {
                ix0: -45,
                iy0: -45,
                nx: 90,
                ny: 90,
            };
            assert_eq!(
                a.beliefs(r).unwrap(),
                b.beliefs(r).unwrap(),
                "fixed extent: {fixed}, scan {k}"
            );
        }
    }
}
