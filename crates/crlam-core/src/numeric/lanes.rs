//! The arithmetic of one lane type (f64, or a vector of f64) as four closures, so that the
//! scalar and the vector kernels of [`super::fastmath`] and [`super::fastlog`] share one
//! expression and with it the order of every operation: a body generic over [`Lanes`] and marked
//! `#[inline(always)]` is instantiated with f64's operators in the scalar function and, through
//! [`simd_lanes`], with an instruction set's intrinsics inside each `#[target_feature]` function
//! (where the closures are compiled with that function's features). Every path then performs
//! the same operations in the same order, without FMA, hence the same results bit for bit.

/// Splat, multiply, add and subtract of lane type `V`.
pub(super) struct Lanes<V, S, M, A, B>
where
    S: Fn(f64) -> V,
    M: Fn(V, V) -> V,
    A: Fn(V, V) -> V,
    B: Fn(V, V) -> V,
{
    pub(super) splat: S,
    pub(super) mul: M,
    pub(super) add: A,
    pub(super) sub: B,
}

/// f64's own operations: the scalar lane.
#[allow(clippy::type_complexity)] // closure types have no names to alias
#[inline(always)]
pub(super) fn scalar() -> Lanes<
    f64,
    impl Fn(f64) -> f64,
    impl Fn(f64, f64) -> f64,
    impl Fn(f64, f64) -> f64,
    impl Fn(f64, f64) -> f64,
> {
    Lanes {
        splat: |v: f64| v,
        mul: |x: f64, y: f64| x * y,
        add: |x: f64, y: f64| x + y,
        sub: |x: f64, y: f64| x - y,
    }
}

/// `simd_lanes!(set1, mul, add, sub)`: the [`Lanes`] of a vector type from its intrinsics, to be
/// written inside the `#[target_feature]` function that uses it.
#[cfg(target_arch = "x86_64")]
macro_rules! simd_lanes {
    ($set:ident, $mul:ident, $add:ident, $sub:ident) => {
        $crate::numeric::lanes::Lanes {
            splat: |v: f64| $set(v),
            mul: |a, b| $mul(a, b),
            add: |a, b| $add(a, b),
            sub: |a, b| $sub(a, b),
        }
    };
}
#[cfg(target_arch = "x86_64")]
pub(super) use simd_lanes;
