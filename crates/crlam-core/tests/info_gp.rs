//! GPVR / UGPVR invariants (planner-spec 9.3, 9.1 items 12–13, 5.2–5.3 magnitudes).

use std::f64::consts::PI;

use crlam_bench::info::{bench_us_per_pose_gpvr, bench_us_per_pose_ugpvr, synthetic_cave_lattice};
use crlam_core::grid::GridGeometry;
use crlam_core::info::gp::*;
use crlam_core::info::lattice::{BeamAngles, OccupancyLattice};
use crlam_core::info::posecov::*;
use crlam_core::info::{evaluate_batch, Candidate, InfoUnits, InformationFunction};
use crlam_core::rng::Rng;

fn cave_map() -> GpVarianceMap {
    GpVarianceMap::new(synthetic_cave_lattice().unwrap())
}

/// The planner's 111 × 111 lattice at prior 0.3 with 0.85 at the given nodes.
fn lattice_with(walls: &[[f64; 2]]) -> OccupancyLattice {
    let g = GridGeometry::new([-1.1, -1.1], 0.2).unwrap();
    let mut l = OccupancyLattice::new(g, 111, 111, vec![0.3; 111 * 111]).unwrap();
    for w in walls {
        let id = l.nearest(w[0], w[1]);
        l.set(id, 0.85);
    }
    l
}

const CAVE_POSES: [[f64; 3]; 5] = [
    [7.5, 2.5, 0.0],
    [12.0, 8.0, 0.4],
    [3.0, 16.0, 1.0],
    [17.2, 12.9, 2.0],
    [8.1, 18.4, -1.0],
];

/// Dense Gauss–Jordan solve of A X = B (A n×n, B n×m, row-major), partial pivoting.
fn solve(mut a: Vec<f64>, mut b: Vec<f64>, n: usize, m: usize) -> Vec<f64> {
    for c in 0..n {
        let p = (c..n)
            .max_by(|&i, &j| a[i * n + c].abs().total_cmp(&a[j * n + c].abs()))
            .unwrap();
        for k in 0..n {
            a.swap(c * n + k, p * n + k);
        }
        for k in 0..m {
            b.swap(c * m + k, p * m + k);
        }
        for r in 0..n {
            if r != c {
                let f = a[r * n + c] / a[c * n + c];
                for k in 0..n {
                    a[r * n + k] -= f * a[c * n + k];
                }
                for k in 0..m {
                    b[r * m + k] -= f * b[c * m + k];
                }
            }
        }
    }
    for r in 0..n {
        for k in 0..m {
            b[r * m + k] /= a[r * n + r];
        }
    }
    b
}

/// s²(t_j) = k(t,t) − K*ᵀ(c·K + σ_n² I)⁻¹K* by a dense solve, with K* = `cross(x_i, t_j)`.
fn brute_variances(
    h: &GpHyper,
    train: &[[f64; 2]],
    test: &[[f64; 2]],
    scale: f64,
    cross: impl Fn([f64; 2], [f64; 2]) -> f64,
) -> Vec<f64> {
    let (n, m) = (train.len(), test.len());
    let dist = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).hypot(a[1] - b[1]);
    let mut a = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..n {
            a[i * n + j] = scale * h.kernel(dist(train[i], train[j]));
        }
        a[i * n + i] += h.sigma_n * h.sigma_n;
    }
    let mut ks = vec![0.0; n * m];
    for i in 0..n {
        for j in 0..m {
            ks[i * m + j] = cross(train[i], test[j]);
        }
    }
    let x = solve(a, ks.clone(), n, m);
    let sf2 = h.sigma_f * h.sigma_f;
    (0..m)
        .map(|j| sf2 - (0..n).map(|i| ks[i * m + j] * x[i * m + j]).sum::<f64>())
        .collect()
}

fn random_points(rng: &mut Rng, n: usize, size: f64) -> Vec<[f64; 2]> {
    (0..n)
        .map(|_| [size * rng.uniform(), size * rng.uniform()])
        .collect()
}

// ---- kernel, Cholesky, posterior ----------------------------------------------------------

#[test]
fn reference_hyperparameters_and_matern_values() {
    let h = GpHyper::reference();
    h.validate().unwrap();
    let sf2 = h.sigma_f * h.sigma_f;
    assert!((h.length_scale - 3.2623).abs() < 5e-5);
    assert!((sf2 - 0.18790).abs() < 5e-6 && (h.sigma_f - 0.43347).abs() < 5e-6);
    assert!((h.sigma_n - 5.0245e-3).abs() < 5e-8);
    assert_eq!(h.kernel(0.0), sf2);
    assert!((h.kernel(h.length_scale) / sf2 - 0.5240).abs() < 5e-5);
    assert!((h.kernel(1.0) / sf2 - 0.92815).abs() < 5e-6);
    let h32 = GpHyper {
        matern: Matern::Nu32,
        ..h
    };
    let want = (1.0 + 3f64.sqrt()) * (-(3f64.sqrt())).exp();
    assert!((h32.kernel(h.length_scale) / sf2 - want).abs() < 1e-14);
    assert!(GpHyper { sigma_n: 0.0, ..h }.validate().is_err());
    assert!(GpHyper {
        length_scale: f64::NAN,
        ..h
    }
    .validate()
    .is_err());
    assert_eq!(Matern::parse("3/2").unwrap(), Matern::Nu32);
}

#[test]
fn kernel_matrix_is_psd() {
    let h = GpHyper::reference();
    let mut rng = Rng::new(1);
    for _ in 0..20 {
        let p = random_points(&mut rng, 30, 10.0);
        let k = |i: usize, j: usize| h.kernel((p[i][0] - p[j][0]).hypot(p[i][1] - p[j][1]));
        for _ in 0..20 {
            let v: Vec<f64> = (0..30).map(|_| rng.normal()).collect();
            let q: f64 = (0..30)
                .flat_map(|i| (0..30).map(move |j| (i, j)))
                .map(|(i, j)| v[i] * k(i, j) * v[j])
                .sum();
            assert!(q > -1e-12, "{q}");
        }
    }
}

#[test]
fn cholesky_reconstructs_and_refuses_indefinite_matrices() {
    let mut rng = Rng::new(2);
    let n = 17;
    let b: Vec<f64> = (0..n * n).map(|_| rng.normal()).collect();
    let mut a = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..n {
            a[i * n + j] = (0..n).map(|k| b[i * n + k] * b[j * n + k]).sum::<f64>();
        }
        a[i * n + i] += 0.1;
    }
    let mut l = a.clone();
    cholesky_lower(&mut l, n).unwrap();
    for i in 0..n {
        for j in 0..=i {
            let s: f64 = (0..=j).map(|k| l[i * n + k] * l[j * n + k]).sum();
            assert!((s - a[i * n + j]).abs() < 1e-10 * (1.0 + a[i * n + j].abs()));
        }
    }
    assert!(cholesky_lower(&mut [1.0, 2.0, 2.0, 1.0], 2).is_err());
    assert!(cholesky_lower(&mut [1.0, 0.0, 0.0, f64::NAN], 2).is_err());
    assert!(cholesky_lower(&mut [1.0, 0.0, 0.0], 2).is_err());
}

#[test]
fn posterior_variance_matches_a_dense_solve_bounds_and_monotone() {
    let h = GpHyper::reference();
    let sf2 = h.sigma_f * h.sigma_f;
    let mut rng = Rng::new(3);
    for trial in 0..30 {
        let mut train = random_points(&mut rng, 5 + trial, 6.0);
        // Exact duplicates are allowed (two test points on one node).
        train.push(train[0]);
        let test = random_points(&mut rng, 12, 6.0);
        let s2 = posterior_variances(&h, &train, &test, None).unwrap();
        let brute = brute_variances(&h, &train, &test, 1.0, |a, b| {
            h.kernel((a[0] - b[0]).hypot(a[1] - b[1]))
        });
        for (s, b) in s2.iter().zip(&brute) {
            assert!(*s > 0.0 && *s <= sf2, "{s}");
            assert!((s - b).abs() < 1e-9 * sf2, "{s} {b}");
        }
        let mut more = train.clone();
        more.push([6.0 * rng.uniform(), 6.0 * rng.uniform()]);
        let s2_more = posterior_variances(&h, &more, &test, None).unwrap();
        for (a, b) in s2_more.iter().zip(&s2) {
            assert!(*a <= *b + 1e-12, "{a} > {b}");
        }
    }
}

#[test]
fn bcm_identities() {
    let mut rng = Rng::new(4);
    for _ in 0..1000 {
        let a = (-10.0 * rng.uniform()).exp();
        let b = (-10.0 * rng.uniform()).exp();
        let f = bcm_fuse(a, b);
        assert!(f <= a.min(b));
        assert!(((1.0 / f) - (1.0 / a + 1.0 / b)).abs() <= 1e-12 * (1.0 / f));
        assert!((a / f).ln() >= 0.0);
    }
    assert_eq!(bcm_fuse(0.0, 0.3), 0.3);
    assert_eq!(bcm_fuse(0.3, 0.0), 0.3);
}

// ---- Gauss–Hermite and the expected kernel ------------------------------------------------

#[test]
fn gauss_hermite_rule() {
    let (x, w) = gauss_hermite(GH_ORDER).unwrap();
    assert_eq!(x.len(), 11);
    assert!((w.iter().sum::<f64>() - PI.sqrt()).abs() < 1e-13);
    assert!((x[10] - 3.6685).abs() < 5e-5 && (x[10] + x[0]).abs() < 1e-13);
    let wmax = w.iter().cloned().fold(0.0, f64::max);
    assert!((wmax - 6.548e-1).abs() < 5e-5);
    let pairs = w
        .iter()
        .flat_map(|a| w.iter().map(move |b| a * b))
        .filter(|&p| p > GH_PAIR_THRESHOLD)
        .count();
    assert_eq!(pairs, 109);
    // Exact for polynomials up to degree 21: ∫ x^{2k} e^{−x²} dx = Γ(k + ½).
    let mut gamma = PI.sqrt();
    for k in 0..=10 {
        let q: f64 = x.iter().zip(&w).map(|(x, w)| w * x.powi(2 * k)).sum();
        assert!((q - gamma).abs() < 1e-12 * gamma, "k = {k}");
        let odd: f64 = x.iter().zip(&w).map(|(x, w)| w * x.powi(2 * k + 1)).sum();
        assert!(odd.abs() < 1e-12 * gamma);
        gamma *= k as f64 + 0.5;
    }
    let (x1, w1) = gauss_hermite(1).unwrap();
    assert!(x1[0].abs() < 1e-15 && (w1[0] - PI.sqrt()).abs() < 1e-15);
    assert_eq!(gauss_hermite(40).unwrap().0.len(), 40);
    assert!(gauss_hermite(0).is_err() && gauss_hermite(101).is_err());
}

#[test]
fn expected_kernel_limits_and_bounds() {
    let h = GpHyper::reference();
    let sf2 = h.sigma_f * h.sigma_f;
    let mut rng = Rng::new(5);
    for _ in 0..200 {
        let x = [20.0 * rng.uniform(), 20.0 * rng.uniform()];
        let z = [x[0] + 4.0 * rng.normal(), x[1] + 4.0 * rng.normal()];
        let plain = h.kernel((x[0] - z[0]).hypot(x[1] - z[1]));
        // k̃ → k as Σ → 0 (the quadrature keeps 1 − 1e-9 of the weight).
        let tiny = ExpectedKernel::new(UgpvrKernel::Expected, [[1e-10, 0.0], [0.0, 1e-10]])
            .unwrap()
            .unwrap();
        assert!((tiny.eval(&h, x, z) - plain).abs() < 1e-8 * sf2);
        let (a, c) = (rng.uniform(), rng.uniform());
        let b = 0.9 * (a * c).sqrt() * (2.0 * rng.uniform() - 1.0);
        let e = ExpectedKernel::new(UgpvrKernel::Expected, [[a, b], [b, c]])
            .unwrap()
            .unwrap();
        assert!(e.eval(&h, x, x) <= sf2);
        assert!(e.eval(&h, x, x) < h.kernel(0.0) * (1.0 - 0.1 * (a + c) / 20.0));
    }
    // A PSD singular Σ uses its semi-definite factor; Σ = 0 is the plain kernel.
    assert!(
        ExpectedKernel::new(UgpvrKernel::Expected, [[0.1, 0.0], [0.0, 0.0]])
            .unwrap()
            .is_some()
    );
    assert!(ExpectedKernel::new(UgpvrKernel::Expected, [[0.0; 2]; 2])
        .unwrap()
        .is_none());
    assert!(ExpectedKernel::new(UgpvrKernel::Expected, [[-0.1, 0.0], [0.0, 0.1]]).is_err());
    assert!(ExpectedKernel::new(UgpvrKernel::Expected, [[0.1, 0.01], [0.0, 0.1]]).is_err());
    assert!(ExpectedKernel::new(UgpvrKernel::Expected, [[f64::NAN, 0.0], [0.0, 0.1]]).is_err());
}

#[test]
fn expected_kernel_matches_monte_carlo() {
    let h = GpHyper::reference();
    let sigma = [[0.5, 0.2], [0.2, 0.3]];
    let e = ExpectedKernel::new(UgpvrKernel::Expected, sigma)
        .unwrap()
        .unwrap();
    let (l11, l21) = (sigma[0][0].sqrt(), sigma[1][0] / sigma[0][0].sqrt());
    let l22 = (sigma[1][1] - l21 * l21).sqrt();
    let mut rng = Rng::new(6);
    for (x, z) in [([0.0, 0.0], [0.0, 0.0]), ([1.0, 2.0], [2.5, 0.5])] {
        let n = 400_000;
        let mc: f64 = (0..n)
            .map(|_| {
                let (g1, g2) = (rng.normal(), rng.normal());
                let u = [x[0] + l11 * g1, x[1] + l21 * g1 + l22 * g2];
                h.kernel((u[0] - z[0]).hypot(u[1] - z[1]))
            })
            .sum::<f64>()
            / n as f64;
        assert!((e.eval(&h, x, z) - mc).abs() < 5e-4 * h.kernel(0.0), "{mc}");
    }
}

#[test]
fn reference_kernel_is_half_the_expected_kernel_of_half_sigma() {
    let h = GpHyper::reference();
    let (a, c) = (0.16, 0.01);
    let r = ExpectedKernel::new(UgpvrKernel::ReferenceHalf, [[a, 0.0], [0.0, c]])
        .unwrap()
        .unwrap();
    assert_eq!(r.n_pairs(), 109);
    assert!((r.weight_sum() - 0.5).abs() < 1e-9);
    // K_train (uncertain, common shift) = ½ K_train (plain).
    assert!((r.train_scale() - 0.5).abs() < 1e-9 && r.train_scale() < 0.5);
    let half = ExpectedKernel::new(UgpvrKernel::Expected, [[a / 2.0, 0.0], [0.0, c / 2.0]])
        .unwrap()
        .unwrap();
    assert_eq!(half.train_scale(), 1.0);
    for (x, z) in [([1.0, 2.0], [1.1, 2.0]), ([0.0, 0.0], [3.0, -1.0])] {
        let (ref_val, clean) = (r.eval(&h, x, z), half.eval(&h, x, z));
        assert!((ref_val - 0.5 * clean).abs() < 1e-14, "{ref_val} {clean}");
    }
    // A singular Σ has no Cholesky factor: the reference falls back to the plain kernel.
    for s in [
        [[0.0; 2]; 2],
        [[0.1, 0.0], [0.0, 0.0]],
        [[1.0, 1.0], [1.0, 1.0]],
    ] {
        assert!(ExpectedKernel::new(UgpvrKernel::ReferenceHalf, s)
            .unwrap()
            .is_none());
    }
}

// ---- the information functions ------------------------------------------------------------

#[test]
fn options_presets_and_names() {
    let r = GpvrOptions::preset(Mode::Reference);
    assert_eq!(r, GpvrOptions::default());
    assert_eq!(r.beam_angles, BeamAngles::Reference);
    assert_eq!(
        (r.free_points, r.fusion),
        (FreePoints::WorldOrigin, Fusion::HitsOnly)
    );
    let c = GpvrOptions::preset(Mode::Clean);
    assert_eq!(
        (c.free_points, c.fusion),
        (FreePoints::Robot, Fusion::AllPoints)
    );
    assert_eq!(c.beam_angles, BeamAngles::Distinct);
    let u = Ugpvr::clean();
    assert_eq!(u.options().kernel, UgpvrKernel::Expected);
    assert_eq!(u.options().jacobian, PoseJacobian::Unicycle);
    assert_eq!(
        Ugpvr::reference().options().kernel,
        UgpvrKernel::ReferenceHalf
    );
    for name in ["reference", "clean"] {
        assert_eq!(Mode::parse(name).unwrap().name(), name);
    }
    assert_eq!(
        FreePoints::parse("reference").unwrap(),
        FreePoints::WorldOrigin
    );
    assert_eq!(Fusion::parse("clean").unwrap().name(), "all_points");
    assert_eq!(
        UgpvrKernel::parse("reference").unwrap().name(),
        "reference_half"
    );
    assert!(Fusion::parse("some").is_err());
    assert!(Gpvr::new(GpvrOptions { n_beams: 0, ..r }).is_err());
    assert!(Gpvr::new(GpvrOptions {
        z_max: f64::NAN,
        ..r
    })
    .is_err());
    assert!(Gpvr::new(GpvrOptions { p_occ: 1.5, ..r }).is_err());
    let g = Gpvr::reference();
    assert_eq!((g.name(), g.units()), ("gpvr", InfoUnits::Nats));
    assert_eq!(Ugpvr::reference().name(), "ugpvr");
}

#[test]
fn reference_free_points_follow_the_world_origin_quirk() {
    let map = cave_map();
    let g = Gpvr::reference();
    let s = g.scan_points(&map, [7.5, 2.5, 0.0]).unwrap();
    let m = s.n_hits;
    assert!(m >= 5);
    let hits = &s.test[..m];
    let n_of = |h: &[f64; 2]| ((6.25 * h[0].hypot(h[1])).ceil() as usize).min(15);
    let n_last = n_of(&hits[m - 1]);
    assert_eq!(s.test.len(), m + m * (n_last - 1));
    for (j, h) in hits.iter().enumerate() {
        let first = s.test[m + j];
        let n = n_of(h) as f64;
        assert!((first[0] - h[0] / n).abs() < 1e-12 && (first[1] - h[1] / n).abs() < 1e-12);
        for b in 1..n_last - 1 {
            let p = s.test[m + b * m + j];
            let f = (b + 1) as f64 / n_last as f64;
            assert!((p[0] - h[0] * f).abs() < 1e-12 && (p[1] - h[1] * f).abs() < 1e-12);
        }
    }
    for (p, &id) in s.test.iter().zip(&s.ids) {
        assert_eq!(id, map.lattice().nearest(p[0], p[1]));
    }
}

#[test]
fn clean_free_points_lie_between_robot_and_hit() {
    let map = cave_map();
    let pose = [12.0, 8.0, 0.4];
    let s = Gpvr::clean().scan_points(&map, pose).unwrap();
    let mut next = s.n_hits;
    for h in &s.test[..s.n_hits] {
        let (dx, dy) = (h[0] - pose[0], h[1] - pose[1]);
        let n = ((6.25 * dx.hypot(dy)).ceil() as usize).min(15);
        for k in 1..n {
            let p = s.test[next];
            let f = k as f64 / n as f64;
            assert!((p[0] - pose[0] - f * dx).abs() < 1e-12);
            assert!((p[1] - pose[1] - f * dy).abs() < 1e-12);
            next += 1;
        }
    }
    assert_eq!(next, s.test.len());
}

#[test]
fn no_hit_gives_zero_and_free_ids_are_untouched_in_hits_only_mode() {
    let empty = GpVarianceMap::new(lattice_with(&[]));
    let c = Candidate::at([10.0, 10.0, 0.0]);
    let e = Gpvr::reference().evaluate(&empty, &(), &c, 0).unwrap();
    assert_eq!(e.gain, 0.0);
    assert!(e.update.is_empty());
    let u = Ugpvr::reference()
        .evaluate(&empty, &root_covariance(), &c, 0)
        .unwrap();
    assert_eq!((u.gain, u.update.len()), (0.0, 0));

    let mut map = cave_map();
    let g = Gpvr::reference();
    let pose = [12.0, 8.0, 0.4];
    let s = g.scan_points(&map, pose).unwrap();
    let e = g.evaluate(&map, &(), &Candidate::at(pose), 0).unwrap();
    g.commit(&mut map, &e.update).unwrap();
    let hit_ids = &s.ids[..s.n_hits];
    for &id in &s.ids[s.n_hits..] {
        if !hit_ids.contains(&id) {
            assert_eq!(map.variances()[id], 1.0);
        }
    }
    for &id in hit_ids {
        assert!(map.variances()[id] < 1e-3);
    }
    let changed = map.variances().iter().filter(|&&v| v != 1.0).count();
    assert_eq!(changed, e.update.len());
}

#[test]
fn first_observation_magnitudes_on_the_cave_lattice() {
    let map = cave_map();
    for pose in CAVE_POSES {
        let c = Candidate::at(pose);
        let s = Gpvr::reference().scan_points(&map, pose).unwrap();
        // Each distinct hit node counts once per occurrence among all the scan's ids.
        let mut hit_ids = s.ids[..s.n_hits].to_vec();
        hit_ids.sort();
        hit_ids.dedup();
        let hit_uses: usize = hit_ids
            .iter()
            .map(|id| s.ids.iter().filter(|&x| x == id).count())
            .sum();
        let gpvr = Gpvr::reference().evaluate(&map, &(), &c, 0).unwrap().gain;
        let per_hit = gpvr / hit_uses as f64;
        assert!(
            (8.5..11.5).contains(&per_hit),
            "GPVR {per_hit} nats per hit"
        );
        // REF UGPVR: s² ≈ σ_f²/2 at a hit, so ≈ ln(1/0.094) = 2.4 nats per hit.
        let root = root_covariance();
        let ugpvr = Ugpvr::reference()
            .evaluate(&map, &root, &c, 0)
            .unwrap()
            .gain;
        let per_hit = ugpvr / hit_uses as f64;
        assert!(
            (2.3..2.8).contains(&per_hit),
            "UGPVR {per_hit} nats per hit"
        );
    }
}

#[test]
fn clean_expected_kernel_magnitude_at_the_root() {
    // Hits only with the clean kernel and Σ₀: s² ≈ 0.005, ≈ 5.3 nats per hit.
    let opts = UgpvrOptions {
        gp: GpvrOptions {
            fusion: Fusion::HitsOnly,
            ..GpvrOptions::preset(Mode::Clean)
        },
        ..UgpvrOptions::preset(Mode::Clean)
    };
    let u = Ugpvr::new(opts).unwrap();
    let map = cave_map();
    for pose in CAVE_POSES {
        let s = Gpvr::new(opts.gp).unwrap().scan_points(&map, pose).unwrap();
        let gain = u
            .evaluate(&map, &root_covariance(), &Candidate::at(pose), 0)
            .unwrap()
            .gain;
        let per_hit = gain / s.n_hits as f64;
        assert!((4.8..5.9).contains(&per_hit), "{per_hit}");
    }
}

#[test]
fn repeated_observations_give_the_diminishing_returns_formula() {
    // One obstacle node 2 m ahead of a beam, the other beams miss: a single hit id.
    let map0 = GpVarianceMap::new(lattice_with(&[[10.0, 4.0]]));
    let opts = GpvrOptions {
        beam_angles: BeamAngles::Distinct,
        free_points: FreePoints::Robot,
        fusion: Fusion::HitsOnly,
        ..GpvrOptions::default()
    };
    let pose = [10.0, 2.0, PI / 2.0];
    for mode in [UgpvrKernel::ReferenceHalf, UgpvrKernel::Expected] {
        let u = Ugpvr::new(UgpvrOptions {
            gp: opts,
            kernel: mode,
            ..UgpvrOptions::default()
        })
        .unwrap();
        let sigma = root_covariance();
        let s = Gpvr::new(opts).unwrap().scan_points(&map0, pose).unwrap();
        assert_eq!(s.n_hits, 1);
        assert_eq!(s.ids.iter().filter(|&&id| id == s.ids[0]).count(), 1);
        let train: Vec<[f64; 2]> = s
            .ids
            .iter()
            .map(|&id| map0.lattice().node_position(id))
            .collect();
        let ek = ExpectedKernel::new(mode, xy_block(&sigma)).unwrap();
        let s2 = posterior_variances(&opts.hyper, &train, &s.test, ek.as_ref()).unwrap()[0];
        let mut map = map0.clone();
        let mut prev = f64::INFINITY;
        for k in 1..=5 {
            let e = u.evaluate(&map, &sigma, &Candidate::at(pose), 0).unwrap();
            let kf = k as f64;
            let want = ((1.0 + kf / s2) / (1.0 + (kf - 1.0) / s2)).ln();
            assert!(
                (e.gain - want).abs() < 1e-9 * want,
                "{k}: {} {want}",
                e.gain
            );
            assert!(e.gain < prev);
            prev = e.gain;
            u.commit(&mut map, &e.update).unwrap();
        }
    }
}

#[test]
fn second_evaluation_at_a_pose_gains_less() {
    for pose in CAVE_POSES {
        let c = Candidate::at(pose);
        for g in [Gpvr::reference(), Gpvr::clean()] {
            let mut map = cave_map();
            let e1 = g.evaluate(&map, &(), &c, 0).unwrap();
            g.commit(&mut map, &e1.update).unwrap();
            let e2 = g.evaluate(&map, &(), &c, 0).unwrap();
            assert!(
                e1.gain > 0.0 && e2.gain < e1.gain,
                "{} {}",
                e1.gain,
                e2.gain
            );
        }
        for u in [Ugpvr::reference(), Ugpvr::clean()] {
            let mut map = cave_map();
            let root = root_covariance();
            let e1 = u.evaluate(&map, &root, &c, 0).unwrap();
            u.commit(&mut map, &e1.update).unwrap();
            let e2 = u.evaluate(&map, &root, &c, 0).unwrap();
            assert!(
                e1.gain > 0.0 && e2.gain < e1.gain,
                "{} {}",
                e1.gain,
                e2.gain
            );
        }
    }
}

#[test]
fn gain_equals_the_committed_log_variance_drop_for_distinct_ids() {
    // Clean fuses every point: the gain is Σ over ids with multiplicity; the map's Σ ln Var
    // drops by the same sum over distinct ids.
    let g = Gpvr::clean();
    let mut map = cave_map();
    let pose = CAVE_POSES[1];
    let s = g.scan_points(&map, pose).unwrap();
    let e = g.evaluate(&map, &(), &Candidate::at(pose), 0).unwrap();
    let before = map.total_log_variance();
    g.commit(&mut map, &e.update).unwrap();
    let drop_weighted: f64 = e
        .update
        .iter()
        .map(|&(id, v)| s.ids.iter().filter(|&&x| x == id).count() as f64 * -v.ln())
        .sum();
    assert!((e.gain - drop_weighted).abs() < 1e-9 * e.gain);
    assert!(before - map.total_log_variance() <= e.gain + 1e-9);
}

#[test]
fn evaluate_is_pure_and_batches_match_the_serial_loop() {
    let map = cave_map();
    let before = map.clone();
    let cands: Vec<Candidate> = CAVE_POSES
        .iter()
        .map(|p| Candidate {
            pose: *p,
            parent: [p[0] - 1.0, p[1] + 0.5],
        })
        .collect();
    let g = Gpvr::clean();
    let u = Ugpvr::reference();
    let root = root_covariance();
    let batch_g = evaluate_batch(&g, &map, &(), &cands, 7).unwrap();
    let batch_u = evaluate_batch(&u, &map, &root, &cands, 7).unwrap();
    for (i, c) in cands.iter().enumerate() {
        let sg = g.evaluate(&map, &(), c, 0).unwrap();
        let su = u.evaluate(&map, &root, c, 0).unwrap();
        assert_eq!(sg.gain, batch_g[i].gain);
        assert_eq!(sg.update, batch_g[i].update);
        assert_eq!(su.gain, batch_u[i].gain);
        assert_eq!(su.belief, batch_u[i].belief);
    }
    assert_eq!(map, before);
}

#[test]
fn commit_validates_the_update_atomically() {
    let g = Gpvr::reference();
    let mut map = cave_map();
    let before = map.clone();
    let n = map.variances().len();
    assert!(g.commit(&mut map, &vec![(0, 0.5), (n, 0.5)]).is_err());
    assert!(g.commit(&mut map, &vec![(0, 0.5), (1, -1.0)]).is_err());
    assert!(g.commit(&mut map, &vec![(0, f64::NAN)]).is_err());
    assert_eq!(map, before);
    let lat = synthetic_cave_lattice().unwrap();
    assert!(GpVarianceMap::with_variances(lat.clone(), vec![1.0; 3]).is_err());
    assert!(GpVarianceMap::with_variances(lat.clone(), vec![0.0; n]).is_err());
    assert!(GpVarianceMap::with_variances(lat, vec![0.5; n]).is_ok());
}

// ---- UGPVR specifics ----------------------------------------------------------------------

#[test]
fn ugpvr_propagates_the_parent_covariance_along_the_edge() {
    let map = cave_map();
    let root = root_covariance();
    for u in [Ugpvr::reference(), Ugpvr::clean()] {
        let c = Candidate {
            pose: [9.0, 4.0, 0.0],
            parent: [7.5, 2.5],
        };
        let e = u.evaluate(&map, &root, &c, 0).unwrap();
        let o = u.options();
        let want = propagate_covariance(&root, c.parent, [9.0, 4.0], &o.noise, o.jacobian);
        assert_eq!(e.belief, want);
        assert_eq!(e.belief[0][0], 0.17);
        // No edge (the root, a surface): the parent's covariance as is.
        let at = u
            .evaluate(&map, &root, &Candidate::at([9.0, 4.0, 0.0]), 0)
            .unwrap();
        assert_eq!(at.belief, root);
    }
    let bad = [[1.0, 2.0, 0.0], [2.0, 1.0, 0.0], [0.0, 0.0, 0.0]];
    assert!(Ugpvr::clean()
        .evaluate(&map, &bad, &Candidate::at([9.0, 4.0, 0.0]), 0)
        .is_err());
}

#[test]
fn reference_ugpvr_with_singular_sigma_is_gpvr() {
    let map = cave_map();
    let zero = [[0.0; 3]; 3];
    for pose in CAVE_POSES {
        let c = Candidate::at(pose);
        let g = Gpvr::reference().evaluate(&map, &(), &c, 0).unwrap();
        let u = Ugpvr::reference().evaluate(&map, &zero, &c, 0).unwrap();
        assert_eq!(g.gain, u.gain);
        assert_eq!(g.update, u.update);
        // The clean kernel at Σ = 0 is the plain kernel too.
        let gc = Gpvr::clean().evaluate(&map, &(), &c, 0).unwrap();
        let uc = Ugpvr::clean().evaluate(&map, &zero, &c, 0).unwrap();
        assert_eq!(gc.gain, uc.gain);
    }
}

#[test]
fn uncertainty_sits_on_the_training_inputs() {
    // Pins the convention: K (training block) unchanged, K* = k̃(x_train, t_test) with the
    // uncertainty on the snapped training nodes, k(t, t) = σ_f² unsmoothed.
    let map = cave_map();
    let u = Ugpvr::clean();
    let h = u.options().gp.hyper;
    let sigma = [[0.3, 0.05, 0.0], [0.05, 0.2, 0.0], [0.0, 0.0, 1e-4]];
    for pose in [CAVE_POSES[0], CAVE_POSES[3]] {
        let s = Gpvr::clean().scan_points(&map, pose).unwrap();
        let train: Vec<[f64; 2]> = s
            .ids
            .iter()
            .map(|&id| map.lattice().node_position(id))
            .collect();
        let ek = ExpectedKernel::new(UgpvrKernel::Expected, xy_block(&sigma))
            .unwrap()
            .unwrap();
        let s2 = brute_variances(&h, &train, &s.test, 1.0, |x, t| ek.eval(&h, x, t));
        // Sequential BCM from the prior 1, gain over every id with multiplicity.
        let mut var: Vec<(usize, f64)> = Vec::new();
        for (&id, &v) in s.ids.iter().zip(&s2) {
            match var.iter_mut().find(|e| e.0 == id) {
                Some(e) => e.1 = bcm_fuse(e.1, v),
                None => var.push((id, bcm_fuse(1.0, v))),
            }
        }
        let want: f64 = s
            .ids
            .iter()
            .map(|id| -var.iter().find(|e| e.0 == *id).unwrap().1.ln())
            .sum();
        let got = u.evaluate(&map, &sigma, &Candidate::at(pose), 0).unwrap();
        assert!((got.gain - want).abs() < 1e-7 * want, "{} {want}", got.gain);
        // The convention matters: smoothing k(t, t) as well would lower it visibly.
        let t = s.test[0];
        assert!(ek.eval(&h, t, t) < 0.99 * h.kernel(0.0));
    }
}

#[test]
fn clean_ugpvr_gains_no_more_than_gpvr_and_decrease_with_uncertainty() {
    let map = cave_map();
    for pose in CAVE_POSES {
        let c = Candidate::at(pose);
        let gpvr = Gpvr::clean().evaluate(&map, &(), &c, 0).unwrap().gain;
        let mut prev = gpvr;
        for s in [0.01, 0.05, 0.1, 0.2, 0.4] {
            let sigma = [[s, 0.0, 0.0], [0.0, s, 0.0], [0.0, 0.0, 0.0]];
            let g = Ugpvr::clean().evaluate(&map, &sigma, &c, 0).unwrap().gain;
            assert!(g <= prev + 1e-9, "s = {s}: {g} > {prev}");
            prev = g;
        }
    }
}

#[test]
fn reference_ugpvr_hardly_depends_on_sigma() {
    let map = cave_map();
    let c = Candidate::at(CAVE_POSES[0]);
    let u = Ugpvr::reference();
    let g0 = u.evaluate(&map, &root_covariance(), &c, 0).unwrap().gain;
    let mut deep = root_covariance();
    for k in 0..10 {
        let x = 7.5 - 3.0 * k as f64;
        deep = propagate_covariance(
            &deep,
            [x + 3.0, 2.5],
            [x, 2.5],
            &EdgeNoise::default(),
            PoseJacobian::Reference,
        );
    }
    let g10 = u.evaluate(&map, &deep, &c, 0).unwrap().gain;
    assert!(g10 < g0 && g10 > 0.95 * g0, "{g0} {g10}");
}

/// Timing on the Cave-like lattice: `cargo test --release --test info_gp -- --ignored`.
#[test]
#[ignore]
fn bench_print() {
    for (name, b) in [
        (
            "gpvr reference",
            bench_us_per_pose_gpvr(&Gpvr::reference(), 160).unwrap(),
        ),
        (
            "gpvr clean",
            bench_us_per_pose_gpvr(&Gpvr::clean(), 160).unwrap(),
        ),
        (
            "ugpvr reference",
            bench_us_per_pose_ugpvr(&Ugpvr::reference(), 160).unwrap(),
        ),
        (
            "ugpvr clean",
            bench_us_per_pose_ugpvr(&Ugpvr::clean(), 32).unwrap(),
        ),
    ] {
        println!("{name}: {b:?}");
    }
}
