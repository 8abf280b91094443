//! Numerics shared by several layers: the standard normal CDF and the fast, bit-reproducible
//! kernels of the hot loops (sensor likelihoods, CRM lanes, information functions).
//!
//! - [`normal_cdf`]: Φ(x) accurate in both tails (libm's erfc), the reference of the fast kernels.
//! - [`fastlog`]: the table-driven logarithm and its AVX2 / AVX-512 slice kernels.
//! - [`fastexp`]: the exponentials (a table and a series, libm-free) and their lane kernels.
//! - [`fastmath`]: Φ by table interpolation and its slice kernels (uses [`normal_cdf`]);
//!   re-exports the logarithms of [`fastlog`] and the exponentials of [`fastexp`].
//!
//! Order inside: `lanes` (the arithmetic that the scalar and vector kernels share) and
//! `simd_dispatch` (one body for the baseline and the AVX2 target), then [`fastlog`] and
//! [`fastexp`], then [`fastmath`]. Below them only [`crate::simd`] (and, in tests,
//! [`crate::rng`]), so every layer above (grid, raycast, sensor, crm, rbpf, info, planner) may use
//! them.

pub mod fastexp;
pub mod fastlog;
pub mod fastmath;
mod lanes;
mod simd_dispatch;

/// Standard normal CDF Φ(x), accurate in both tails (via erfc).
#[inline]
pub fn normal_cdf(x: f64) -> f64 {
    0.5 * libm::erfc(-x * std::f64::consts::FRAC_1_SQRT_2)
}
