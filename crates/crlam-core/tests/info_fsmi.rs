//! OGMI / FSMI invariants (planner-spec 9.2 items 1–7, 9.1 item 13 for FSMI and IIG 'mi').

use crlam_bench::info::{bench_fsmi_vs_julian, bench_lattice};
use crlam_core::grid::GridGeometry;
use crlam_core::info::bernoulli_entropy;
use crlam_core::info::fsmi::*;
use crlam_core::info::iig_mi::IigMi;
use crlam_core::info::lattice::{BeamAngles, OccupancyLattice};
use crlam_core::info::{Candidate, InformationFunction};
use crlam_core::rng::Rng;

fn params(sigma: f64) -> OgmiParams {
    OgmiParams {
        sigma,
        ..OgmiParams::default()
    }
}

/// A random beam: n cells with widths in [0.05, 0.3] m starting at `start`, occupancies mixing
/// free-ish, unknown and occupied-ish values (and some exact 0).
fn random_beam(rng: &mut Rng, n: usize) -> (Vec<f64>, Vec<f64>) {
    let mut edges = vec![0.1 * rng.uniform()];
    for _ in 0..n {
        let last = *edges.last().unwrap();
        edges.push(last + 0.05 + 0.25 * rng.uniform());
    }
    let o = (0..n)
        .map(|_| match (rng.uniform() * 4.0) as usize {
            0 => 0.05 + 0.3 * rng.uniform(),
            1 => 0.5,
            2 => rng.uniform(),
            _ => 0.1 * rng.uniform(),
        })
        .collect();
    (o, edges)
}

fn bernoulli_kl(delta: f64, r: f64) -> f64 {
    let (p, q) = (r / (1.0 + r), 1.0 / (1.0 + r));
    let (pp, qq) = (r * delta / (1.0 + r * delta), 1.0 / (1.0 + r * delta));
    pp * (pp / p).ln() + qq * (qq / q).ln()
}

#[test]
fn kl_factor_is_the_bernoulli_kl_and_has_the_limits() {
    let mut rng = Rng::new(1);
    for _ in 0..10_000 {
        let delta = (rng.uniform() * 6.0 - 3.0).exp();
        let r = (rng.uniform() * 36.0 - 18.0).exp();
        let f = kl_factor(delta, r);
        assert!(f >= 0.0);
        let kl = bernoulli_kl(delta, r);
        assert!(
            (f - kl).abs() <= 1e-12 * kl.max(1.0),
            "δ={delta} r={r}: {f} vs {kl}"
        );
        assert_eq!(kl_factor(1.0, r), 0.0);
    }
    for delta in [0.1, 1.0 / 1.5, 1.5, 10.0] {
        assert_eq!(kl_factor(delta, 0.0), 0.0);
        assert_eq!(kl_factor(delta, f64::INFINITY), 0.0);
        assert!(kl_factor(delta, 1e12) < 1e-10 && kl_factor(delta, 1e-12) < 1e-10);
        // Small-r asymptote r(1 − δ + δ ln δ) and large-r asymptote (δ − 1 − ln δ)/(rδ).
        let small = 1e-9 * (1.0 - delta + delta * delta.ln());
        assert!((kl_factor(delta, 1e-9) - small).abs() < 1e-6 * small);
        let large = (delta - 1.0 - delta.ln()) / (1e9 * delta);
        assert!((kl_factor(delta, 1e9) - large).abs() < 1e-6 * large);
    }
    // r = 1, δ = 1.5: p = 1/2, p′ = 3/5.
    let expect = 0.6 * (1.2f64).ln() + 0.4 * (0.8f64).ln();
    assert!((kl_factor(1.5, 1.0) - expect).abs() < 1e-15);
}

#[test]
fn probability_bookkeeping() {
    let mut rng = Rng::new(2);
    let mut terms = BeamTerms::new();
    for _ in 0..200 {
        let n = 1 + (rng.uniform() * 60.0) as usize;
        let (o, edges) = random_beam(&mut rng, n);
        terms.compute(&o, &OgmiParams::default()).unwrap();
        let total: f64 = terms.p_first().iter().sum::<f64>() + terms.p_none();
        assert!((total - 1.0).abs() < 1e-12);
        assert_eq!(terms.gains().len(), n + 1);
        for sigma in [0.02, 0.05, 0.1] {
            for j in 0..n {
                let g = reading_cell_probabilities(&edges, sigma, j).unwrap();
                let mass: f64 = g.iter().sum();
                assert!(mass <= 1.0 + 1e-12);
                let mu = 0.5 * (edges[j] + edges[j + 1]);
                if mu - edges[0] > 9.0 * sigma && edges[n] - mu > 9.0 * sigma {
                    assert!((mass - 1.0).abs() < 1e-12, "{mass}");
                }
            }
        }
    }
}

#[test]
fn beam_mi_is_non_negative_and_vanishes_on_known_cells() {
    let mut rng = Rng::new(3);
    let p = OgmiParams::default();
    for _ in 0..300 {
        let n = (rng.uniform() * 40.0) as usize;
        let (o, edges) = random_beam(&mut rng, n);
        for mi in [
            fsmi_beam(&o, &edges, &p).unwrap(),
            fsmi_beam_truncated(&o, &edges, &p, 3.0).unwrap(),
            fsmi_beam_noise_free(&o, &edges, &p).unwrap(),
            julian_beam_mi(&o, &edges, &p, 4).unwrap(),
        ] {
            assert!(mi >= 0.0 && mi.is_finite());
        }
    }
    // Cells at ε or 1 − ε: MI → 0 with ε (O(ε)).
    let (o0, edges) = random_beam(&mut rng, 30);
    let mut last = f64::INFINITY;
    for eps in [1e-2, 1e-4, 1e-6, 1e-9] {
        let o: Vec<f64> = o0
            .iter()
            .map(|&x| if x < 0.4 { eps } else { 1.0 - eps })
            .collect();
        let mi = fsmi_beam(&o, &edges, &p).unwrap();
        assert!(mi < last && mi < 10.0 * eps, "ε={eps}: {mi}");
        last = mi;
    }
    // Exactly known cells (r = 0 or ∞): exactly 0 and no NaN.
    let o: Vec<f64> = o0
        .iter()
        .map(|&x| if x < 0.4 { 0.0 } else { 1.0 })
        .collect();
    assert_eq!(fsmi_beam(&o, &edges, &p).unwrap(), 0.0);
    assert_eq!(julian_beam_mi(&o, &edges, &p, 3).unwrap(), 0.0);
    let all_free = vec![0.0; 30];
    assert_eq!(fsmi_beam_noise_free(&all_free, &edges, &p).unwrap(), 0.0);
}

#[test]
fn occlusion_cells_behind_a_certain_wall() {
    let mut rng = Rng::new(4);
    let p = OgmiParams::default();
    for _ in 0..100 {
        let (mut o, edges) = random_beam(&mut rng, 40);
        let wall = 5 + (rng.uniform() * 20.0) as usize;
        o[wall] = 1.0;
        let before = [
            fsmi_beam_noise_free(&o, &edges, &p).unwrap(),
            fsmi_beam(&o, &edges, &p).unwrap(),
            fsmi_beam_truncated(&o, &edges, &p, 3.0).unwrap(),
        ];
        // Every cell behind the wall: the noise-free MI does not move at all.
        let mut behind = o.clone();
        for x in &mut behind[wall + 1..] {
            *x = rng.uniform();
        }
        assert_eq!(
            fsmi_beam_noise_free(&behind, &edges, &p).unwrap(),
            before[0]
        );
        // With noise a reading of the wall may land behind it (the Gaussian model), so cells
        // more than 12σ behind are the ones that cannot matter (truncated: beyond the window).
        let far = edges[wall + 1] + 12.0 * p.sigma;
        let mut far_changed = o.clone();
        for k in wall + 1..40 {
            if edges[k] > far {
                far_changed[k] = rng.uniform();
            }
        }
        let after = fsmi_beam(&far_changed, &edges, &p).unwrap();
        assert!(
            (after - before[1]).abs() <= 1e-12 * before[1].max(1e-300),
            "{after} vs {}",
            before[1]
        );
        let after = fsmi_beam_truncated(&far_changed, &edges, &p, 3.0).unwrap();
        assert_eq!(after, before[2]);
    }
}

#[test]
fn fsmi_equals_julians_integral() {
    let mut rng = Rng::new(5);
    let mut terms = BeamTerms::new();
    let mut worst: f64 = 0.0;
    for i in 0..200 {
        let n = 1 + (rng.uniform() * 60.0) as usize;
        let (o, edges) = random_beam(&mut rng, n);
        let sigma = [0.02, 0.05, 0.1][i % 3];
        let p = params(sigma);
        let full = fsmi_beam(&o, &edges, &p).unwrap();
        // Midpoint error ~ (h/σ)²/24 per cell: h = 0.3 m / 300 keeps it near 1e-5 at σ = 0.02.
        let julian = julian_beam_mi(&o, &edges, &p, 300).unwrap();
        let rel = (full - julian).abs() / full;
        worst = worst.max(rel);
        assert!(rel < 1e-4, "beam {i}: n={n} σ={sigma}: {full} vs {julian}");
        let trunc = fsmi_beam_truncated(&o, &edges, &p, DEFAULT_TRUNCATION_SIGMAS).unwrap();
        assert!((trunc - full).abs() < 1e-3 * full, "{trunc} vs {full}");
        // The closed form against the explicit double sum Σ_j P_j Σ_k C_k G_kj.
        terms.compute(&o, &p).unwrap();
        let (pf, c) = (terms.p_first(), terms.gains());
        // C_k (batched logarithms) against the scalar per-cell KL factors.
        let odds = |x: f64| {
            if x == 1.0 {
                f64::INFINITY
            } else {
                x / (1.0 - x)
            }
        };
        let mut loss = 0.0;
        for k in 0..=n {
            let want = loss
                + if k < n {
                    kl_factor(p.delta_occ, odds(o[k]))
                } else {
                    0.0
                };
            assert!(
                (c[k] - want).abs() <= 1e-14 * want.max(1e-3),
                "C_{k}: {} vs {want}",
                c[k]
            );
            if k < n {
                loss += kl_factor(p.delta_emp, odds(o[k]));
            }
        }
        let mut direct = terms.p_none() * c[n];
        for (j, pj) in pf.iter().enumerate() {
            let g = reading_cell_probabilities(&edges, sigma, j).unwrap();
            direct += pj * g.iter().zip(c).map(|(g, c)| g * c).sum::<f64>();
        }
        assert!((direct - full).abs() < 1e-12 * full.max(1e-3));
    }
    eprintln!("FSMI vs Julian (λ_z = 300): worst relative difference {worst:.2e}");
}

#[test]
fn noise_free_is_the_sum_over_events_and_the_small_sigma_limit() {
    let mut rng = Rng::new(6);
    let p = OgmiParams::default();
    for _ in 0..200 {
        let n = 1 + (rng.uniform() * 60.0) as usize;
        let (o, edges) = random_beam(&mut rng, n);
        // Σ_j P_j C_j + P_∅ C_{n+1}, built here from kl_factor directly.
        let (mut survive, mut loss, mut expect) = (1.0, 0.0, 0.0);
        for &x in &o {
            let r = x / (1.0 - x);
            expect += x * survive * (loss + kl_factor(p.delta_occ, r));
            loss += kl_factor(p.delta_emp, r);
            survive *= 1.0 - x;
        }
        expect += survive * loss;
        let nf = fsmi_beam_noise_free(&o, &edges, &p).unwrap();
        assert!((nf - expect).abs() < 1e-13 * expect.max(1.0));
        // Cells are ≥ 5 cm wide: at σ = 1e-4 every Gaussian stays in its cell.
        let tiny = fsmi_beam(&o, &edges, &params(1e-4)).unwrap();
        assert!((tiny - nf).abs() < 1e-12 * nf.max(1.0));
        let small = fsmi_beam(&o, &edges, &params(1e-3)).unwrap();
        let wider = fsmi_beam(&o, &edges, &params(0.02)).unwrap();
        assert!((small - nf).abs() <= (wider - nf).abs() + 1e-15);
    }
}

#[test]
fn beam_functions_refuse_bad_input() {
    let p = OgmiParams::default();
    assert!(fsmi_beam(&[0.5, 0.5], &[0.0, 0.2], &p).is_err());
    assert!(fsmi_beam(&[0.5, 1.5], &[0.0, 0.2, 0.4], &p).is_err());
    assert!(fsmi_beam(&[0.5, 0.5], &[0.0, 0.3, 0.2], &p).is_err());
    assert!(fsmi_beam(&[0.5], &[0.0, f64::NAN], &p).is_err());
    assert!(julian_beam_mi(&[0.5], &[0.0, 0.2], &p, 0).is_err());
    assert!(fsmi_beam_truncated(&[0.5], &[0.0, 0.2], &p, 0.0).is_err());
    for bad in [
        OgmiParams {
            delta_occ: 0.9,
            ..p
        },
        OgmiParams {
            delta_emp: 1.0,
            ..p
        },
        OgmiParams { sigma: 0.0, ..p },
        OgmiParams {
            z_max: f64::NAN,
            ..p
        },
    ] {
        assert!(bad.validate().is_err());
        assert!(fsmi_beam(&[0.5], &[0.0, 0.2], &bad).is_err());
    }
    assert_eq!(fsmi_beam(&[], &[0.0], &p).unwrap(), 0.0);
}

fn square_lattice(n: usize, prob: Vec<f64>) -> OccupancyLattice {
    OccupancyLattice::new(GridGeometry::new([0.0, 0.0], 0.2).unwrap(), n, n, prob).unwrap()
}

/// Centre (m) of node (a, b) of a lattice with origin (0, 0) and 0.2 m spacing.
fn centre(a: usize, b: usize) -> [f64; 2] {
    [0.2 * (a as f64 + 0.5), 0.2 * (b as f64 + 0.5)]
}

fn all_variants() -> Vec<Fsmi> {
    [
        FsmiVariant::Full,
        FsmiVariant::Truncated { width_sigmas: 3.0 },
        FsmiVariant::NoiseFree,
        FsmiVariant::Julian { points_per_cell: 8 },
    ]
    .into_iter()
    .map(Fsmi::new)
    .collect()
}

#[test]
fn scan_mi_is_invariant_under_quarter_turns_and_shifts() {
    let n = 61;
    let mut rng = Rng::new(7);
    let prob: Vec<f64> = (0..n * n)
        .map(|_| [0.3, 0.5, 0.85, 0.1][(rng.uniform() * 4.0) as usize])
        .collect();
    // (a, b) → (n − 1 − b, a) is a quarter turn about the lattice centre.
    let mut turned = vec![0.0; n * n];
    for b in 0..n {
        for a in 0..n {
            turned[a * n + (n - 1 - b)] = prob[b * n + a];
        }
    }
    let (map, map_turned) = (square_lattice(n, prob.clone()), square_lattice(n, turned));
    // A shift by (3, −2) cells with the content moved along.
    let mut shifted = vec![0.3; n * n];
    for b in 2..n {
        for a in 0..n - 3 {
            shifted[(b - 2) * n + a + 3] = prob[b * n + a];
        }
    }
    let map_shifted = square_lattice(n, shifted);
    for f in all_variants() {
        for _ in 0..10 {
            let (a, b) = (
                27 + (rng.uniform() * 5.0) as usize,
                27 + (rng.uniform() * 5.0) as usize,
            );
            let theta = 0.1 + rng.uniform();
            let p = centre(a, b);
            let mi = f.scan_mi(&map, [p[0], p[1], theta]).unwrap();
            let q = centre(n - 1 - b, a);
            let mi_turned = f
                .scan_mi(
                    &map_turned,
                    [q[0], q[1], theta + std::f64::consts::FRAC_PI_2],
                )
                .unwrap();
            let s = centre(a + 3, b - 2);
            let mi_shifted = f.scan_mi(&map_shifted, [s[0], s[1], theta]).unwrap();
            assert!(mi > 0.0);
            assert!(
                (mi - mi_turned).abs() < 1e-9 * mi,
                "{}: {mi} vs {mi_turned}",
                f.name()
            );
            assert!(
                (mi - mi_shifted).abs() < 1e-9 * mi,
                "{}: {mi} vs {mi_shifted}",
                f.name()
            );
        }
    }
}

#[test]
fn known_map_gives_zero_unknown_map_gives_more_with_range() {
    let n = 101;
    let mut known = vec![0.0; n * n];
    for i in 0..n {
        for j in [0, 40, 70] {
            known[i * n + j] = 1.0;
            known[j * n + i] = 1.0;
        }
    }
    let known = square_lattice(n, known);
    let unknown = square_lattice(n, vec![0.5; n * n]);
    let pose = [10.1, 10.1, 0.3];
    for f in all_variants() {
        assert_eq!(f.scan_mi(&known, pose).unwrap(), 0.0, "{}", f.name());
        assert!(f.scan_mi(&unknown, pose).unwrap() > 0.0);
    }
    let mut last = 0.0;
    for z_max in [0.1, 0.3, 0.5, 1.0, 2.0, 3.0, 5.0, 8.0] {
        let mut f = Fsmi::new(FsmiVariant::NoiseFree);
        f.params.z_max = z_max;
        let mi = f.scan_mi(&unknown, pose).unwrap();
        assert!(mi >= last, "z_max {z_max}: {mi} < {last}");
        last = mi;
    }
}

fn poses() -> Vec<[f64; 3]> {
    let mut rng = Rng::new(8);
    (0..12)
        .map(|_| [1.0 + 18.0 * rng.uniform(), 1.0 + 18.0 * rng.uniform(), 0.0])
        .collect()
}

type LatticeFn =
    dyn InformationFunction<Map = OccupancyLattice, Belief = (), Update = Vec<(usize, f64)>>;

/// Pure evaluate; commit writes exactly the update. Returns the gains (first, after one commit)
/// per pose, the poses visited in turn on one map.
fn eval_commit_eval(f: &LatticeFn) -> Vec<(f64, f64)> {
    let mut map = bench_lattice(11).unwrap();
    let mut gains = Vec::new();
    for pose in poses() {
        let before = map.clone();
        let c = Candidate::at(pose);
        let first = f.evaluate(&map, &(), &c, 0).unwrap();
        let again = f.evaluate(&map, &(), &c, 0).unwrap();
        assert_eq!(map, before, "evaluate must not change the map");
        assert_eq!((first.gain, &first.update), (again.gain, &again.update));
        f.commit(&mut map, &first.update).unwrap();
        for &(id, p) in &first.update {
            assert_eq!(map.get(id), p);
        }
        let changed = (0..map.len())
            .filter(|&i| map.get(i) != before.get(i))
            .count();
        assert!(changed <= first.update.len());
        gains.push((first.gain, f.evaluate(&map, &(), &c, 0).unwrap().gain));
    }
    let len = map.len();
    assert!(f.commit(&mut map, &vec![(len, 0.5)]).is_err());
    assert!(f.commit(&mut map, &vec![(0, 1.5)]).is_err());
    gains
}

#[test]
fn iig_mi_commit_lowers_the_next_gain() {
    // planner-spec 9.1 item 13: second ≤ first, strictly when the first is > 0.
    for upper_bound in [false, true] {
        let f = IigMi {
            upper_bound,
            ..IigMi::default()
        };
        for (first, second) in eval_commit_eval(&f) {
            assert!(
                first > 0.0 && second < first,
                "{}: {second} ≥ {first}",
                f.name()
            );
        }
    }
}

#[test]
fn fsmi_virtual_scans_are_pure_and_eventually_exhaust_the_gain() {
    for f in all_variants() {
        eval_commit_eval(&f);
    }
    // Item 13 does NOT hold for FSMI with the inverse-sensor virtual scan: making cells freer
    // lets the next predicted reading reach further, which can raise Julian's MI. On a uniform
    // 0.5 map the second gain is higher; repeated scans then drive it down.
    let f = Fsmi::new(FsmiVariant::Full);
    let mut map = square_lattice(101, vec![0.5; 101 * 101]);
    let c = Candidate::at([10.1, 10.1, 0.2]);
    let mut gains = Vec::new();
    for _ in 0..30 {
        let e = f.evaluate(&map, &(), &c, 0).unwrap();
        f.commit(&mut map, &e.update).unwrap();
        gains.push(e.gain);
    }
    assert!(gains[1] > gains[0], "{gains:?}");
    let peak = (0..30)
        .max_by(|&a, &b| gains[a].total_cmp(&gains[b]))
        .unwrap();
    assert!(
        gains[peak + 1..].windows(2).all(|w| w[1] < w[0]),
        "{gains:?}"
    );
    assert!(gains[29] < 0.1 * gains[0], "{gains:?}");
}

#[test]
fn fsmi_update_is_the_inverse_sensor_model() {
    let n = 41;
    let mut prob = vec![0.3; n * n];
    prob[20 * n + 25] = 0.85; // 5 cells to the right of the pose's node (20, 20)
    let map = square_lattice(n, prob);
    let mut f = Fsmi::new(FsmiVariant::NoiseFree);
    f.n_beams = 1;
    let p = centre(20, 20);
    let e = f
        .evaluate(&map, &(), &Candidate::at([p[0], p[1], 0.0]), 0)
        .unwrap();
    let odds = |x: f64| x / (1.0 - x);
    let ids: Vec<usize> = e.update.iter().map(|u| u.0).collect();
    assert_eq!(ids, (20..=25).map(|a| 20 * n + a).collect::<Vec<_>>());
    for &(id, value) in &e.update[..5] {
        assert!((odds(value) - odds(0.3) / 1.5).abs() < 1e-12, "{id}");
    }
    assert!((odds(e.update[5].1) - odds(0.85) * 1.5).abs() < 1e-12);
    // Four beams share the pose's node: its odds get δ_emp four times.
    f.n_beams = 4;
    let e = f
        .evaluate(&map, &(), &Candidate::at([p[0], p[1], 0.0]), 0)
        .unwrap();
    let own = e.update.iter().find(|u| u.0 == 20 * n + 20).unwrap().1;
    assert!((odds(own) - odds(0.3) / 1.5f64.powi(4)).abs() < 1e-12);
}

#[test]
fn iig_mi_saturated_pose_gives_zero() {
    let map = square_lattice(60, vec![0.01; 3600]);
    let f = IigMi::default();
    let e = f
        .evaluate(&map, &(), &Candidate::at([6.1, 6.1, 0.0]), 0)
        .unwrap();
    assert!(e.gain < 1e-12);
    assert!(e.update.is_empty() || e.update.iter().all(|&(id, v)| v == map.get(id)));
}

#[test]
fn iig_mi_hand_checked_cases() {
    let n = 20;
    let h = bernoulli_entropy;
    // Enclosed: the 8 neighbours of node (10, 10) are walls, so every beam is 2 steps (own node at
    // 0.079 m, then a wall at 0.159 m) and no integration point fits (0.5 m > 0.159 m).
    let mut prob = vec![0.3; n * n];
    for b in 9..=11 {
        for a in 9..=11 {
            prob[b * n + a] = 0.85;
        }
    }
    prob[10 * n + 10] = 0.3;
    let p = centre(10, 10);
    let pose = Candidate::at([p[0], p[1], 0.0]);
    let f = IigMi::default();
    let e = f
        .evaluate(&square_lattice(n, prob.clone()), &(), &pose, 0)
        .unwrap();
    assert!(
        (e.gain - 10.0 * (h(0.3) + h(0.85))).abs() < 1e-12,
        "{}",
        e.gain
    );
    prob[10 * n + 10] = 0.02; // saturated own node: only the walls count
    let e = f.evaluate(&square_lattice(n, prob), &(), &pose, 0).unwrap();
    assert!((e.gain - 10.0 * h(0.85)).abs() < 1e-12, "{}", e.gain);

    // One beam to the left (angle −π): steps k·5/63 m visit nodes 10, 9, 9, 8, 8, 8, then the
    // wall node 7 at 0.556 m. One integration point z = 0.5; its nearest step is step 6
    // (0.476 m, node 8). Each unsaturated step updates node 8 once (0.3 → 0.18 → 0.108 →
    // 0.0648 → 0.049 floor); steps 5 and 6 find it saturated.
    let mut prob = vec![0.3; n * n];
    prob[10 * n + 7] = 0.85;
    let map = square_lattice(n, prob);
    let mut f = IigMi {
        n_beams: 1,
        ..IigMi::default()
    };
    let e = f.evaluate(&map, &(), &pose, 0).unwrap();
    let ranges: Vec<f64> = (1..=6).map(|k| k as f64 * 5.0 / 63.0).collect();
    let gauss = |r: f64| {
        (-0.5 * ((r - 0.5) / 0.05f64).powi(2)).exp() / (0.05 * (2.0 * std::f64::consts::PI).sqrt())
    };
    let (mut survive, mut pz) = (1.0, 0.0);
    for &r in &ranges {
        let spike = if (r - 0.5f64).abs() < 0.05 { 1.0 } else { 0.0 };
        let g = (0.7 * gauss(r) + 0.1 * 0.2 + 0.1 * spike).max(0.2);
        pz += g * 0.3 * survive;
        survive *= 0.7;
    }
    pz += 0.2 * survive;
    let mut expect = 6.0 * h(0.3) + h(0.85);
    let mut node8 = 0.3;
    let unsaturated_steps = [true, true, true, true, false, false, true];
    for unsat in unsaturated_steps {
        if unsat {
            node8 = (0.6f64 * node8).max(0.049);
            expect -= 0.5 * pz * h(node8);
        } else {
            expect -= h(0.049);
        }
    }
    assert!((e.gain - expect).abs() < 1e-12, "{} vs {expect}", e.gain);
    assert_eq!(e.update, vec![(10 * n + 8, 0.049)]);
    // 'miub' = prior entropy minus the saturated steps, never below 'mi'.
    f.upper_bound = true;
    let ub = f.evaluate(&map, &(), &pose, 0).unwrap();
    assert!((ub.gain - (6.0 * h(0.3) + h(0.85) - 2.0 * h(0.049))).abs() < 1e-12);
    assert_eq!(ub.update, e.update);
}

#[test]
fn per_pose_functions_refuse_bad_input() {
    let map = bench_lattice(1).unwrap();
    let c = Candidate::at([f64::NAN, 1.0, 0.0]);
    assert!(Fsmi::default().evaluate(&map, &(), &c, 0).is_err());
    assert!(IigMi::default().evaluate(&map, &(), &c, 0).is_err());
    let outside = Candidate::at([50.0, 1.0, 0.0]);
    assert!(Fsmi::default().evaluate(&map, &(), &outside, 0).is_err());
    let f = Fsmi {
        n_beams: 0,
        ..Fsmi::default()
    };
    assert!(f.validate().is_err());
    let g = IigMi {
        int_res: 0.0,
        ..IigMi::default()
    };
    assert!(g.validate().is_err());
    assert_eq!(
        Fsmi::new(FsmiVariant::Julian {
            points_per_cell: 10
        })
        .name(),
        "ogmi_julian"
    );
    assert_eq!(Fsmi::default().name(), "fsmi");
    assert_eq!(IigMi::default().beam_angles, BeamAngles::Reference);
}

/// `cargo test -p crlam-core --test info_fsmi -- --ignored --nocapture` prints the timings.
#[test]
#[ignore]
fn bench_report() {
    let b = bench_fsmi_vs_julian(200, 42).unwrap();
    println!("{b:#?}");
    println!(
        "speed-up vs Julian(λ_z = {}): full {:.1}x, truncated {:.1}x, noise-free {:.1}x",
        b.julian_points_per_cell,
        b.julian_us / b.full_us,
        b.julian_us / b.truncated_us,
        b.julian_us / b.noise_free_us
    );
}
