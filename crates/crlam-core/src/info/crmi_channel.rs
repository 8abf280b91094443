//! The discretised range channel of one CRMI beam (crm-spec 5.2): CDF bin masses per cause,
//! and the unpooled reference computation of the bin probabilities, posteriors and per-cell MI
//! that the pooled pose evaluation in [`crate::info::crmi`] must reproduce.

use crate::crm::update::{cause_sweep, cause_sweep_log, LINEAR_ETA_MIN};
use crate::error::Result;
use crate::info::crmi_config::{CrmiConfig, CrmiQuadrature, SUPPORT_SIGMAS};
use crate::numeric::fastmath::{lower_tail_abs_slice, tail_difference};
use crate::sensor::{normal_cdf, SensorModelKind};

/// The discretised channel of one beam: bin edges and each cause's bin masses.
#[derive(Debug, Default)]
pub struct BeamChannel {
    /// Bin edges z_0 = 0 < … < z_Q = z_max.
    pub(crate) edges: Vec<f64>,
    /// ℓ_l(q), row l (N × (Q + 1), the atom last).
    pub(crate) like: Vec<f64>,
    /// ℓ_∞(q), Q + 1 entries.
    pub(crate) like_inf: Vec<f64>,
    /// First and last bin (< Q) with ℓ_l(q) > 0 per cell for the pooled `ijrr` path.
    pub(crate) support: Vec<(usize, usize)>,
    /// Standardised support edges (z_e − d_l)/σ of every cell, back to back, and the value of
    /// their [`crate::numeric::fastmath::normal_tail`] (whose flag is u > 0).
    tail_u: Vec<f64>,
    tail_v: Vec<f64>,
}

impl BeamChannel {
    /// Fills the channel for cells at distances `d` (m) along the beam.
    pub(crate) fn build(&mut self, cfg: &CrmiConfig, d: &[f64]) {
        let m = &cfg.model;
        let q_n = cfg.n_bins();
        let n = d.len();
        self.edges.clear();
        self.edges
            .extend((0..=q_n).map(|q| (q as f64 * cfg.lambda_z).min(m.z_max)));
        self.like.clear();
        self.like.resize(n * (q_n + 1), 0.0);
        self.like_inf.clear();
        self.like_inf.resize(q_n + 1, 0.0);
        self.support.clear();
        let pure_hit = m.kind == SensorModelKind::Ijrr;
        let (w_h, w_s, w_x, w_r) = (m.w_hit, m.w_short, m.w_max, m.w_rand);
        let lam = m.lambda_short;
        let sig = m.sigma_hit;
        let z_max = m.z_max;
        // Bins that can carry hit mass: within SUPPORT_SIGMAS of d_l.
        let reach = SUPPORT_SIGMAS * sig;
        // `as usize` truncates toward 0 and saturates negatives at 0: floor, clamped at bin 0.
        let bin_of = |z: f64| ((z / cfg.lambda_z) as usize).min(q_n - 1);
        // Tail-aware CDFs at every support edge of every cell, in one vectorised pass.
        self.tail_u.clear();
        self.support
            .extend(d.iter().map(|&dl| (bin_of(dl - reach), bin_of(dl + reach))));
        if w_h > 0.0 {
            for (&dl, &(q_lo, q_hi)) in d.iter().zip(&self.support) {
                self.tail_u
                    .extend(self.edges[q_lo..=q_hi + 1].iter().map(|&z| (z - dl) / sig));
            }
        }
        self.tail_v.resize(self.tail_u.len(), 0.0);
        lower_tail_abs_slice(&self.tail_u, &mut self.tail_v);
        let mut at = 0;
        for (l, &dl) in d.iter().enumerate() {
            let row = &mut self.like[l * (q_n + 1)..(l + 1) * (q_n + 1)];
            let (q_lo, q_hi) = self.support[l];
            let short_norm = if w_s > 0.0 {
                -(-lam * dl).exp_m1()
            } else {
                0.0
            };
            let (lo, hi) = if pure_hit { (q_lo, q_hi) } else { (0, q_n - 1) };
            let n_edges = if w_h > 0.0 { q_hi + 2 - q_lo } else { 0 };
            let (tu, tv) = (
                &self.tail_u[at..at + n_edges],
                &self.tail_v[at..at + n_edges],
            );
            at += n_edges;
            let tail = |e: usize| (tu[e] > 0.0, tv[e]);
            // Normaliser: the Gaussian mass over the support bins (which lie inside [0, z_max],
            // so this also truncates at the range limits); the midpoint rule uses Z_h(d).
            let z_norm = match cfg.quadrature {
                CrmiQuadrature::Cdf if n_edges > 0 => tail_difference(tail(0), tail(n_edges - 1)),
                _ => normal_cdf((z_max - dl) / sig) - normal_cdf(-dl / sig),
            };
            for q in lo..=hi {
                let (a, b) = (self.edges[q], self.edges[q + 1]);
                let mut v = 0.0;
                if n_edges > 0 && q >= q_lo && q <= q_hi && z_norm > 0.0 {
                    let mass = match cfg.quadrature {
                        CrmiQuadrature::Cdf => tail_difference(tail(q - q_lo), tail(q + 1 - q_lo)),
                        CrmiQuadrature::Midpoint => midpoint_hit_mass(a, b, dl, sig),
                    };
                    v += w_h * mass.max(0.0) / z_norm;
                }
                if w_s > 0.0 && short_norm > 0.0 {
                    v += w_s * short_mass(cfg.quadrature, a, b, dl, lam) / short_norm;
                }
                if w_r > 0.0 {
                    v += w_r * (b - a) / z_max;
                }
                row[q] = v;
            }
            row[q_n] = w_x;
        }
        let short_norm = -(-lam * z_max).exp_m1();
        for q in 0..q_n {
            let (a, b) = (self.edges[q], self.edges[q + 1]);
            let mut v = w_r * (b - a) / z_max;
            if w_s > 0.0 {
                v += w_s * short_mass(cfg.quadrature, a, b, z_max, lam) / short_norm;
            }
            self.like_inf[q] = v;
        }
        self.like_inf[q_n] = w_h + w_x;
    }
}

/// Midpoint-rule stand-in for the mass of N(d, σ²) in [a, b): density at the centre × width.
#[inline]
fn midpoint_hit_mass(a: f64, b: f64, d: f64, sig: f64) -> f64 {
    let u = (0.5 * (a + b) - d) / sig;
    (-0.5 * u * u).exp() / (sig * (2.0 * std::f64::consts::PI).sqrt()) * (b - a)
}

/// Unnormalised short-reading mass λ∫ e^{−λz} over [a, min(b, d)) (or its midpoint stand-in).
#[inline]
fn short_mass(quad: CrmiQuadrature, a: f64, b: f64, d: f64, lam: f64) -> f64 {
    match quad {
        CrmiQuadrature::Cdf => ((-lam * a).exp() - (-lam * b.min(d)).exp()).max(0.0),
        CrmiQuadrature::Midpoint => {
            let c = 0.5 * (a + b);
            if c > d {
                0.0
            } else {
                lam * (-lam * c).exp() * (b - a)
            }
        }
    }
}

/// The bin masses of the channel for cells at distances `d` (m): (ℓ_l(q) per cell, each Q + 1
/// long with the atom last; ℓ_∞(q)).
pub fn channel_masses(cfg: &CrmiConfig, d: &[f64]) -> Result<(Vec<Vec<f64>>, Vec<f64>)> {
    cfg.validate()?;
    let mut ch = BeamChannel::default();
    ch.build(cfg, d);
    let w = cfg.n_bins() + 1;
    Ok((
        (0..d.len())
            .map(|l| ch.like[l * w..(l + 1) * w].to_vec())
            .collect(),
        ch.like_inf,
    ))
}

/// Everything the exact channel implies for one beam (crm-spec 5.2 steps 1–2).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BeamPosteriors {
    /// P(q), Q + 1 entries (the atom last); renormalised in the midpoint quadrature.
    pub bin_probability: Vec<f64>,
    /// p'^l(q): for bin q, the N × K posteriors (row-major).
    pub posteriors: Vec<Vec<f64>>,
}

/// Per-bin predictive probabilities and posteriors of one beam whose cells (in ray order, at
/// chord-midpoint distances `d`, m) hold the pmfs `beliefs` (N × K row-major, normalised) over
/// the levels `mu`. The unpooled reference of the pose evaluation.
pub fn beam_posteriors(
    cfg: &CrmiConfig,
    mu: &[f64],
    beliefs: &[f64],
    d: &[f64],
) -> Result<BeamPosteriors> {
    cfg.validate()?;
    let k = mu.len();
    let n = d.len();
    if beliefs.len() != n * k {
        return Err(crate::error::CrlamError::Shape(format!(
            "{} belief entries for {n} cells of {k} levels",
            beliefs.len()
        )));
    }
    let mut ch = BeamChannel::default();
    ch.build(cfg, d);
    let q_n = cfg.n_bins();
    let mhat: Vec<f64> = (0..n)
        .map(|l| (0..k).map(|i| mu[i] * beliefs[l * k + i]).sum())
        .collect();
    let mut out = BeamPosteriors::default();
    let mut col = vec![0.0; n];
    let mut alpha = vec![0.0; n];
    let mut s = Vec::new();
    for q in 0..=q_n {
        for l in 0..n {
            col[l] = ch.like[l * (q_n + 1) + q];
        }
        let eta = sweep(&mhat, &col, ch.like_inf[q], &mut s, &mut alpha);
        let mut post = vec![0.0; n * k];
        for l in 0..n {
            let p = &beliefs[l * k..(l + 1) * k];
            posterior(p, mu, alpha[l], mhat[l], &mut post[l * k..(l + 1) * k]);
        }
        out.bin_probability.push(eta.max(0.0));
        out.posteriors.push(post);
    }
    if cfg.quadrature == CrmiQuadrature::Midpoint {
        let total: f64 = out.bin_probability.iter().sum();
        if total > 0.0 {
            out.bin_probability.iter_mut().for_each(|p| *p /= total);
        }
    }
    Ok(out)
}

/// Per-cell MI (nats, ray order) of one beam from [`beam_posteriors`]:
/// I_l = H(p^l) − Σ_q P(q) H(p'^l(q)), clipped at 0 in the midpoint quadrature.
pub fn beam_crmi(cfg: &CrmiConfig, mu: &[f64], beliefs: &[f64], d: &[f64]) -> Result<Vec<f64>> {
    let bp = beam_posteriors(cfg, mu, beliefs, d)?;
    let k = mu.len();
    Ok((0..d.len())
        .map(|l| {
            let prior = crate::info::entropy_nats(&beliefs[l * k..(l + 1) * k]);
            let expected: f64 = bp
                .bin_probability
                .iter()
                .zip(&bp.posteriors)
                .map(|(pq, post)| pq * crate::info::entropy_nats(&post[l * k..(l + 1) * k]))
                .sum();
            let i = prior - expected;
            if cfg.quadrature == CrmiQuadrature::Midpoint {
                i.max(0.0)
            } else {
                i
            }
        })
        .collect())
}

/// Backward sweep with the log-space fallback; returns η and fills α.
#[inline]
pub(crate) fn sweep(
    mhat: &[f64],
    like: &[f64],
    like_inf: f64,
    s: &mut Vec<f64>,
    alpha: &mut [f64],
) -> f64 {
    let eta = cause_sweep(mhat, like, like_inf, s, Some(alpha));
    if eta >= LINEAR_ETA_MIN || eta == 0.0 && like.iter().all(|&x| x == 0.0) && like_inf == 0.0 {
        return eta;
    }
    let ll: Vec<f64> = like.iter().map(|x| x.ln()).collect();
    cause_sweep_log(mhat, &ll, like_inf.ln(), s, Some(alpha)).exp()
}

/// p' = p ⊙ (1 + α(μ − m̂)), factors clipped at 0, renormalised (crm-spec 5.2 step 2).
#[inline]
pub(crate) fn posterior(p: &[f64], mu: &[f64], alpha: f64, mhat: f64, out: &mut [f64]) {
    let mut sum = 0.0;
    for i in 0..p.len() {
        out[i] = p[i] * (1.0 + alpha * (mu[i] - mhat)).max(0.0);
        sum += out[i];
    }
    if sum > 0.0 {
        let inv = 1.0 / sum;
        out.iter_mut().for_each(|x| *x *= inv);
    } else {
        out.copy_from_slice(p);
    }
}
