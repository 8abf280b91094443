//! The natural logarithm of the CRMI and FSMI inner loops: a scalar, division-free, table-driven
//! log ([`ln_normal`], a few ulp) and slice kernels that run it eight lanes wide with explicit
//! AVX-512 (the tables held in registers and read with two-register permutes), four lanes wide
//! with explicit AVX2 (the tables read with in-register permutes) or scalar, by
//! [`crate::simd::level`]. Every path performs the scalar's
//! operations in its order, without FMA, so results do not depend on the CPU (tested bit for bit).

#[cfg(target_arch = "x86_64")]
use crate::numeric::lanes::simd_lanes;
use crate::numeric::lanes::{scalar, Lanes};

/// The nodes c_j (exact, as bits): 1 + j/16 for j < 8, (1 + j/16)/2 for the halved mantissas.
const C_NODE: [u64; 16] = [
    0x3ff0000000000000,
    0x3ff1000000000000,
    0x3ff2000000000000,
    0x3ff3000000000000,
    0x3ff4000000000000,
    0x3ff5000000000000,
    0x3ff6000000000000,
    0x3ff7000000000000,
    0x3fe8000000000000,
    0x3fe9000000000000,
    0x3fea000000000000,
    0x3feb000000000000,
    0x3fec000000000000,
    0x3fed000000000000,
    0x3fee000000000000,
    0x3fef000000000000,
];
/// 1/c_j, correctly rounded (bits).
const INV_NODE: [u64; 16] = [
    0x3ff0000000000000,
    0x3fee1e1e1e1e1e1e,
    0x3fec71c71c71c71c,
    0x3feaf286bca1af28,
    0x3fe999999999999a,
    0x3fe8618618618618,
    0x3fe745d1745d1746,
    0x3fe642c8590b2164,
    0x3ff5555555555555,
    0x3ff47ae147ae147b,
    0x3ff3b13b13b13b14,
    0x3ff2f684bda12f68,
    0x3ff2492492492492,
    0x3ff1a7b9611a7b96,
    0x3ff1111111111111,
    0x3ff0842108421084,
];
/// ln c_j, correctly rounded (bits).
const LN_NODE: [u64; 16] = [
    0x0000000000000000,
    0x3faf0a30c01162a6,
    0x3fbe27076e2af2e6,
    0x3fc5ff3070a793d4,
    0x3fcc8ff7c79a9a22,
    0x3fd1675cababa60e,
    0x3fd4618bc21c5ec2,
    0x3fd739d7f6bbd007,
    0xbfd269621134db92,
    0xbfcf991c6cb3b379,
    0xbfca93ed3c8ad9e3,
    0xbfc5bf406b543db2,
    0xbfc1178e8227e47c,
    0xbfb9335e5d594989,
    0xbfb08598b59e3a07,
    0xbfa0415d89e74444,
];

const MANTISSA: u64 = 0x000f_ffff_ffff_ffff;
const ONE: u64 = 0x3ff0_0000_0000_0000;
const TWO52: f64 = 4_503_599_627_370_496.0;
/// Mantissas at or above this are halved (and the exponent raised), so that m ∈ [47/64, 47/32).
const HALVE_FROM: f64 = 1.468_75;
const LN_2: f64 = std::f64::consts::LN_2;
/// ln(1 + r) = r + r² Q(r) on r ∈ [−0.0209, 0.0323] (every |r| the nodes leave): Q's degree-7
/// least-squares fit in the weight r², within 1.2e-16 relative of ln(1 + r) there (evaluated in
/// double; Taylor's series needs degree 10 for the same).
const Q: [f64; 8] = [
    -0.500_000_000_000_001_1,
    0.333_333_333_333_477_87,
    -0.249_999_999_986_732_17,
    0.199_999_998_457_970_45,
    -0.166_666_701_729_382_47,
    0.142_862_306_411_616_96,
    -0.125_019_844_257_254_04,
    0.105_621_334_307_632_25,
];

/// ln x = e ln 2 + ln c_j + ln(1 + r) on any lane type, from e, r and the lookup of ln c_j:
/// ln(1 + r) = r + r² Q(r) with Q in Estrin's scheme (the last steps of [`ln_normal`] and its
/// vector kernels). The lookup runs where the sum needs it, as in the hand-written kernels
/// before (the instruction schedule, hence the speed, depends on that order).
#[inline(always)]
fn ln_from_parts<V: Copy, S, M, A, B>(
    o: &Lanes<V, S, M, A, B>,
    e: V,
    r: V,
    ln_node: impl FnOnce() -> V,
) -> V
where
    S: Fn(f64) -> V,
    M: Fn(V, V) -> V,
    A: Fn(V, V) -> V,
    B: Fn(V, V) -> V,
{
    let (c, mul, add) = (&o.splat, &o.mul, &o.add);
    let r2 = mul(r, r);
    let r4 = mul(r2, r2);
    let q01 = add(c(Q[0]), mul(r, c(Q[1])));
    let q23 = add(c(Q[2]), mul(r, c(Q[3])));
    let q45 = add(c(Q[4]), mul(r, c(Q[5])));
    let q67 = add(c(Q[6]), mul(r, c(Q[7])));
    let q = add(add(q01, mul(r2, q23)), mul(r4, add(q45, mul(r2, q67))));
    add(mul(e, c(LN_2)), add(ln_node(), add(r, mul(r2, q))))
}

/// Natural log of a positive, normal, finite x to within a few ulp (relative in [0.73, 1.47),
/// where no e ln 2 term can cancel, absolute elsewhere), branch-free and without a division:
/// x = 2^e·m with m ∈ [47/64, 47/32), its node c_j (1 + j/16, or half that for the halved
/// mantissas; m − c_j is exact and |r| ≤ 1/32 for r = (m − c_j)·(1/c_j)), then
/// ln x = e ln 2 + ln c_j + ln(1 + r), the last by a degree-9 polynomial (`Q`) in Estrin's
/// scheme (e ln 2 with one constant: its rounding, |e|·2.3e-17, is below an ulp of e ln 2).
/// ln(1) is exactly 0 (there c_0 = 1 and r = 0). The exponent is read as a float through the
/// 2^52 trick and j straight from the mantissa bits, so the only loads are three 16-entry tables
/// and loops over it vectorise (on wide vectors the division of the earlier atanh form was the
/// bottleneck).
#[inline(always)]
pub fn ln_normal(x: f64) -> f64 {
    let bits = x.to_bits();
    let e = f64::from_bits(TWO52.to_bits() | (bits >> 52)) - (TWO52 + 1023.0);
    let m = f64::from_bits((bits & MANTISSA) | ONE);
    let big = m >= HALVE_FROM;
    let m = if big { 0.5 * m } else { m };
    let e = if big { e + 1.0 } else { e };
    let j = node_index(bits);
    let r = (m - f64::from_bits(C_NODE[j])) * f64::from_bits(INV_NODE[j]);
    ln_from_parts(&scalar(), e, r, || f64::from_bits(LN_NODE[j]))
}

/// The node of a mantissa: round-half-up of its fraction in sixteenths, modulo 16, read from the
/// bits. It is 8 or more exactly for the mantissas that are halved (from 1 + 7.5/16 on), whose
/// table entries hold the halved nodes, except those from 1 + 15.5/16 on, which carry to 16, i.e.
/// 0, whose node c_0 = 1 is also their halved node (1 + 16/16)/2.
#[inline(always)]
fn node_index(bits: u64) -> usize {
    ((bits.wrapping_add(1 << 47) >> 48) & 15) as usize
}

/// [`ln_normal`] of eight lanes with explicit AVX-512F: the same operations in the same order
/// (the node tables are read with `vpermt2pd` from registers instead of memory), so every lane
/// equals the scalar bit for bit.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
#[inline]
pub(crate) unsafe fn ln_normal_x8(x: std::arch::x86_64::__m512d) -> std::arch::x86_64::__m512d {
    use std::arch::x86_64::*;
    let c = |v: f64| _mm512_set1_pd(v);
    let table =
        |t: &[u64; 16], half: usize| _mm512_loadu_pd(t.as_ptr().add(8 * half) as *const f64);
    let bits = _mm512_castpd_si512(x);
    // The exponent and the mantissa in [1, 2) of a positive normal x: exact, so equal to the
    // scalar's bit manipulations.
    let e = _mm512_getexp_pd(x);
    let m = _mm512_getmant_pd::<_MM_MANT_NORM_1_2, _MM_MANT_SIGN_SRC>(x);
    let big = _mm512_cmp_pd_mask::<_CMP_GE_OQ>(m, c(HALVE_FROM));
    let m = _mm512_mask_mul_pd(m, big, m, c(0.5));
    let e = _mm512_mask_add_pd(e, big, e, c(1.0));
    // vpermt2pd reads the low four bits of each lane: the node index, bit 3 choosing the half.
    let j = _mm512_srli_epi64::<48>(_mm512_add_epi64(bits, _mm512_set1_epi64(1 << 47)));
    let node = |t: &[u64; 16]| _mm512_permutex2var_pd(table(t, 0), j, table(t, 1));
    let r = _mm512_mul_pd(_mm512_sub_pd(m, node(&C_NODE)), node(&INV_NODE));
    let ops = simd_lanes!(_mm512_set1_pd, _mm512_mul_pd, _mm512_add_pd, _mm512_sub_pd);
    ln_from_parts(&ops, e, r, || node(&LN_NODE))
}

/// [`ln_normal`] of four lanes with explicit AVX2: the scalar's operations in its order (the
/// exponent read through the 2^52 trick, the node tables looked up with in-register permutes
/// instead of gathers), so every lane equals the scalar bit for bit.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
pub(crate) unsafe fn ln_normal_x4(x: std::arch::x86_64::__m256d) -> std::arch::x86_64::__m256d {
    use std::arch::x86_64::*;
    let c = |v: f64| _mm256_set1_pd(v);
    let ci = |v: u64| _mm256_set1_epi64x(v as i64);
    let bits = _mm256_castpd_si256(x);
    let e = _mm256_sub_pd(
        _mm256_castsi256_pd(_mm256_or_si256(
            ci(TWO52.to_bits()),
            _mm256_srli_epi64::<52>(bits),
        )),
        c(TWO52 + 1023.0),
    );
    let m = _mm256_castsi256_pd(_mm256_or_si256(
        _mm256_and_si256(bits, ci(MANTISSA)),
        ci(ONE),
    ));
    let big = _mm256_cmp_pd::<_CMP_GE_OQ>(m, c(HALVE_FROM));
    let m = _mm256_blendv_pd(m, _mm256_mul_pd(c(0.5), m), big);
    let e = _mm256_blendv_pd(e, _mm256_add_pd(e, c(1.0)), big);
    let j = _mm256_and_si256(
        _mm256_srli_epi64::<48>(_mm256_add_epi64(bits, ci(1 << 47))),
        ci(15),
    );
    // Table entry j of each lane: the dword pair (2(j mod 4), 2(j mod 4) + 1) of each of the four
    // quarters, then bits 2 and 3 of j (moved to the sign bit) choose the quarter.
    let low2 = _mm256_slli_epi64::<1>(_mm256_and_si256(j, ci(3)));
    let pair = _mm256_or_si256(low2, _mm256_slli_epi64::<32>(_mm256_add_epi64(low2, ci(1))));
    let (bit2, bit3) = (
        _mm256_castsi256_pd(_mm256_slli_epi64::<61>(j)),
        _mm256_castsi256_pd(_mm256_slli_epi64::<60>(j)),
    );
    let node = |t: &[u64; 16]| {
        let q = |k: usize| {
            _mm256_castsi256_pd(_mm256_permutevar8x32_epi32(
                _mm256_loadu_si256(t.as_ptr().add(4 * k) as *const __m256i),
                pair,
            ))
        };
        let lo = _mm256_blendv_pd(q(0), q(1), bit2);
        let hi = _mm256_blendv_pd(q(2), q(3), bit2);
        _mm256_blendv_pd(lo, hi, bit3)
    };
    let (mul, add) = (|a, b| _mm256_mul_pd(a, b), |a, b| _mm256_add_pd(a, b));
    // The node c_j itself needs no table: (1 + j/16), halved from j = 8 on, every step exact.
    let jf = _mm256_sub_pd(
        _mm256_castsi256_pd(_mm256_or_si256(j, ci(TWO52.to_bits()))),
        c(TWO52),
    );
    let c_node = mul(
        add(c(1.0), mul(jf, c(1.0 / 16.0))),
        _mm256_blendv_pd(c(1.0), c(0.5), bit3),
    );
    let r = mul(_mm256_sub_pd(m, c_node), node(&INV_NODE));
    let ops = simd_lanes!(_mm256_set1_pd, _mm256_mul_pd, _mm256_add_pd, _mm256_sub_pd);
    ln_from_parts(&ops, e, r, || node(&LN_NODE))
}

/// `$vis fn $name(args)` runs `$at(`[`crate::simd::level`]`(), args)`; `$vis fn $at(level, args)`
/// runs the explicit eight-lane `$wide(args)` at AVX-512, the explicit four-lane `$avx(args)` at
/// AVX2 and `$body(args)` otherwise (a level the CPU lacks is lowered to one it has). The vector
/// versions must equal `$body` bit for bit.
macro_rules! log_slice_kernel {
    ($(#[$doc:meta])* $vis:vis $name:ident, $at:ident, $wide:ident, $avx:ident, $body:ident,
     ($($arg:ident: $ty:ty),*)) => {
        $(#[$doc])*
        $vis fn $name($($arg: $ty),*) {
            $at($crate::simd::level(), $($arg),*)
        }

        #[doc = concat!("[`", stringify!($name), "`] at a given level (lowered to the best the CPU supports).")]
        $vis fn $at(level: $crate::simd::SimdLevel, $($arg: $ty),*) {
            match level.runnable() {
                // SAFETY: `runnable` only returns levels the CPU supports.
                #[cfg(target_arch = "x86_64")]
                $crate::simd::SimdLevel::Avx512 => unsafe { $wide($($arg),*) },
                #[cfg(target_arch = "x86_64")]
                $crate::simd::SimdLevel::Avx2 => unsafe { $avx($($arg),*) },
                _ => $body($($arg),*),
            }
        }
    };
}

log_slice_kernel! {
    /// `out[i] = ln_normal(max(xs[i], f64::MIN_POSITIVE))` over two equal-length slices, eight
    /// lanes wide with AVX-512F, four with AVX2, scalar elsewhere (the same results on every path).
    pub ln_clamped_slice, ln_clamped_slice_at, ln_clamped_slice_wide, ln_clamped_slice_avx2,
    ln_clamped_slice_body,
    (xs: &[f64], out: &mut [f64])
}

#[inline(always)]
fn ln_clamped_slice_body(xs: &[f64], out: &mut [f64]) {
    for (o, &x) in out.iter_mut().zip(xs) {
        *o = ln_normal(x.max(f64::MIN_POSITIVE));
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn ln_clamped_slice_wide(xs: &[f64], out: &mut [f64]) {
    use std::arch::x86_64::*;
    let n = xs.len().min(out.len());
    let whole = n / 8 * 8;
    let tiny = _mm512_set1_pd(f64::MIN_POSITIVE);
    for i in (0..whole).step_by(8) {
        // max(x, tiny) returns tiny for NaN x, as f64::max does.
        let x = _mm512_max_pd(_mm512_loadu_pd(xs.as_ptr().add(i)), tiny);
        _mm512_storeu_pd(out.as_mut_ptr().add(i), ln_normal_x8(x));
    }
    ln_clamped_slice_body(&xs[whole..n], &mut out[whole..n]);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn ln_clamped_slice_avx2(xs: &[f64], out: &mut [f64]) {
    use std::arch::x86_64::*;
    let n = xs.len().min(out.len());
    let whole = n / 4 * 4;
    let tiny = _mm256_set1_pd(f64::MIN_POSITIVE);
    for i in (0..whole).step_by(4) {
        // max(x, tiny) with tiny second returns tiny for NaN x, as f64::max does.
        let x = _mm256_max_pd(_mm256_loadu_pd(xs.as_ptr().add(i)), tiny);
        _mm256_storeu_pd(out.as_mut_ptr().add(i), ln_normal_x4(x));
    }
    ln_clamped_slice_body(&xs[whole..n], &mut out[whole..n]);
}

log_slice_kernel! {
    /// ln(1 + x) of every `xs[i]` into `out[i]` for x > −1 with 1 + x normal, to within a few ulp,
    /// in one pass that vectorises like [`ln_clamped_slice`]: u = 1 + x rounded, then
    /// ln(1 + x) = ln(u) · x/(u − 1), which cancels u's rounding error (x itself when u = 1).
    pub ln_1p_slice, ln_1p_slice_at, ln_1p_slice_wide, ln_1p_slice_avx2, ln_1p_slice_body,
    (xs: &[f64], out: &mut [f64])
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

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn ln_1p_slice_wide(xs: &[f64], out: &mut [f64]) {
    use std::arch::x86_64::*;
    let n = xs.len().min(out.len());
    let whole = n / 8 * 8;
    let (zero, one) = (_mm512_setzero_pd(), _mm512_set1_pd(1.0));
    for i in (0..whole).step_by(8) {
        let x = _mm512_loadu_pd(xs.as_ptr().add(i));
        let u = _mm512_add_pd(one, x);
        let d = _mm512_sub_pd(u, one);
        let exact = _mm512_cmp_pd_mask::<_CMP_EQ_OQ>(d, zero);
        let ratio = _mm512_div_pd(x, _mm512_mask_blend_pd(exact, d, one));
        let scaled = _mm512_mul_pd(ln_normal_x8(u), ratio);
        _mm512_storeu_pd(
            out.as_mut_ptr().add(i),
            _mm512_mask_blend_pd(exact, scaled, x),
        );
    }
    ln_1p_slice_body(&xs[whole..n], &mut out[whole..n]);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn ln_1p_slice_avx2(xs: &[f64], out: &mut [f64]) {
    use std::arch::x86_64::*;
    let n = xs.len().min(out.len());
    let whole = n / 4 * 4;
    let (zero, one) = (_mm256_setzero_pd(), _mm256_set1_pd(1.0));
    for i in (0..whole).step_by(4) {
        let x = _mm256_loadu_pd(xs.as_ptr().add(i));
        let u = _mm256_add_pd(one, x);
        let d = _mm256_sub_pd(u, one);
        let exact = _mm256_cmp_pd::<_CMP_EQ_OQ>(d, zero);
        let ratio = _mm256_div_pd(x, _mm256_blendv_pd(d, one, exact));
        let scaled = _mm256_mul_pd(ln_normal_x4(u), ratio);
        _mm256_storeu_pd(out.as_mut_ptr().add(i), _mm256_blendv_pd(scaled, x, exact));
    }
    ln_1p_slice_body(&xs[whole..n], &mut out[whole..n]);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simd::SimdLevel;

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
    fn slice_log_equals_the_scalar_log_bit_for_bit_at_every_level() {
        let mut rng = crate::rng::Rng::new(3);
        let xs: Vec<f64> = (0..1003)
            .map(|i| match i % 7 {
                0 => 0.0,
                1 => -1.0,
                2 => f64::NAN,
                _ => (rng.uniform() * 60.0 - 30.0).exp2(),
            })
            .collect();
        for level in SimdLevel::ALL {
            if !level.supported() {
                crate::simd::report_skip("slice_log_equals_the_scalar_log", level);
                continue;
            }
            let mut out = vec![0.0; xs.len()];
            ln_clamped_slice_at(level, &xs, &mut out);
            for (x, o) in xs.iter().zip(&out) {
                let want = ln_normal(x.max(f64::MIN_POSITIVE)).to_bits();
                assert_eq!(o.to_bits(), want, "{level} {x}");
            }
            let ys: Vec<f64> = xs
                .iter()
                .map(|x| if x.is_nan() { 0.5 } else { x.clamp(-0.9, 1e6) })
                .collect();
            let (mut a, mut b) = (vec![0.0; ys.len()], vec![0.0; ys.len()]);
            ln_1p_slice_at(level, &ys, &mut a);
            ln_1p_slice_body(&ys, &mut b);
            for (y, (p, q)) in ys.iter().zip(a.iter().zip(&b)) {
                assert_eq!(p.to_bits(), q.to_bits(), "{level} {y}");
            }
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

    #[test]
    fn log_is_exact_at_one_and_keeps_relative_accuracy_near_it() {
        assert_eq!(ln_normal(1.0).to_bits(), 0.0f64.to_bits());
        for x in [
            1.0 + 1e-12,
            1.0 - 1e-12,
            1.0 + 3e-5,
            0.999,
            1.02,
            0.97,
            0.74,
            1.46,
            0.8f64,
        ] {
            let want = x.ln();
            assert!(((ln_normal(x) - want) / want).abs() < 4e-16, "{x}");
        }
    }

    #[test]
    fn slice_kernels_give_the_scalar_bits_on_every_node_and_edge() {
        // Every table node, both sides of the halving edge and of each rounding boundary.
        let top = 1.0 + 15.5 / 16.0;
        let mut xs = vec![
            HALVE_FROM,
            HALVE_FROM.next_down(),
            top,
            top.next_down(),
            1.0,
            2.0,
            0.5,
        ];
        xs.extend([1e-300, 1e300, 2.0f64.next_down(), 0.5f64.next_up()]);
        for j in 0..16 {
            let edge = 1.0 + (j as f64 + 0.5) / 16.0;
            xs.extend([
                edge,
                edge.next_down(),
                edge.next_up(),
                1.0 + j as f64 / 16.0,
            ]);
        }
        let ys: Vec<f64> = xs.iter().map(|x| (x - 1.0).max(-0.9)).collect();
        for level in SimdLevel::ALL {
            if !level.supported() {
                crate::simd::report_skip("slice_kernels_give_the_scalar_bits", level);
                continue;
            }
            let mut out = vec![0.0; xs.len()];
            ln_clamped_slice_at(level, &xs, &mut out);
            for (x, o) in xs.iter().zip(&out) {
                assert_eq!(o.to_bits(), ln_normal(*x).to_bits(), "{level} {x}");
                assert!((o - x.ln()).abs() <= 2e-16 * x.ln().abs().max(1.0), "{x}");
            }
            let (mut a, mut b) = (vec![0.0; ys.len()], vec![0.0; ys.len()]);
            ln_1p_slice_at(level, &ys, &mut a);
            ln_1p_slice_body(&ys, &mut b);
            for (x, y) in a.iter().zip(&b) {
                assert_eq!(x.to_bits(), y.to_bits(), "{level}");
            }
        }
    }
}
