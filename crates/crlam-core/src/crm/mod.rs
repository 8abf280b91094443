//! Confidence-rich maps: per-cell beliefs over occupancy levels and their beam update.

mod batch;
pub mod beam;
pub(crate) mod far_simd;
mod forward;
mod lanes;
#[cfg(target_arch = "x86_64")]
mod lanes_avx2;
pub mod levels;
pub mod map;
mod mean_cache;
mod reading_table;
mod scan;
mod scan_cells;
pub mod update;
mod window_simd;
mod windowed;

pub use beam::{BatchKernel, BeamPlan, ScanOptions, ScanStats, ScanUpdateMode};
pub use levels::{level_values, moments, tilted_prior, uniform_prior, LevelPlacement};
pub use map::{with_thread_scratch, CrmConfig, CrmMap, CrmScratch};
