//! CRMI: the expected information gain of a virtual scan about the CRM cells it crosses, by the
//! exact discrete channel of crm-spec 5.2.
//!
//! A beam's reading is discretised into Q = ⌈z_max/λ_z⌉ range bins plus the no-return atom; each
//! cause's bin masses come from CDFs, so the channel is exactly normalised. For every bin the
//! backward sweep of the map update gives the bin's predictive probability P(q) = η and each
//! cell's update coefficient α_l(q); the cell's MI is H(p) − Σ_q P(q) H(p ⊙ (1 + α(μ − m̂))).
//!
//! With the pure-hit (`ijrr`) model most (cell, bin) pairs need no entropy: a bin whose Gaussian
//! support lies wholly beyond cell l leaves it the constant "seen free" posterior
//! p ⊙ (1 − μ)/(1 − m̂) (α = −1/(1 − m̂)), and a bin wholly before cell l leaves it unchanged (α = 0).
//! Those bins are pooled, which makes the cost O(N · bins-per-support · K) instead of O(N Q K)
//! with the same result. The hit Gaussian is cut at ±[`SUPPORT_SIGMAS`] σ and its mass
//! renormalised over the bins it covers (the moved tail mass is 2e-9), so that the pooled bins
//! carry exactly zero hit likelihood and the channel stays exactly normalised.

use crate::crm::update::{cause_sweep, cause_sweep_log, LINEAR_ETA_MIN};
use crate::crm::CrmMap;
use crate::error::{config_err, Result};
use crate::grid::check_pose;
use crate::info::fastmath::{ln_normal, normal_tail, tail_difference};
use crate::info::lattice::BeamAngles;
use crate::info::{Candidate, Evaluation, InfoUnits, InformationFunction};
use crate::raycast::traverse_with;
use crate::sensor::{normal_cdf, SensorModel, SensorModelKind};

/// The hit Gaussian is cut at ± this many σ (tail mass 2e-9) and renormalised over its support.
pub const SUPPORT_SIGMAS: f64 = 6.0;

/// How bin masses are computed from the sensor densities.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CrmiQuadrature {
    /// Exact CDF differences (default; crm-spec 5.2).
    Cdf,
    /// Density at the bin centre × bin width, P(q) renormalised, I clipped at 0 (parity with a
    /// midpoint rule; mis-normalised for σ ≲ λ_z/2, crm-spec 5.2).
    Midpoint,
}

impl CrmiQuadrature {
    /// Parses `"cdf" | "midpoint"`.
    pub fn parse(name: &str) -> Result<Self> {
        match name {
            "cdf" | "exact" => Ok(Self::Cdf),
            "midpoint" => Ok(Self::Midpoint),
            other => Err(config_err(
                "crmi_quadrature",
                format!("unknown quadrature {other:?}; expected cdf or midpoint"),
            )),
        }
    }

    pub fn name(&self) -> &'static str {
        match self {
            Self::Cdf => "cdf",
            Self::Midpoint => "midpoint",
        }
    }
}

/// How a cell crossed by several beams of one candidate counts (crm-spec 5.2).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CellDedupe {
    /// Once per beam (R3's Eq. 3; default).
    Sum,
    /// The largest per-beam value only (ablation).
    Max,
}

impl CellDedupe {
    /// Parses `"sum" | "max"`.
    pub fn parse(name: &str) -> Result<Self> {
        match name {
            "sum" => Ok(Self::Sum),
            "max" => Ok(Self::Max),
            other => Err(config_err(
                "dedupe_cells",
                format!("unknown rule {other:?}; expected sum or max"),
            )),
        }
    }

    pub fn name(&self) -> &'static str {
        match self {
            Self::Sum => "sum",
            Self::Max => "max",
        }
    }
}

/// Settings of CRMI at a candidate pose.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CrmiConfig {
    /// The model that updates the map (`ijrr` or `mixture`); its z_max is the beam length.
    pub model: SensorModel,
    /// Beams per candidate (n_z = 10 in the paper).
    pub n_beams: usize,
    pub beam_angles: BeamAngles,
    /// Range bin width λ_z (m).
    pub lambda_z: f64,
    pub quadrature: CrmiQuadrature,
    pub dedupe: CellDedupe,
    pub units: InfoUnits,
    /// The virtual scan of the map mutation hits the first cell whose mean exceeds this.
    pub hit_threshold: f64,
}

impl CrmiConfig {
    /// The spec's defaults (ijrr, 10 distinct beams, λ_z = 0.1 m, CDF bins, bits) for a grid of
    /// resolution `resolution` (m) and a sensor range `z_max` (m).
    pub fn new(z_max: f64, resolution: f64) -> Self {
        Self {
            model: SensorModel::with_defaults(SensorModelKind::Ijrr, z_max, resolution),
            n_beams: 10,
            beam_angles: BeamAngles::Distinct,
            lambda_z: 0.1,
            quadrature: CrmiQuadrature::Cdf,
            dedupe: CellDedupe::Sum,
            units: InfoUnits::Bits,
            hit_threshold: 0.5,
        }
    }

    pub fn validate(&self) -> Result<()> {
        self.model.validate()?;
        if self.model.kind == SensorModelKind::AuthorsCode {
            return Err(config_err(
                "model",
                "CRMI needs a proper channel: use ijrr or mixture (authors_code is not normalised)",
            ));
        }
        if self.n_beams == 0 || self.n_beams > 100_000 {
            return Err(config_err(
                "n_beams",
                format!("must be in [1, 100000], got {}", self.n_beams),
            ));
        }
        let bins = self.model.z_max / self.lambda_z;
        if !(self.lambda_z.is_finite() && self.lambda_z > 0.0 && bins <= 1e6) {
            return Err(config_err(
                "lambda_z",
                format!(
                    "must be > 0 with at most 1e6 bins up to z_max, got {}",
                    self.lambda_z
                ),
            ));
        }
        if !(self.hit_threshold > 0.0 && self.hit_threshold < 1.0) {
            return Err(config_err(
                "hit_threshold",
                format!("must be in (0, 1), got {}", self.hit_threshold),
            ));
        }
        Ok(())
    }

    /// Number of range bins Q (the atom is bin Q).
    pub fn n_bins(&self) -> usize {
        (self.model.z_max / self.lambda_z - 1e-9).ceil().max(1.0) as usize
    }
}

/// The discretised channel of one beam: bin edges and each cause's bin masses.
#[derive(Debug, Default)]
pub struct BeamChannel {
    /// Bin edges z_0 = 0 < … < z_Q = z_max.
    edges: Vec<f64>,
    /// ℓ_l(q), row l (N × (Q + 1), the atom last).
    like: Vec<f64>,
    /// ℓ_∞(q), Q + 1 entries.
    like_inf: Vec<f64>,
    /// First and last bin (< Q) with ℓ_l(q) > 0 per cell for the pooled `ijrr` path.
    support: Vec<(usize, usize)>,
    /// Per-edge CDF of the current cell: (upper tail?, value).
    tails: Vec<(bool, f64)>,
}

/// Per-beam scratch buffers.
#[derive(Debug, Default)]
pub struct CrmiScratch {
    channel: BeamChannel,
    probs: Vec<f64>,
    log_p: Vec<f64>,
    mhat: Vec<f64>,
    h: Vec<f64>,
    exp_h: Vec<f64>,
    col: Vec<f64>,
    alpha: Vec<f64>,
    s: Vec<f64>,
    s2: Vec<f64>,
    reach: Vec<f64>,
    p_free: Vec<f64>,
    p_same: Vec<f64>,
    dist: Vec<f64>,
    cells: Vec<(i64, i64)>,
    per_cell: Vec<f64>,
    pose_cells: Vec<((i64, i64), f64)>,
}

impl BeamChannel {
    /// Fills the channel for cells at distances `d` (m) along the beam.
    fn build(&mut self, cfg: &CrmiConfig, d: &[f64]) {
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
        for (l, &dl) in d.iter().enumerate() {
            let row = &mut self.like[l * (q_n + 1)..(l + 1) * (q_n + 1)];
            // Bins that can carry hit mass: within SUPPORT_SIGMAS of d_l.
            let reach = SUPPORT_SIGMAS * sig;
            let q_lo = (((dl - reach) / cfg.lambda_z).floor().max(0.0) as usize).min(q_n - 1);
            let q_hi = (((dl + reach) / cfg.lambda_z).floor().max(0.0) as usize).min(q_n - 1);
            let short_norm = -(-lam * dl).exp_m1();
            let (lo, hi) = if pure_hit { (q_lo, q_hi) } else { (0, q_n - 1) };
            // Tail-aware CDF at each edge of the hit support, computed once per edge.
            self.tails.clear();
            if w_h > 0.0 {
                for e in q_lo..=q_hi + 1 {
                    let u = (self.edges[e] - dl) / sig;
                    self.tails.push(normal_tail(u));
                }
            }
            // Normaliser: the Gaussian mass over the support bins (which lie inside [0, z_max],
            // so this also truncates at the range limits); the midpoint rule uses Z_h(d).
            let z_norm = match (self.tails.first(), self.tails.last(), cfg.quadrature) {
                (Some(&a), Some(&b), CrmiQuadrature::Cdf) => tail_difference(a, b),
                _ => normal_cdf((z_max - dl) / sig) - normal_cdf(-dl / sig),
            };
            for q in lo..=hi {
                let (a, b) = (self.edges[q], self.edges[q + 1]);
                let mut v = 0.0;
                if !self.tails.is_empty() && q >= q_lo && q <= q_hi && z_norm > 0.0 {
                    let mass = match cfg.quadrature {
                        CrmiQuadrature::Cdf => {
                            tail_difference(self.tails[q - q_lo], self.tails[q + 1 - q_lo])
                        }
                        CrmiQuadrature::Midpoint => midpoint_hit_mass(a, b, dl, sig),
                    };
                    v += w_h * mass.max(0.0) / z_norm;
                }
                if w_s > 0.0 && short_norm > 0.0 {
                    v += w_s * short_mass(cfg.quadrature, a, b, dl, lam) / short_norm;
                }
                v += w_r * (b - a) / z_max;
                row[q] = v;
            }
            row[q_n] = w_x;
            self.support.push((q_lo, q_hi));
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
fn sweep(mhat: &[f64], like: &[f64], like_inf: f64, s: &mut Vec<f64>, alpha: &mut [f64]) -> f64 {
    let eta = cause_sweep(mhat, like, like_inf, s, Some(alpha));
    if eta >= LINEAR_ETA_MIN || eta == 0.0 && like.iter().all(|&x| x == 0.0) && like_inf == 0.0 {
        return eta;
    }
    let ll: Vec<f64> = like.iter().map(|x| x.ln()).collect();
    cause_sweep_log(mhat, &ll, like_inf.ln(), s, Some(alpha)).exp()
}

/// p' = p ⊙ (1 + α(μ − m̂)), factors clipped at 0, renormalised (crm-spec 5.2 step 2).
#[inline]
fn posterior(p: &[f64], mu: &[f64], alpha: f64, mhat: f64, out: &mut [f64]) {
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

/// Levels processed per block by [`posterior_entropy`] (K may be larger: blocks repeat).
const LEVEL_BLOCK: usize = 16;

/// Entropy (nats) of p ⊙ f / Σ given log p, with f_i = 1 + α(μ_i − m̂) clipped at 0. Written
/// branch-free over blocks of levels so that the compiler can vectorise the logarithms.
#[inline]
fn posterior_entropy(p: &[f64], log_p: &[f64], mu: &[f64], alpha: f64, mhat: f64) -> f64 {
    let mut sum = 0.0;
    let mut acc = 0.0;
    let mut f = [1.0f64; LEVEL_BLOCK];
    for start in (0..p.len()).step_by(LEVEL_BLOCK) {
        let len = (p.len() - start).min(LEVEL_BLOCK);
        let (pb, lb, mb) = (
            &p[start..start + len],
            &log_p[start..start + len],
            &mu[start..start + len],
        );
        for i in 0..len {
            f[i] = (1.0 + alpha * (mb[i] - mhat)).max(0.0);
        }
        let mut lf = [0.0f64; LEVEL_BLOCK];
        for i in 0..len {
            // A clipped factor has zero weight; its log only needs to be finite.
            lf[i] = ln_normal(f[i].max(f64::MIN_POSITIVE));
        }
        for i in 0..len {
            let w = pb[i] * f[i];
            sum += w;
            acc += w * (lb[i] + lf[i]);
        }
    }
    if sum > 0.0 {
        sum.ln() - acc / sum
    } else {
        0.0
    }
}

/// Pooled per-cell MI (nats) of one beam into `sc.per_cell`, from `sc.probs` (N × K), `sc.dist`.
fn beam_crmi_pooled(cfg: &CrmiConfig, mu: &[f64], sc: &mut CrmiScratch) {
    let k = mu.len();
    let n = sc.dist.len();
    sc.channel.build(cfg, &sc.dist);
    let q_n = cfg.n_bins();
    let pure_hit = cfg.model.kind == SensorModelKind::Ijrr;
    let ch = &sc.channel;
    sc.mhat.clear();
    sc.h.clear();
    sc.log_p.clear();
    sc.reach.clear();
    let mut reach = 1.0;
    for l in 0..n {
        let p = &sc.probs[l * k..(l + 1) * k];
        let m: f64 = (0..k).map(|i| mu[i] * p[i]).sum();
        sc.mhat.push(m);
        sc.reach.push(reach);
        reach *= 1.0 - m;
        let mut h = 0.0;
        for &x in p {
            let lx = if x > 0.0 { x.ln() } else { 0.0 };
            h -= x * lx;
            sc.log_p.push(lx);
        }
        sc.h.push(h);
    }
    sc.exp_h.clear();
    sc.exp_h.resize(n, 0.0);
    sc.p_free.clear();
    sc.p_free.resize(n + 1, 0.0);
    sc.p_same.clear();
    sc.p_same.resize(n + 1, 0.0);
    sc.col.resize(n, 0.0);
    sc.alpha.resize(n, 0.0);
    sc.s.resize(n, 0.0);
    let mut total = 0.0;
    let (mut lo, mut hi) = (0usize, 0usize);
    for q in 0..=q_n {
        let w = q_n + 1;
        let (first, last) = if pure_hit && q < q_n {
            // Cells whose hit support contains bin q: a window that only moves forward with q.
            while lo < n && ch.support[lo].1 < q {
                lo += 1;
            }
            hi = hi.max(lo);
            while hi < n && ch.support[hi].0 <= q {
                hi += 1;
            }
            if lo >= hi {
                continue; // no cause can give this bin: P(q) = 0
            }
            // Only the window has likelihood; before it the beam passes, after it nothing
            // returns (ℓ_∞(q) = 0 below the atom), so the sweep starts at 0 after the window.
            let mut s_acc = 0.0;
            for l in (lo..hi).rev() {
                sc.s[l] = s_acc;
                let m = sc.mhat[l];
                s_acc = m * ch.like[l * w + q] + (1.0 - m) * s_acc;
            }
            let eta = sc.reach[lo] * s_acc;
            if eta >= LINEAR_ETA_MIN {
                let inv = 1.0 / eta;
                for l in lo..hi {
                    sc.alpha[l] = sc.reach[l] * (ch.like[l * w + q] - sc.s[l]) * inv;
                }
                total += eta;
                sc.p_free[lo] += eta;
                sc.p_same[hi] += eta;
                for l in lo..hi {
                    let p = &sc.probs[l * k..(l + 1) * k];
                    let lp = &sc.log_p[l * k..(l + 1) * k];
                    sc.exp_h[l] += eta * posterior_entropy(p, lp, mu, sc.alpha[l], sc.mhat[l]);
                }
                continue;
            }
            // Underflow: the generic sweep below has the log-space fallback.
            (lo, hi)
        } else {
            (0, n)
        };
        for l in 0..n {
            sc.col[l] = ch.like[l * w + q];
        }
        let eta = sweep(&sc.mhat, &sc.col, ch.like_inf[q], &mut sc.s2, &mut sc.alpha);
        if eta.is_nan() || eta <= 0.0 {
            continue;
        }
        total += eta;
        if pure_hit && q < q_n {
            sc.p_free[first] += eta;
            sc.p_same[last] += eta;
        }
        let range = if pure_hit && q < q_n {
            first..last
        } else {
            0..n
        };
        for l in range {
            let p = &sc.probs[l * k..(l + 1) * k];
            let lp = &sc.log_p[l * k..(l + 1) * k];
            sc.exp_h[l] += eta * posterior_entropy(p, lp, mu, sc.alpha[l], sc.mhat[l]);
        }
    }
    // Cell l sees "free" from every bin whose window starts after l and is untouched by every
    // bin whose window ends at or before l: suffix and prefix sums of the per-bin masses.
    if pure_hit {
        let mut acc = 0.0;
        for l in (0..n).rev() {
            acc += sc.p_free[l + 1];
            sc.p_free[l + 1] = acc;
        }
        let mut acc = 0.0;
        for l in 0..=n {
            acc += sc.p_same[l];
            sc.p_same[l] = acc;
        }
    }
    let renorm = if cfg.quadrature == CrmiQuadrature::Midpoint && total > 0.0 {
        1.0 / total
    } else {
        1.0
    };
    sc.per_cell.clear();
    for l in 0..n {
        let mut e = sc.exp_h[l];
        if pure_hit {
            let pf = sc.p_free[l + 1];
            if pf > 0.0 {
                let p = &sc.probs[l * k..(l + 1) * k];
                let lp = &sc.log_p[l * k..(l + 1) * k];
                let a = -1.0 / (1.0 - sc.mhat[l]).max(1e-300);
                e += pf * posterior_entropy(p, lp, mu, a, sc.mhat[l]);
            }
            e += sc.p_same[l] * sc.h[l];
        }
        let mut i = sc.h[l] - renorm * e;
        if cfg.quadrature == CrmiQuadrature::Midpoint {
            i = i.max(0.0);
        }
        sc.per_cell.push(i);
    }
}

/// The virtual scan a candidate records on commit: the most likely reading of each beam (the
/// first cell whose mean exceeds the threshold, else a no-return), at the candidate's pose.
#[derive(Clone, Debug, PartialEq)]
pub struct VirtualScan {
    pub pose: [f64; 3],
    /// Beam angles relative to the pose heading (rad).
    pub angles: Vec<f64>,
    /// Ranges (m); z_max for no-returns.
    pub ranges: Vec<f64>,
}

/// CRMI of candidate poses on a [`CrmMap`].
#[derive(Clone, Debug)]
pub struct Crmi {
    cfg: CrmiConfig,
}

impl Crmi {
    pub fn new(cfg: CrmiConfig) -> Result<Self> {
        cfg.validate()?;
        Ok(Self { cfg })
    }

    pub fn config(&self) -> &CrmiConfig {
        &self.cfg
    }

    /// World-frame beam angles at a candidate.
    pub fn beam_angles(&self, pose: [f64; 3]) -> Vec<f64> {
        self.cfg.beam_angles.angles(self.cfg.n_beams, pose[2])
    }

    /// CRMI (in the configured units) at `pose`, using `sc` for buffers.
    pub fn gain_with(&self, map: &CrmMap, pose: [f64; 3], sc: &mut CrmiScratch) -> Result<f64> {
        check_pose(pose)?;
        let mu = map.levels();
        let k = mu.len();
        let g = *map.geometry();
        let ext = map.grid().fixed_extent();
        sc.pose_cells.clear();
        let mut total = 0.0;
        for angle in self.beam_angles(pose) {
            sc.cells.clear();
            sc.dist.clear();
            let (cells, dist) = (&mut sc.cells, &mut sc.dist);
            traverse_with(
                &g,
                [pose[0], pose[1]],
                angle,
                self.cfg.model.z_max,
                ext.as_ref(),
                |c| {
                    cells.push((c.ix, c.iy));
                    dist.push(c.mid());
                    true
                },
            );
            sc.probs.clear();
            for &(ix, iy) in sc.cells.iter() {
                let p = map.cell(ix, iy);
                let s: f64 = p.iter().map(|&x| x as f64).sum();
                sc.probs.extend(p.iter().map(|&x| x as f64 / s));
            }
            debug_assert_eq!(sc.probs.len(), sc.cells.len() * k);
            beam_crmi_pooled(&self.cfg, mu, sc);
            match self.cfg.dedupe {
                CellDedupe::Sum => total += sc.per_cell.iter().sum::<f64>(),
                CellDedupe::Max => sc
                    .pose_cells
                    .extend(sc.cells.iter().copied().zip(sc.per_cell.iter().copied())),
            }
        }
        if self.cfg.dedupe == CellDedupe::Max {
            sc.pose_cells
                .sort_by(|a, b| a.0.cmp(&b.0).then(b.1.total_cmp(&a.1)));
            sc.pose_cells.dedup_by(|a, b| a.0 == b.0);
            total = sc.pose_cells.iter().map(|c| c.1).sum();
        }
        Ok(match self.cfg.units {
            InfoUnits::Nats => total,
            InfoUnits::Bits => total / std::f64::consts::LN_2,
        })
    }

    /// The most likely scan at `pose` on the current map (see [`VirtualScan`]).
    pub fn virtual_scan(&self, map: &CrmMap, pose: [f64; 3]) -> VirtualScan {
        virtual_scan(
            map,
            pose,
            &self.beam_angles(pose),
            self.cfg.model.z_max,
            self.cfg.hit_threshold,
        )
    }
}

/// Casts the beams (world-frame `angles`) from `pose` against the map's mean: a beam returns the
/// chord midpoint of the first cell whose mean exceeds `threshold`, else z_max (a no-return).
pub fn virtual_scan(
    map: &CrmMap,
    pose: [f64; 3],
    angles: &[f64],
    z_max: f64,
    threshold: f64,
) -> VirtualScan {
    let g = *map.geometry();
    let ext = map.grid().fixed_extent();
    let ranges = angles
        .iter()
        .map(|&a| {
            let mut r = z_max;
            traverse_with(&g, [pose[0], pose[1]], a, z_max, ext.as_ref(), |c| {
                if map.mean_at(c.ix, c.iy) > threshold {
                    r = c.mid().min(z_max);
                    false
                } else {
                    true
                }
            });
            r
        })
        .collect();
    VirtualScan {
        pose,
        angles: angles.iter().map(|a| a - pose[2]).collect(),
        ranges,
    }
}

impl InformationFunction for Crmi {
    type Map = CrmMap;
    type Belief = ();
    type Update = VirtualScan;

    fn name(&self) -> &'static str {
        "crmi"
    }

    fn units(&self) -> InfoUnits {
        self.cfg.units
    }

    fn evaluate(
        &self,
        map: &CrmMap,
        _parent: &(),
        candidate: &Candidate,
        _seed: u64,
    ) -> Result<Evaluation<(), VirtualScan>> {
        let mut sc = CrmiScratch::default();
        let gain = self.gain_with(map, candidate.pose, &mut sc)?;
        Ok(Evaluation {
            gain,
            belief: (),
            update: self.virtual_scan(map, candidate.pose),
        })
    }

    fn commit(&self, map: &mut CrmMap, update: &VirtualScan) -> Result<()> {
        commit_virtual_scan(map, update, &self.cfg.model)
    }
}

/// Applies a virtual scan to the map with `model` (the map mutation of planner-spec 3.5).
pub fn commit_virtual_scan(
    map: &mut CrmMap,
    scan: &VirtualScan,
    model: &SensorModel,
) -> Result<()> {
    let mut sc = crate::crm::CrmScratch::default();
    map.update_scan(
        scan.pose,
        &scan.angles,
        &scan.ranges,
        model,
        &crate::crm::ScanOptions::default(),
        &mut sc,
    )?;
    Ok(())
}
