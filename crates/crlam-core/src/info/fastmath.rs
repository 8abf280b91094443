//! Fast, accurate scalar kernels for the CRMI inner loops: Φ by quintic Hermite interpolation
//! of a table (absolute error < 1e-13) and a branch-free natural log (a few ulp).

use std::sync::OnceLock;

use crate::sensor::normal_cdf;

/// `pub fn $name(args)`: runs `$body(args)` compiled for AVX2 (as `$avx`) when the CPU has it, and
/// the baseline build of the same body otherwise. The bodies are plain loops that the compiler
/// vectorises without FMA contraction, so both builds give the same results.
macro_rules! avx2_dispatch {
    ($(#[$doc:meta])* $name:ident, $avx:ident, $body:ident, ($($arg:ident: $ty:ty),*)) => {
        $(#[$doc])*
        pub fn $name($($arg: $ty),*) {
            #[cfg(target_arch = "x86_64")]
            {
                if std::arch::is_x86_feature_detected!("avx2") {
                    // SAFETY: the CPU supports AVX2, checked just above.
                    unsafe { $avx($($arg),*) };
                    return;
                }
            }
            $body($($arg),*);
        }

        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx2")]
        unsafe fn $avx($($arg: $ty),*) {
            $body($($arg),*);
        }
    };
}

/// Table spacing of [`normal_cdf_fast`] (in σ units).
const STEP: f64 = 1.0 / 32.0;
/// Φ is tabulated on [−LIMIT, 0]; beyond, Φ(−8.5) < 1e-17 is taken as 0 (and Φ(u) = 1 − Φ(−u)).
const LIMIT: f64 = 8.5;

struct CdfTable {
    /// (Φ, φ, φ′) at u_k = −LIMIT + k·STEP, k = 0..=N.
    nodes: Vec<[f64; 3]>,
    /// Interval k's two nodes side by side, (nodes[k], nodes[k + 1], 0, 0): two aligned vector
    /// loads per lane for the AVX2 path.
    intervals: Vec<Interval>,
}

#[derive(Clone, Copy)]
#[repr(C, align(64))]
struct Interval([f64; 8]);

fn table() -> &'static CdfTable {
    static T: OnceLock<CdfTable> = OnceLock::new();
    T.get_or_init(|| {
        let n = (LIMIT / STEP).round() as usize;
        let nodes = (0..=n)
            .map(|k| {
                let u = -LIMIT + k as f64 * STEP;
                let pdf = (-0.5 * u * u).exp() / (2.0 * std::f64::consts::PI).sqrt();
                [normal_cdf(u), pdf, -u * pdf]
            })
            .collect::<Vec<[f64; 3]>>();
        let intervals = nodes
            .windows(2)
            .map(|w| {
                Interval([
                    w[0][0], w[0][1], w[0][2], w[1][0], w[1][1], w[1][2], 0.0, 0.0,
                ])
            })
            .collect();
        CdfTable { nodes, intervals }
    })
}

/// The lower tail Φ(u) for u ≤ 0, by quintic Hermite interpolation between tabulated Φ, φ, φ′.
#[inline]
fn lower_tail(u: f64) -> f64 {
    lower_tail_with(&table().nodes, u)
}

/// [`lower_tail`] on a given table, branch-free (selects instead of jumps) so that loops over it
/// vectorise: u ≤ −LIMIT reads node 0 and is then replaced by 0.
#[inline(always)]
fn lower_tail_with(nodes: &[[f64; 3]], u: f64) -> f64 {
    let x = ((u + LIMIT) / STEP).max(0.0);
    let k = (x as usize).min(nodes.len() - 2);
    let s = x - k as f64;
    let (a, b) = (nodes[k], nodes[k + 1]);
    let (s2, s3) = (s * s, s * s * s);
    let (s4, s5) = (s3 * s, s3 * s2);
    let h0 = 1.0 - 10.0 * s3 + 15.0 * s4 - 6.0 * s5;
    let h1 = s - 6.0 * s3 + 8.0 * s4 - 3.0 * s5;
    let h2 = 0.5 * s2 - 1.5 * s3 + 1.5 * s4 - 0.5 * s5;
    let h3 = 0.5 * s3 - s4 + 0.5 * s5;
    let h4 = -4.0 * s3 + 7.0 * s4 - 3.0 * s5;
    let h5 = 10.0 * s3 - 15.0 * s4 + 6.0 * s5;
    let v = a[0] * h0
        + STEP * a[1] * h1
        + STEP * STEP * (a[2] * h2 + b[2] * h3)
        + STEP * b[1] * h4
        + b[0] * h5;
    if u <= -LIMIT {
        0.0
    } else {
        v
    }
}

/// Φ(x) of every `xs[i]` into `out[i]`, equal to [`normal_cdf_fast`] bit for bit (0 and 1
/// beyond ∓8.5), in one vectorising pass like [`lower_tail_abs_slice`]. Finite inputs only.
pub fn normal_cdf_slice(xs: &[f64], out: &mut [f64]) {
    lower_tail_abs_slice(xs, out);
    for (o, &x) in out.iter_mut().zip(xs) {
        *o = if x > 0.0 { 1.0 - *o } else { *o };
    }
}

/// out[i] = Φ(−|xs[i]|): the value of [`normal_tail`]`(xs[i])` (whose flag is `xs[i] > 0`), bit
/// for bit, in one pass that vectorises (AVX2 where the CPU has it, with the same operations as
/// the scalar function, so results do not depend on the CPU). Finite inputs only.
pub fn lower_tail_abs_slice(xs: &[f64], out: &mut [f64]) {
    let t = table();
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx2") {
            unsafe { lower_tail_abs_slice_avx2(t, xs, out) };
            return;
        }
    }
    lower_tail_abs_slice_body(&t.nodes, xs, out);
}

/// Four lanes at a time with explicit AVX2, with the scalar function's operations in its order and
/// no FMA, so that every lane equals [`lower_tail_with`] bit for bit; the remainder goes through
/// the scalar. Each lane's interval is read as two aligned vectors and the four lanes' reads are
/// transposed (AVX2 gathers are several times slower on the CPUs we measured).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn lower_tail_abs_slice_avx2(table: &CdfTable, xs: &[f64], out: &mut [f64]) {
    use std::arch::x86_64::*;
    let nodes = &table.nodes;
    let len = xs.len().min(out.len());
    let lanes = len / 4 * 4;
    let base = table.intervals.as_ptr() as *const f64;
    let last = _mm_set1_epi32((nodes.len() - 2) as i32);
    let sign = _mm256_set1_pd(-0.0);
    let limit = _mm256_set1_pd(LIMIT);
    let neg_limit = _mm256_set1_pd(-LIMIT);
    let step = _mm256_set1_pd(STEP);
    let step2 = _mm256_set1_pd(STEP * STEP);
    let zero = _mm256_setzero_pd();
    let c = |v: f64| _mm256_set1_pd(v);
    let (mul, add, sub) = (
        |a, b| _mm256_mul_pd(a, b),
        |a, b| _mm256_add_pd(a, b),
        |a, b| _mm256_sub_pd(a, b),
    );
    let mut i = 0;
    while i < lanes {
        let x = _mm256_loadu_pd(xs.as_ptr().add(i));
        let u = _mm256_or_pd(x, sign); // −|x|
        let t = _mm256_max_pd(_mm256_div_pd(add(u, limit), step), zero);
        let k = _mm_min_epi32(_mm256_cvttpd_epi32(t), last);
        let s = sub(t, _mm256_cvtepi32_pd(k));
        // k ≤ nodes.len() − 2 = intervals.len() − 1: every read is in bounds.
        let mut idx = [0i32; 4];
        _mm_storeu_si128(idx.as_mut_ptr() as *mut __m128i, k);
        let row =
            |lane: usize, half: usize| _mm256_load_pd(base.add(idx[lane] as usize * 8 + half * 4));
        let (lo0, lo1, lo2, lo3) = (row(0, 0), row(1, 0), row(2, 0), row(3, 0));
        let (hi0, hi1, hi2, hi3) = (row(0, 1), row(1, 1), row(2, 1), row(3, 1));
        // 4 × 4 transposes: lo rows hold (a0, a1, a2, b0), hi rows (b1, b2, 0, 0).
        let (t0, t1) = (_mm256_unpacklo_pd(lo0, lo1), _mm256_unpackhi_pd(lo0, lo1));
        let (t2, t3) = (_mm256_unpacklo_pd(lo2, lo3), _mm256_unpackhi_pd(lo2, lo3));
        let a0 = _mm256_permute2f128_pd::<0x20>(t0, t2);
        let a1 = _mm256_permute2f128_pd::<0x20>(t1, t3);
        let a2 = _mm256_permute2f128_pd::<0x31>(t0, t2);
        let b0 = _mm256_permute2f128_pd::<0x31>(t1, t3);
        let (u0, u1) = (_mm256_unpacklo_pd(hi0, hi1), _mm256_unpackhi_pd(hi0, hi1));
        let (u2, u3) = (_mm256_unpacklo_pd(hi2, hi3), _mm256_unpackhi_pd(hi2, hi3));
        let b1 = _mm256_permute2f128_pd::<0x20>(u0, u2);
        let b2 = _mm256_permute2f128_pd::<0x20>(u1, u3);
        let s2 = mul(s, s);
        let s3 = mul(s2, s);
        let s4 = mul(s3, s);
        let s5 = mul(s3, s2);
        let h0 = sub(
            add(sub(c(1.0), mul(c(10.0), s3)), mul(c(15.0), s4)),
            mul(c(6.0), s5),
        );
        let h1 = sub(
            add(sub(s, mul(c(6.0), s3)), mul(c(8.0), s4)),
            mul(c(3.0), s5),
        );
        let h2 = sub(
            add(sub(mul(c(0.5), s2), mul(c(1.5), s3)), mul(c(1.5), s4)),
            mul(c(0.5), s5),
        );
        let h3 = add(sub(mul(c(0.5), s3), s4), mul(c(0.5), s5));
        let h4 = sub(add(mul(c(-4.0), s3), mul(c(7.0), s4)), mul(c(3.0), s5));
        let h5 = add(sub(mul(c(10.0), s3), mul(c(15.0), s4)), mul(c(6.0), s5));
        let v = add(
            add(
                add(
                    add(mul(a0, h0), mul(mul(step, a1), h1)),
                    mul(step2, add(mul(a2, h2), mul(b2, h3))),
                ),
                mul(mul(step, b1), h4),
            ),
            mul(b0, h5),
        );
        let saturated = _mm256_cmp_pd::<_CMP_LE_OQ>(u, neg_limit);
        _mm256_storeu_pd(out.as_mut_ptr().add(i), _mm256_andnot_pd(saturated, v));
        i += 4;
    }
    lower_tail_abs_slice_body(nodes, &xs[lanes..len], &mut out[lanes..len]);
}

#[inline(always)]
fn lower_tail_abs_slice_body(nodes: &[[f64; 3]], xs: &[f64], out: &mut [f64]) {
    for (o, &x) in out.iter_mut().zip(xs) {
        *o = lower_tail_with(nodes, -x.abs());
    }
}

/// A tail of the standard normal: `(upper, value)` = (false, Φ(u)) for u ≤ 0 and (true, Φ(−u))
/// for u > 0, so that differences between nearby points keep their precision.
#[inline]
pub fn normal_tail(u: f64) -> (bool, f64) {
    if u > 0.0 {
        (true, lower_tail(-u))
    } else {
        (false, lower_tail(u))
    }
}

/// Φ(u) from the table (absolute error < 1e-13).
#[inline]
pub fn normal_cdf_fast(u: f64) -> f64 {
    if u > 0.0 {
        1.0 - lower_tail(-u)
    } else {
        lower_tail(u)
    }
}

/// Φ(b) − Φ(a) for a ≤ b from two [`normal_tail`] values.
#[inline]
pub fn tail_difference(a: (bool, f64), b: (bool, f64)) -> f64 {
    match (a.0, b.0) {
        (false, false) => b.1 - a.1,
        (true, true) => a.1 - b.1,
        _ => (1.0 - b.1) - a.1,
    }
}

/// Natural log of a positive, normal, finite x to within a few ulp, branch-free: x = 2^e·m with
/// m ∈ [√½, √2), ln m = 2 atanh(s), s = (m − 1)/(m + 1), |s| ≤ 0.172, by its series to s^21
/// (truncation below 1e-17), evaluated by Estrin's scheme for a short dependency chain. The
/// exponent is read as a float through the 2^52 trick so that loops over it vectorise.
#[inline(always)]
pub fn ln_normal(x: f64) -> f64 {
    const MANTISSA: u64 = 0x000f_ffff_ffff_ffff;
    const ONE: u64 = 0x3ff0_0000_0000_0000;
    const TWO52: f64 = 4_503_599_627_370_496.0;
    let bits = x.to_bits();
    let e_field = f64::from_bits(TWO52.to_bits() | (bits >> 52)) - TWO52;
    let m = f64::from_bits((bits & MANTISSA) | ONE);
    let big = m > std::f64::consts::SQRT_2;
    let m = if big { 0.5 * m } else { m };
    let e = e_field - 1023.0 + if big { 1.0 } else { 0.0 };
    let s = (m - 1.0) / (m + 1.0);
    let z = s * s;
    let z2 = z * z;
    let z4 = z2 * z2;
    let z8 = z4 * z4;
    let p01 = 1.0 + z * (1.0 / 3.0);
    let p23 = 1.0 / 5.0 + z * (1.0 / 7.0);
    let p45 = 1.0 / 9.0 + z * (1.0 / 11.0);
    let p67 = 1.0 / 13.0 + z * (1.0 / 15.0);
    let p89 = 1.0 / 17.0 + z * (1.0 / 19.0);
    let p10 = 1.0 / 21.0;
    let q0 = p01 + z2 * p23;
    let q1 = p45 + z2 * p67;
    let q2 = p89 + z2 * p10;
    let poly = q0 + z4 * q1 + z8 * q2;
    e * std::f64::consts::LN_2 + 2.0 * s * poly
}

avx2_dispatch! {
    /// ln(1 + x) of every `xs[i]` into `out[i]` for x > −1 with 1 + x normal, to within a few ulp,
    /// in one pass that vectorises like [`ln_clamped_slice`]: u = 1 + x rounded, then
    /// ln(1 + x) = ln(u) · x/(u − 1), which cancels u's rounding error (x itself when u = 1).
    ln_1p_slice, ln_1p_slice_avx2, ln_1p_slice_body, (xs: &[f64], out: &mut [f64])
}

#[inline(always)]
fn ln_1p_slice_body(xs: &[f64], out: &mut [f64]) {
    for (o, &x) in out.iter_mut().zip(xs) {
        let u = 1.0 + x;
        let d = u - 1.0;
        let scaled = ln_normal(u) * (x / if d == 0.0 { 1.0 } else { d });
        *o = if d == 0.0 { x } else { scaled };
    }
}

/// e^x to within a few ulp for x ≤ 709.7, branch-light and libm-free: x = n ln 2 + r with
/// |r| ≤ ½ ln 2 (Cody–Waite split of ln 2), e^r by its Taylor series to r¹³ (truncation below
/// 1e-17 relative) in Estrin's scheme, scaled by 2ⁿ through the exponent bits. Results that
/// would be subnormal (x < −708.3) go to libm; NaN propagates.
#[inline(always)]
pub fn exp_fast(x: f64) -> f64 {
    if !(EXP_MIN..=EXP_MAX).contains(&x) {
        return x.exp();
    }
    exp_in_range(x)
}

/// The range of [`exp_fast`]'s own evaluation (normal results, no overflow).
const EXP_MIN: f64 = -708.3;
const EXP_MAX: f64 = 709.7;

/// e^x for x in [`EXP_MIN`, `EXP_MAX`] (see [`exp_fast`]).
#[inline(always)]
fn exp_in_range(x: f64) -> f64 {
    const LOG2E: f64 = std::f64::consts::LOG2_E;
    // fdlibm's split: LN2_HI has 32 trailing zero bits, so n · LN2_HI is exact for |n| < 2²⁰.
    const LN2_HI: f64 = f64::from_bits(0x3fe6_2e42_fee0_0000);
    const LN2_LO: f64 = f64::from_bits(0x3dea_39ef_3579_3c76);
    const SHIFTER: f64 = 6_755_399_441_055_744.0; // 1.5 · 2⁵²: adding it rounds to an integer
    let k = x * LOG2E + SHIFTER;
    let n = k - SHIFTER;
    let r = (x - n * LN2_HI) - n * LN2_LO;
    let r2 = r * r;
    let r4 = r2 * r2;
    let r8 = r4 * r4;
    let c01 = 1.0 + r;
    let c23 = 1.0 / 2.0 + r * (1.0 / 6.0);
    let c45 = 1.0 / 24.0 + r * (1.0 / 120.0);
    let c67 = 1.0 / 720.0 + r * (1.0 / 5_040.0);
    let c89 = 1.0 / 40_320.0 + r * (1.0 / 362_880.0);
    let c1011 = 1.0 / 3_628_800.0 + r * (1.0 / 39_916_800.0);
    let c1213 = 1.0 / 479_001_600.0 + r * (1.0 / 6_227_020_800.0);
    let q0 = c01 + r2 * c23;
    let q1 = c45 + r2 * c67;
    let q2 = c89 + r2 * c1011;
    let poly = q0 + r4 * q1 + r8 * (q2 + r4 * c1213);
    // n sits in the low bits of k's mantissa (two's complement around the shifter).
    let ni = (k.to_bits() as i64).wrapping_sub(SHIFTER.to_bits() as i64);
    // Split 2ⁿ in two factors so that n = 1024 (x near 709.7) does not overflow the exponent.
    let half = ni >> 1;
    let s1 = f64::from_bits(((half + 1023) as u64) << 52);
    let s2 = f64::from_bits(((ni - half + 1023) as u64) << 52);
    poly * s1 * s2
}

avx2_dispatch! {
    /// `out[i] = ln_normal(max(xs[i], f64::MIN_POSITIVE))` over two equal-length slices. On x86-64
    /// CPUs with AVX2 the same code runs four lanes wide (the operations, hence the results, are
    /// those of [`ln_normal`]: no FMA contraction); elsewhere two lanes (SSE2) or scalar.
    ln_clamped_slice, ln_clamped_slice_avx2, ln_clamped_slice_body, (xs: &[f64], out: &mut [f64])
}

#[inline(always)]
fn ln_clamped_slice_body(xs: &[f64], out: &mut [f64]) {
    for (o, &x) in out.iter_mut().zip(xs) {
        *o = ln_normal(x.max(f64::MIN_POSITIVE));
    }
}

avx2_dispatch! {
    /// In place, x ← [`exp_fast`](x) for x ≥ −708.3 and 0 below (where e^x < 2.2e-308: the
    /// difference cannot show in a sum that has a term near 1, the use here). −∞ gives 0; inputs
    /// must not be NaN. Branch-free, so it runs four lanes wide on CPUs with AVX2 (the operations,
    /// hence the results, are those of [`exp_fast`]).
    exp_for_sums, exp_for_sums_avx2, exp_for_sums_body, (xs: &mut [f64])
}

#[inline(always)]
fn exp_for_sums_body(xs: &mut [f64]) {
    for x in xs.iter_mut() {
        let v = *x;
        let e = exp_in_range(v.clamp(EXP_MIN, EXP_MAX));
        *x = if v < EXP_MIN { 0.0 } else { e };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tabulated_cdf_is_within_1e13_of_erfc() {
        let mut worst: f64 = 0.0;
        let mut u = -9.0;
        while u < 9.0 {
            let (up, v) = normal_tail(u);
            let exact = if up { normal_cdf(-u) } else { normal_cdf(u) };
            worst = worst.max((v - exact).abs());
            u += 0.000_731;
        }
        assert!(worst < 1e-13, "{worst}");
        assert_eq!(normal_tail(-20.0), (false, 0.0));
        for u in [-3.3, -0.2, 0.0, 0.7, 5.1] {
            assert!((normal_cdf_fast(u) - normal_cdf(u)).abs() < 1e-13);
        }
    }

    #[test]
    fn slice_cdf_and_tails_equal_the_scalar_functions_bit_for_bit() {
        let mut rng = crate::rng::Rng::new(9);
        let xs: Vec<f64> = (0..4003)
            .map(|i| match i % 11 {
                0 => -8.5,
                1 => 8.5,
                2 => 0.0,
                3 => -0.0,
                4 => -LIMIT - 1e-12,
                5 => 30.0 * (rng.uniform() - 0.5),
                _ => 18.0 * (rng.uniform() - 0.5),
            })
            .collect();
        let mut cdf = vec![0.0; xs.len()];
        normal_cdf_slice(&xs, &mut cdf);
        let mut tails = vec![0.0; xs.len()];
        lower_tail_abs_slice(&xs, &mut tails);
        for ((&x, c), t) in xs.iter().zip(&cdf).zip(&tails) {
            assert_eq!(c.to_bits(), normal_cdf_fast(x).to_bits(), "{x}");
            assert_eq!(t.to_bits(), normal_tail(x).1.to_bits(), "{x}");
        }
        let mut scalar = vec![0.0; xs.len()];
        lower_tail_abs_slice_body(&table().nodes, &xs, &mut scalar);
        assert_eq!(tails, scalar);
    }

    #[test]
    fn slice_ln_1p_matches_libm() {
        let mut rng = crate::rng::Rng::new(5);
        let mut worst: f64 = 0.0;
        for i in 0..20_000 {
            let x = match i % 4 {
                0 => -0.5 + rng.uniform(),
                1 => (rng.uniform() - 0.5) * 1e-9,
                2 => rng.uniform() * 1e6,
                _ => -0.999 * rng.uniform(),
            };
            let mut out = [0.0];
            ln_1p_slice(&[x], &mut out);
            let want = x.ln_1p();
            let err = if want == 0.0 {
                out[0].abs()
            } else {
                ((out[0] - want) / want).abs()
            };
            worst = worst.max(err);
        }
        assert!(worst < 1e-14, "{worst}");
        let mut out = [1.0; 2];
        ln_1p_slice(&[0.0, 1e-300], &mut out);
        assert_eq!(out, [0.0, 1e-300]);
    }

    #[test]
    fn slice_exp_equals_the_scalar_exp_in_range_and_zero_below() {
        let mut rng = crate::rng::Rng::new(4);
        let xs: Vec<f64> = (0..1001)
            .map(|i| match i % 9 {
                0 => f64::NEG_INFINITY,
                1 => -708.4,
                2 => -708.3,
                _ => -rng.uniform() * 720.0,
            })
            .collect();
        let mut out = xs.clone();
        exp_for_sums(&mut out);
        for (x, o) in xs.iter().zip(&out) {
            let want = if *x < -708.3 { 0.0 } else { exp_fast(*x) };
            assert_eq!(o.to_bits(), want.to_bits(), "{x}");
        }
    }

    #[test]
    fn fast_exp_is_accurate_over_the_normal_range() {
        let mut rng = crate::rng::Rng::new(2);
        let mut worst: f64 = 0.0;
        for _ in 0..400_000 {
            let x = rng.uniform() * 1417.0 - 708.0;
            let (a, b) = (exp_fast(x), x.exp());
            worst = worst.max((a - b).abs() / b);
        }
        for x in [
            0.0,
            1.0,
            -1.0,
            0.5 * std::f64::consts::LN_2,
            709.7,
            -708.3,
            1e-300,
        ] {
            worst = worst.max((exp_fast(x) - x.exp()).abs() / x.exp());
        }
        assert!(worst < 1e-15, "{worst}");
        assert_eq!(exp_fast(-800.0), 0.0);
        assert_eq!(exp_fast(f64::NEG_INFINITY), 0.0);
        assert!(exp_fast(f64::NAN).is_nan());
        assert_eq!(exp_fast(800.0), f64::INFINITY);
    }

    #[test]
    fn slice_log_equals_the_scalar_log_bit_for_bit() {
        let mut rng = crate::rng::Rng::new(3);
        let xs: Vec<f64> = (0..1003)
            .map(|i| match i % 7 {
                0 => 0.0,
                1 => -1.0,
                _ => (rng.uniform() * 60.0 - 30.0).exp2(),
            })
            .collect();
        let mut out = vec![0.0; xs.len()];
        ln_clamped_slice(&xs, &mut out);
        for (x, o) in xs.iter().zip(&out) {
            assert_eq!(o.to_bits(), ln_normal(x.max(f64::MIN_POSITIVE)).to_bits());
        }
    }

    #[test]
    fn fast_log_is_accurate_over_the_normal_range() {
        let mut rng = crate::rng::Rng::new(1);
        let mut worst: f64 = 0.0;
        for _ in 0..200_000 {
            let x = (rng.uniform() * 1400.0 - 700.0).exp2() * (1.0 + rng.uniform());
            let (a, b) = (ln_normal(x), x.ln());
            worst = worst.max((a - b).abs() / b.abs().max(1.0));
        }
        for x in [
            1.0,
            2.0,
            0.5,
            std::f64::consts::SQRT_2,
            f64::MIN_POSITIVE,
            f64::MAX,
        ] {
            worst = worst.max((ln_normal(x) - x.ln()).abs() / x.ln().abs().max(1.0));
        }
        assert!(worst < 1e-15, "{worst}");
    }
}
