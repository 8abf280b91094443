//! Fast, accurate scalar kernels for the CRMI inner loops: Φ by quintic Hermite interpolation
//! of a table (absolute error < 1e-13) and a branch-free natural log (a few ulp).

use std::sync::OnceLock;

use crate::sensor::normal_cdf;

/// Table spacing of [`normal_cdf_fast`] (in σ units).
const STEP: f64 = 1.0 / 32.0;
/// Φ is tabulated on [−LIMIT, 0]; beyond, Φ(−8.5) < 1e-17 is taken as 0 (and Φ(u) = 1 − Φ(−u)).
const LIMIT: f64 = 8.5;

struct CdfTable {
    /// (Φ, φ, φ′) at u_k = −LIMIT + k·STEP, k = 0..=N.
    nodes: Vec<[f64; 3]>,
}

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
            .collect();
        CdfTable { nodes }
    })
}

/// The lower tail Φ(u) for u ≤ 0, by quintic Hermite interpolation between tabulated Φ, φ, φ′.
#[inline]
fn lower_tail(u: f64) -> f64 {
    if u <= -LIMIT {
        return 0.0;
    }
    let t = table();
    let x = (u + LIMIT) / STEP;
    let k = (x as usize).min(t.nodes.len() - 2);
    let s = x - k as f64;
    let (a, b) = (t.nodes[k], t.nodes[k + 1]);
    let (s2, s3) = (s * s, s * s * s);
    let (s4, s5) = (s3 * s, s3 * s2);
    let h0 = 1.0 - 10.0 * s3 + 15.0 * s4 - 6.0 * s5;
    let h1 = s - 6.0 * s3 + 8.0 * s4 - 3.0 * s5;
    let h2 = 0.5 * s2 - 1.5 * s3 + 1.5 * s4 - 0.5 * s5;
    let h3 = 0.5 * s3 - s4 + 0.5 * s5;
    let h4 = -4.0 * s3 + 7.0 * s4 - 3.0 * s5;
    let h5 = 10.0 * s3 - 15.0 * s4 + 6.0 * s5;
    a[0] * h0
        + STEP * a[1] * h1
        + STEP * STEP * (a[2] * h2 + b[2] * h3)
        + STEP * b[1] * h4
        + b[0] * h5
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

/// `out[i] = ln_normal(max(xs[i], f64::MIN_POSITIVE))` over two equal-length slices. On x86-64
/// CPUs with AVX2 the same code runs four lanes wide (the operations, hence the results, are
/// those of [`ln_normal`]: no FMA contraction); elsewhere two lanes (SSE2) or scalar.
pub fn ln_clamped_slice(xs: &[f64], out: &mut [f64]) {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2, checked just above.
            unsafe { ln_clamped_slice_avx2(xs, out) };
            return;
        }
    }
    ln_clamped_slice_body(xs, out);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn ln_clamped_slice_avx2(xs: &[f64], out: &mut [f64]) {
    ln_clamped_slice_body(xs, out);
}

#[inline(always)]
fn ln_clamped_slice_body(xs: &[f64], out: &mut [f64]) {
    for (o, &x) in out.iter_mut().zip(xs) {
        *o = ln_normal(x.max(f64::MIN_POSITIVE));
    }
}

/// In place, x ← [`exp_fast`](x) for x ≥ −708.3 and 0 below (where e^x < 2.2e-308: the
/// difference cannot show in a sum that has a term near 1, the use here). −∞ gives 0; inputs
/// must not be NaN. Branch-free, so it runs four lanes wide on CPUs with AVX2 (the operations,
/// hence the results, are those of [`exp_fast`]).
pub fn exp_for_sums(xs: &mut [f64]) {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2, checked just above.
            unsafe { exp_for_sums_avx2(xs) };
            return;
        }
    }
    exp_for_sums_body(xs);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn exp_for_sums_avx2(xs: &mut [f64]) {
    exp_for_sums_body(xs);
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
