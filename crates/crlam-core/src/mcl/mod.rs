//! Monte Carlo localization on a fixed confidence-rich map: AMCL's algorithm (KLD-adaptive
//! particle count, recovery by random particles from the free space, clusters for the estimate)
//! with the CRM's closed-form predictive scan likelihood as the measurement model.
//!
//! - [`field`]: the per-map structure, the expected occupancy of every cell in a flat array;
//! - [`likelihood`]: the scan likelihood read from it, with a stated error bound;
//! - [`hit_table`]: the hit density's truncation normaliser from a table of Φ;
//! - [`kld`]: Fox's sample-count bound and the pose histogram;
//! - [`cluster`]: the clusters of a weighted set;
//! - [`climb`]: the scan-matched proposal of a spread set (an endpoint score and its climb);
//! - [`baseline`]: AMCL's likelihood-field and beam models, the alternatives to the CRM likelihood;
//! - [`config`]: the localizer's settings;
//! - [`filter`]: the localizer (its resamplings in `resampling`, its tempering and spread in
//!   `weighing`).

pub mod baseline;
pub mod climb;
pub mod cluster;
pub mod config;
pub mod field;
pub mod filter;
pub mod hit_table;
pub mod kld;
pub mod likelihood;
mod resampling;
mod weighing;

#[cfg(test)]
mod tests;

pub use baseline::{BeamParams, LikelihoodFieldParams, Measurement};
pub use cluster::{clusters, Cluster};
pub use field::MeanField;
pub use filter::{Mcl, MclConfig, MclInit, MclStep};
pub use kld::{kld_sample_count, KldSettings};
pub use likelihood::{
    beam_log_eta, scan_log_likelihood, select_beams, BeamEta, LikelihoodSettings, ScanFit,
};
