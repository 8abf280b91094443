//! Confidence-rich maps: per-cell beliefs over occupancy levels and their beam update.

pub mod beam;
pub mod levels;
pub mod map;
pub mod update;

pub use beam::{BeamPlan, ScanOptions, ScanStats, ScanUpdateMode};
pub use levels::{level_values, moments, tilted_prior, uniform_prior, LevelPlacement};
pub use map::{CrmConfig, CrmMap, CrmScratch};
