//! [`BeamJob`]: one beam of a batch scan as the batch kernels take it (the windowed kernel, the
//! lanes and the full sweep), kept per thread in the map scratch.

use crate::crm::beam::BeamPlan;
use crate::crm::reading_table::ReadingConstants;

/// A beam of a batch scan: its weight and map plans (either may be absent) and its direction.
#[derive(Clone, Copy, Debug)]
pub(crate) struct BeamJob {
    pub(crate) w_plan: Option<BeamPlan>,
    pub(crate) m_plan: Option<BeamPlan>,
    pub(crate) dir: [f64; 2],
    /// The weighed reading's constants, when the scan's table has them.
    pub(crate) consts: Option<ReadingConstants>,
}
