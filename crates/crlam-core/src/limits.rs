//! Resource limits: every allocation whose size comes from input data (a map's extent, a cell
//! rectangle, a particle count) is checked against one of these limits *before* it is made, and
//! buffers sized by data are reserved fallibly (`try_reserve`), so that no input can make the
//! process abort on an out-of-memory error.
//!
//! The limits are process-wide (like an `rlimit`): the Python package sets them from its
//! configuration (`crlam.limits`, the `--max-map-cells` / `--max-particles` flags or the
//! `CRLAM_MAX_MAP_CELLS` / `CRLAM_MAX_PARTICLES` environment variables) before any work starts.

use std::sync::atomic::{AtomicU64, Ordering};

use crate::error::{CrlamError, Result};

/// Default largest number of cells a map may cover (its storage rectangle) or a dense export of
/// it may hold: 4,000 x 4,000 cells, an 800 m square at 0.2 m or a 200 m square at 0.05 m. Writing
/// a map folder of that size takes about 2 GB.
pub const DEFAULT_MAX_MAP_CELLS: u64 = 16_000_000;

/// Default largest number of particles of a filter or a pose belief.
pub const DEFAULT_MAX_PARTICLES: u64 = 100_000;

static MAX_MAP_CELLS: AtomicU64 = AtomicU64::new(DEFAULT_MAX_MAP_CELLS);
static MAX_PARTICLES: AtomicU64 = AtomicU64::new(DEFAULT_MAX_PARTICLES);

/// The limit on map cells in force.
pub fn max_map_cells() -> u64 {
    MAX_MAP_CELLS.load(Ordering::Relaxed)
}

/// The limit on particles in force.
pub fn max_particles() -> u64 {
    MAX_PARTICLES.load(Ordering::Relaxed)
}

/// Sets the limit on map cells (at least 1).
pub fn set_max_map_cells(cells: u64) {
    MAX_MAP_CELLS.store(cells.max(1), Ordering::Relaxed);
}

/// Sets the limit on particles (at least 1).
pub fn set_max_particles(particles: u64) {
    MAX_PARTICLES.store(particles.max(1), Ordering::Relaxed);
}

/// Refuses `cells` (as a float, so that an absurd extent cannot overflow on the way) above the
/// map-cell limit; `what` names the input that asks for them.
pub fn check_map_cells(what: &str, cells: f64) -> Result<()> {
    let limit = max_map_cells();
    if cells.is_nan() || cells > limit as f64 {
        return Err(CrlamError::Limit {
            what: what.to_string(),
            needed: cells,
            limit,
            unit: "map cells",
            setting: "map_cells",
        });
    }
    Ok(())
}

/// Refuses a particle count above the particle limit.
pub fn check_particles(what: &str, particles: usize) -> Result<()> {
    let limit = max_particles();
    if particles as u64 > limit {
        return Err(CrlamError::Limit {
            what: what.to_string(),
            needed: particles as f64,
            limit,
            unit: "particles",
            setting: "particles",
        });
    }
    Ok(())
}

/// An empty vector with room for `n` values, or an error naming `what` when the memory cannot be
/// had (instead of the abort of `Vec::with_capacity`).
pub fn try_vec<T>(n: usize, what: &str) -> Result<Vec<T>> {
    let mut v = Vec::new();
    v.try_reserve_exact(n).map_err(|_| {
        CrlamError::Alloc(format!(
            "{what}: cannot allocate {n} values of {} bytes",
            std::mem::size_of::<T>()
        ))
    })?;
    Ok(v)
}

/// `n` copies of `value`, allocated fallibly (see [`try_vec`]).
pub fn try_filled<T: Clone>(n: usize, value: T, what: &str) -> Result<Vec<T>> {
    let mut v = try_vec(n, what)?;
    v.resize(n, value);
    Ok(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn absurd_requests_are_errors_not_aborts() {
        assert!(try_vec::<u64>(usize::MAX / 4, "test").is_err());
        assert!(check_map_cells("test", f64::INFINITY).is_err());
        assert!(check_map_cells("test", f64::NAN).is_err());
        assert!(check_map_cells("test", 10.0).is_ok());
        let e = check_particles("test", usize::MAX).unwrap_err().to_string();
        assert!(
            e.contains("particles") && e.contains("--max-particles"),
            "{e}"
        );
        assert_eq!(try_filled(3, 7u8, "test").unwrap(), vec![7, 7, 7]);
    }
}
