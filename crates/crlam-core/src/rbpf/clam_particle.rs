//! RBPF-CLAM's particle ([`ClamParticle`]) and its weight at a pose: the CRM predictive
//! likelihood of a scan under the particle's pre-update map, shared by the filter
//! ([`super::clam`]) and the scan-match proposal ([`super::clam_match`]).

use crate::crm::{CrmMap, CrmScratch};
use crate::error::Result;
use crate::pose::{compose, Pose};
use crate::rbpf::clam_config::{scan_opts, ClamConfig};
use crate::rbpf::common::ScanInput;
use crate::rbpf::hit_means::HitMeans;
use crate::rbpf::lineage::NodeId;

/// One particle: pose, log-weight and its own map.
#[derive(Clone, Debug)]
pub struct ClamParticle {
    pub pose: Pose,
    pub log_w: f64,
    pub map: CrmMap,
    /// The means of the map's hits, kept when the scan-match proposal reads them
    /// ([`crate::rbpf::ScanMatchSettings::hit_means`]).
    pub hits: Option<HitMeans>,
    /// The particle's pose at the last processed scan in the filter's [`crate::rbpf::PathTree`].
    pub path: NodeId,
}

/// The CRM predictive log-likelihood Σ log η of the scan taken at robot pose `pose` (every
/// `weight_stride`-th beam), without updating the map: the update waits for resampling.
pub(crate) fn weigh_at_pose(
    cfg: &ClamConfig,
    map: &mut CrmMap,
    pose: Pose,
    scan: &ScanInput,
    sc: &mut CrmScratch,
) -> Result<f64> {
    let (ll, _) = map.weigh_scan(
        compose(pose, scan.laser_offset),
        scan.angles,
        scan.ranges,
        &cfg.weight_model,
        cfg.weight_stride,
        &cfg.mapping_model,
        &scan_opts(cfg, cfg.map_stride),
        sc,
    )?;
    Ok(ll)
}
