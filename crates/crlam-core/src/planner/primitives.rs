//! The IIG primitives of planner-spec 3.2: Steer, the collision walks of NoCollision, EdgeCost
//! and SampleFree.

use super::settings::{CollisionMode, SteerMode, COLLISION_STEP, MIN_EDGE};
use super::world::PlannerWorld;
use crate::rng::Rng;

/// Euclidean distance (m): EdgeCost.
#[inline]
pub fn distance(a: [f64; 2], b: [f64; 2]) -> f64 {
    (b[0] - a[0]).hypot(b[1] - a[1])
}

/// Steer from `a` toward `b` (m); `None` when the mode fails.
pub fn steer(a: [f64; 2], b: [f64; 2], mode: SteerMode) -> Option<[f64; 2]> {
    let d = distance(a, b);
    match mode {
        SteerMode::Reference {
            fraction,
            min_distance,
        } => (d >= min_distance && d > 0.0).then(|| {
            [
                a[0] + fraction * (b[0] - a[0]),
                a[1] + fraction * (b[1] - a[1]),
            ]
        }),
        SteerMode::Clean { step } => {
            if d <= MIN_EDGE {
                None
            } else if d <= step {
                Some(b)
            } else {
                let t = step / d;
                Some([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])])
            }
        }
    }
}

/// The points NoCollision tests on the edge `a → b`, in order (m).
/// - Reference: a + s·(b − a) for s = 0.08 k ≤ L = ‖b − a‖, k = 1, 2, … (direction not
///   normalised; `a` itself is not tested).
/// - Clean: n = ⌈L / 0.08⌉ (≥ 1) equal steps, a and b included.
pub fn collision_walk(a: [f64; 2], b: [f64; 2], mode: CollisionMode) -> Vec<[f64; 2]> {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let len = dx.hypot(dy);
    match mode {
        CollisionMode::Reference => {
            let mut out = Vec::new();
            let mut k = 1u64;
            loop {
                let s = k as f64 * COLLISION_STEP;
                if s > len {
                    break;
                }
                out.push([a[0] + s * dx, a[1] + s * dy]);
                k += 1;
            }
            out
        }
        CollisionMode::Clean => {
            let n = ((len / COLLISION_STEP).ceil() as usize).max(1);
            let mut out: Vec<[f64; 2]> = (0..n)
                .map(|i| {
                    let t = i as f64 / n as f64;
                    [a[0] + t * dx, a[1] + t * dy]
                })
                .collect();
            out.push(b);
            out
        }
    }
}

/// NoCollision: true when no walk point is within `clearance` (m) of an obstacle point.
pub fn edge_is_free(
    world: &PlannerWorld,
    a: [f64; 2],
    b: [f64; 2],
    clearance: f64,
    mode: CollisionMode,
) -> bool {
    collision_walk(a, b, mode)
        .into_iter()
        .all(|p| !world.too_close(p, clearance))
}

/// SampleFree: uniform draws over a candidate node list fixed at the start.
#[derive(Clone, Debug)]
pub struct SampleFree {
    positions: Vec<[f64; 2]>,
    rng: Rng,
}

impl SampleFree {
    /// Draws among the lattice nodes whose prior is below `threshold`, from `Rng::new(seed)`.
    /// `None` when there is no such node.
    pub fn new(world: &PlannerWorld, threshold: f64, seed: u64) -> Option<Self> {
        let positions: Vec<[f64; 2]> = world
            .free_nodes(threshold)
            .into_iter()
            .map(|id| world.prior().node_position(id))
            .collect();
        (!positions.is_empty()).then(|| Self {
            positions,
            rng: Rng::new(seed),
        })
    }

    /// Number of candidate nodes.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// Whether there is no point (candidate).
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// The next sample (m): candidate ⌊u·n⌋ for u uniform in [0, 1).
    pub fn draw(&mut self) -> [f64; 2] {
        let n = self.positions.len();
        let k = ((self.rng.uniform() * n as f64) as usize).min(n - 1);
        self.positions[k]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reference_steer_is_half_way_with_a_minimum() {
        let m = SteerMode::REFERENCE;
        assert_eq!(steer([0.0, 0.0], [0.99, 0.0], m), None);
        assert_eq!(steer([0.0, 0.0], [1.0, 0.0], m), Some([0.5, 0.0]));
        assert_eq!(steer([1.0, 1.0], [5.0, 4.0], m), Some([3.0, 2.5]));
    }

    #[test]
    fn clean_steer_moves_at_most_one_step() {
        let m = SteerMode::Clean { step: 0.5 };
        assert_eq!(steer([0.0, 0.0], [0.3, 0.4], m), Some([0.3, 0.4]));
        let p = steer([0.0, 0.0], [3.0, 4.0], m).unwrap();
        assert!((p[0] - 0.3).abs() < 1e-15 && (p[1] - 0.4).abs() < 1e-15);
        assert_eq!(steer([1.0, 1.0], [1.0, 1.0], m), None);
    }

    #[test]
    fn walks() {
        // Reference, L = 0.5: s = 0.08 … 0.48 along the unnormalised direction, so the points
        // stop at half the edge.
        let r = collision_walk([0.0, 0.0], [0.5, 0.0], CollisionMode::Reference);
        assert_eq!(r.len(), 6);
        assert!((r[5][0] - 0.48 * 0.5).abs() < 1e-15);
        // L = 2: points go up to a + 2(b − a), beyond b.
        let r = collision_walk([0.0, 0.0], [2.0, 0.0], CollisionMode::Reference);
        assert_eq!(r.len(), 25);
        assert!((r[24][0] - 4.0).abs() < 1e-12);
        let c = collision_walk([0.0, 0.0], [0.5, 0.0], CollisionMode::Clean);
        assert_eq!(c.len(), 8);
        assert_eq!(c[0], [0.0, 0.0]);
        assert_eq!(c[7], [0.5, 0.0]);
        assert!(c
            .windows(2)
            .all(|w| w[1][0] - w[0][0] <= COLLISION_STEP + 1e-15));
    }
}
