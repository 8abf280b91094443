//! Pose entropy of a particle set and the pose half of UCRMI (crm-spec 6.1–6.4, invariants 25–29).
//!
//! - [`weight_entropy`]: the weight-only entropy of Eq. 18 (the `weights` ablation).
//! - [`particle_entropy`]: the Boers et al. (2010) differential-entropy estimator of Eqs. 19–21
//!   with the corrections of crm-spec 6.2, in log space.
//! - [`EdgeTransition`], [`propagate_along_edge`], [`edge_log_transition`]: the planner's per-edge
//!   motion model of 6.4 step 1 and its density; [`edge_particle_entropy`] joins them to 6.2.
//! - [`sample_root_particles`], [`root_entropy`]: the root belief N(x_init, Σ_0) of 6.4.
//! - [`pose_information_gain`], [`ucrmi_mix`]: I_p and I_c of 6.3 (bits).
//!
//! Entropies are in nats unless a name says bits. Pose entropies are differential entropies of
//! (x, y, θ) in (m, m, rad): they can be negative and only their differences mean anything.
//!
//! Ancestry convention: current particle `j` descends from previous particle `j` (same index).
//! [`propagate_along_edge`] keeps the order, and after a resampling the caller must reorder the
//! previous set (or duplicate its entries) so that index `j` is again the ancestor of `j`.

use std::f64::consts::LN_2;

use crate::error::{config_err, CrlamError, Result};
use crate::numeric::fastmath::exp_for_sums;
use crate::pose::wrap;
use crate::rng::Rng;

/// ln(2π).
const LN_2PI: f64 = 1.837_877_066_409_345_5;

/// Edges shorter than this (m) have no direction: see [`EdgeTransition::new`].
pub const MIN_EDGE_LENGTH: f64 = 1e-9;

/// Root covariance diagonal Σ_0 = diag(0.4², 0.1², 1e-6) in (m², m², rad²): R5's UGPVR setup
/// with a tiny heading variance instead of 0 so that densities exist (crm-spec 6.4).
pub const ROOT_COV_DIAG: [f64; 3] = [0.16, 0.01, 1e-6];

/// The paper's UCRMI weight α = 0.5 between map and pose information (crm-spec 6.3).
pub const UCRMI_ALPHA: f64 = 0.5;

/// log Σ_i exp(x_i), computed around the maximum. −∞ for an empty slice or when every entry is
/// −∞. Entries must not be NaN or +∞ (the callers here reject those first).
pub fn log_sum_exp(x: &[f64]) -> f64 {
    let m = x.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if m == f64::NEG_INFINITY {
        return m;
    }
    m + x.iter().map(|&v| (v - m).exp()).sum::<f64>().ln()
}

/// [`log_sum_exp`] of `x` (overwritten) with the exponentials from [`exp_for_sums`] (a few ulp;
/// terms below e^−708.3 count as 0, which cannot change a sum that contains the maximum's 1), for
/// the O(n²) sums of the entropy estimator.
fn log_sum_exp_terms(x: &mut [f64]) -> f64 {
    let m = x.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if m == f64::NEG_INFINITY {
        return m;
    }
    x.iter_mut().for_each(|v| *v -= m);
    exp_for_sums(x);
    m + x.iter().sum::<f64>().ln()
}

/// Checks non-negative finite weights with a positive sum and returns them normalised.
fn normalised_weights(w: &[f64], field: &'static str) -> Result<Vec<f64>> {
    if w.is_empty() {
        return Err(CrlamError::Shape(format!("{field}: no weights")));
    }
    if let Some(&v) = w.iter().find(|v| !v.is_finite()) {
        return Err(CrlamError::NonFinite { field, value: v });
    }
    if w.iter().any(|&v| v < 0.0) {
        return Err(config_err(field, "weights must be >= 0"));
    }
    // Dividing by the largest weight first keeps the sum finite for weights near f64::MAX.
    let m = w.iter().copied().fold(0.0, f64::max);
    if m == 0.0 {
        return Err(config_err(field, "weights are all zero"));
    }
    let s: f64 = w.iter().map(|&v| v / m).sum();
    Ok(w.iter().map(|&v| v / m / s).collect())
}

/// Weight-only entropy H_w = −Σ_j w̄_j ln w̄_j in nats (crm-spec 6.1, Eq. 18), with 0 ln 0 = 0.
/// `w` (length n ≥ 1) need not be normalised. The result lies in [0, ln n] (up to rounding),
/// with ln n exactly for uniform weights. Errors on an empty slice, a negative or non-finite
/// weight, or all-zero weights.
pub fn weight_entropy(w: &[f64]) -> Result<f64> {
    let w = normalised_weights(w, "weights")?;
    Ok(crate::info::entropy_nats(&w))
}

/// Rejects NaN and +∞ in a log-weight-like slice (−∞, a zero weight or density, is allowed).
fn check_log_values(x: &[f64], field: &'static str) -> Result<()> {
    match x.iter().find(|v| v.is_nan() || **v == f64::INFINITY) {
        Some(&v) => Err(CrlamError::NonFinite { field, value: v }),
        None => Ok(()),
    }
}

/// Particle-based differential entropy of the posterior pose belief in nats (crm-spec 6.2,
/// the corrected Boers estimator):
///
/// H_k ≈ LSE_j(log w_{k−1}^j + ℓ_j) − Σ_j w_k^j [ℓ_j + LSE_i(log w_{k−1}^i + log p(x_k^j | x_{k−1}^i, u))]
///
/// - `prev_log_w[i]`: log weight of previous particle i (n entries; need not be normalised,
///   −∞ = zero weight). Uniform after a resampling.
/// - `log_lik[j]`: scan log-likelihood ℓ_j of current particle j (−∞ allowed), before tempering.
/// - `log_transition(j, i)`: log p(x_k^j | x_{k−1}^i, u), the motion density from previous
///   particle i to current particle j (−∞ allowed when it underflows).
///
/// Current particle j descends from previous particle j, so its posterior weight is
/// w_k^j ∝ w_{k−1}^j e^{ℓ_j} (before any resampling at k). The value is invariant to adding a
/// constant to all of `prev_log_w` or all of `log_lik`. Differential entropy: may be negative.
///
/// Cost: n² calls of `log_transition`, in a fixed serial order, skipping pairs whose weight is
/// zero; the function is pure, so calls on different inputs may run in parallel and results are
/// bit-identical run to run. Errors: length mismatch or n = 0 (`Shape`), NaN/+∞ inputs or
/// transition values (`NonFinite`), zero evidence (every w_{k−1}^j e^{ℓ_j} = 0), or a current
/// particle of positive weight whose predictive density is zero (`Config`; its own ancestor's
/// density must be positive).
pub fn particle_entropy(
    prev_log_w: &[f64],
    log_lik: &[f64],
    log_transition: impl Fn(usize, usize) -> f64,
) -> Result<f64> {
    particle_entropy_rows(prev_log_w, log_lik, |j, row| {
        for (i, (r, &w)) in row.iter_mut().zip(prev_log_w).enumerate() {
            // Zero-weight previous particles are never asked about (their row entry is unused).
            *r = if w == f64::NEG_INFINITY {
                0.0
            } else {
                log_transition(j, i)
            };
        }
    })
}

/// [`particle_entropy`] with the transitions delivered a row at a time: `fill_row(j, row)` writes
/// log p(x_k^j | x_{k−1}^i, u) into `row[i]` for every i (rows of skipped pairs are ignored), so
/// that a caller can compute a row in one vectorisable pass.
pub fn particle_entropy_rows(
    prev_log_w: &[f64],
    log_lik: &[f64],
    mut fill_row: impl FnMut(usize, &mut [f64]),
) -> Result<f64> {
    let n = prev_log_w.len();
    if n == 0 || log_lik.len() != n {
        return Err(CrlamError::Shape(format!(
            "particle_entropy: {} previous log-weights and {} log-likelihoods (need equal, >= 1)",
            n,
            log_lik.len()
        )));
    }
    check_log_values(prev_log_w, "prev_log_w")?;
    check_log_values(log_lik, "log_lik")?;

    // Normalised previous log-weights (finite LSE: some posterior term is finite, checked below).
    let joint: Vec<f64> = prev_log_w.iter().zip(log_lik).map(|(a, b)| a + b).collect();
    let log_evidence = log_sum_exp(&joint);
    if log_evidence == f64::NEG_INFINITY {
        return Err(config_err(
            "log_lik",
            "zero evidence: every particle has zero posterior weight",
        ));
    }
    let lse_prev = log_sum_exp(prev_log_w);
    let lw: Vec<f64> = prev_log_w.iter().map(|&v| v - lse_prev).collect();

    // Written as H = −Σ_j w_k^j [log w_k^j − log w_{k−1}^j + L_j], L_j = LSE_i(log w_{k−1}^i +
    // log p(x^j | x^i)). This equals the spec's form (substitute ℓ_j = log w_k^j + LSE(joint)
    // − log w_{k−1}^j) but never subtracts the large scan log-likelihoods from each other.
    let mut row = vec![0.0; n];
    let mut terms = vec![0.0; n];
    let mut h = 0.0;
    for j in 0..n {
        let log_wk = joint[j] - log_evidence;
        let wk = log_wk.exp();
        if wk == 0.0 {
            continue; // 0 · log 0 = 0, and w_{k−1}^j may be zero here
        }
        fill_row(j, &mut row);
        // Previous particles of zero weight take no part (their transitions are not checked).
        for (i, (&lwi, &t)) in lw.iter().zip(&row).enumerate() {
            if lwi != f64::NEG_INFINITY && (t.is_nan() || t == f64::INFINITY) {
                return Err(CrlamError::NonFinite {
                    field: "log_transition",
                    value: row[i],
                });
            }
        }
        for ((o, &lwi), &t) in terms.iter_mut().zip(&lw).zip(&row) {
            *o = if lwi == f64::NEG_INFINITY {
                f64::NEG_INFINITY
            } else {
                lwi + t
            };
        }
        let log_pred = log_sum_exp_terms(&mut terms);
        if log_pred == f64::NEG_INFINITY {
            return Err(config_err(
                "log_transition",
                format!("current particle {j} has zero density under every previous particle"),
            ));
        }
        h -= wk * (log_wk - lw[j] + log_pred);
    }
    Ok(h)
}

/// [`particle_entropy`] with a precomputed n × n log-transition matrix, row-major:
/// `log_transition[j * n + i]` = log p(x_k^j | x_{k−1}^i, u) (row = current, column = previous).
pub fn particle_entropy_matrix(
    prev_log_w: &[f64],
    log_lik: &[f64],
    log_transition: &[f64],
) -> Result<f64> {
    let n = prev_log_w.len();
    if log_transition.len() != n * n {
        return Err(CrlamError::Shape(format!(
            "particle_entropy_matrix: {} transition entries for {} particles (need n²)",
            log_transition.len(),
            n
        )));
    }
    particle_entropy(prev_log_w, log_lik, |j, i| log_transition[j * n + i])
}

/// ln |A| of a symmetric positive-definite d × d matrix (row-major, `a.len() == d²`) by
/// Cholesky. Errors on a shape mismatch, d = 0, non-finite entries, asymmetry beyond 1e-9 of the
/// largest diagonal entry, or a matrix that is not positive definite.
pub fn log_det_spd(a: &[f64], d: usize) -> Result<f64> {
    if d == 0 || a.len() != d * d {
        return Err(CrlamError::Shape(format!(
            "log_det_spd: {} entries for a {d}×{d} matrix",
            a.len()
        )));
    }
    if let Some(&v) = a.iter().find(|v| !v.is_finite()) {
        return Err(CrlamError::NonFinite {
            field: "covariance",
            value: v,
        });
    }
    let scale = (0..d).map(|k| a[k * d + k].abs()).fold(0.0, f64::max);
    for r in 0..d {
        for c in 0..r {
            if (a[r * d + c] - a[c * d + r]).abs() > 1e-9 * scale {
                return Err(config_err("covariance", "matrix is not symmetric"));
            }
        }
    }
    // Lower Cholesky factor, in place of a copy; ln|A| = 2 Σ ln L_kk.
    let mut l = a.to_vec();
    let mut log_det = 0.0;
    for k in 0..d {
        let mut pivot = l[k * d + k];
        for m in 0..k {
            pivot -= l[k * d + m] * l[k * d + m];
        }
        if pivot <= 0.0 || !pivot.is_finite() {
            return Err(config_err("covariance", "matrix is not positive definite"));
        }
        let lkk = pivot.sqrt();
        l[k * d + k] = lkk;
        log_det += 2.0 * lkk.ln();
        for r in k + 1..d {
            let mut v = l[r * d + k];
            for m in 0..k {
                v -= l[r * d + m] * l[k * d + m];
            }
            l[r * d + k] = v / lkk;
        }
    }
    Ok(log_det)
}

/// Entropy ½ ln((2πe)^d |Σ|) in nats of a d-dimensional Gaussian with covariance `cov`
/// (row-major d × d, symmetric positive definite; see [`log_det_spd`] for the errors).
pub fn gaussian_entropy_nd(cov: &[f64], d: usize) -> Result<f64> {
    Ok(0.5 * (d as f64 * (LN_2PI + 1.0) + log_det_spd(cov, d)?))
}

/// Entropy ½ ln((2πe)³ |Σ|) in nats of a Gaussian over (x, y, θ); `cov` in (m, m, rad)².
pub fn gaussian_entropy(cov: &[[f64; 3]; 3]) -> Result<f64> {
    let flat: Vec<f64> = cov.iter().flatten().copied().collect();
    gaussian_entropy_nd(&flat, 3)
}

/// Entropy in nats of a Gaussian with diagonal covariance `var` (each variance finite, > 0).
pub fn gaussian_entropy_diag(var: &[f64]) -> Result<f64> {
    check_variances(var, "variance")?;
    let d = var.len() as f64;
    Ok(0.5 * (d * (LN_2PI + 1.0) + var.iter().map(|v| v.ln()).sum::<f64>()))
}

fn check_variances(var: &[f64], field: &'static str) -> Result<()> {
    if var.is_empty() {
        return Err(CrlamError::Shape(format!("{field}: no variances")));
    }
    match var.iter().find(|v| !v.is_finite() || **v <= 0.0) {
        Some(&v) if !v.is_finite() => Err(CrlamError::NonFinite { field, value: v }),
        Some(_) => Err(config_err(field, "variances must be > 0")),
        None => Ok(()),
    }
}

/// Per-edge motion noise of the planner (crm-spec 6.4 step 1): ε ~ N(0, diag(q_xy, q_xy,
/// q_theta)), applied once per edge whatever its length.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EdgeMotionNoise {
    /// Position variance per axis (m²), in the edge frame. Default 0.1².
    pub q_xy: f64,
    /// Heading variance (rad²). Default (0.15°)².
    pub q_theta: f64,
}

impl Default for EdgeMotionNoise {
    /// R5's UGPVR values Q = diag(0.1², 0.1², (0.15°)²).
    fn default() -> Self {
        Self {
            q_xy: 0.1 * 0.1,
            q_theta: 0.15f64.to_radians().powi(2),
        }
    }
}

impl EdgeMotionNoise {
    /// Both variances must be finite and > 0 (the transition density must exist).
    pub fn validate(&self) -> Result<()> {
        check_variances(&[self.q_xy], "q_xy")?;
        check_variances(&[self.q_theta], "q_theta")
    }
}

/// The motion model of one planner edge `from → to` (crm-spec 6.4 step 1), validated once so
/// that sampling and the O(n²) density calls need no checks.
///
/// A child of parent pose p is p + (dx, dy) + Rot(h)·ε_xy in position and h + ε_θ (wrapped to
/// (−π, π]) in heading: the heading is reset to the edge direction, independent of p's heading.
/// Its density is N(Rot(h)ᵀ(Δpos − (dx, dy)); 0, q_xy I) · N(wrap(θ − h); 0, q_theta), a normal
/// density at the wrapped residual (exact up to the mass beyond ±π, negligible for q_theta ≪ π²).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EdgeTransition {
    delta: [f64; 2],
    /// (h, sin h, cos h), or `None` to use each parent's own heading.
    heading: Option<(f64, f64, f64)>,
    noise: EdgeMotionNoise,
    sd_xy: f64,
    sd_theta: f64,
    log_norm: f64,
}

impl EdgeTransition {
    /// The edge from position `from` to `to` (m). Heading h: `heading` if given (rad); else the
    /// edge direction atan2(dy, dx); else, for an edge shorter than [`MIN_EDGE_LENGTH`] (no
    /// direction), each parent particle's own heading, so a zero-length edge keeps the heading
    /// and only adds noise. Errors on non-finite inputs or invalid noise.
    pub fn new(
        from: [f64; 2],
        to: [f64; 2],
        noise: EdgeMotionNoise,
        heading: Option<f64>,
    ) -> Result<Self> {
        noise.validate()?;
        for (field, v) in [("from", from), ("to", to)] {
            if let Some(&x) = v.iter().find(|x| !x.is_finite()) {
                return Err(CrlamError::NonFinite { field, value: x });
            }
        }
        let delta = [to[0] - from[0], to[1] - from[1]];
        let h = match heading {
            Some(h) if !h.is_finite() => {
                return Err(CrlamError::NonFinite {
                    field: "heading",
                    value: h,
                })
            }
            Some(h) => Some(h),
            None => edge_heading(from, to),
        };
        Ok(Self {
            delta,
            heading: h.map(|h| {
                let (s, c) = h.sin_cos();
                (h, s, c)
            }),
            noise,
            sd_xy: noise.q_xy.sqrt(),
            sd_theta: noise.q_theta.sqrt(),
            log_norm: -1.5 * LN_2PI - noise.q_xy.ln() - 0.5 * noise.q_theta.ln(),
        })
    }

    /// The world-frame increment (dx, dy) = to − from (m).
    pub fn delta(&self) -> [f64; 2] {
        self.delta
    }

    /// The heading h (rad) used for children of `parent`.
    pub fn heading_for(&self, parent: [f64; 3]) -> f64 {
        self.heading.map_or(parent[2], |(h, _, _)| h)
    }

    fn frame(&self, parent: [f64; 3]) -> (f64, f64, f64) {
        self.heading.unwrap_or_else(|| {
            let (s, c) = parent[2].sin_cos();
            (parent[2], s, c)
        })
    }

    /// Draws one child pose of `parent` (three standard normals from `rng`).
    pub fn sample(&self, parent: [f64; 3], rng: &mut Rng) -> [f64; 3] {
        let (h, s, c) = self.frame(parent);
        let ex = self.sd_xy * rng.normal();
        let ey = self.sd_xy * rng.normal();
        let et = self.sd_theta * rng.normal();
        [
            parent[0] + self.delta[0] + c * ex - s * ey,
            parent[1] + self.delta[1] + s * ex + c * ey,
            wrap(h + et),
        ]
    }

    /// log p(child | parent) (density in (m, m, rad)). Non-finite poses give NaN.
    pub fn log_density(&self, child: [f64; 3], parent: [f64; 3]) -> f64 {
        let (h, s, c) = self.frame(parent);
        let rx = child[0] - parent[0] - self.delta[0];
        let ry = child[1] - parent[1] - self.delta[1];
        // Rot(h)ᵀ r: the residual in the edge frame.
        let ax = c * rx + s * ry;
        let ay = -s * rx + c * ry;
        let at = wrap(child[2] - h);
        self.log_norm - 0.5 * ((ax * ax + ay * ay) / self.noise.q_xy + at * at / self.noise.q_theta)
    }
}

/// Direction atan2(dy, dx) (rad) of the edge `from → to`, or `None` if it is shorter than
/// [`MIN_EDGE_LENGTH`].
pub fn edge_heading(from: [f64; 2], to: [f64; 2]) -> Option<f64> {
    let (dx, dy) = (to[0] - from[0], to[1] - from[1]);
    (dx.hypot(dy) >= MIN_EDGE_LENGTH).then(|| dy.atan2(dx))
}

fn check_poses(poses: &[[f64; 3]], field: &'static str) -> Result<()> {
    match poses.iter().flatten().find(|v| !v.is_finite()) {
        Some(&v) => Err(CrlamError::NonFinite { field, value: v }),
        None => Ok(()),
    }
}

/// Propagates every particle along the edge `from → to` (crm-spec 6.4 step 1); child `j`
/// descends from `particles[j]`. `heading`: see [`EdgeTransition::new`] (`None` = the edge
/// direction). Draws 3 normals per particle from `rng`, in particle order.
pub fn propagate_along_edge(
    particles: &[[f64; 3]],
    from: [f64; 2],
    to: [f64; 2],
    noise: EdgeMotionNoise,
    heading: Option<f64>,
    rng: &mut Rng,
) -> Result<Vec<[f64; 3]>> {
    let edge = EdgeTransition::new(from, to, noise, heading)?;
    check_poses(particles, "particles")?;
    Ok(particles.iter().map(|&p| edge.sample(p, rng)).collect())
}

/// log p(next | prev) of the edge motion model (see [`EdgeTransition`]). For many pairs build
/// one [`EdgeTransition`] and call its `log_density` instead.
pub fn edge_log_transition(
    next: [f64; 3],
    prev: [f64; 3],
    from: [f64; 2],
    to: [f64; 2],
    noise: EdgeMotionNoise,
    heading: Option<f64>,
) -> Result<f64> {
    let edge = EdgeTransition::new(from, to, noise, heading)?;
    check_poses(&[next, prev], "pose")?;
    Ok(edge.log_density(next, prev))
}

/// Entropy (nats) of the children after one edge (crm-spec 6.4 step 4): [`particle_entropy`]
/// with the parents as the previous set and the edge density as the transition. `children[j]`
/// descends from `parents[j]`; `log_lik[j]` is the virtual-scan log-likelihood of child j.
pub fn edge_particle_entropy(
    parents: &[[f64; 3]],
    parent_log_w: &[f64],
    children: &[[f64; 3]],
    log_lik: &[f64],
    edge: &EdgeTransition,
) -> Result<f64> {
    let n = parents.len();
    if children.len() != n || parent_log_w.len() != n {
        return Err(CrlamError::Shape(format!(
            "edge_particle_entropy: {n} parents, {} weights, {} children",
            parent_log_w.len(),
            children.len()
        )));
    }
    check_poses(parents, "parents")?;
    check_poses(children, "children")?;
    let Some((h, _, _)) = edge.heading else {
        return particle_entropy(parent_log_w, log_lik, |j, i| {
            edge.log_density(children[j], parents[i])
        });
    };
    // With one frame for every parent, |Rot(h)ᵀ r|² = |r|² and the heading residual depends on
    // the child only: log p(j | i) = c_j − |x_j − x_i − Δ|² / (2 q_xy), equal to
    // `log_density` to rounding and free of per-pair trigonometry.
    let q = edge.noise;
    let c: Vec<f64> = children
        .iter()
        .map(|ch| {
            let at = wrap(ch[2] - h);
            edge.log_norm - 0.5 * at * at / q.q_theta
        })
        .collect();
    let base: Vec<[f64; 2]> = parents
        .iter()
        .map(|p| [p[0] + edge.delta[0], p[1] + edge.delta[1]])
        .collect();
    let half_inv_q = 0.5 / q.q_xy;
    let (bx, by): (Vec<f64>, Vec<f64>) = base.iter().map(|b| (b[0], b[1])).unzip();
    particle_entropy_rows(parent_log_w, log_lik, |j, row| {
        let (cx, cy, cj) = (children[j][0], children[j][1], c[j]);
        for ((r, &x), &y) in row.iter_mut().zip(&bx).zip(&by) {
            let (rx, ry) = (cx - x, cy - y);
            *r = cj - half_inv_q * (rx * rx + ry * ry);
        }
    })
}

/// `n` root particles ~ N(mean, diag(cov_diag)) (crm-spec 6.4 Root; default
/// [`ROOT_COV_DIAG`]), headings wrapped to (−π, π]. Draws 3 normals per particle, in order.
/// Errors on n = 0, non-finite mean or non-positive variances.
pub fn sample_root_particles(
    mean: [f64; 3],
    cov_diag: [f64; 3],
    n: usize,
    rng: &mut Rng,
) -> Result<Vec<[f64; 3]>> {
    if n == 0 {
        return Err(config_err("n", "at least one particle is needed"));
    }
    check_poses(&[mean], "mean")?;
    check_variances(&cov_diag, "cov_diag")?;
    let sd = cov_diag.map(f64::sqrt);
    Ok((0..n)
        .map(|_| {
            let x = mean[0] + sd[0] * rng.normal();
            let y = mean[1] + sd[1] * rng.normal();
            let t = wrap(mean[2] + sd[2] * rng.normal());
            [x, y, t]
        })
        .collect())
}

/// H_root = ½ ln((2πe)³ |diag(cov_diag)|) in nats (crm-spec 6.4 Root); about −5.870 for
/// [`ROOT_COV_DIAG`].
pub fn root_entropy(cov_diag: [f64; 3]) -> Result<f64> {
    gaussian_entropy_diag(&cov_diag)
}

/// I_p = (H_prev − H_new) / ln 2 in bits from two entropies in nats (crm-spec 6.3, Eq. 22).
/// Not clipped: negative when the motion adds more uncertainty than the scan removes.
pub fn pose_information_gain(h_prev_nats: f64, h_new_nats: f64) -> f64 {
    (h_prev_nats - h_new_nats) / LN_2
}

/// UCRMI I_c = α I_m + (1 − α) I_p (crm-spec 6.3, Eq. 23), both gains in bits, α ∈ [0, 1]
/// ([`UCRMI_ALPHA`] = 0.5). α = 1 returns I_m and α = 0 returns I_p exactly. Errors on
/// non-finite gains or α outside [0, 1].
pub fn ucrmi_mix(i_m_bits: f64, i_p_bits: f64, alpha: f64) -> Result<f64> {
    if !(0.0..=1.0).contains(&alpha) {
        return Err(config_err("alpha", format!("{alpha} is not in [0, 1]")));
    }
    for (field, v) in [("i_m_bits", i_m_bits), ("i_p_bits", i_p_bits)] {
        if !v.is_finite() {
            return Err(CrlamError::NonFinite { field, value: v });
        }
    }
    Ok(alpha * i_m_bits + (1.0 - alpha) * i_p_bits)
}

/// Weighted covariance Σ_j w̄_j (p_j − μ)(p_j − μ)ᵀ (m²) of the particle positions (x, y), with
/// μ the weighted mean and w normalised first (no small-sample correction). For the 90 % ellipses
/// of the UCRMI figure (crm-spec 6.4). Errors as [`weight_entropy`], on a length mismatch, or on
/// non-finite positions.
pub fn weighted_position_covariance(particles: &[[f64; 3]], w: &[f64]) -> Result<[[f64; 2]; 2]> {
    if particles.len() != w.len() {
        return Err(CrlamError::Shape(format!(
            "weighted_position_covariance: {} particles, {} weights",
            particles.len(),
            w.len()
        )));
    }
    let w = normalised_weights(w, "weights")?;
    if let Some(&v) = particles
        .iter()
        .flat_map(|p| &p[..2])
        .find(|v| !v.is_finite())
    {
        return Err(CrlamError::NonFinite {
            field: "particles",
            value: v,
        });
    }
    let mut mean = [0.0; 2];
    for (p, &wj) in particles.iter().zip(&w) {
        mean[0] += wj * p[0];
        mean[1] += wj * p[1];
    }
    let mut c = [[0.0; 2]; 2];
    for (p, &wj) in particles.iter().zip(&w) {
        let d = [p[0] - mean[0], p[1] - mean[1]];
        c[0][0] += wj * d[0] * d[0];
        c[0][1] += wj * d[0] * d[1];
        c[1][1] += wj * d[1] * d[1];
    }
    c[1][0] = c[0][1];
    Ok(c)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn log_sum_exp_is_stable() {
        assert_eq!(log_sum_exp(&[]), f64::NEG_INFINITY);
        assert_eq!(log_sum_exp(&[f64::NEG_INFINITY; 2]), f64::NEG_INFINITY);
        let v = log_sum_exp(&[-1000.0, -1000.0 + 2f64.ln(), f64::NEG_INFINITY]);
        assert!((v - (-1000.0 + 3f64.ln())).abs() < 1e-12);
    }

    #[test]
    fn one_particle_without_motion_spread_is_its_transition_entropy() {
        // n = 1: H = −log p(x^1 | x^1) whatever the likelihood.
        let h = particle_entropy(&[-3.0], &[-40.0], |_, _| -1.25).unwrap();
        assert!((h - 1.25).abs() < 1e-15);
        assert!((weight_entropy(&[1.0, 1.0, 2.0]).unwrap() - 1.5 * LN_2).abs() < 1e-15);
    }
}
