//! Rao-Blackwellized particle filters: RBPF-CLAM (CRM maps, closed-form predictive weights) and
//! the RBPF-OGM baseline (GMapping-style log-odds maps with scan matching).
//!
//! Both filters share the input (a laser scan with the odometry pose at its time), the update
//! triggers (like GMapping's linearUpdate / angularUpdate, with odometry carried between
//! processed scans), the weighted-mean estimate and the resampling rule.

pub mod clam;
pub mod clam_match;
pub mod common;
pub mod estimate;
pub mod lineage;
pub mod match_surface;
mod motion_prior;
pub mod ogm;
mod ogm_config;
mod proposal;
pub mod scanmatch;
mod scanmatch_params;

pub use clam::{ClamConfig, ClamParticle, ClamPrior, ClamProposal, RbpfClam};
pub use clam_match::{ScanMatchSettings, ScanMatchWeight};
pub use common::{
    weighted_mean_pose, FilterStep, OdometryTracker, ParticleFilter, ProposalPose, ScanInput,
    UpdateTrigger,
};
pub use estimate::{mode_seeking_pose, ModeBandwidth, WeighedSet};
pub use lineage::{NodeId, PathTree, NO_NODE};
pub use match_surface::MatchSurface;
pub use ogm::{MotionDraws, OgmFilterConfig, OgmMemoryStats, OgmParticle, RbpfOgm};
pub use scanmatch::{FreeTest, MatcherParams, PreparedScan, ProposalParams, ScanFit, ScanMatcher};
