//! crm-spec section 7, items 25–29: weight entropy, the corrected Boers particle entropy (6.2),
//! the planner's edge motion model (6.4) and the UCRMI mix (6.3).

// Index loops over the d ≤ 3 coordinates read more clearly than zipped iterators.
#![allow(clippy::needless_range_loop)]

use std::f64::consts::{LN_2, PI};

use crlam_core::info::entropy::*;
use crlam_core::pose::wrap;
use crlam_core::rng::Rng;
use crlam_core::CrlamError;

const LN_2PI: f64 = 1.837_877_066_409_345_5;

fn log_normal_1d(x: f64, var: f64) -> f64 {
    -0.5 * (LN_2PI + var.ln() + x * x / var)
}

/// Lower Cholesky factor of a 3 × 3 SPD matrix (test-side, independent of the module).
fn chol3(a: [[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let mut l = [[0.0; 3]; 3];
    for r in 0..3 {
        for c in 0..=r {
            let s: f64 = (0..c).map(|k| l[r][k] * l[c][k]).sum();
            l[r][c] = if r == c {
                (a[r][r] - s).sqrt()
            } else {
                (a[r][c] - s) / l[c][c]
            };
        }
    }
    l
}

/// Determinant by cofactor expansion.
fn det3(a: [[f64; 3]; 3]) -> f64 {
    a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1])
        - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
        + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0])
}

fn add3(a: [[f64; 3]; 3], b: [[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let mut c = a;
    for r in 0..3 {
        for k in 0..3 {
            c[r][k] += b[r][k];
        }
    }
    c
}

fn diag3(d: [f64; 3]) -> [[f64; 3]; 3] {
    [[d[0], 0.0, 0.0], [0.0, d[1], 0.0], [0.0, 0.0, d[2]]]
}

// ---------------------------------------------------------------------------------------------
// Item 25: weight entropy.

#[test]
fn item25_weight_entropy_range_and_maximum_at_uniform() {
    for n in 1..=64usize {
        let h = weight_entropy(&vec![3.7; n]).unwrap();
        assert!((h - (n as f64).ln()).abs() < 1e-12, "n={n}: {h}");
    }
    assert_eq!(weight_entropy(&[0.0, 5.0, 0.0]).unwrap(), 0.0); // 0 ln 0 = 0
    let mut rng = Rng::new(25);
    for trial in 0..500 {
        let n = 1 + trial % 40;
        let w: Vec<f64> = (0..n)
            .map(|_| {
                if rng.uniform() < 0.2 {
                    0.0
                } else {
                    rng.uniform()
                }
            })
            .chain([1.0])
            .collect();
        let h = weight_entropy(&w).unwrap();
        let ln_n = (w.len() as f64).ln();
        assert!(
            (-1e-12..=ln_n + 1e-12).contains(&h),
            "{h} outside [0, {ln_n}]"
        );
        // Scale invariance (normalised first).
        let scaled: Vec<f64> = w.iter().map(|v| v * 1e300).collect();
        assert!((weight_entropy(&scaled).unwrap() - h).abs() < 1e-12);
        // Any non-uniform perturbation of the uniform weights lowers H_w.
        let pert: Vec<f64> = (0..w.len()).map(|_| 1.0 + 0.5 * rng.uniform()).collect();
        if w.len() > 1 {
            assert!(weight_entropy(&pert).unwrap() < ln_n);
        }
    }
    assert!(matches!(weight_entropy(&[]), Err(CrlamError::Shape(_))));
    assert!(matches!(
        weight_entropy(&[0.5, -0.1]),
        Err(CrlamError::Config { .. })
    ));
    assert!(matches!(
        weight_entropy(&[0.5, f64::NAN]),
        Err(CrlamError::NonFinite { .. })
    ));
    assert!(matches!(
        weight_entropy(&[0.5, f64::INFINITY]),
        Err(CrlamError::NonFinite { .. })
    ));
    assert!(matches!(
        weight_entropy(&[0.0, 0.0]),
        Err(CrlamError::Config { .. })
    ));
}

// ---------------------------------------------------------------------------------------------
// The estimator against the spec's formula written out literally, and its invariances.

#[test]
fn particle_entropy_equals_the_spec_formula() {
    let mut rng = Rng::new(62);
    for trial in 0..50 {
        let n = 1 + trial % 9;
        let lw: Vec<f64> = (0..n).map(|_| 2.0 * rng.normal()).collect();
        let ll: Vec<f64> = (0..n).map(|_| 3.0 * rng.normal()).collect();
        let t: Vec<f64> = (0..n * n).map(|_| 2.0 * rng.normal()).collect();
        // Literal 6.2 in linear space with normalised w_{k−1}.
        let wp: Vec<f64> = lw.iter().map(|v| v.exp()).collect();
        let sp: f64 = wp.iter().sum();
        let wp: Vec<f64> = wp.iter().map(|v| v / sp).collect();
        let evidence: f64 = (0..n).map(|j| wp[j] * ll[j].exp()).sum();
        let wk: Vec<f64> = (0..n).map(|j| wp[j] * ll[j].exp() / evidence).collect();
        let mut expect = evidence.ln();
        for j in 0..n {
            let inner: f64 = (0..n).map(|i| wp[i] * t[j * n + i].exp()).sum();
            expect -= wk[j] * (ll[j] + inner.ln());
        }
        let got = particle_entropy_matrix(&lw, &ll, &t).unwrap();
        assert!(
            (got - expect).abs() < 1e-10 * (1.0 + expect.abs()),
            "{got} vs {expect}"
        );
        let by_closure = particle_entropy(&lw, &ll, |j, i| t[j * n + i]).unwrap();
        assert_eq!(got.to_bits(), by_closure.to_bits());
        // Shifts of all log-weights or all log-likelihoods do not change H (even huge ones).
        let lw2: Vec<f64> = lw.iter().map(|v| v - 700.0).collect();
        let ll2: Vec<f64> = ll.iter().map(|v| v - 5000.0).collect();
        let shifted = particle_entropy_matrix(&lw2, &ll2, &t).unwrap();
        assert!((shifted - got).abs() < 1e-9 * (1.0 + got.abs()));
    }
}

#[test]
fn particle_entropy_zero_weights_and_errors() {
    let t = |j: usize, i: usize| -((j as f64 - i as f64).powi(2));
    let ninf = f64::NEG_INFINITY;
    // A previous particle of zero weight (and its child) drops out entirely.
    let a = particle_entropy(&[0.0, ninf, 0.5], &[-1.0, 3.0, -2.0], |j, i| {
        assert!(i != 1, "zero-weight previous particles are skipped");
        t(j, i)
    })
    .unwrap();
    let keep = [0usize, 2];
    let b = particle_entropy(&[0.0, 0.5], &[-1.0, -2.0], |j, i| t(keep[j], keep[i])).unwrap();
    assert!((a - b).abs() < 1e-12);
    // A zero likelihood removes the child but keeps the parent as a mixture component.
    assert!(particle_entropy(&[0.0, 0.0], &[ninf, 0.0], t)
        .unwrap()
        .is_finite());

    assert!(matches!(
        particle_entropy(&[], &[], t),
        Err(CrlamError::Shape(_))
    ));
    assert!(matches!(
        particle_entropy(&[0.0], &[0.0, 1.0], t),
        Err(CrlamError::Shape(_))
    ));
    assert!(matches!(
        particle_entropy(&[f64::NAN], &[0.0], t),
        Err(CrlamError::NonFinite { .. })
    ));
    assert!(matches!(
        particle_entropy(&[0.0], &[f64::INFINITY], t),
        Err(CrlamError::NonFinite { .. })
    ));
    assert!(matches!(
        particle_entropy(&[0.0, ninf], &[ninf, 0.0], t),
        Err(CrlamError::Config { .. })
    ));
    assert!(matches!(
        particle_entropy(&[0.0], &[0.0], |_, _| f64::NAN),
        Err(CrlamError::NonFinite { .. })
    ));
    assert!(matches!(
        particle_entropy(&[0.0], &[0.0], |_, _| ninf),
        Err(CrlamError::Config { .. })
    ));
    assert!(matches!(
        particle_entropy_matrix(&[0.0, 0.0], &[0.0, 0.0], &[0.0; 3]),
        Err(CrlamError::Shape(_))
    ));
}

// ---------------------------------------------------------------------------------------------
// Item 26: linear-Gaussian check against the Kalman posterior entropy.

/// One linear-Gaussian step in d ≤ 3 dimensions with prior N(0, P), random walk N(0, diag q),
/// measurement z = x + v, v ~ N(0, diag r). Returns (estimate − Kalman) in nats.
fn kalman_bias(p: [[f64; 3]; 3], q: [f64; 3], r: [f64; 3], d: usize, n: usize, seed: u64) -> f64 {
    let mut rng = Rng::new(seed);
    let lp = chol3(p);
    let draw = |rng: &mut Rng, l: &[[f64; 3]; 3]| {
        let e = [rng.normal(), rng.normal(), rng.normal()];
        let mut x = [0.0; 3];
        for a in 0..d {
            x[a] = (0..=a).map(|b| l[a][b] * e[b]).sum();
        }
        x
    };
    let prev: Vec<[f64; 3]> = (0..n).map(|_| draw(&mut rng, &lp)).collect();
    let lq = diag3(q.map(f64::sqrt));
    let cur: Vec<[f64; 3]> = prev
        .iter()
        .map(|x| {
            let e = draw(&mut rng, &lq);
            [x[0] + e[0], x[1] + e[1], x[2] + e[2]]
        })
        .collect();
    // A truth from the predictive distribution and its measurement.
    let truth = draw(&mut rng, &chol3(add3(p, diag3(q))));
    let lr = diag3(r.map(f64::sqrt));
    let v = draw(&mut rng, &lr);
    let z: Vec<f64> = (0..d).map(|a| truth[a] + v[a]).collect();
    let ll: Vec<f64> = cur
        .iter()
        .map(|x| (0..d).map(|a| log_normal_1d(x[a] - z[a], r[a])).sum())
        .collect();
    let lw = vec![0.0; n];
    let h = particle_entropy(&lw, &ll, |j, i| {
        (0..d)
            .map(|a| log_normal_1d(cur[j][a] - prev[i][a], q[a]))
            .sum()
    })
    .unwrap();
    // Kalman: |P_post| = |P_pred| |R| / |P_pred + R| (P_post⁻¹ = P_pred⁻¹ + R⁻¹).
    let pad = |m: [[f64; 3]; 3]| {
        let mut m = m;
        for a in d..3 {
            m[a] = [0.0; 3];
            m[a][a] = 1.0;
        }
        m
    };
    let ppred = add3(p, diag3(q));
    let det_post = det3(pad(ppred)) * det3(pad(diag3(r))) / det3(pad(add3(ppred, diag3(r))));
    let h_kalman = 0.5 * (d as f64 * (LN_2PI + 1.0) + det_post.ln());
    h - h_kalman
}

#[test]
fn item26_linear_gaussian_1d() {
    let p = diag3([1.0, 0.0, 0.0]);
    let biases: Vec<f64> = (0..5)
        .map(|s| kalman_bias(p, [0.1, 0.0, 0.0], [0.2, 0.0, 0.0], 1, 2000, 100 + s))
        .collect();
    let mean = biases.iter().sum::<f64>() / 5.0;
    println!("1-D bias per seed {biases:?}, mean {mean:.4} nats");
    assert!(mean.abs() < 0.05, "1-D bias {mean}");
}

#[test]
fn item26_linear_gaussian_3d() {
    let p = [[1.0, 0.3, 0.0], [0.3, 0.5, 0.1], [0.0, 0.1, 0.2]];
    let biases: Vec<f64> = (0..5)
        .map(|s| kalman_bias(p, [0.1, 0.05, 0.02], [0.3, 0.2, 0.1], 3, 2000, 200 + s))
        .collect();
    let mean = biases.iter().sum::<f64>() / 5.0;
    println!("3-D bias per seed {biases:?}, mean {mean:.4} nats");
    assert!(mean.abs() < 0.2, "3-D bias {mean}");
}

// ---------------------------------------------------------------------------------------------
// Item 27: peaked vs flat likelihood; flat = entropy of the predicted mixture.

/// A 1-D predicted mixture: `m` components N(c_i, q) with weights v_i, each duplicated `reps`
/// times in the previous set (weight v_i / reps), one child drawn per duplicate.
struct Mixture {
    centres: Vec<f64>,
    weights: Vec<f64>,
    q: f64,
    prev: Vec<f64>,
    prev_log_w: Vec<f64>,
    children: Vec<f64>,
}

fn mixture(m: usize, reps: usize, q: f64, seed: u64) -> Mixture {
    let mut rng = Rng::new(seed);
    let centres: Vec<f64> = (0..m).map(|_| 2.0 * rng.normal()).collect();
    let raw: Vec<f64> = (0..m).map(|_| 0.2 + rng.uniform()).collect();
    let s: f64 = raw.iter().sum();
    let weights: Vec<f64> = raw.iter().map(|v| v / s).collect();
    let mut prev = Vec::new();
    let mut prev_log_w = Vec::new();
    let mut children = Vec::new();
    for (c, v) in centres.iter().zip(&weights) {
        for _ in 0..reps {
            prev.push(*c);
            prev_log_w.push((v / reps as f64).ln());
            children.push(c + q.sqrt() * rng.normal());
        }
    }
    Mixture {
        centres,
        weights,
        q,
        prev,
        prev_log_w,
        children,
    }
}

impl Mixture {
    fn density(&self, x: f64) -> f64 {
        self.centres
            .iter()
            .zip(&self.weights)
            .map(|(c, v)| v * log_normal_1d(x - c, self.q).exp())
            .sum()
    }

    fn entropy(&self, log_lik: &[f64]) -> f64 {
        particle_entropy(&self.prev_log_w, log_lik, |j, i| {
            log_normal_1d(self.children[j] - self.prev[i], self.q)
        })
        .unwrap()
    }
}

#[test]
fn item27_flat_likelihood_gives_the_predicted_mixture_entropy() {
    let mx = mixture(50, 40, 0.09, 27);
    let n = mx.children.len();
    let flat = mx.entropy(&vec![-3.0; n]);

    // Identity: with ℓ constant, H = −Σ_j w_{k−1}^j ln q(x^j), q the mixture density
    // (duplicated components collapse to the 50 distinct ones). Brute force in linear space.
    let w: Vec<f64> = mx.prev_log_w.iter().map(|v| v.exp()).collect();
    let f: Vec<f64> = mx.children.iter().map(|&x| -mx.density(x).ln()).collect();
    let identity: f64 = w.iter().zip(&f).map(|(a, b)| a * b).sum();
    assert!((flat - identity).abs() < 1e-10, "{flat} vs {identity}");

    // Independent value: −∫ q ln q by the midpoint rule on [min − 10σ, max + 10σ], step σ/100
    // (quadrature error far below 1e-6). The estimate is a Monte Carlo average over 2000
    // children, so it must be within 4 standard errors of it.
    let sd = mx.q.sqrt();
    let lo = mx.centres.iter().copied().fold(f64::INFINITY, f64::min) - 10.0 * sd;
    let hi = mx.centres.iter().copied().fold(f64::NEG_INFINITY, f64::max) + 10.0 * sd;
    let dx = sd / 100.0;
    let steps = ((hi - lo) / dx).ceil() as usize;
    let exact: f64 = (0..steps)
        .map(|k| {
            let q = mx.density(lo + (k as f64 + 0.5) * dx);
            if q > 0.0 {
                -q * q.ln() * dx
            } else {
                0.0
            }
        })
        .sum();
    let var: f64 = w
        .iter()
        .zip(&f)
        .map(|(a, b)| a * a * (b - identity).powi(2))
        .sum();
    let se = var.sqrt();
    println!("flat-likelihood H {flat:.4}, quadrature {exact:.4}, standard error {se:.4}");
    assert!(
        (flat - exact).abs() < 4.0 * se,
        "{flat} vs {exact} (se {se})"
    );
}

#[test]
fn item27_peaked_likelihood_lowers_the_entropy() {
    let mx = mixture(50, 40, 0.09, 270);
    let lik = |r: f64| -> Vec<f64> {
        mx.children
            .iter()
            .map(|&x| log_normal_1d(x - 0.5, r))
            .collect()
    };
    let flat = mx.entropy(&vec![0.0; mx.children.len()]);
    let hs: Vec<f64> = [100.0, 1.0, 0.1, 0.01]
        .iter()
        .map(|&r| mx.entropy(&lik(r)))
        .collect();
    println!("flat {flat:.3}, R = 100, 1, 0.1, 0.01: {hs:?}");
    assert!(hs[0] < flat + 0.01);
    assert!(hs.windows(2).all(|p| p[1] < p[0]), "{hs:?}");
    assert!(hs[3] < flat - 1.0);
}

// ---------------------------------------------------------------------------------------------
// Item 28: the UCRMI mix; I_p in bits.

#[test]
fn item28_ucrmi_endpoints_and_units() {
    let mut rng = Rng::new(28);
    for _ in 0..200 {
        let (im, ip) = (5.0 * rng.normal(), 5.0 * rng.normal());
        assert_eq!(ucrmi_mix(im, ip, 1.0).unwrap(), im);
        assert_eq!(ucrmi_mix(im, ip, 0.0).unwrap(), ip);
        let half = ucrmi_mix(im, ip, UCRMI_ALPHA).unwrap();
        assert!((half - 0.5 * (im + ip)).abs() < 1e-12);
    }
    assert!(ucrmi_mix(1.0, 1.0, 1.5).is_err() && ucrmi_mix(1.0, 1.0, -0.1).is_err());
    assert!(ucrmi_mix(1.0, 1.0, f64::NAN).is_err());
    assert!(ucrmi_mix(f64::NAN, 1.0, 0.5).is_err() && ucrmi_mix(1.0, f64::INFINITY, 0.5).is_err());
    // One nat is 1/ln 2 bits; I_p is signed (not clipped).
    assert!((pose_information_gain(1.0, 0.0) - 1.0 / LN_2).abs() < 1e-15);
    assert!((pose_information_gain(-2.0, -2.0 + LN_2) + 1.0).abs() < 1e-15);
}

// ---------------------------------------------------------------------------------------------
// Item 29 and the edge model of 6.4 step 1.

#[test]
fn item29_transition_density_is_invariant_to_full_turns() {
    let noise = EdgeMotionNoise::default();
    let mut rng = Rng::new(29);
    let tp = 2.0 * PI;
    for _ in 0..500 {
        let from = [rng.normal(), rng.normal()];
        let to = [from[0] + rng.normal(), from[1] + rng.normal()];
        let h = (to[1] - from[1]).atan2(to[0] - from[0]);
        let prev = [
            from[0] + 0.1 * rng.normal(),
            from[1] + 0.1 * rng.normal(),
            PI * (2.0 * rng.uniform() - 1.0),
        ];
        // Headings near the ±π cut are the interesting case: residuals of a few σ around h.
        let theta = h + noise.q_theta.sqrt() * rng.normal();
        let next = [
            to[0] + 0.2 * rng.normal(),
            to[1] + 0.2 * rng.normal(),
            theta,
        ];
        let base = edge_log_transition(next, prev, from, to, noise, None).unwrap();
        assert!(base.is_finite());
        // Storing θ + 2kπ rounds θ by up to ½ ulp(|θ| + 2|k|π) ≈ 1e-15 rad, which moves log p by
        // |θ − h| / q_θ times that (~1e-12 at 3σ): hence 1e-12 relative to |log p|.
        let tol = 1e-12 * (1.0 + base.abs());
        for k in [-2.0, -1.0, 1.0, 2.0] {
            let shifted = [next[0], next[1], theta + k * tp];
            let v = edge_log_transition(shifted, prev, from, to, noise, None).unwrap();
            assert!((v - base).abs() < tol, "{v} vs {base}");
            let v = edge_log_transition(next, prev, from, to, noise, Some(h + k * tp)).unwrap();
            assert!((v - base).abs() < tol, "{v} vs {base}");
            let pp = [prev[0], prev[1], prev[2] + k * tp];
            let v = edge_log_transition(next, pp, from, to, noise, None).unwrap();
            assert_eq!(v, base); // the parent's heading does not enter a directed edge
        }
    }
    // Zero-length edge with no explicit heading: the parent's heading, also modulo 2π.
    let p = [1.0, 1.0, 3.1];
    let c = [1.05, 0.98, 3.104 - 2.0 * PI];
    let a = edge_log_transition(c, p, [1.0, 1.0], [1.0, 1.0], noise, None).unwrap();
    let b =
        edge_log_transition(c, [1.0, 1.0, 3.1 - tp], [1.0, 1.0], [1.0, 1.0], noise, None).unwrap();
    assert!(a.is_finite() && (a - b).abs() < 1e-9);
}

#[test]
fn edge_propagation_matches_its_model() {
    let noise = EdgeMotionNoise {
        q_xy: 0.04,
        q_theta: 0.01,
    };
    let (from, to) = ([1.0, 2.0], [-2.0, 2.5]); // heading near π: the wrapped case
    let h = (0.5f64).atan2(-3.0);
    let parent = [0.3, -0.4, 1.0];
    let n = 40_000;
    let mut rng = Rng::new(64);
    let kids = propagate_along_edge(&vec![parent; n], from, to, noise, None, &mut rng).unwrap();
    let nf = n as f64;
    let mx = kids.iter().map(|k| k[0]).sum::<f64>() / nf;
    let my = kids.iter().map(|k| k[1]).sum::<f64>() / nf;
    let mt = kids.iter().map(|k| wrap(k[2] - h)).sum::<f64>() / nf;
    let cov = weighted_position_covariance(&kids, &vec![1.0; n]).unwrap();
    let vt = kids.iter().map(|k| wrap(k[2] - h).powi(2)).sum::<f64>() / nf;
    // Standard errors: 0.2/√n = 0.001 for the means, ~0.04·√(2/n) = 3e-4 for the variances.
    assert!((mx - (parent[0] - 3.0)).abs() < 0.005 && (my - (parent[1] + 0.5)).abs() < 0.005);
    assert!(mt.abs() < 0.003);
    assert!((cov[0][0] - 0.04).abs() < 0.002 && (cov[1][1] - 0.04).abs() < 0.002);
    assert!(cov[0][1].abs() < 0.002 && (vt - 0.01).abs() < 5e-4);
    assert!(kids.iter().all(|k| k[2] > -PI && k[2] <= PI));
    // The density is the sampler's: E[−log p] over the samples = the noise entropy.
    let edge = EdgeTransition::new(from, to, noise, None).unwrap();
    let nll = -kids
        .iter()
        .map(|&k| edge.log_density(k, parent))
        .sum::<f64>()
        / nf;
    let h_noise = gaussian_entropy_diag(&[0.04, 0.04, 0.01]).unwrap();
    assert!((nll - h_noise).abs() < 0.03, "{nll} vs {h_noise}");
    // Deterministic: the same seed gives bit-identical particles.
    let again =
        propagate_along_edge(&vec![parent; n], from, to, noise, None, &mut Rng::new(64)).unwrap();
    assert_eq!(kids, again);
    // Zero-length edge, no heading given: headings stay around the parent's.
    let still =
        propagate_along_edge(&vec![parent; 2000], from, from, noise, None, &mut rng).unwrap();
    let ms = still.iter().map(|k| k[2]).sum::<f64>() / 2000.0;
    assert!((ms - parent[2]).abs() < 0.01);

    assert!(EdgeMotionNoise::default().validate().is_ok());
    let d = EdgeMotionNoise::default();
    assert!(
        (d.q_xy - 0.01).abs() < 1e-15 && (d.q_theta - (0.15 * PI / 180.0).powi(2)).abs() < 1e-18
    );
    for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        assert!(EdgeMotionNoise { q_xy: bad, ..d }.validate().is_err());
        assert!(EdgeMotionNoise { q_theta: bad, ..d }.validate().is_err());
    }
    assert!(propagate_along_edge(&[[f64::NAN, 0.0, 0.0]], from, to, d, None, &mut rng).is_err());
    assert!(edge_log_transition(parent, parent, [f64::NAN, 0.0], to, d, None).is_err());
}

// ---------------------------------------------------------------------------------------------
// Root, one edge, Gaussian entropies and the ellipse covariance.

#[test]
fn root_and_one_edge_match_the_gaussian_entropies() {
    let h_root = root_entropy(ROOT_COV_DIAG).unwrap();
    let expect = 0.5 * (3.0 * (LN_2PI + 1.0) + (0.16f64 * 0.01 * 1e-6).ln());
    assert!((h_root - expect).abs() < 1e-12);
    assert!((h_root - gaussian_entropy(&diag3(ROOT_COV_DIAG)).unwrap()).abs() < 1e-12);

    let n = 2000;
    let mut rng = Rng::new(640);
    let mean = [2.0, 3.0, 0.5];
    let roots = sample_root_particles(mean, ROOT_COV_DIAG, n, &mut rng).unwrap();
    let cov = weighted_position_covariance(&roots, &vec![1.0; n]).unwrap();
    assert!((cov[0][0] - 0.16).abs() < 0.02 && (cov[1][1] - 0.01).abs() < 0.0015);
    let noise = EdgeMotionNoise::default();
    let (from, to) = ([2.0, 3.0], [4.0, 4.0]);
    let kids = propagate_along_edge(&roots, from, to, noise, None, &mut rng).unwrap();
    let edge = EdgeTransition::new(from, to, noise, None).unwrap();
    let lw = vec![-(n as f64).ln(); n];
    let h_edge = edge_particle_entropy(&roots, &lw, &kids, &vec![0.0; n], &edge).unwrap();
    // Children: position N(mean + d, Σ_0,xy + q_xy I) (isotropic noise), heading N(h, q_θ).
    let h_true = gaussian_entropy_diag(&[0.16 + 0.01, 0.01 + 0.01, noise.q_theta]).unwrap();
    let ip = pose_information_gain(h_root, h_edge);
    println!("H_root {h_root:.4}, H_edge {h_edge:.4} (Gaussian {h_true:.4}), I_p {ip:.3} bits");
    assert!((h_edge - h_true).abs() < 0.1, "{h_edge} vs {h_true}");
    // A scan that pins the position down lowers the entropy and raises I_p.
    let ll: Vec<f64> = kids
        .iter()
        .map(|k| log_normal_1d(k[0] - 4.0, 0.01) + log_normal_1d(k[1] - 4.0, 0.01))
        .collect();
    let h_scan = edge_particle_entropy(&roots, &lw, &kids, &ll, &edge).unwrap();
    assert!(h_scan < h_edge - 1.0);
    assert!(edge_particle_entropy(&roots[1..], &lw, &kids, &ll, &edge).is_err());

    assert!(sample_root_particles(mean, ROOT_COV_DIAG, 0, &mut rng).is_err());
    assert!(sample_root_particles(mean, [0.1, 0.0, 0.1], 5, &mut rng).is_err());
}

#[test]
fn gaussian_entropy_and_log_det() {
    let a = [[2.0, 0.3, -0.4], [0.3, 1.0, 0.2], [-0.4, 0.2, 0.5]];
    let h = gaussian_entropy(&a).unwrap();
    let expect = 0.5 * (3.0 * (LN_2PI + 1.0) + det3(a).ln());
    assert!((h - expect).abs() < 1e-12);
    assert!(
        (gaussian_entropy_nd(&[4.0], 1).unwrap() - 0.5 * (LN_2PI + 1.0 + 4f64.ln())).abs() < 1e-15
    );
    let flat: Vec<f64> = a.iter().flatten().copied().collect();
    assert!((log_det_spd(&flat, 3).unwrap() - det3(a).ln()).abs() < 1e-12);
    assert!(gaussian_entropy(&[[1.0, 2.0, 0.0], [2.0, 1.0, 0.0], [0.0, 0.0, 1.0]]).is_err());
    assert!(gaussian_entropy(&[[1.0, 0.5, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]).is_err());
    assert!(log_det_spd(&[1.0, 0.0], 2).is_err() && log_det_spd(&[f64::NAN], 1).is_err());
}

#[test]
fn weighted_position_covariance_by_hand() {
    let p = [[0.0, 0.0, 9.0], [2.0, 0.0, -9.0], [0.0, 4.0, 0.0]];
    let c = weighted_position_covariance(&p, &[2.0, 1.0, 1.0]).unwrap();
    // mean (0.5, 1); entries Σ w d dᵀ with w = (0.5, 0.25, 0.25).
    let expect = [[0.75, -0.5], [-0.5, 3.0]];
    for r in 0..2 {
        for k in 0..2 {
            assert!((c[r][k] - expect[r][k]).abs() < 1e-12, "{c:?}");
        }
    }
    assert!(weighted_position_covariance(&p, &[1.0, 1.0]).is_err());
    assert!(weighted_position_covariance(&p, &[1.0, -1.0, 1.0]).is_err());
}

#[test]
fn parallel_calls_equal_serial_calls() {
    use rayon::prelude::*;
    let sets: Vec<Mixture> = (0..8).map(|s| mixture(10, 20, 0.05, 900 + s)).collect();
    let ll = |m: &Mixture| -> Vec<f64> { m.children.iter().map(|x| -x * x).collect() };
    let serial: Vec<f64> = sets.iter().map(|m| m.entropy(&ll(m))).collect();
    let parallel: Vec<f64> = sets.par_iter().map(|m| m.entropy(&ll(m))).collect();
    assert_eq!(
        serial.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
        parallel.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
    );
}
