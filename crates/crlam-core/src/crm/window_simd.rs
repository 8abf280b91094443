//! The window of up to sixteen weighed beams at once, after their far phases, in two sets of
//! eight AVX-512 lanes (the [`super::far_simd`] walk lanes), or four sets of four AVX2 lanes
//! ([`super::lanes_avx2`]), by the level of [`crate::simd`].
//!
//! In the window, a weighed beam's cells from the far phase's end to the end of the mapping ray,
//! each cause adds π·L to η: the mixture's hit density (a Gaussian through
//! [`exp_table_avx512`], lane for lane the scalar `exp_table`), its short term (the same
//! exponential) and its floor. Each lane does what the scalar loop of [`super::windowed`] does
//! for such a cell, in its order, and stops before any cell the lanes do not handle (past the
//! mapping ray, or where the hit density needs its truncation normaliser near 0 or z_max), for
//! the scalar kernel to take up from the same state. So a beam ends as if it had walked alone.

#[cfg(target_arch = "x86_64")]
use super::far_simd::SET;
#[cfg(target_arch = "x86_64")]
use super::far_simd::{Crossing, WalkLanes};
use super::lane_io::{WindowLanesIo, WindowModel, LANES};
#[cfg(target_arch = "x86_64")]
use crate::numeric::fastmath::exp_table_avx512;
#[cfg(target_arch = "x86_64")]
use crate::sensor::{GAUSS_CUTOFF_SIGMAS, SQRT_2PI, TRUNC_SIGMAS};
use crate::simd::SimdLevel;
#[cfg(target_arch = "x86_64")]
use std::arch::x86_64::*;

/// Walks the windows of `io`'s beams (at most [`LANES`]) at `level` (lowered to the best the
/// CPU supports), reading m̂ from `means` at the walk's window index. Every walk's cells must lie
/// inside `means`' window. Returns false, touching nothing, at the scalar level.
pub(crate) fn window_phase(
    level: SimdLevel,
    io: WindowLanesIo,
    means: &[f64],
    w: &WindowModel,
) -> bool {
    assert!(io.walks.len() <= LANES);
    // SAFETY: the CPU supports the level (`runnable`); the caller guarantees every index the
    // walks reach lies in `means`.
    #[cfg(target_arch = "x86_64")]
    match level.runnable() {
        SimdLevel::Avx512 => {
            unsafe { window_phase_avx512(io, means, w) };
            return true;
        }
        SimdLevel::Avx2 => {
            unsafe { super::lanes_avx2::window_phase_avx2(io, means, w) };
            return true;
        }
        SimdLevel::Scalar => {}
    }
    let _ = (level, io, means, w);
    false
}

/// The broadcast constants of one window step.
#[cfg(target_arch = "x86_64")]
struct Consts {
    sigma: __m512d,
    peak_denominator: __m512d,
    cutoff: __m512d,
    trunc: __m512d,
    z_max: __m512d,
    hit_reach: __m512d,
    neg_lambda: __m512d,
    w_hit: __m512d,
    w_short: __m512d,
    floor: __m512d,
}

/// One set of window lanes.
#[cfg(target_arch = "x86_64")]
struct WindowLanes {
    walk: WalkLanes,
    reach: __m512d,
    z: __m512d,
    map_length: __m512d,
    short_numerator: __m512d,
    reach_far: __m512d,
    entered: __mmask8,
    eta: __m512d,
    active: __mmask8,
    /// Lanes with a mapping ray (the scalar kernel's `map_on`).
    map_on: __mmask8,
    at_tail: __mmask8,
    bailed: __mmask8,
}

#[cfg(target_arch = "x86_64")]
impl WindowLanes {
    /// The lanes `range` of `io`.
    #[target_feature(enable = "avx512f")]
    unsafe fn load(io: &WindowLanesIo, range: std::ops::Range<usize>) -> Self {
        let ld = |v: &[f64]| {
            let mut a = [0.0; SET];
            a[..v.len()].copy_from_slice(v);
            _mm512_loadu_pd(a.as_ptr())
        };
        let walk = WalkLanes::load(io.walks[range.clone()].iter());
        let active = walk.live;
        let map_length = ld(&io.map_length[range.clone()]);
        let map_on =
            _mm512_cmp_pd_mask::<_CMP_GT_OQ>(map_length, _mm512_set1_pd(f64::NEG_INFINITY));
        Self {
            walk,
            reach: ld(&io.reach[range.clone()]),
            z: ld(&io.z[range.clone()]),
            map_length,
            map_on,
            at_tail: 0,
            bailed: 0,
            short_numerator: ld(&io.short_numerator[range]),
            reach_far: _mm512_set1_pd(f64::NAN),
            entered: 0,
            eta: _mm512_setzero_pd(),
            active,
        }
    }

    /// One cell of every active lane, as the scalar loop does it for a window cell.
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn step(&mut self, means: &[f64], k: &Consts) {
        let c: Crossing = self.walk.crossing();
        let (add, sub, mul) = (_mm512_add_pd, _mm512_sub_pd, _mm512_mul_pd);
        let t_in = self.walk.t_in;
        let d = mul(_mm512_set1_pd(0.5), add(t_in, c.t_out));
        // in_map: t_in < m_len && m_len − t_in ≥ MIN_CHORD.
        let in_map = _mm512_cmp_pd_mask::<_CMP_LT_OQ>(t_in, self.map_length)
            & _mm512_cmp_pd_mask::<_CMP_GE_OQ>(
                sub(self.map_length, t_in),
                _mm512_set1_pd(crate::raycast::MIN_CHORD),
            );
        // hit_density_fast: within the hit reach, u = (z − d)/σ, 0 beyond the cutoff, the
        // truncation normaliser (left to the scalar kernel) within TRUNC_SIGMAS σ of 0 or z_max.
        let abs = |v: __m512d| _mm512_abs_pd(v);
        let in_hit = _mm512_cmp_pd_mask::<_CMP_LE_OQ>(abs(sub(d, self.z)), k.hit_reach);
        // Not past the hit reach (the scalar tail test is d − z > hit reach).
        let in_hit_raw = !_mm512_cmp_pd_mask::<_CMP_GT_OQ>(sub(d, self.z), k.hit_reach);
        let u = _mm512_div_pd(sub(self.z, d), k.sigma);
        let gauss = in_hit & !_mm512_cmp_pd_mask::<_CMP_GT_OQ>(abs(u), k.cutoff);
        let untruncated = _mm512_cmp_pd_mask::<_CMP_GT_OQ>(d, k.trunc)
            & _mm512_cmp_pd_mask::<_CMP_GT_OQ>(sub(k.z_max, d), k.trunc);
        // The short term: 0 unless z ≤ d and d > 0 (the scalar `z > d || d <= 0.0` negated).
        let short_on = !_mm512_cmp_pd_mask::<_CMP_GT_OQ>(self.z, d)
            & !_mm512_cmp_pd_mask::<_CMP_LE_OQ>(d, _mm512_setzero_pd());
        let x_short = mul(k.neg_lambda, d);
        let x_ok = _mm512_cmp_pd_mask::<_CMP_GE_OQ>(x_short, _mm512_set1_pd(-708.0))
            & _mm512_cmp_pd_mask::<_CMP_LE_OQ>(x_short, _mm512_set1_pd(709.0));
        // A lane stops unmoved before its first tail cell (past the mapping ray and the hit
        // reach: the tail lanes take it from there) and before a cell only the scalar kernel
        // handles (past the mapping ray within the hit reach, or a truncated hit density).
        let tail = self.map_on & !in_map & !in_hit_raw;
        let handled = in_map & (!gauss | untruncated) & (!short_on | x_ok);
        let stop = self.active & c.reported & !handled;
        self.at_tail |= stop & tail;
        self.bailed |= stop & !tail;
        let adv = self.active & !stop;
        let take = adv & c.reported;
        let one = _mm512_set1_pd(1.0);
        let m = _mm512_mask_i64gather_pd::<8>(one, take, self.walk.index, means.as_ptr());
        let first = take & !self.entered;
        self.reach_far = _mm512_mask_mov_pd(self.reach_far, first, self.reach);
        self.entered |= take;
        // −0.5·u·u stays within exp_table's range (|u| ≤ 37) wherever it is used.
        let x_hit = mul(mul(_mm512_set1_pd(-0.5), u), u);
        let peak = _mm512_div_pd(exp_table_avx512(x_hit), k.peak_denominator);
        let hit = _mm512_maskz_mov_pd(gauss, peak);
        let short_term = _mm512_div_pd(self.short_numerator, sub(one, exp_table_avx512(x_short)));
        let short = _mm512_maskz_mov_pd(short_on, short_term);
        let like = add(add(mul(k.w_hit, hit), mul(k.w_short, short)), k.floor);
        let pi_l = mul(mul(self.reach, m), like);
        self.eta = _mm512_mask_add_pd(self.eta, take, self.eta, pi_l);
        self.reach = _mm512_mask_mul_pd(self.reach, take, self.reach, sub(one, m));
        self.active = self.walk.advance(adv, &c);
    }

    #[target_feature(enable = "avx512f")]
    unsafe fn store(&self, io: &mut WindowLanesIo, range: std::ops::Range<usize>) {
        let mut f = [[0.0f64; SET]; 3];
        _mm512_storeu_pd(f[0].as_mut_ptr(), self.reach);
        _mm512_storeu_pd(f[1].as_mut_ptr(), self.reach_far);
        _mm512_storeu_pd(f[2].as_mut_ptr(), self.eta);
        self.walk.store(io.walks[range.clone()].iter_mut());
        for (i, lane) in range.enumerate() {
            if self.walk.live & (1 << i) != 0 {
                io.reach[lane] = f[0][i];
                io.reach_far[lane] = f[1][i];
                io.eta[lane] = f[2][i];
                io.at_tail[lane] = self.at_tail & (1 << i) != 0;
                io.bailed[lane] = self.bailed & (1 << i) != 0;
            }
        }
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn window_phase_avx512(mut io: WindowLanesIo, means: &[f64], w: &WindowModel) {
    let m = &w.model;
    let s = m.sigma_hit;
    let set = |v: f64| _mm512_set1_pd(v);
    // The scalar expressions, so the same constants.
    let k = Consts {
        sigma: set(s),
        peak_denominator: set(s * SQRT_2PI),
        cutoff: set(GAUSS_CUTOFF_SIGMAS),
        trunc: set(TRUNC_SIGMAS * s),
        z_max: set(m.z_max),
        hit_reach: set(w.hit_reach),
        neg_lambda: set(-m.lambda_short),
        w_hit: set(m.w_hit),
        w_short: set(m.w_short),
        floor: set(m.w_rand / m.z_max),
    };
    let n = io.walks.len();
    let (ra, rb) = (0..n.min(SET), n.min(SET)..n);
    let mut a = WindowLanes::load(&io, ra.clone());
    let mut b = WindowLanes::load(&io, rb.clone());
    while a.active | b.active != 0 {
        if a.active != 0 {
            a.step(means, &k);
        }
        if b.active != 0 {
            b.step(means, &k);
        }
    }
    a.store(&mut io, ra);
    b.store(&mut io, rb);
}
