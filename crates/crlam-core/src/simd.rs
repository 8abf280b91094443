//! The instruction-set level of the core's vector kernels, decided once per process.
//!
//! Every kernel with explicit vector code (the CRM lanes of [`crate::crm`], the logarithm,
//! exponential and Φ slices of [`crate::numeric::fastlog`] and [`crate::numeric::fastmath`], the
//! divergences of the CRMI) dispatches on [`level`]: AVX-512F, AVX2 or the portable scalar code.
//! Every path performs the scalar code's operations in its order, without fused multiply-adds,
//! so results are the same bit for bit at every level (the tests compare each level against the
//! scalar one); only the speed differs.
//!
//! The level is the best the CPU supports ([`SimdLevel::detected`]) unless the environment
//! variable `CRLAM_SIMD` (`scalar`, `avx2` or `avx512`) lowers it. A request the CPU cannot run
//! (or a value that is not a level) never executes unsupported instructions: the best supported
//! level runs instead and a warning is printed once on standard error and kept in
//! [`SimdChoice::warning`] (reported by `crlam bench`). Tests run a kernel at an explicit level
//! through [`with_level`] (this thread only) or the kernels' `*_at(level, ...)` entry points.
//!
//! On targets other than x86-64 the only level is [`SimdLevel::Scalar`]; all vector code is
//! compiled for x86-64 only.

use std::cell::Cell;
use std::sync::OnceLock;

/// An instruction-set level of the vector kernels, ordered from the narrowest.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum SimdLevel {
    /// The portable code (which the compiler may still vectorise for the build's baseline).
    Scalar,
    /// Four f64 lanes with AVX2 (no FMA is used, so FMA is not required).
    Avx2,
    /// Eight f64 lanes with AVX-512F (AVX2 is required too, for the kernels without an
    /// eight-lane version).
    Avx512,
}

impl SimdLevel {
    /// Every level, narrowest first.
    pub const ALL: [SimdLevel; 3] = [SimdLevel::Scalar, SimdLevel::Avx2, SimdLevel::Avx512];

    /// The name `CRLAM_SIMD` and `crlam bench` use: `scalar`, `avx2` or `avx512`.
    pub fn name(self) -> &'static str {
        match self {
            SimdLevel::Scalar => "scalar",
            SimdLevel::Avx2 => "avx2",
            SimdLevel::Avx512 => "avx512",
        }
    }

    /// The level of a name (case and surrounding blanks ignored).
    pub fn parse(name: &str) -> Option<SimdLevel> {
        match name.trim().to_ascii_lowercase().as_str() {
            "scalar" => Some(SimdLevel::Scalar),
            "avx2" => Some(SimdLevel::Avx2),
            "avx512" => Some(SimdLevel::Avx512),
            _ => None,
        }
    }

    /// The best level this CPU supports (detected once).
    pub fn detected() -> SimdLevel {
        static DETECTED: OnceLock<SimdLevel> = OnceLock::new();
        *DETECTED.get_or_init(detect)
    }

    /// Whether this CPU can run the level.
    pub fn supported(self) -> bool {
        self <= SimdLevel::detected()
    }

    /// The level itself where the CPU supports it, else the best it does.
    pub fn runnable(self) -> SimdLevel {
        self.min(SimdLevel::detected())
    }
}

impl std::fmt::Display for SimdLevel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

#[cfg(target_arch = "x86_64")]
fn detect() -> SimdLevel {
    let avx2 = std::arch::is_x86_feature_detected!("avx2");
    if avx2 && std::arch::is_x86_feature_detected!("avx512f") {
        SimdLevel::Avx512
    } else if avx2 {
        SimdLevel::Avx2
    } else {
        SimdLevel::Scalar
    }
}

#[cfg(not(target_arch = "x86_64"))]
fn detect() -> SimdLevel {
    SimdLevel::Scalar
}

/// The process's level and how it was chosen.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SimdChoice {
    /// The level the kernels run at.
    pub level: SimdLevel,
    /// The best level the CPU supports.
    pub detected: SimdLevel,
    /// The value of `CRLAM_SIMD`, if set and not blank.
    pub requested: Option<String>,
    /// Why the request was not followed (a level the CPU lacks, or not a level), if it was not.
    pub warning: Option<String>,
}

impl SimdChoice {
    /// The choice for a value of `CRLAM_SIMD` on a CPU whose best level is `detected`.
    pub fn resolve(requested: Option<&str>, detected: SimdLevel) -> SimdChoice {
        let requested = requested.map(str::trim).filter(|s| !s.is_empty());
        let (level, warning) = match requested {
            None => (detected, None),
            Some(r) => match SimdLevel::parse(r) {
                Some(l) if l <= detected => (l, None),
                Some(l) => (
                    detected,
                    Some(format!(
                        "CRLAM_SIMD={r}: this CPU does not support {l}; running at {detected}, the \
                         best it supports"
                    )),
                ),
                None => (
                    detected,
                    Some(format!(
                        "CRLAM_SIMD={r} is not a level (scalar, avx2 or avx512); running at \
                         {detected}, the best this CPU supports"
                    )),
                ),
            },
        };
        SimdChoice {
            level,
            detected,
            requested: requested.map(str::to_owned),
            warning,
        }
    }
}

/// The process's choice: `CRLAM_SIMD` read once, at the first call (a warning, if any, is
/// printed then).
pub fn choice() -> &'static SimdChoice {
    static CHOICE: OnceLock<SimdChoice> = OnceLock::new();
    CHOICE.get_or_init(|| {
        let env = std::env::var("CRLAM_SIMD").ok();
        let c = SimdChoice::resolve(env.as_deref(), SimdLevel::detected());
        if let Some(w) = &c.warning {
            eprintln!("crlam: warning: {w}");
        }
        c
    })
}

thread_local! {
    static OVERRIDE: Cell<Option<SimdLevel>> = const { Cell::new(None) };
}

/// The level the kernels run at on this thread: a [`with_level`] override, else the process's
/// [`choice`]. Always one the CPU supports.
#[inline]
pub fn level() -> SimdLevel {
    OVERRIDE.with(Cell::get).unwrap_or_else(|| choice().level)
}

/// Runs `f` with this thread's kernels at `level` (lowered to the best the CPU supports if it
/// lacks `level`: check [`SimdLevel::supported`] first where that matters). Work `f` hands to
/// other threads (rayon) runs at the process's level.
pub fn with_level<R>(level: SimdLevel, f: impl FnOnce() -> R) -> R {
    struct Restore(Option<SimdLevel>);
    impl Drop for Restore {
        fn drop(&mut self) {
            OVERRIDE.with(|o| o.set(self.0));
        }
    }
    let _restore = Restore(OVERRIDE.with(|o| o.replace(Some(level.runnable()))));
    f()
}

/// The vector features of this CPU the core can use or reports, in a fixed order (empty off
/// x86-64).
pub fn cpu_features() -> Vec<&'static str> {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::is_x86_feature_detected as has;
        let all = [
            ("sse4.2", has!("sse4.2")),
            ("avx", has!("avx")),
            ("avx2", has!("avx2")),
            ("fma", has!("fma")),
            ("bmi2", has!("bmi2")),
            ("avx512f", has!("avx512f")),
            ("avx512dq", has!("avx512dq")),
            ("avx512vl", has!("avx512vl")),
        ];
        all.iter().filter(|(_, on)| *on).map(|(n, _)| *n).collect()
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        Vec::new()
    }
}

/// Prints (to standard error) that a test skipped `level`, which this CPU cannot run.
#[cfg(test)]
pub(crate) fn report_skip(test: &str, level: SimdLevel) {
    eprintln!("{test}: skipped: {level} not supported by this CPU");
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_levels_are_ordered() {
        for l in SimdLevel::ALL {
            assert_eq!(SimdLevel::parse(l.name()), Some(l));
            assert_eq!(l.to_string(), l.name());
        }
        assert_eq!(SimdLevel::parse(" AVX2 "), Some(SimdLevel::Avx2));
        assert_eq!(SimdLevel::parse("sse"), None);
        assert!(SimdLevel::Scalar < SimdLevel::Avx2 && SimdLevel::Avx2 < SimdLevel::Avx512);
        assert!(SimdLevel::Scalar.supported());
    }

    #[test]
    fn requests_lower_the_level_and_unsupported_ones_fall_back_with_a_warning() {
        use SimdLevel::*;
        let c = SimdChoice::resolve(None, Avx512);
        assert_eq!((c.level, c.warning), (Avx512, None));
        let c = SimdChoice::resolve(Some(""), Avx2);
        assert_eq!((c.level, c.requested, c.warning), (Avx2, None, None));
        let c = SimdChoice::resolve(Some("scalar"), Avx512);
        assert_eq!((c.level, c.warning), (Scalar, None));
        let c = SimdChoice::resolve(Some("avx2"), Avx512);
        assert_eq!((c.level, c.warning), (Avx2, None));
        let c = SimdChoice::resolve(Some("avx512"), Avx2);
        assert_eq!(c.level, Avx2);
        let w = c.warning.unwrap();
        assert!(
            w.contains("does not support avx512") && w.contains("avx2"),
            "{w}"
        );
        let c = SimdChoice::resolve(Some("neon"), Scalar);
        assert_eq!(c.level, Scalar);
        assert!(c.warning.unwrap().contains("not a level"));
        assert_eq!(c.requested.as_deref(), Some("neon"));
    }

    #[test]
    fn the_process_level_is_supported_and_overrides_nest_and_restore() {
        let base = level();
        assert!(base.supported());
        assert!(choice().level.supported());
        with_level(SimdLevel::Scalar, || {
            assert_eq!(level(), SimdLevel::Scalar);
            with_level(SimdLevel::Avx512, || {
                assert_eq!(level(), SimdLevel::Avx512.runnable());
            });
            assert_eq!(level(), SimdLevel::Scalar);
        });
        assert_eq!(level(), base);
        #[cfg(target_arch = "x86_64")]
        {
            let f = cpu_features();
            assert_eq!(
                f.contains(&"avx2"),
                std::arch::is_x86_feature_detected!("avx2")
            );
        }
    }
}
