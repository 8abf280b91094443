//! CRMI invariants (crm-spec 7, items 17–24) and the interface contract of the info module.

use crlam_core::crm::{level_values, CrmConfig, CrmMap, LevelPlacement};
use crlam_core::grid::{CellRect, GridGeometry};
use crlam_core::info::crmi::{
    beam_crmi, beam_posteriors, channel_masses, CellDedupe, Crmi, CrmiConfig, CrmiQuadrature,
    CrmiScratch,
};
use crlam_core::info::lattice::BeamAngles;
use crlam_core::info::{
    entropy_nats, evaluate_batch, gain_batch, Candidate, InfoUnits, InformationFunction,
};
use crlam_core::rng::Rng;
use crlam_core::sensor::{SensorModel, SensorModelKind};

const LN2: f64 = std::f64::consts::LN_2;

fn cfg(kind: SensorModelKind) -> CrmiConfig {
    let mut c = CrmiConfig::new(5.0, 0.2);
    c.model = SensorModel::with_defaults(kind, 5.0, 0.2);
    c
}

fn random_beliefs(rng: &mut Rng, n: usize, k: usize) -> Vec<f64> {
    let mut b = Vec::with_capacity(n * k);
    for _ in 0..n {
        let row: Vec<f64> = (0..k).map(|_| rng.uniform().powi(3) + 1e-6).collect();
        let s: f64 = row.iter().sum();
        b.extend(row.iter().map(|x| x / s));
    }
    b
}

fn ray_distances(n: usize, res: f64, jitter: f64) -> Vec<f64> {
    (0..n).map(|l| (l as f64 + 0.5) * res + jitter).collect()
}

#[test]
fn bin_probabilities_sum_to_one_and_total_probability_holds() {
    // Items 17 and 21: exact channel normalisation and Σ_q P(q) p'(q) = p.
    let mu = level_values(10, LevelPlacement::Midpoints).unwrap();
    let mut rng = Rng::new(7);
    for kind in [SensorModelKind::Ijrr, SensorModelKind::Mixture] {
        for trial in 0..20 {
            let n = 3 + trial % 23;
            let b = random_beliefs(&mut rng, n, 10);
            let d = ray_distances(n, 0.2, 0.03 * rng.uniform());
            let bp = beam_posteriors(&cfg(kind), &mu, &b, &d).unwrap();
            let s: f64 = bp.bin_probability.iter().sum();
            assert!((s - 1.0).abs() < 1e-12, "{kind:?}: ΣP = {s}");
            for (i, &p) in b.iter().enumerate() {
                let mix: f64 = bp
                    .bin_probability
                    .iter()
                    .zip(&bp.posteriors)
                    .map(|(pq, post)| pq * post[i])
                    .sum();
                assert!((mix - p).abs() < 1e-12, "{kind:?} entry {i}: {mix} vs {p}");
            }
        }
    }
}

#[test]
fn per_cell_mi_is_between_zero_and_the_cell_entropy() {
    // Item 18.
    let mu = level_values(10, LevelPlacement::Midpoints).unwrap();
    let mut rng = Rng::new(11);
    for kind in [SensorModelKind::Ijrr, SensorModelKind::Mixture] {
        for _ in 0..20 {
            let n = 25;
            let b = random_beliefs(&mut rng, n, 10);
            let d = ray_distances(n, 0.2, 0.0);
            let i = beam_crmi(&cfg(kind), &mu, &b, &d).unwrap();
            for l in 0..n {
                let h = entropy_nats(&b[l * 10..(l + 1) * 10]);
                assert!(
                    i[l] >= -1e-12 && i[l] <= h + 1e-12,
                    "{kind:?} cell {l}: {}",
                    i[l]
                );
            }
        }
    }
}

#[test]
fn uniform_ray_matches_the_spec_numbers() {
    // Item 20 and the 5.2 numbers: 25 cells, Δ = 0.2, z_max = 5, uniform prior, λ_z = 0.1,
    // σ = 0.06 m (the spec's test value; the default σ_hit is 0.0586 m).
    let mu = level_values(10, LevelPlacement::Midpoints).unwrap();
    let b = vec![0.1; 250];
    let d = ray_distances(25, 0.2, 0.0);
    let with_sigma = |kind| {
        let mut c = cfg(kind);
        c.model.sigma_hit = 0.06;
        c
    };
    let ijrr: Vec<f64> = beam_crmi(&with_sigma(SensorModelKind::Ijrr), &mu, &b, &d)
        .unwrap()
        .iter()
        .map(|x| x / LN2)
        .collect();
    assert!((ijrr[0] - 0.235).abs() < 5e-4, "{:?}", &ijrr[..4]);
    assert!((ijrr[1] - 0.108).abs() < 5e-4 && (ijrr[2] - 0.054).abs() < 5e-4);
    for w in ijrr.windows(2) {
        assert!(w[1] < w[0]);
    }
    let total: f64 = ijrr.iter().sum();
    assert!((total - 0.450).abs() < 2e-3, "total {total}");
    let mix: Vec<f64> = beam_crmi(&with_sigma(SensorModelKind::Mixture), &mu, &b, &d)
        .unwrap()
        .iter()
        .map(|x| x / LN2)
        .collect();
    assert!((mix[0] - 0.155).abs() < 5e-4 && (mix[1] - 0.067).abs() < 5e-4);
    let total: f64 = mix.iter().sum();
    assert!((total - 0.278).abs() < 2e-3, "total {total}");
}

/// I(M_l; Q) by enumerating every joint configuration of a tiny ray.
fn enumerated_mi(mu: &[f64], b: &[f64], like: &[Vec<f64>], like_inf: &[f64], l: usize) -> f64 {
    let k = mu.len();
    let n = like.len();
    let nq = like_inf.len();
    // p(q | m_l = μ_a) for each level a, marginalising the other cells.
    let mut cond = vec![vec![0.0; nq]; k];
    let total = k.pow(n as u32);
    for code in 0..total {
        let mut c = code;
        let mut levels = vec![0; n];
        for lv in levels.iter_mut() {
            *lv = c % k;
            c /= k;
        }
        let mut weight = 1.0;
        for j in 0..n {
            if j != l {
                weight *= b[j * k + levels[j]];
            }
        }
        for q in 0..nq {
            let mut reach = 1.0;
            let mut p = 0.0;
            for j in 0..n {
                let m = mu[levels[j]];
                p += reach * m * like[j][q];
                reach *= 1.0 - m;
            }
            p += reach * like_inf[q];
            cond[levels[l]][q] += weight * p;
        }
    }
    let pq: Vec<f64> = (0..nq)
        .map(|q| (0..k).map(|a| b[l * k + a] * cond[a][q]).sum())
        .collect();
    let mut mi = 0.0;
    for a in 0..k {
        for q in 0..nq {
            let joint = b[l * k + a] * cond[a][q];
            if joint > 0.0 {
                mi += joint * (cond[a][q] / pq[q]).ln();
            }
        }
    }
    mi
}

#[test]
fn tiny_rays_match_brute_force_enumeration() {
    // Item 22, for both models and a coarse bin grid so every bin matters.
    let mut rng = Rng::new(3);
    for kind in [SensorModelKind::Ijrr, SensorModelKind::Mixture] {
        for trial in 0..30 {
            let k = 2 + trial % 3;
            let n = 1 + trial % 4;
            let mu: Vec<f64> = (0..k).map(|i| (i as f64 + 0.5) / k as f64).collect();
            let mut c = cfg(kind);
            c.model.z_max = 1.0;
            c.model.sigma_hit = 0.05 + 0.1 * rng.uniform();
            c.lambda_z = 0.1;
            let b = random_beliefs(&mut rng, n, k);
            let d = ray_distances(n, 0.2, 0.05 * rng.uniform());
            let (like, like_inf) = channel_masses(&c, &d).unwrap();
            let got = beam_crmi(&c, &mu, &b, &d).unwrap();
            for (l, g) in got.iter().enumerate() {
                let want = enumerated_mi(&mu, &b, &like, &like_inf, l);
                assert!(
                    (g - want).abs() < 1e-12,
                    "{kind:?} trial {trial} cell {l}: {g} vs {want}"
                );
            }
        }
    }
}

fn map_with(f: impl Fn(i64, i64) -> Vec<f64>) -> CrmMap {
    let g = GridGeometry::new([0.0, 0.0], 0.2).unwrap();
    let rect = CellRect {
        ix0: 0,
        iy0: 0,
        nx: 100,
        ny: 100,
    };
    let mut c = CrmConfig::new(g);
    c.extent = Some(rect);
    let mut m = CrmMap::new(&c).unwrap();
    let mut v = Vec::with_capacity(100 * 100 * 10);
    for iy in 0..100 {
        for ix in 0..100 {
            v.extend(f(ix, iy));
        }
    }
    m.set_beliefs(rect, &v).unwrap();
    m
}

fn one_hot(level: usize, floor: f64) -> Vec<f64> {
    let mut p = vec![floor; 10];
    p[level] = 1.0 - 9.0 * floor;
    p
}

#[test]
fn known_maps_carry_no_information() {
    // Item 19: exactly 0 for one-hot beliefs, < 1e-6 for floored one-hot beliefs.
    let wall = |ix: i64, iy: i64| ix % 17 == 0 || iy % 13 == 0;
    let crmi = Crmi::new(cfg(SensorModelKind::Ijrr)).unwrap();
    for floor in [0.0, 1e-12] {
        let m = map_with(|ix, iy| one_hot(if wall(ix, iy) { 9 } else { 0 }, floor));
        let mut sc = CrmiScratch::default();
        for pose in [[10.1, 10.1, 0.0], [5.3, 7.7, 1.0]] {
            let g = crmi.gain_with(&m, pose, &mut sc).unwrap();
            if floor == 0.0 {
                assert_eq!(g, 0.0);
            } else {
                assert!(g.abs() < 1e-6, "{g}");
            }
        }
    }
}

#[test]
fn pooled_pose_evaluation_equals_the_unpooled_reference() {
    let mut rng = Rng::new(5);
    let m = map_with(|_, _| {
        let row: Vec<f64> = (0..10).map(|_| rng_uniform_cell()).collect();
        let s: f64 = row.iter().sum();
        row.iter().map(|x| x / s).collect()
    });
    // The midpoint quadrature renormalises P(q), so there the pooled evaluation cannot use the
    // expected-divergence form and rebuilds the entropy difference: both paths are checked.
    let settings = [
        (SensorModelKind::Ijrr, CrmiQuadrature::Cdf),
        (SensorModelKind::Mixture, CrmiQuadrature::Cdf),
        (SensorModelKind::Ijrr, CrmiQuadrature::Midpoint),
        (SensorModelKind::Mixture, CrmiQuadrature::Midpoint),
    ];
    for (kind, quadrature) in settings {
        let mut c = cfg(kind);
        c.quadrature = quadrature;
        let crmi = Crmi::new(c).unwrap();
        for _ in 0..5 {
            let pose = [
                5.0 + 10.0 * rng.uniform(),
                5.0 + 10.0 * rng.uniform(),
                6.0 * rng.uniform(),
            ];
            let mut sc = CrmiScratch::default();
            let got = crmi.gain_with(&m, pose, &mut sc).unwrap();
            let want = unpooled_gain_bits(&m, &crmi, &c, pose);
            assert!(
                (got - want).abs() < 1e-12 * want.max(1.0),
                "{kind:?}: {got} vs {want}"
            );
        }
    }
}

/// CRMI (bits) at `pose` from the unpooled per-beam reference `beam_crmi`.
fn unpooled_gain_bits(m: &CrmMap, crmi: &Crmi, c: &CrmiConfig, pose: [f64; 3]) -> f64 {
    let mu = m.levels().to_vec();
    let mut want = 0.0;
    for a in crmi.beam_angles(pose) {
        let mut cells = Vec::new();
        crlam_core::raycast::traverse(
            m.geometry(),
            [pose[0], pose[1]],
            a,
            c.model.z_max,
            m.grid().fixed_extent().as_ref(),
            &mut cells,
        );
        let d: Vec<f64> = cells.iter().map(|c| c.mid()).collect();
        let mut b = Vec::new();
        for c in &cells {
            let p = m.cell(c.ix, c.iy);
            let s: f64 = p.iter().map(|&x| x as f64).sum();
            b.extend(p.iter().map(|&x| x as f64 / s));
        }
        want += beam_crmi(c, &mu, &b, &d).unwrap().iter().sum::<f64>();
    }
    want / LN2
}

#[test]
fn pooled_evaluation_survives_reach_underflow() {
    // A 5 m corridor of 1 cm cells that are mostly occupied: the reach to its far end is about
    // 0.12^500, far below f64, so the far bins take the log-space fallback sweep and their
    // probabilities underflow. The evaluation stays finite and equal to the reference.
    let res = 0.01;
    let g = GridGeometry::new([0.0, 0.0], res).unwrap();
    let rect = CellRect {
        ix0: 0,
        iy0: 0,
        nx: 600,
        ny: 3,
    };
    let mut cc = CrmConfig::new(g);
    cc.extent = Some(rect);
    let mut m = CrmMap::new(&cc).unwrap();
    let mut rng = Rng::new(11);
    let mut v = Vec::new();
    for _ in 0..rect.n_cells() {
        let row: Vec<f64> = (0..10)
            .map(|k| ((k + 1) as f64).powi(6) * (0.5 + rng.uniform()))
            .collect();
        let s: f64 = row.iter().sum();
        v.extend(row.iter().map(|x| x / s));
    }
    m.set_beliefs(rect, &v).unwrap();
    let mut c = CrmiConfig::new(5.0, res);
    c.model = SensorModel::with_defaults(SensorModelKind::Ijrr, 5.0, res);
    let crmi = Crmi::new(c).unwrap();
    let pose = [0.005, 0.015, 0.0];
    let got = crmi
        .gain_with(&m, pose, &mut CrmiScratch::default())
        .unwrap();
    let want = unpooled_gain_bits(&m, &crmi, &c, pose);
    assert!(got.is_finite() && got > 0.0, "{got}");
    assert!(
        (got - want).abs() < 1e-12 * want.max(1.0),
        "{got} vs {want}"
    );
}

/// A deterministic pseudo-random value per call (thread-local counter), for map fills.
fn rng_uniform_cell() -> f64 {
    use std::cell::Cell;
    thread_local!(static STATE: Cell<u64> = const { Cell::new(1) });
    STATE.with(|s| {
        let mut r = Rng::new(s.get());
        s.set(s.get() + 1);
        r.uniform().powi(2) + 1e-3
    })
}

#[test]
fn rotating_the_beams_by_one_step_changes_nothing() {
    // Item 23: with distinct beams over 360°, θ and θ + 2π/n_z give the same set of rays.
    let m = map_with(one_hot_mix);
    let crmi = Crmi::new(cfg(SensorModelKind::Ijrr)).unwrap();
    let mut sc = CrmiScratch::default();
    let a = crmi.gain_with(&m, [9.95, 10.05, 0.3], &mut sc).unwrap();
    let b = crmi
        .gain_with(
            &m,
            [9.95, 10.05, 0.3 + std::f64::consts::TAU / 10.0],
            &mut sc,
        )
        .unwrap();
    assert!((a - b).abs() < 1e-9 * a, "{a} vs {b}");
}

fn one_hot_mix(ix: i64, iy: i64) -> Vec<f64> {
    if (ix + 2 * iy) % 7 == 0 {
        one_hot(8, 1e-3)
    } else {
        vec![0.1; 10]
    }
}

#[test]
fn observed_surroundings_give_less_information() {
    // Item 24: well-observed free cells around one pose, unknown cells around the other.
    let m = map_with(|ix, _| {
        if ix < 50 {
            one_hot(0, 1e-6)
        } else {
            vec![0.1; 10]
        }
    });
    let crmi = Crmi::new(cfg(SensorModelKind::Ijrr)).unwrap();
    let mut sc = CrmiScratch::default();
    let known = crmi.gain_with(&m, [3.0, 10.0, 0.0], &mut sc).unwrap();
    let unknown = crmi.gain_with(&m, [17.0, 10.0, 0.0], &mut sc).unwrap();
    assert!(known < 0.1 * unknown, "{known} vs {unknown}");
}

#[test]
fn evaluate_is_pure_and_commit_lowers_the_next_gain() {
    // planner-spec 9.1 item 13 for CRMI, in a room with known walls: the virtual scan hits them
    // and the repeat evaluation is worth less. (On an all-unknown map a no-return scan can raise
    // the next CRMI: the cells it clears let later beams reach farther, so no general
    // monotonicity is asserted.)
    let mut m = map_with(|ix, iy| {
        if ix == 40 || ix == 60 || iy == 40 || iy == 60 {
            one_hot(9, 1e-3)
        } else {
            vec![0.1; 10]
        }
    });
    let crmi = Crmi::new(cfg(SensorModelKind::Ijrr)).unwrap();
    let c = Candidate::at([10.0, 10.0, 0.0]);
    let e1 = crmi.evaluate(&m, &(), &c, 0).unwrap();
    let e1b = crmi.evaluate(&m, &(), &c, 0).unwrap();
    assert_eq!(e1.gain, e1b.gain);
    crmi.commit(&mut m, &e1.update).unwrap();
    let e2 = crmi.evaluate(&m, &(), &c, 0).unwrap();
    assert!(e2.gain < e1.gain, "{} then {}", e1.gain, e2.gain);
    assert_eq!(crmi.units(), InfoUnits::Bits);
}

#[test]
fn batch_equals_serial_and_dedupe_max_is_smaller() {
    let m = map_with(one_hot_mix);
    let crmi = Crmi::new(cfg(SensorModelKind::Ijrr)).unwrap();
    let cands: Vec<Candidate> = (0..40)
        .map(|i| Candidate::at([2.0 + 0.4 * i as f64, 7.0 + 0.1 * i as f64, 0.1 * i as f64]))
        .collect();
    let batch = gain_batch(&crmi, &m, &(), &cands, 9).unwrap();
    let evals = evaluate_batch(&crmi, &m, &(), &cands, 9).unwrap();
    for (i, c) in cands.iter().enumerate() {
        let serial = crmi.evaluate(&m, &(), c, 0).unwrap().gain;
        assert_eq!(batch[i], serial);
        assert_eq!(evals[i].gain, serial);
    }
    let mut c = cfg(SensorModelKind::Ijrr);
    c.dedupe = CellDedupe::Max;
    let max = Crmi::new(c).unwrap();
    let mut sc = CrmiScratch::default();
    let p = [10.0, 10.0, 0.0];
    assert!(max.gain_with(&m, p, &mut sc).unwrap() < crmi.gain_with(&m, p, &mut sc).unwrap());
}

#[test]
fn midpoint_quadrature_is_normalised_and_close_for_wide_beams() {
    let mu = level_values(10, LevelPlacement::Midpoints).unwrap();
    let b = vec![0.1; 250];
    let d = ray_distances(25, 0.2, 0.0);
    let mut c = cfg(SensorModelKind::Ijrr);
    c.quadrature = CrmiQuadrature::Midpoint;
    let bp = beam_posteriors(&c, &mu, &b, &d).unwrap();
    assert!((bp.bin_probability.iter().sum::<f64>() - 1.0).abs() < 1e-12);
    let mid: f64 = beam_crmi(&c, &mu, &b, &d).unwrap().iter().sum();
    let exact: f64 = beam_crmi(&cfg(SensorModelKind::Ijrr), &mu, &b, &d)
        .unwrap()
        .iter()
        .sum();
    // σ ≈ 0.059 m against λ_z = 0.1 m: bins 1.7σ wide, so the midpoint rule is a few % off.
    assert!((mid - exact).abs() < 0.1 * exact, "{mid} vs {exact}");
    // With bins much narrower than σ both rules converge to the same value.
    c.lambda_z = 0.005;
    let mut fine = cfg(SensorModelKind::Ijrr);
    fine.lambda_z = 0.005;
    let mid: f64 = beam_crmi(&c, &mu, &b, &d).unwrap().iter().sum();
    let exact: f64 = beam_crmi(&fine, &mu, &b, &d).unwrap().iter().sum();
    assert!((mid - exact).abs() < 1e-3 * exact, "{mid} vs {exact}");
}

#[test]
fn bad_settings_are_refused() {
    let mut c = cfg(SensorModelKind::Ijrr);
    c.lambda_z = 0.0;
    assert!(Crmi::new(c).is_err());
    let mut c = cfg(SensorModelKind::Ijrr);
    c.model = SensorModel::with_defaults(SensorModelKind::AuthorsCode, 5.0, 0.2);
    assert!(Crmi::new(c).is_err());
    let crmi = Crmi::new(cfg(SensorModelKind::Ijrr)).unwrap();
    let m = map_with(|_, _| vec![0.1; 10]);
    let mut sc = CrmiScratch::default();
    assert!(crmi.gain_with(&m, [f64::NAN, 0.0, 0.0], &mut sc).is_err());
    let _ = BeamAngles::Reference;
}

mod authors_variants {
    use super::*;
    use crlam_core::info::crmi_authors::{r1_mi_map, AuthorsCrmiConfig, MlScanBinary, R1Map};

    fn room() -> CrmMap {
        map_with(|ix, iy| {
            if ix == 40 || ix == 60 || iy == 40 || iy == 60 {
                one_hot(9, 1e-3)
            } else {
                vec![0.1; 10]
            }
        })
    }

    #[test]
    fn most_likely_scan_stops_at_the_first_likely_wall() {
        let m = room();
        let cfg = AuthorsCrmiConfig::new(5.0, 0.2);
        // From (10.1, 10.1) the wall column ix = 60 starts at x = 12.0: 1.9 m, rounded to 2.0.
        let s = cfg.most_likely_scan(&m, [10.1, 10.1, 0.0]);
        assert!((s.ranges[0] - 2.0).abs() < 1e-9, "{:?}", s.ranges);
        // An unknown map (m̂ = 0.5, not above 0.5) gives no-returns.
        let u = map_with(|_, _| vec![0.1; 10]);
        let s = cfg.most_likely_scan(&u, [10.1, 10.1, 0.0]);
        assert!(s.ranges.iter().all(|&r| r == 5.0));
    }

    #[test]
    fn ml_scan_binary_drops_entropy_and_repeats_gain_less() {
        let mut m = room();
        let f = MlScanBinary::new(AuthorsCrmiConfig::new(5.0, 0.2)).unwrap();
        let c = Candidate::at([10.1, 10.1, 0.0]);
        let e1 = f.evaluate(&m, &(), &c, 0).unwrap();
        assert!(e1.gain > 1.0, "{}", e1.gain);
        assert_eq!(f.evaluate(&m, &(), &c, 0).unwrap().gain, e1.gain);
        // The binary entropy is flat at m̂ = 0.5, so the first updates of unknown cells lose
        // little of it and later ones more; once the cells are confident the gain vanishes.
        let mut gains = vec![e1.gain];
        for _ in 0..40 {
            let e = f.evaluate(&m, &(), &c, 0).unwrap();
            f.commit(&mut m, &e.update).unwrap();
            gains.push(e.gain);
        }
        let peak = gains.iter().cloned().fold(0.0, f64::max);
        assert!(*gains.last().unwrap() < 0.2 * peak, "{gains:?}");
        // A fully known map has no binary entropy to lose.
        let known = map_with(|ix, iy| one_hot(if ix == 60 || iy == 60 { 9 } else { 0 }, 0.0));
        let g = f.evaluate(&known, &(), &c, 0).unwrap().gain;
        assert!(g.abs() < 0.5, "{g}");
    }

    #[test]
    fn r1_map_is_floored_bounded_and_below_the_prior_entropy() {
        let mut m = room();
        let before = m.clone();
        let model = AuthorsCrmiConfig::new(5.0, 0.2).model;
        let angles: Vec<f64> = (0..12)
            .map(|k| k as f64 * std::f64::consts::TAU / 12.0)
            .collect();
        let ranges = vec![1.9; 12];
        let cells = r1_mi_map(&mut m, [10.1, 10.1, 0.0], &angles, &ranges, &model).unwrap();
        assert!(cells.len() > 100);
        for &((x, y), v) in &cells {
            let h0 = crlam_core::info::bernoulli_entropy(before.mean_at(x, y)) / LN2;
            assert!((0.01..=1.0).contains(&v), "{v}");
            assert!(v <= h0.max(0.01) + 1e-12, "cell ({x},{y}): {v} > {h0}");
        }
        // R1's integration lowers the cells the beams reach.
        let lowered = cells
            .iter()
            .filter(|&&((x, y), v)| {
                v < crlam_core::info::bernoulli_entropy(before.mean_at(x, y)) / LN2 - 1e-3
            })
            .count();
        assert!(lowered > 20, "{lowered}");
        // The map was updated with the scan.
        assert!(m.mean_at(52, 50) < before.mean_at(52, 50));
        let f = R1Map::new(AuthorsCrmiConfig::new(5.0, 0.2)).unwrap();
        let g = f
            .evaluate(&room(), &(), &Candidate::at([10.1, 10.1, 0.0]), 0)
            .unwrap()
            .gain;
        assert!(g > 0.0 && g.is_finite());
    }
}
