//! The discretised range channel of one CRMI beam (crm-spec 5.2): CDF bin masses per cause,
//! and the unpooled reference computation of the bin probabilities, posteriors and per-cell MI
//! that the pooled pose evaluation in [`crate::info::crmi`] must reproduce.

use crate::crm::update::{cause_sweep, cause_sweep_log, LINEAR_ETA_MIN};
use crate::error::Result;
use crate::info::crmi::{CrmiConfig, CrmiQuadrature, SUPPORT_SIGMAS};
use crate::info::fastmath::{ln_normal, lower_tail_abs_slice, tail_difference};
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
    /// their [`crate::info::fastmath::normal_tail`] (whose flag is u > 0).
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

/// KL(p' ‖ p) (nats) of the posterior p' = p ⊙ f / s, with f_i = max(1 + α(μ_i − m̂), 0) and
/// s = Σ_i p_i f_i: Σ_i p_i f_i ln f_i / s − ln s. A bin's posterior never needs ln p. The scalar
/// definition that [`KlBatch`] reproduces bit for bit (tested).
#[cfg(test)]
fn posterior_kl(p: &[f64], mu: &[f64], alpha: f64, mhat: f64) -> f64 {
    let (mut s, mut g) = (0.0, 0.0);
    for (&pi, &m) in p.iter().zip(mu) {
        kl_level_step(m, alpha, mhat, pi, &mut s, &mut g);
    }
    kl_from_sums(s, g)
}

/// Σ_i p_i f_i ln f_i / s − ln s. For a proper likelihood ratio s = 1 up to rounding, so ln s is
/// a series (exact to 1e-20 there); 0 when the posterior vanishes.
#[inline]
fn kl_from_sums(s: f64, g: f64) -> f64 {
    if s <= 0.0 {
        return 0.0;
    }
    let d = s - 1.0;
    if d.abs() < 1e-5 {
        // Series of g/s and ln s to third order (error < 1e-20 relative): no division.
        g * (1.0 - d * (1.0 - d * (1.0 - d))) - d * (1.0 - d * (0.5 - d * (1.0 / 3.0)))
    } else {
        g / s - s.ln()
    }
}

/// One queued (cell, bin) posterior: its coefficient α, the cell's mean m̂, the weight its KL
/// is added with, and the cell (its pmf starts at `cell · K`). 32 bytes, so that the eight-lane
/// kernel reads a field of eight jobs with one gather.
#[derive(Clone, Copy, Debug)]
#[repr(C)]
pub(crate) struct KlJob {
    alpha: f64,
    mhat: f64,
    weight: f64,
    cell: usize,
}

/// KL divergences of many (cell, bin) posteriors of one beam from their priors, evaluated
/// together: every pair adds its K terms in level order with the operations of
/// [`posterior_kl`] (equal to it bit for bit), but eight pairs at a time with explicit AVX-512
/// (the fields and pmf entries gathered, the sums kept in registers), or level by level over all
/// pairs so that each step vectorises four wide with AVX2.
#[derive(Debug, Default)]
pub(crate) struct KlBatch {
    jobs: Vec<KlJob>,
    /// Where the jobs of the open writer start.
    open_at: usize,
    /// Per job: KL of its posterior, filled by [`KlBatch::flush`].
    kl: Vec<f64>,
    /// Level-by-level path: the jobs' α, m̂, pmf entries of one level and running sums.
    alpha: Vec<f64>,
    mhat: Vec<f64>,
    p_level: Vec<f64>,
    s: Vec<f64>,
    g: Vec<f64>,
}

/// Up to a known number of jobs written into a batch: `push` keeps its count in a register
/// (a `Vec::push` per job would chain every job through the vector's length in memory).
pub(crate) struct KlJobWriter<'a> {
    slots: &'a mut [KlJob],
    used: usize,
}

impl KlJobWriter<'_> {
    /// Queues the posterior of `cell` (mean `mhat`) under coefficient `alpha`; it adds
    /// `weight` · KL to `out[cell]` on flush. Panics past the capacity it was opened with.
    #[inline]
    pub(crate) fn push(&mut self, cell: usize, weight: f64, alpha: f64, mhat: f64) {
        self.slots[self.used] = KlJob {
            alpha,
            mhat,
            weight,
            cell,
        };
        self.used += 1;
    }

    /// The number of jobs written (to pass to [`KlBatch::close`]).
    pub(crate) fn used(&self) -> usize {
        self.used
    }
}

impl KlBatch {
    /// Queues the posterior of `cell` (mean `mhat`) under coefficient `alpha`; it adds
    /// `weight` · KL to `out[cell]` on flush.
    #[cfg(test)]
    fn push(&mut self, cell: usize, weight: f64, alpha: f64, mhat: f64) {
        let mut w = self.open(1);
        w.push(cell, weight, alpha, mhat);
        let used = w.used();
        self.close(used);
    }

    /// Room for `capacity` more jobs; write them with the writer, then [`KlBatch::close`] with
    /// its count.
    pub(crate) fn open(&mut self, capacity: usize) -> KlJobWriter<'_> {
        let start = self.jobs.len();
        let blank = KlJob {
            alpha: 0.0,
            mhat: 0.0,
            weight: 0.0,
            cell: 0,
        };
        self.jobs.resize(start + capacity, blank);
        self.open_at = start;
        KlJobWriter {
            slots: &mut self.jobs[start..],
            used: 0,
        }
    }

    /// Keeps the `used` jobs written since [`KlBatch::open`].
    pub(crate) fn close(&mut self, used: usize) {
        self.jobs.truncate(self.open_at + used);
    }

    /// Adds weight · KL of every queued pair to `out[cell]` (in queue order) and empties the
    /// queue. `probs` holds the cells' pmfs (N × K) over the levels `mu`.
    pub(crate) fn flush(&mut self, probs: &[f64], mu: &[f64], out: &mut [f64]) {
        let n = self.jobs.len();
        self.kl.clear();
        self.kl.resize(n, 0.0);
        #[cfg(target_arch = "x86_64")]
        if crate::info::fastlog::has_avx512() {
            let k = mu.len();
            assert!(self.jobs.iter().all(|j| (j.cell + 1) * k <= probs.len()));
            // SAFETY: AVX-512F is there (checked), and every cell's K entries are in `probs`.
            unsafe { kl_jobs_wide(probs, mu, &self.jobs, &mut self.kl) };
        } else {
            self.level_by_level(probs, mu);
        }
        #[cfg(not(target_arch = "x86_64"))]
        self.level_by_level(probs, mu);
        for (job, kl) in self.jobs.iter().zip(&self.kl) {
            out[job.cell] += job.weight * kl;
        }
        self.jobs.clear();
    }

    /// `self.kl` by sweeping the levels over all jobs (each step vectorises).
    fn level_by_level(&mut self, probs: &[f64], mu: &[f64]) {
        let k = mu.len();
        let n = self.jobs.len();
        self.alpha.clear();
        self.alpha.extend(self.jobs.iter().map(|j| j.alpha));
        self.mhat.clear();
        self.mhat.extend(self.jobs.iter().map(|j| j.mhat));
        self.s.clear();
        self.s.resize(n, 0.0);
        self.g.clear();
        self.g.resize(n, 0.0);
        self.p_level.resize(n, 0.0);
        for (i, &m) in mu.iter().enumerate() {
            for (pl, job) in self.p_level.iter_mut().zip(&self.jobs) {
                *pl = probs[job.cell * k + i];
            }
            kl_level_sums(
                m,
                &self.alpha,
                &self.mhat,
                &self.p_level,
                &mut self.s,
                &mut self.g,
            );
        }
        for j in 0..n {
            self.kl[j] = kl_from_sums(self.s[j], self.g[j]);
        }
    }
}

/// One level's term of a posterior's divergence sums: with the factor f = max(1 + α(μ − m̂), 0)
/// and w = p f, s += w and g += w ln f (the log of max(f, MIN_POSITIVE): a clipped factor has
/// zero weight, its log only needs to be finite).
#[inline(always)]
fn kl_level_step(mu: f64, alpha: f64, mhat: f64, p: f64, s: &mut f64, g: &mut f64) {
    let f = (1.0 + alpha * (mu - mhat)).max(0.0);
    let w = p * f;
    *s += w;
    *g += w * ln_normal(f.max(f64::MIN_POSITIVE));
}

crate::info::fastmath::simd_by_target! {
    /// [`kl_level_step`] of level `mu` for every pair j (α_j, m̂_j, p_j), into the pair's sums.
    kl_level_sums, kl_level_sums_avx2, kl_level_sums_body,
    (mu: f64, alpha: &[f64], mhat: &[f64], p: &[f64], s: &mut [f64], g: &mut [f64])
}

#[inline(always)]
fn kl_level_sums_body(
    mu: f64,
    alpha: &[f64],
    mhat: &[f64],
    p: &[f64],
    s: &mut [f64],
    g: &mut [f64],
) {
    let n = alpha.len();
    let (mhat, p, s, g) = (&mhat[..n], &p[..n], &mut s[..n], &mut g[..n]);
    for j in 0..n {
        kl_level_step(mu, alpha[j], mhat[j], p[j], &mut s[j], &mut g[j]);
    }
}

/// `kl[j]` = [`posterior_kl`] of job j (its cell's pmf in `probs`, α_j, m̂_j), eight jobs at a
/// time with the scalar's operations in its order (a last partial group is padded with copies of
/// its first job, whose lanes are dropped).
///
/// # Safety
/// The CPU must support AVX-512F, and `(cell + 1) · K <= probs.len()` for every job.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn kl_jobs_wide(probs: &[f64], mu: &[f64], jobs: &[KlJob], kl: &mut [f64]) {
    let n = jobs.len();
    assert!(kl.len() >= n);
    let whole = n / 8 * 8;
    for j in (0..whole).step_by(8) {
        let group = kl_group_wide(probs, mu, &jobs[j..j + 8]);
        kl[j..j + 8].copy_from_slice(&group);
    }
    if whole < n {
        let mut padded = [jobs[whole]; 8];
        padded[..n - whole].copy_from_slice(&jobs[whole..]);
        let group = kl_group_wide(probs, mu, &padded);
        kl[whole..n].copy_from_slice(&group[..n - whole]);
    }
}

/// [`posterior_kl`] of eight jobs in the lanes of one vector.
///
/// # Safety
/// As [`kl_jobs_wide`]; `jobs` holds eight jobs.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
#[inline]
unsafe fn kl_group_wide(probs: &[f64], mu: &[f64], jobs: &[KlJob]) -> [f64; 8] {
    use crate::info::fastlog::ln_normal_x8;
    use std::arch::x86_64::*;
    assert!(jobs.len() >= 8);
    let (one, zero) = (_mm512_set1_pd(1.0), _mm512_setzero_pd());
    let tiny = _mm512_set1_pd(f64::MIN_POSITIVE);
    // One field of eight consecutive jobs: 4 words apart.
    let stride = _mm512_setr_epi64(0, 4, 8, 12, 16, 20, 24, 28);
    let base = jobs.as_ptr() as *const f64;
    let a = _mm512_i64gather_pd::<8>(stride, base);
    let m = _mm512_i64gather_pd::<8>(stride, base.add(1));
    let cell = _mm512_i64gather_epi64::<8>(stride, base.add(3) as *const i64);
    // cell · K from 32-bit halves (cells and K are far below 2^32), without AVX-512DQ.
    let row = _mm512_mul_epu32(cell, _mm512_set1_epi64(mu.len() as i64));
    let (mut s, mut g) = (zero, zero);
    for (i, &mu_i) in mu.iter().enumerate() {
        // max(·, 0) and max(·, tiny) return the second operand for NaN, as f64::max does.
        let d = _mm512_sub_pd(_mm512_set1_pd(mu_i), m);
        let f = _mm512_max_pd(_mm512_add_pd(one, _mm512_mul_pd(a, d)), zero);
        let at = _mm512_add_epi64(row, _mm512_set1_epi64(i as i64));
        // In bounds: every row + i < (cell + 1) · K <= probs.len() (the caller's contract).
        let p = _mm512_i64gather_pd::<8>(at, probs.as_ptr());
        let w = _mm512_mul_pd(p, f);
        s = _mm512_add_pd(s, w);
        g = _mm512_add_pd(g, _mm512_mul_pd(w, ln_normal_x8(_mm512_max_pd(f, tiny))));
    }
    let mut sv = [0.0; 8];
    let mut gv = [0.0; 8];
    _mm512_storeu_pd(sv.as_mut_ptr(), s);
    _mm512_storeu_pd(gv.as_mut_ptr(), g);
    std::array::from_fn(|t| kl_from_sums(sv[t], gv[t]))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// (cell, weight, α) of a queued posterior.
    type Job = (usize, f64, f64);

    /// Levels, seven random pmfs over 10 midpoint levels, their means, and 45 jobs over them
    /// whose coefficients include 0, the "seen free" −1/(1 − m̂), large hits and factors that
    /// clip at 0.
    fn fixture() -> (Vec<f64>, Vec<f64>, Vec<f64>, Vec<Job>) {
        let mut rng = crate::rng::Rng::new(11);
        let k = 10;
        let mu: Vec<f64> = (0..k).map(|i| (i as f64 + 0.5) / k as f64).collect();
        let mut probs = Vec::new();
        for c in 0..7 {
            let raw: Vec<f64> = (0..k)
                .map(|i| {
                    if c == 3 && i % 3 == 0 {
                        0.0
                    } else {
                        rng.uniform()
                    }
                })
                .collect();
            let sum: f64 = raw.iter().sum();
            probs.extend(raw.iter().map(|x| x / sum));
        }
        let mhat: Vec<f64> = (0..7)
            .map(|c| (0..k).map(|i| mu[i] * probs[c * k + i]).sum())
            .collect();
        let jobs = (0..45)
            .map(|j| {
                let c = (j * 5) % 7;
                let alpha = match j % 5 {
                    0 => 0.0,
                    1 => -1.0 / (1.0 - mhat[c]),
                    2 => 40.0 * rng.uniform(),
                    3 => -3.0 * rng.uniform() - 1.5,
                    _ => (rng.uniform() - 0.5) * 1e-3,
                };
                (c, 0.1 + rng.uniform(), alpha)
            })
            .collect();
        (mu, probs, mhat, jobs)
    }

    #[test]
    fn batched_divergences_equal_the_scalar_ones_bit_for_bit_on_every_path() {
        let (mu, probs, mhat, jobs) = fixture();
        let k = mu.len();
        let mut want = [0.0; 7];
        let mut batch = KlBatch::default();
        for &(c, weight, alpha) in &jobs {
            let kl = posterior_kl(&probs[c * k..(c + 1) * k], &mu, alpha, mhat[c]);
            assert!(kl.is_finite() && kl >= -1e-15, "{kl}");
            want[c] += weight * kl;
            batch.push(c, weight, alpha, mhat[c]);
        }
        // The dispatched path (eight lanes where the CPU has AVX-512).
        let mut got = vec![0.0; 7];
        batch.flush(&probs, &mu, &mut got);
        assert!(batch.jobs.is_empty());
        // The level-by-level path, whatever the CPU.
        for &(c, weight, alpha) in &jobs {
            batch.push(c, weight, alpha, mhat[c]);
        }
        batch.kl.resize(jobs.len(), 0.0);
        batch.level_by_level(&probs, &mu);
        let mut level = [0.0; 7];
        for (job, kl) in batch.jobs.iter().zip(&batch.kl) {
            level[job.cell] += job.weight * kl;
        }
        for c in 0..7 {
            assert_eq!(got[c].to_bits(), want[c].to_bits(), "cell {c}");
            assert_eq!(level[c].to_bits(), want[c].to_bits(), "cell {c}");
        }
    }

    #[test]
    fn divergence_is_zero_for_an_unchanged_posterior_and_matches_the_definition() {
        let (mu, probs, mhat, _) = fixture();
        let k = mu.len();
        for c in 0..7 {
            let p = &probs[c * k..(c + 1) * k];
            // Only the pmf's rounding (its sum is 1 ± an ulp) is left.
            assert!(posterior_kl(p, &mu, 0.0, mhat[c]).abs() < 1e-15);
            for alpha in [0.7, -0.9, 5.0] {
                let mut post = vec![0.0; k];
                posterior(p, &mu, alpha, mhat[c], &mut post);
                let direct: f64 = (0..k)
                    .filter(|&i| post[i] > 0.0)
                    .map(|i| post[i] * (post[i] / p[i]).ln())
                    .sum();
                let kl = posterior_kl(p, &mu, alpha, mhat[c]);
                assert!((kl - direct).abs() < 1e-14, "{kl} {direct}");
            }
        }
    }
}
