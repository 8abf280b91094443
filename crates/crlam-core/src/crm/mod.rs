//! Confidence-rich maps: per-cell beliefs over occupancy levels and their beam update.
//!
//! Dependencies point one way, from the scan updates down to the per-cell algebra (a module uses
//! only modules listed before it; `tests/test_rust_modules.py` checks that there are no
//! loops):
//!
//! 1. [`levels`], [`beam`] (beam plans, scan options), [`update`] (the per-cell factor algebra),
//!    `mean_cache` (block means), `lane_io` (what the lane kernels take and return);
//! 2. `reading_table`, `scan_cells` (a scan's cells and their write-back), `beam_job` (one beam
//!    of a batch scan);
//! 3. `windowed` (the scalar windowed kernel);
//! 4. `lanes_avx2` (AVX2 lanes), then `far_simd` (far phase and tail with AVX-512, dispatch by
//!    level), then `window_simd` (window lanes with AVX-512, dispatch by level);
//! 5. [`map`] (the map and its per-thread scratch, which holds the kernels' buffers);
//! 6. `lanes` (drives the three lane phases), `forward` (the mixture's forward sums);
//! 7. `batch` and `scan`: the scan updates, the entry points of [`CrmMap`].

mod batch;
pub mod beam;
mod beam_job;
pub(crate) mod far_simd;
mod forward;
pub(crate) mod lane_io;
mod lanes;
#[cfg(target_arch = "x86_64")]
mod lanes_avx2;
pub mod levels;
pub mod map;
pub(crate) mod mean_cache;
mod reading_table;
mod scan;
mod scan_cells;
pub mod update;
mod window_simd;
mod windowed;

pub use beam::{BatchKernel, BeamPlan, ScanOptions, ScanStats, ScanUpdateMode};
pub use levels::{level_values, moments, tilted_prior, uniform_prior, LevelPlacement};
pub use map::{with_thread_scratch, CrmConfig, CrmMap, CrmScratch};
