//! crlam-bench: the fixed workloads behind `crlam bench`, timed in-process on one thread, and the
//! synthetic maps they run on, kept out of the core library ([`crlam_core`]). The PyO3 glue
//! (crates/crlam-py) runs them by name for `crlam bench`, the examples time single workloads for
//! profiling, and the core's tests borrow the synthetic lattices of [`info`].
//!
//! - [`slam`]: ray casting, CRM beam updates and the particle filters.
//! - [`mcl`]: Monte Carlo localization on a fixed CRM.
//! - [`info`]: the information functions (CRMI, UCRMI, FSMI and Julian's OGMI, IIG 'mi', GPVR,
//!   UGPVR) on a synthetic cave-like lattice.

pub mod info;
pub mod mcl;
pub mod slam;
