//! Exponentials for the CRMI inner loops, without libm's call: [`exp_table`] (a 128-entry table
//! of 2^(j/128) and a short series, within 2 ulp of libm) and [`exp_for_sums`] (branch-free, for
//! terms of sums), each with AVX2 and AVX-512 lanes equal to the scalar results bit for bit.

#[cfg(target_arch = "x86_64")]
use crate::numeric::lanes::simd_lanes;
use crate::numeric::lanes::{scalar, Lanes};
use crate::numeric::simd_dispatch::simd_by_target;

/// 2^(j/128) for j = 0..127, correctly rounded (bits).
const EXP2_TABLE: [u64; 128] = [
    0x3ff0000000000000,
    0x3ff0163da9fb3335,
    0x3ff02c9a3e778061,
    0x3ff04315e86e7f85,
    0x3ff059b0d3158574,
    0x3ff0706b29ddf6de,
    0x3ff0874518759bc8,
    0x3ff09e3ecac6f383,
    0x3ff0b5586cf9890f,
    0x3ff0cc922b7247f7,
    0x3ff0e3ec32d3d1a2,
    0x3ff0fb66affed31b,
    0x3ff11301d0125b51,
    0x3ff12abdc06c31cc,
    0x3ff1429aaea92de0,
    0x3ff15a98c8a58e51,
    0x3ff172b83c7d517b,
    0x3ff18af9388c8dea,
    0x3ff1a35beb6fcb75,
    0x3ff1bbe084045cd4,
    0x3ff1d4873168b9aa,
    0x3ff1ed5022fcd91d,
    0x3ff2063b88628cd6,
    0x3ff21f49917ddc96,
    0x3ff2387a6e756238,
    0x3ff251ce4fb2a63f,
    0x3ff26b4565e27cdd,
    0x3ff284dfe1f56381,
    0x3ff29e9df51fdee1,
    0x3ff2b87fd0dad990,
    0x3ff2d285a6e4030b,
    0x3ff2ecafa93e2f56,
    0x3ff306fe0a31b715,
    0x3ff32170fc4cd831,
    0x3ff33c08b26416ff,
    0x3ff356c55f929ff1,
    0x3ff371a7373aa9cb,
    0x3ff38cae6d05d866,
    0x3ff3a7db34e59ff7,
    0x3ff3c32dc313a8e5,
    0x3ff3dea64c123422,
    0x3ff3fa4504ac801c,
    0x3ff4160a21f72e2a,
    0x3ff431f5d950a897,
    0x3ff44e086061892d,
    0x3ff46a41ed1d0057,
    0x3ff486a2b5c13cd0,
    0x3ff4a32af0d7d3de,
    0x3ff4bfdad5362a27,
    0x3ff4dcb299fddd0d,
    0x3ff4f9b2769d2ca7,
    0x3ff516daa2cf6642,
    0x3ff5342b569d4f82,
    0x3ff551a4ca5d920f,
    0x3ff56f4736b527da,
    0x3ff58d12d497c7fd,
    0x3ff5ab07dd485429,
    0x3ff5c9268a5946b7,
    0x3ff5e76f15ad2148,
    0x3ff605e1b976dc09,
    0x3ff6247eb03a5585,
    0x3ff6434634ccc320,
    0x3ff6623882552225,
    0x3ff68155d44ca973,
    0x3ff6a09e667f3bcd,
    0x3ff6c012750bdabf,
    0x3ff6dfb23c651a2f,
    0x3ff6ff7df9519484,
    0x3ff71f75e8ec5f74,
    0x3ff73f9a48a58174,
    0x3ff75feb564267c9,
    0x3ff780694fde5d3f,
    0x3ff7a11473eb0187,
    0x3ff7c1ed0130c132,
    0x3ff7e2f336cf4e62,
    0x3ff80427543e1a12,
    0x3ff82589994cce13,
    0x3ff8471a4623c7ad,
    0x3ff868d99b4492ed,
    0x3ff88ac7d98a6699,
    0x3ff8ace5422aa0db,
    0x3ff8cf3216b5448c,
    0x3ff8f1ae99157736,
    0x3ff9145b0b91ffc6,
    0x3ff93737b0cdc5e5,
    0x3ff95a44cbc8520f,
    0x3ff97d829fde4e50,
    0x3ff9a0f170ca07ba,
    0x3ff9c49182a3f090,
    0x3ff9e86319e32323,
    0x3ffa0c667b5de565,
    0x3ffa309bec4a2d33,
    0x3ffa5503b23e255d,
    0x3ffa799e1330b358,
    0x3ffa9e6b5579fdbf,
    0x3ffac36bbfd3f37a,
    0x3ffae89f995ad3ad,
    0x3ffb0e07298db666,
    0x3ffb33a2b84f15fb,
    0x3ffb59728de5593a,
    0x3ffb7f76f2fb5e47,
    0x3ffba5b030a1064a,
    0x3ffbcc1e904bc1d2,
    0x3ffbf2c25bd71e09,
    0x3ffc199bdd85529c,
    0x3ffc40ab5fffd07a,
    0x3ffc67f12e57d14b,
    0x3ffc8f6d9406e7b5,
    0x3ffcb720dcef9069,
    0x3ffcdf0b555dc3fa,
    0x3ffd072d4a07897c,
    0x3ffd2f87080d89f2,
    0x3ffd5818dcfba487,
    0x3ffd80e316c98398,
    0x3ffda9e603db3285,
    0x3ffdd321f301b460,
    0x3ffdfc97337b9b5f,
    0x3ffe264614f5a129,
    0x3ffe502ee78b3ff6,
    0x3ffe7a51fbc74c83,
    0x3ffea4afa2a490da,
    0x3ffecf482d8e67f1,
    0x3ffefa1bee615a27,
    0x3fff252b376bba97,
    0x3fff50765b6e4540,
    0x3fff7bfdad9cbe14,
    0x3fffa7c1819e90d8,
    0x3fffd3c22b8f71f1,
];

/// Range of [`exp_table`]'s own path; outside it (and for NaN) libm's exp answers.
const EXP_TABLE_MIN: f64 = -708.0;
const EXP_TABLE_MAX: f64 = 709.0;

/// 128/ln 2, and ln2/128 split so that k·HI is exact for |k| < 2¹⁸ ([`exp_table`]).
const INV_LN2_128: f64 = 184.664_965_233_787_3;
const LN2_128_HI: f64 = f64::from_bits(0x3f76_2e42_fef8_0000);
const LN2_128_LO: f64 = 1.265_508_608_332_543_8e-13;
/// 1.5 · 2⁵²: adding it rounds to an integer, which then sits in the low mantissa bits.
const SHIFTER: f64 = 6_755_399_441_055_744.0;

/// The rounding of [`exp_table`] on any lane type: z = x·128/ln 2 + [`SHIFTER`], which holds
/// k = round(128x/ln 2) in its low mantissa bits, and k as a float; returned as (z, k).
#[inline(always)]
fn exp_table_round<V: Copy, S, M, A, B>(o: &Lanes<V, S, M, A, B>, x: V) -> (V, V)
where
    S: Fn(f64) -> V,
    M: Fn(V, V) -> V,
    A: Fn(V, V) -> V,
    B: Fn(V, V) -> V,
{
    let (c, mul, add, sub) = (&o.splat, &o.mul, &o.add, &o.sub);
    let z = add(mul(x, c(INV_LN2_128)), c(SHIFTER));
    (z, sub(z, c(SHIFTER)))
}

/// The remainder of [`exp_table`] on any lane type: r = x − k·ln2/128 (Cody–Waite), k a float.
/// The kernels take it after reading k's integer bits, in the order of the hand-written kernels
/// before (their instruction schedule, hence their speed, depends on it).
#[inline(always)]
fn exp_table_remainder<V: Copy, S, M, A, B>(o: &Lanes<V, S, M, A, B>, x: V, kf: V) -> V
where
    S: Fn(f64) -> V,
    M: Fn(V, V) -> V,
    A: Fn(V, V) -> V,
    B: Fn(V, V) -> V,
{
    let (c, mul, sub) = (&o.splat, &o.mul, &o.sub);
    sub(sub(x, mul(kf, c(LN2_128_HI))), mul(kf, c(LN2_128_LO)))
}

/// e^r of [`exp_table`] on any lane type: its series to r⁵.
#[inline(always)]
fn exp_table_series<V: Copy, S, M, A, B>(o: &Lanes<V, S, M, A, B>, r: V) -> V
where
    S: Fn(f64) -> V,
    M: Fn(V, V) -> V,
    A: Fn(V, V) -> V,
    B: Fn(V, V) -> V,
{
    let (c, mul, add) = (&o.splat, &o.mul, &o.add);
    let r2 = mul(r, r);
    let inner = add(
        add(c(0.5), mul(r, c(1.0 / 6.0))),
        mul(r2, add(c(1.0 / 24.0), mul(r, c(1.0 / 120.0)))),
    );
    add(add(c(1.0), r), mul(r2, inner))
}

/// e^x within 2 ulp, inlined and without libm's call: x = (128e + j + f)·ln2/128 with
/// |f·ln2/128| ≤ ln2/256, e^x = 2^e · 2^(j/128) · e^r, 2^(j/128) from a correctly rounded
/// table and e^r by its series to r⁵ (truncation below 1e-18 relative). For hot loops where a
/// call to libm's exp is the cost; x outside [−708, 709] (or NaN) goes to libm.
#[inline(always)]
pub fn exp_table(x: f64) -> f64 {
    if !(EXP_TABLE_MIN..=EXP_TABLE_MAX).contains(&x) {
        return x.exp();
    }
    let (z, kf) = exp_table_round(&scalar(), x);
    let k = (z.to_bits() as i64).wrapping_sub(SHIFTER.to_bits() as i64);
    let r = exp_table_remainder(&scalar(), x, kf);
    // 2^e · 2^(j/128) by adding e to the table entry's exponent (e ∈ [−1022, 1022] here).
    let t = f64::from_bits(EXP2_TABLE[(k & 127) as usize].wrapping_add(((k >> 7) as u64) << 52));
    t * exp_table_series(&scalar(), r)
}

/// Eight lanes of [`exp_table`] for x in [−708, 709] (the caller checks the range; outside it
/// the scalar function calls libm): the scalar operations one for one, so each lane equals
/// `exp_table` bit for bit.
///
/// # Safety
/// The CPU must support AVX-512F.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
pub(crate) unsafe fn exp_table_avx512(x: std::arch::x86_64::__m512d) -> std::arch::x86_64::__m512d {
    use std::arch::x86_64::*;
    let ops = simd_lanes!(_mm512_set1_pd, _mm512_mul_pd, _mm512_add_pd, _mm512_sub_pd);
    let (z, kf) = exp_table_round(&ops, x);
    let k = _mm512_sub_epi64(
        _mm512_castpd_si512(z),
        _mm512_set1_epi64(SHIFTER.to_bits() as i64),
    );
    let r = exp_table_remainder(&ops, x, kf);
    let j = _mm512_and_si512(k, _mm512_set1_epi64(127));
    let entry = _mm512_i64gather_epi64::<8>(j, EXP2_TABLE.as_ptr() as *const i64);
    let t = _mm512_castsi512_pd(_mm512_add_epi64(
        entry,
        _mm512_slli_epi64::<52>(_mm512_srai_epi64::<7>(k)),
    ));
    _mm512_mul_pd(t, exp_table_series(&ops, r))
}

/// Four lanes of [`exp_table`] with AVX2, as [`exp_table_avx512`]: x in [−708, 709] (checked by
/// the caller), the scalar operations one for one, so each lane equals `exp_table` bit for bit.
/// AVX2 has no 64-bit arithmetic shift; k = round(128x/ln 2) lies in ±2^17, so the 32-bit one
/// on both halves of each lane is the same shift.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
pub(crate) unsafe fn exp_table_x4(x: std::arch::x86_64::__m256d) -> std::arch::x86_64::__m256d {
    use std::arch::x86_64::*;
    let ops = simd_lanes!(_mm256_set1_pd, _mm256_mul_pd, _mm256_add_pd, _mm256_sub_pd);
    let (z, kf) = exp_table_round(&ops, x);
    let k = _mm256_sub_epi64(
        _mm256_castpd_si256(z),
        _mm256_set1_epi64x(SHIFTER.to_bits() as i64),
    );
    let r = exp_table_remainder(&ops, x, kf);
    let j = _mm256_and_si256(k, _mm256_set1_epi64x(127));
    let entry = _mm256_i64gather_epi64::<8>(EXP2_TABLE.as_ptr() as *const i64, j);
    let t = _mm256_castsi256_pd(_mm256_add_epi64(
        entry,
        _mm256_slli_epi64::<52>(_mm256_srai_epi32::<7>(k)),
    ));
    _mm256_mul_pd(t, exp_table_series(&ops, r))
}

/// The range of [`exp_in_range`] (normal results, no overflow).
const EXP_MIN: f64 = -708.3;
const EXP_MAX: f64 = 709.7;

/// log2 e, and fdlibm's split of ln 2: LN2_HI has 32 trailing zero bits, so n · LN2_HI is exact
/// for |n| < 2²⁰ ([`exp_in_range`]).
const LOG2E: f64 = std::f64::consts::LOG2_E;
const LN2_HI: f64 = f64::from_bits(0x3fe6_2e42_fee0_0000);
const LN2_LO: f64 = f64::from_bits(0x3dea_39ef_3579_3c76);

/// The reduction of [`exp_in_range`] on any lane type: k = x·log2 e + [`SHIFTER`] (n = round(x/ln 2)
/// in its low mantissa bits) and r = x − n ln 2 (Cody–Waite), returned as (k, r).
#[inline(always)]
fn exp_reduce<V: Copy, S, M, A, B>(o: &Lanes<V, S, M, A, B>, x: V) -> (V, V)
where
    S: Fn(f64) -> V,
    M: Fn(V, V) -> V,
    A: Fn(V, V) -> V,
    B: Fn(V, V) -> V,
{
    let (c, mul, add, sub) = (&o.splat, &o.mul, &o.add, &o.sub);
    let k = add(mul(x, c(LOG2E)), c(SHIFTER));
    let n = sub(k, c(SHIFTER));
    let r = sub(sub(x, mul(n, c(LN2_HI))), mul(n, c(LN2_LO)));
    (k, r)
}

/// e^r of [`exp_in_range`] on any lane type: its Taylor series to r¹³ in Estrin's scheme.
#[inline(always)]
fn exp_series<V: Copy, S, M, A, B>(o: &Lanes<V, S, M, A, B>, r: V) -> V
where
    S: Fn(f64) -> V,
    M: Fn(V, V) -> V,
    A: Fn(V, V) -> V,
    B: Fn(V, V) -> V,
{
    let (c, mul, add) = (&o.splat, &o.mul, &o.add);
    let r2 = mul(r, r);
    let r4 = mul(r2, r2);
    let r8 = mul(r4, r4);
    let pair = |a: f64, b: f64| add(c(a), mul(r, c(b)));
    let c01 = add(c(1.0), r);
    let c23 = pair(1.0 / 2.0, 1.0 / 6.0);
    let c45 = pair(1.0 / 24.0, 1.0 / 120.0);
    let c67 = pair(1.0 / 720.0, 1.0 / 5_040.0);
    let c89 = pair(1.0 / 40_320.0, 1.0 / 362_880.0);
    let c1011 = pair(1.0 / 3_628_800.0, 1.0 / 39_916_800.0);
    let c1213 = pair(1.0 / 479_001_600.0, 1.0 / 6_227_020_800.0);
    let q0 = add(c01, mul(r2, c23));
    let q1 = add(c45, mul(r2, c67));
    let q2 = add(c89, mul(r2, c1011));
    add(add(q0, mul(r4, q1)), mul(r8, add(q2, mul(r4, c1213))))
}

/// e^x to within a few ulp for x in [`EXP_MIN`, `EXP_MAX`], branch-free and libm-free (the body
/// of [`exp_for_sums`]): x = n ln 2 + r with |r| ≤ ½ ln 2 (Cody–Waite split of ln 2), e^r by its
/// Taylor series to r¹³ (truncation below 1e-17 relative) in Estrin's scheme, scaled by 2ⁿ
/// through the exponent bits.
#[inline(always)]
fn exp_in_range(x: f64) -> f64 {
    let (k, r) = exp_reduce(&scalar(), x);
    let poly = exp_series(&scalar(), r);
    // n sits in the low bits of k's mantissa (two's complement around the shifter).
    let ni = (k.to_bits() as i64).wrapping_sub(SHIFTER.to_bits() as i64);
    // Split 2ⁿ in two factors so that n = 1024 (x near 709.7) does not overflow the exponent.
    let half = ni >> 1;
    let s1 = f64::from_bits(((half + 1023) as u64) << 52);
    let s2 = f64::from_bits(((ni - half + 1023) as u64) << 52);
    poly * s1 * s2
}

simd_by_target! {
    /// In place, x ← `exp_in_range(x)` for x ≥ −708.3 and 0 below (where e^x < 2.2e-308: the
    /// difference cannot show in a sum that has a term near 1, the use here). −∞ gives 0; inputs
    /// must not be NaN. Branch-free, so it runs four lanes wide at the AVX2 and AVX-512 levels (the
    /// operations, hence the results, are those of the scalar `exp_in_range`).
    pub exp_for_sums, exp_for_sums_at, exp_for_sums_avx2, exp_for_sums_body, (xs: &mut [f64])
}

#[inline(always)]
fn exp_for_sums_body(xs: &mut [f64]) {
    for x in xs.iter_mut() {
        let v = *x;
        let e = exp_in_range(v.clamp(EXP_MIN, EXP_MAX));
        *x = if v < EXP_MIN { 0.0 } else { e };
    }
}

/// Eight lanes of [`exp_for_sums`]'s map, x ↦ `exp_in_range(x)` for x ≥ −708.3 and 0 below:
/// the scalar operations, one for one and in the same order (no fused multiply-adds), so each
/// lane equals the scalar result bit for bit. Inputs must not be NaN.
///
/// # Safety
/// The CPU must support AVX-512F.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
pub(crate) unsafe fn exp_for_sums_avx512(
    x: std::arch::x86_64::__m512d,
) -> std::arch::x86_64::__m512d {
    use std::arch::x86_64::*;
    let ops = simd_lanes!(_mm512_set1_pd, _mm512_mul_pd, _mm512_add_pd, _mm512_sub_pd);
    let set = |v: f64| _mm512_set1_pd(v);
    // `clamp`: below the minimum the minimum, above the maximum the maximum.
    let xc = _mm512_min_pd(_mm512_max_pd(x, set(EXP_MIN)), set(EXP_MAX));
    let (k, r) = exp_reduce(&ops, xc);
    let poly = exp_series(&ops, r);
    let ni = _mm512_sub_epi64(
        _mm512_castpd_si512(k),
        _mm512_set1_epi64(SHIFTER.to_bits() as i64),
    );
    let half = _mm512_srai_epi64::<1>(ni);
    let bias = _mm512_set1_epi64(1023);
    let s1 = _mm512_castsi512_pd(_mm512_slli_epi64::<52>(_mm512_add_epi64(half, bias)));
    let s2 = _mm512_castsi512_pd(_mm512_slli_epi64::<52>(_mm512_add_epi64(
        _mm512_sub_epi64(ni, half),
        bias,
    )));
    let e = _mm512_mul_pd(_mm512_mul_pd(poly, s1), s2);
    let below = _mm512_cmp_pd_mask::<_CMP_LT_OQ>(x, set(EXP_MIN));
    _mm512_mask_blend_pd(below, e, _mm512_setzero_pd())
}

/// Four lanes of [`exp_for_sums`]'s map with AVX2, as [`exp_for_sums_avx512`]: each lane equals
/// the scalar result bit for bit. Inputs must not be NaN. (n ∈ [−1022, 1024] fits 32 bits, so the
/// 32-bit arithmetic shift is the 64-bit one.)
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
pub(crate) unsafe fn exp_for_sums_x4(x: std::arch::x86_64::__m256d) -> std::arch::x86_64::__m256d {
    use std::arch::x86_64::*;
    let ops = simd_lanes!(_mm256_set1_pd, _mm256_mul_pd, _mm256_add_pd, _mm256_sub_pd);
    let set = |v: f64| _mm256_set1_pd(v);
    // `clamp`: below the minimum the minimum, above the maximum the maximum.
    let xc = _mm256_min_pd(_mm256_max_pd(x, set(EXP_MIN)), set(EXP_MAX));
    let (k, r) = exp_reduce(&ops, xc);
    let poly = exp_series(&ops, r);
    let ni = _mm256_sub_epi64(
        _mm256_castpd_si256(k),
        _mm256_set1_epi64x(SHIFTER.to_bits() as i64),
    );
    let half = _mm256_srai_epi32::<1>(ni);
    let bias = _mm256_set1_epi64x(1023);
    let s1 = _mm256_castsi256_pd(_mm256_slli_epi64::<52>(_mm256_add_epi64(half, bias)));
    let s2 = _mm256_castsi256_pd(_mm256_slli_epi64::<52>(_mm256_add_epi64(
        _mm256_sub_epi64(ni, half),
        bias,
    )));
    let e = _mm256_mul_pd(_mm256_mul_pd(poly, s1), s2);
    let below = _mm256_cmp_pd::<_CMP_LT_OQ>(x, set(EXP_MIN));
    _mm256_blendv_pd(e, _mm256_setzero_pd(), below)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simd::SimdLevel;

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
        for level in SimdLevel::ALL {
            if !level.supported() {
                crate::simd::report_skip("slice_exp_equals_the_scalar_exp_in_range", level);
                continue;
            }
            let mut out = xs.clone();
            exp_for_sums_at(level, &mut out);
            for (x, o) in xs.iter().zip(&out) {
                let want = if *x < -708.3 { 0.0 } else { exp_in_range(*x) };
                assert_eq!(o.to_bits(), want.to_bits(), "{level} {x}");
            }
        }
    }

    /// The vector map of `level` (eight or four lanes) over `xs`, or None (reported as skipped)
    /// where the CPU lacks the level.
    #[cfg(target_arch = "x86_64")]
    fn lanes_map(
        test: &str,
        level: SimdLevel,
        xs: &[f64],
        wide: unsafe fn(std::arch::x86_64::__m512d) -> std::arch::x86_64::__m512d,
        narrow: unsafe fn(std::arch::x86_64::__m256d) -> std::arch::x86_64::__m256d,
    ) -> Option<Vec<f64>> {
        use std::arch::x86_64::*;
        if !level.supported() {
            crate::simd::report_skip(test, level);
            return None;
        }
        let mut got = xs.to_vec();
        match level {
            // SAFETY: the CPU supports the level, checked above.
            SimdLevel::Avx512 => {
                for c in got.chunks_exact_mut(8) {
                    unsafe { _mm512_storeu_pd(c.as_mut_ptr(), wide(_mm512_loadu_pd(c.as_ptr()))) };
                }
            }
            SimdLevel::Avx2 => {
                for c in got.chunks_exact_mut(4) {
                    unsafe {
                        _mm256_storeu_pd(c.as_mut_ptr(), narrow(_mm256_loadu_pd(c.as_ptr())))
                    };
                }
            }
            SimdLevel::Scalar => return None,
        }
        Some(got)
    }

    #[test]
    fn vector_exp_equals_the_scalar_exp_bit_for_bit_at_every_level() {
        let mut rng = crate::rng::Rng::new(5);
        let xs: Vec<f64> = (0..4096)
            .map(|i| match i % 13 {
                0 => f64::NEG_INFINITY,
                1 => -708.4,
                2 => -708.3,
                3 => 0.0,
                4 => -0.0,
                5 => 709.7,
                6 => -rng.uniform() * 720.0,
                7 => (rng.uniform() - 0.5) * 1400.0,
                _ => -rng.uniform() * 3.0,
            })
            .collect();
        let mut want = xs.clone();
        exp_for_sums_body(&mut want);
        #[cfg(target_arch = "x86_64")]
        for level in [SimdLevel::Avx2, SimdLevel::Avx512] {
            let test = "vector_exp_equals_the_scalar_exp";
            let Some(got) = lanes_map(test, level, &xs, exp_for_sums_avx512, exp_for_sums_x4)
            else {
                continue;
            };
            for ((g, w), x) in got.iter().zip(&want).zip(&xs) {
                assert_eq!(g.to_bits(), w.to_bits(), "{level} {x}");
            }
        }
    }

    #[test]
    fn vector_table_exp_equals_the_scalar_one_bit_for_bit_at_every_level() {
        let mut rng = crate::rng::Rng::new(8);
        let xs: Vec<f64> = (0..8192)
            .map(|i| match i % 11 {
                0 => -708.0,
                1 => 709.0,
                2 => 0.0,
                3 => -0.0,
                4 => (rng.uniform() - 0.5) * 1e-9,
                5 => rng.uniform() * 1417.0 - 708.0,
                _ => -rng.uniform() * 40.0,
            })
            .collect();
        #[cfg(target_arch = "x86_64")]
        for level in [SimdLevel::Avx2, SimdLevel::Avx512] {
            let test = "vector_table_exp_equals_the_scalar_one";
            let Some(got) = lanes_map(test, level, &xs, exp_table_avx512, exp_table_x4) else {
                continue;
            };
            for (g, &x) in got.iter().zip(&xs) {
                assert_eq!(g.to_bits(), exp_table(x).to_bits(), "{level} {x}");
            }
        }
        let _ = &xs;
    }

    #[test]
    fn table_exp_is_within_two_ulp_of_libm() {
        let mut rng = crate::rng::Rng::new(6);
        let mut worst: f64 = 0.0;
        for i in 0..400_000 {
            let x = match i % 4 {
                0 => rng.uniform() * 1417.0 - 708.0,
                1 => (rng.uniform() - 0.5) * 1e-6,
                2 => -rng.uniform() * 40.0,
                _ => (rng.uniform() - 0.5) * 4.0,
            };
            let (a, b) = (exp_table(x), x.exp());
            worst = worst.max((a - b).abs() / b);
        }
        assert!(worst < 4.5e-16, "{worst}");
        for x in [0.0, -0.0, 1.0, -708.0, 709.0, -708.5, 709.5, -800.0, 800.0] {
            let (a, b) = (exp_table(x), x.exp());
            assert!(a == b || (a - b).abs() <= 4.5e-16 * b, "{x}: {a} vs {b}");
        }
        assert_eq!(exp_table(0.0), 1.0);
        assert_eq!(exp_table(f64::NEG_INFINITY), 0.0);
        assert_eq!(exp_table(f64::INFINITY), f64::INFINITY);
        assert!(exp_table(f64::NAN).is_nan());
    }

    #[test]
    fn libm_free_exp_is_accurate_over_its_range() {
        let mut rng = crate::rng::Rng::new(2);
        let mut worst: f64 = 0.0;
        for _ in 0..400_000 {
            let x = rng.uniform() * (EXP_MAX - EXP_MIN) + EXP_MIN;
            let (a, b) = (exp_in_range(x), x.exp());
            worst = worst.max((a - b).abs() / b);
        }
        for x in [
            0.0,
            1.0,
            -1.0,
            0.5 * std::f64::consts::LN_2,
            EXP_MAX,
            EXP_MIN,
            1e-300,
        ] {
            worst = worst.max((exp_in_range(x) - x.exp()).abs() / x.exp());
        }
        assert!(worst < 1e-15, "{worst}");
    }
}
