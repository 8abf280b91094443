//! The planner's world (planner-spec 2.1–2.2): the prior occupancy lattice, whose free nodes
//! SampleFree draws from, and the obstacle point set that NoCollision tests against.

use super::spatial::PointGrid;
use crate::error::{config_err, CrlamError, Result};
use crate::info::lattice::OccupancyLattice;

/// Bucket side (m) of the obstacle index; any value gives the same answers.
const OBSTACLE_BUCKET: f64 = 0.5;

/// The prior lattice and the obstacle points.
#[derive(Clone, Debug)]
pub struct PlannerWorld {
    prior: OccupancyLattice,
    obstacles: PointGrid,
}

impl PlannerWorld {
    /// A world from the prior lattice and obstacle points (m, each finite). The points are the
    /// reference's point set (planner-spec 2.1: lower-left pixel corners plus the border walls),
    /// not squares.
    pub fn new(prior: OccupancyLattice, obstacle_points: Vec<[f64; 2]>) -> Result<Self> {
        let mut lo = [f64::INFINITY; 2];
        let mut hi = [f64::NEG_INFINITY; 2];
        for p in &obstacle_points {
            for k in 0..2 {
                if !p[k].is_finite() {
                    return Err(CrlamError::NonFinite {
                        field: "obstacle_points",
                        value: p[k],
                    });
                }
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        if obstacle_points.is_empty() {
            (lo, hi) = ([0.0; 2], [0.0; 2]);
        }
        let mut obstacles = PointGrid::new(lo, hi, OBSTACLE_BUCKET)?;
        for p in obstacle_points {
            obstacles.insert(p)?;
        }
        Ok(Self { prior, obstacles })
    }

    /// A world whose obstacle points are the positions of the lattice nodes with prior
    /// probability ≥ `obstacle_threshold` (in (0, 1]). On the planner's lattice, whose 0.85 nodes
    /// are those within 0.1 m of an obstacle point (planner-spec 2.2), a threshold of 0.5 gives
    /// back the obstacle points that sit on nodes.
    pub fn from_lattice(prior: OccupancyLattice, obstacle_threshold: f64) -> Result<Self> {
        if !(obstacle_threshold > 0.0 && obstacle_threshold <= 1.0) {
            return Err(config_err(
                "obstacle_threshold",
                format!("must be in (0, 1], got {obstacle_threshold}"),
            ));
        }
        let points = (0..prior.len())
            .filter(|&id| prior.get(id) >= obstacle_threshold)
            .map(|id| prior.node_position(id))
            .collect();
        Self::new(prior, points)
    }

    /// The prior occupancy lattice.
    pub fn prior(&self) -> &OccupancyLattice {
        &self.prior
    }

    /// The obstacle points (m).
    pub fn obstacle_points(&self) -> &[[f64; 2]] {
        self.obstacles.points()
    }

    /// SampleFree's candidate set: the ids of the lattice nodes with prior < `threshold`, in id
    /// order. It includes margin nodes outside the walls, as the reference does.
    pub fn free_nodes(&self, threshold: f64) -> Vec<usize> {
        (0..self.prior.len())
            .filter(|&id| self.prior.get(id) < threshold)
            .collect()
    }

    /// Whether some obstacle point lies within `clearance` (m) of `p` (distance ≤ clearance).
    pub fn too_close(&self, p: [f64; 2], clearance: f64) -> bool {
        self.obstacles.any_within(p, clearance)
    }

    /// Lower-left and upper-right node positions (m) of the lattice.
    pub fn lattice_box(&self) -> ([f64; 2], [f64; 2]) {
        (
            self.prior.node_position(0),
            self.prior.node_position(self.prior.len() - 1),
        )
    }
}
