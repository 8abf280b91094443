//! Prior map states for the information functions (crm-spec 6.5, planner-spec 2.2).

use crate::crm::{tilted_prior, CrmConfig, CrmMap, LevelPlacement};
use crate::error::Result;
use crate::info::lattice::OccupancyLattice;

/// Means outside this range are clamped: the tilted pmf over 10 midpoint levels cannot reach
/// the level extremes 0.05 / 0.95.
pub const TILTED_MEAN_RANGE: (f64, f64) = (0.06, 0.94);

/// A CRM over the lattice's cells (same geometry, fixed extent) whose every cell holds the
/// tilted pmf (crm-spec 1.3) with mean equal to the lattice probability, so that every
/// information function sees the same prior mean map (crm-spec 6.5).
pub fn crm_from_lattice(lat: &OccupancyLattice, n_levels: usize) -> Result<CrmMap> {
    let mut cfg = CrmConfig::new(*lat.geometry());
    cfg.n_levels = n_levels;
    cfg.placement = LevelPlacement::Midpoints;
    cfg.extent = Some(lat.rect());
    let mut map = CrmMap::new(&cfg)?;
    let mu = map.levels().to_vec();
    let mut cache: Vec<(u64, Vec<f64>)> = Vec::new();
    let mut values = Vec::with_capacity(lat.len() * mu.len());
    for &p in lat.probabilities() {
        let m = p.clamp(TILTED_MEAN_RANGE.0, TILTED_MEAN_RANGE.1);
        let key = m.to_bits();
        let pmf = match cache.iter().find(|(k, _)| *k == key) {
            Some((_, v)) => v.clone(),
            None => {
                let v = tilted_prior(&mu, m)?;
                if cache.len() < 64 {
                    cache.push((key, v.clone()));
                }
                v
            }
        };
        values.extend(pmf);
    }
    map.set_beliefs(lat.rect(), &values)?;
    Ok(map)
}
