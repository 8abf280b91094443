//! KL divergences of many CRMI posteriors from their priors, batched (crm-spec 5.2): the MI of a
//! cell is Σ_q P(q) KL(p'(q) ‖ p), and each (cell, bin) posterior p' = p ⊙ f / s with
//! f_i = max(1 + α(μ_i − m̂), 0) needs K logarithms, most of CRMI's time. The batch evaluates them
//! eight posteriors at a time with explicit AVX-512, four at a time with explicit AVX2, or level by
//! level (by [`crate::simd::level`]), with the scalar definition's operations in its order, so
//! every path gives the same bits.

use crate::numeric::fastmath::ln_normal;

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
        self.evaluate(crate::simd::level(), probs, mu);
        for (job, kl) in self.jobs.iter().zip(&self.kl) {
            out[job.cell] += job.weight * kl;
        }
        self.jobs.clear();
    }

    /// `self.kl` for the queued jobs at `level` (lowered to the best the CPU supports): eight
    /// jobs at a time at AVX-512, four at AVX2, level by level otherwise.
    fn evaluate(&mut self, level: crate::simd::SimdLevel, probs: &[f64], mu: &[f64]) {
        let level = level.runnable();
        #[cfg(target_arch = "x86_64")]
        if level >= crate::simd::SimdLevel::Avx2 {
            let k = mu.len();
            assert!(self.jobs.iter().all(|j| (j.cell + 1) * k <= probs.len()));
            // SAFETY: the CPU supports the level (`runnable`), and every cell's K entries are
            // in `probs` (checked above).
            unsafe {
                if level == crate::simd::SimdLevel::Avx512 {
                    kl_jobs_wide(probs, mu, &self.jobs, &mut self.kl);
                } else {
                    kl_jobs_x4(probs, mu, &self.jobs, &mut self.kl);
                }
            }
            return;
        }
        self.level_by_level(level, probs, mu);
    }

    /// `self.kl` by sweeping the levels over all jobs (each step vectorises).
    fn level_by_level(&mut self, level: crate::simd::SimdLevel, probs: &[f64], mu: &[f64]) {
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
            kl_level_sums_at(
                level,
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

crate::numeric::fastmath::simd_by_target! {
    /// [`kl_level_step`] of level `mu` for every pair j (α_j, m̂_j, p_j), into the pair's sums.
    kl_level_sums, kl_level_sums_at, kl_level_sums_avx2, kl_level_sums_body,
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
    use crate::numeric::fastlog::ln_normal_x8;
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

/// `kl[j]` = [`posterior_kl`] of job j, four jobs at a time with AVX2, as [`kl_jobs_wide`].
///
/// # Safety
/// The CPU must support AVX2, and `(cell + 1) · K <= probs.len()` for every job.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn kl_jobs_x4(probs: &[f64], mu: &[f64], jobs: &[KlJob], kl: &mut [f64]) {
    let n = jobs.len();
    assert!(kl.len() >= n);
    let whole = n / 4 * 4;
    for j in (0..whole).step_by(4) {
        let group = kl_group_x4(probs, mu, &jobs[j..j + 4]);
        kl[j..j + 4].copy_from_slice(&group);
    }
    if whole < n {
        let mut padded = [jobs[whole]; 4];
        padded[..n - whole].copy_from_slice(&jobs[whole..]);
        let group = kl_group_x4(probs, mu, &padded);
        kl[whole..n].copy_from_slice(&group[..n - whole]);
    }
}

/// [`posterior_kl`] of four jobs in the lanes of one AVX2 vector: the four 32-byte jobs are
/// loaded as rows and transposed into fields.
///
/// # Safety
/// As [`kl_jobs_x4`]; `jobs` holds four jobs.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn kl_group_x4(probs: &[f64], mu: &[f64], jobs: &[KlJob]) -> [f64; 4] {
    use crate::numeric::fastlog::ln_normal_x4;
    use std::arch::x86_64::*;
    assert!(jobs.len() >= 4);
    let (one, zero) = (_mm256_set1_pd(1.0), _mm256_setzero_pd());
    let tiny = _mm256_set1_pd(f64::MIN_POSITIVE);
    // Rows (α, m̂, weight, cell) of the four jobs, transposed.
    let row = |t: usize| _mm256_loadu_pd(jobs.as_ptr().add(t) as *const f64);
    let (r0, r1, r2, r3) = (row(0), row(1), row(2), row(3));
    let (t0, t1) = (_mm256_unpacklo_pd(r0, r1), _mm256_unpackhi_pd(r0, r1));
    let (t2, t3) = (_mm256_unpacklo_pd(r2, r3), _mm256_unpackhi_pd(r2, r3));
    let a = _mm256_permute2f128_pd::<0x20>(t0, t2);
    let m = _mm256_permute2f128_pd::<0x20>(t1, t3);
    let cell = _mm256_castpd_si256(_mm256_permute2f128_pd::<0x31>(t1, t3));
    // cell · K from 32-bit halves (cells and K are far below 2^32).
    let k = mu.len();
    let row = _mm256_mul_epu32(cell, _mm256_set1_epi64x(k as i64));
    let rows: [*const f64; 4] = std::array::from_fn(|t| probs.as_ptr().add(jobs[t].cell * k));
    let (mut s, mut g) = (zero, zero);
    let mut step = |mu_i: f64, p: __m256d| {
        // max(·, 0) and max(·, tiny) return the second operand for NaN, as f64::max does.
        let d = _mm256_sub_pd(_mm256_set1_pd(mu_i), m);
        let f = _mm256_max_pd(_mm256_add_pd(one, _mm256_mul_pd(a, d)), zero);
        let w = _mm256_mul_pd(p, f);
        s = _mm256_add_pd(s, w);
        g = _mm256_add_pd(g, _mm256_mul_pd(w, ln_normal_x4(_mm256_max_pd(f, tiny))));
    };
    // Four levels at a time: the four pmf rows' entries i..i + 4 loaded and transposed (AVX2
    // gathers are slow on many CPUs); the remaining levels gathered. In bounds: every
    // row + i < (cell + 1) · K <= probs.len() (the caller's contract).
    let whole = k / 4 * 4;
    for i in (0..whole).step_by(4) {
        let ld = |t: usize| _mm256_loadu_pd(rows[t].add(i));
        let (r0, r1, r2, r3) = (ld(0), ld(1), ld(2), ld(3));
        let (t0, t1) = (_mm256_unpacklo_pd(r0, r1), _mm256_unpackhi_pd(r0, r1));
        let (t2, t3) = (_mm256_unpacklo_pd(r2, r3), _mm256_unpackhi_pd(r2, r3));
        step(mu[i], _mm256_permute2f128_pd::<0x20>(t0, t2));
        step(mu[i + 1], _mm256_permute2f128_pd::<0x20>(t1, t3));
        step(mu[i + 2], _mm256_permute2f128_pd::<0x31>(t0, t2));
        step(mu[i + 3], _mm256_permute2f128_pd::<0x31>(t1, t3));
    }
    for (i, &mu_i) in mu.iter().enumerate().skip(whole) {
        let at = _mm256_add_epi64(row, _mm256_set1_epi64x(i as i64));
        step(mu_i, _mm256_i64gather_pd::<8>(probs.as_ptr(), at));
    }
    let mut sv = [0.0; 4];
    let mut gv = [0.0; 4];
    _mm256_storeu_pd(sv.as_mut_ptr(), s);
    _mm256_storeu_pd(gv.as_mut_ptr(), g);
    std::array::from_fn(|t| kl_from_sums(sv[t], gv[t]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::info::crmi_channel::posterior;

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
        // The dispatched path.
        let mut got = vec![0.0; 7];
        batch.flush(&probs, &mu, &mut got);
        assert!(batch.jobs.is_empty());
        for c in 0..7 {
            assert_eq!(got[c].to_bits(), want[c].to_bits(), "cell {c}");
        }
        // Every level (level by level at scalar), 45 jobs and a shorter batch (a partial group).
        for level in crate::simd::SimdLevel::ALL {
            if !level.supported() {
                crate::simd::report_skip("batched_divergences_equal_the_scalar_ones", level);
                continue;
            }
            for n in [jobs.len(), 6] {
                for &(c, weight, alpha) in &jobs[..n] {
                    batch.push(c, weight, alpha, mhat[c]);
                }
                batch.kl.clear();
                batch.kl.resize(n, 0.0);
                batch.evaluate(level, &probs, &mu);
                for (job, (kl, &(c, _, alpha))) in batch.jobs.iter().zip(batch.kl.iter().zip(&jobs))
                {
                    let want = posterior_kl(&probs[c * k..(c + 1) * k], &mu, alpha, mhat[c]);
                    assert_eq!(job.cell, c);
                    assert_eq!(kl.to_bits(), want.to_bits(), "{level} cell {c}");
                }
                batch.jobs.clear();
            }
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
