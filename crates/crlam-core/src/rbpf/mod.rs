//! Rao-Blackwellized particle filters: RBPF-CLAM (CRM maps, closed-form predictive weights) and
//! the RBPF-OGM baseline (GMapping-style log-odds maps with scan matching).
//!
//! Both filters share the input (a laser scan with the odometry pose at its time), the update
//! triggers (like GMapping's linearUpdate / angularUpdate, with odometry carried between
//! processed scans), the weighted-mean estimate and the resampling rule.
//!
//! Dependencies point one way (a module uses only modules listed before it;
//! `tests/test_rust_modules.py` checks that there are no loops):
//!
//! 1. [`lineage`] (the path tree), [`estimate`], [`common`] (the filters' shared input, triggers
//!    and estimate), `motion_prior`;
//! 2. `scanmatch_params`, `prepared_scan` (a scan's matching beams), [`hit_means`] (where in
//!    its cells a CRM saw its walls), [`match_surface`] (the cells the matcher reads), [`scanmatch`] (GMapping's matcher and improved proposal),
//!    [`correlative`] (the wide-window search in front of it), [`loop_match`] (the same search
//!    over old endpoints, for loop closing);
//! 3. RBPF-OGM: `ogm_config`, then [`ogm`];
//! 4. RBPF-CLAM: `clam_config` (settings), `clam_particle` (the particle and its weight at a
//!    pose), `proposal` (the likelihood-mode proposal), [`clam_match`] (the scan-match
//!    proposal), then [`clam`] (the filter).

pub mod clam;
mod clam_config;
pub mod clam_match;
mod clam_particle;
pub mod common;
pub mod correlative;
pub mod degeneracy;
pub mod estimate;
pub mod hit_means;
pub mod lineage;
pub mod local_match;
pub mod loop_match;
pub mod match_surface;
mod motion_prior;
pub mod ogm;
mod ogm_config;
mod prepared_scan;
mod proposal;
pub mod scanmatch;
mod scanmatch_params;

pub use clam::{ClamConfig, ClamParticle, ClamPrior, ClamProposal, FrontEndCounts, RbpfClam};
pub use clam_match::{
    Degeneracy, MatchClimb, MatchRange, ScanMatchSettings, ScanMatchWeight, NO_RETURN_TOLERANCE,
};
pub use common::{
    weighted_mean_pose, FilterStep, OdometryTracker, ParticleFilter, ProposalPose, ScanInput,
    UpdateTrigger,
};
pub use correlative::{CorrelativeMatch, CorrelativeSettings};
pub use estimate::{mode_seeking_pose, ModeBandwidth, WeighedSet};
pub use hit_means::HitMeans;
pub use lineage::{NodeId, PathTree, NO_NODE};
pub use local_match::{LocalMapMatcher, LocalMatch};
pub use loop_match::{match_against_points, MAX_LOOP_POINTS};
pub use match_surface::MatchSurface;
pub use ogm::{MotionDraws, OgmFilterConfig, OgmMemoryStats, OgmParticle, RbpfOgm};
pub use prepared_scan::BeamSelection;
pub use scanmatch::{FreeTest, MatcherParams, PreparedScan, ProposalParams, ScanFit, ScanMatcher};
