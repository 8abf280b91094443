//! crlam-core: confidence-rich mapping (CRM), RBPF-CLAM, Monte Carlo localization and information
//! functions.
//!
//! Pure Rust, no Python. Every fallible entry point returns [`Result`] with [`CrlamError`];
//! nothing here panics on user input.

// Index loops over parallel per-level arrays read more clearly than zipped iterators here.
#![allow(clippy::needless_range_loop)]

pub mod crm;
pub mod error;
pub mod grid;
pub mod info;
pub mod limits;
pub mod mcl;
pub mod motion;
pub mod numeric;
pub mod ogm;
pub mod planner;
pub mod pose;
pub mod raycast;
pub mod rbpf;
pub mod resample;
pub mod rng;
pub mod sensor;
pub mod sim;
pub mod simd;

pub use error::{CrlamError, Result};
