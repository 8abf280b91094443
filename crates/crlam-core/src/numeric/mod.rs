//! Numerics shared by several layers: the standard normal CDF and the fast, bit-reproducible
//! kernels of the hot loops (sensor likelihoods, CRM lanes, information functions).
//!
//! - [`normal_cdf`]: Φ(x) accurate in both tails (libm's erfc), the reference of the fast kernels.
//! - [`fastlog`]: the table-driven logarithm and its AVX2 / AVX-512 slice kernels.
//! - [`fastmath`]: Φ by table interpolation, the exponentials and their slice kernels (uses
//!   [`fastlog`] and [`normal_cdf`]).
//!
//! Order inside: `lanes` (the arithmetic that the scalar and vector kernels share), then
//! [`fastlog`], then [`fastmath`]. Below them only [`crate::simd`] (and, in tests,
//! [`crate::rng`]), so every layer above (grid, raycast, sensor, crm, rbpf, info, planner) may use
//! them.

pub mod fastlog;
pub mod fastmath;
mod lanes;

/// Standard normal CDF Φ(x), accurate in both tails (via erfc).
#[inline]
pub fn normal_cdf(x: f64) -> f64 {
    0.5 * libm::erfc(-x * std::f64::consts::FRAC_1_SQRT_2)
}
