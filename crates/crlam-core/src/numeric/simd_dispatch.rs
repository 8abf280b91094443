//! [`simd_by_target!`](simd_by_target): one body compiled for the baseline target and for AVX2,
//! chosen at run time by the SIMD level (the kernels of `fastmath` and `fastexp`, CRMI's KL terms).

/// `$vis fn $name(args)`: `$body(args)` compiled for AVX2 (as `$avx`) where
/// [`crate::simd::level`] is AVX2 or above, the baseline build of the same body otherwise (the
/// same operations, hence the same results); `$vis fn $at(level, args)` the same at a given level
/// (lowered to the best the CPU supports).
macro_rules! simd_by_target {
    ($(#[$doc:meta])* $vis:vis $name:ident, $at:ident, $avx:ident, $body:ident, ($($arg:ident: $ty:ty),*)) => {
        $(#[$doc])*
        #[allow(dead_code)]
        $vis fn $name($($arg: $ty),*) {
            $at($crate::simd::level(), $($arg),*)
        }

        #[doc = concat!("[`", stringify!($name), "`] at a given level (lowered to the best the CPU supports).")]
        #[allow(dead_code)]
        $vis fn $at(level: $crate::simd::SimdLevel, $($arg: $ty),*) {
            #[cfg(target_arch = "x86_64")]
            if level.runnable() >= $crate::simd::SimdLevel::Avx2 {
                // SAFETY: `runnable` only returns levels the CPU supports, and every level from
                // AVX2 up includes AVX2.
                unsafe { $avx($($arg),*) };
                return;
            }
            let _ = level;
            $body($($arg),*);
        }

        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx2")]
        unsafe fn $avx($($arg: $ty),*) {
            $body($($arg),*);
        }
    };
}
pub(crate) use simd_by_target;
