//! Where a scan leaves the pose free: the direction along which its geometry constrains a
//! match less than [`DEGENERATE_RATIO`] times as much as along the best one (a featureless
//! corridor: every wall runs along it).
//!
//! Each endpoint's surface normal comes from a line fitted to it and its neighbours in scan
//! order (those within [`NEIGHBOUR_REACH`] of it, at least [`MIN_NEIGHBOURS`] of them, the fit
//! flat to [`MAX_CURVATURE`]). A translation δ of the scan moves endpoint i off its surface by
//! n_i·δ, so H = Σ n_i n_iᵀ is the information a point-to-line match has about δ (up to the
//! noise's scale): its smaller eigenvalue over its larger is how well the weakest direction is
//! constrained against the best. A scan is degenerate when that ratio is below
//! [`DEGENERATE_RATIO`] (fewer than one in twenty endpoints' worth of constraint along the
//! weakest direction), and then its weak direction is the eigenvector of the smaller eigenvalue.
//!
//! The filters use it as Zhang, Kaess and Singh's solution remapping ("On degeneracy of
//! optimization-based state estimation problems", ICRA 2016): along that direction the scan
//! says nothing, so the match keeps the odometry's prediction there, and the importance weight
//! reads the scan at the particle's pose moved back along it to the prediction, so that the map's
//! own unevenness along the direction (a cell is as confident as the scans that crossed it)
//! does not rank the particles.

use crate::pose::Pose;

/// Smaller over larger eigenvalue of H below which a scan is degenerate.
pub const DEGENERATE_RATIO: f64 = 0.05;

/// Neighbours within this distance (m) of an endpoint enter its line fit.
pub const NEIGHBOUR_REACH: f64 = 0.3;

/// Neighbours on each side, in scan order, that a line fit looks at.
const NEIGHBOURS_EACH_SIDE: usize = 4;

/// Points a line fit needs (the endpoint included).
pub const MIN_NEIGHBOURS: usize = 4;

/// Smaller over larger eigenvalue of a fit's scatter above which the neighbourhood is not a line
/// (a corner, clutter) and gives no normal.
pub const MAX_CURVATURE: f64 = 0.05;

/// Endpoints with a normal a scan needs before it can be called degenerate.
pub const MIN_NORMALS: usize = 20;

/// The eigen-decomposition of a symmetric 2×2 matrix [[a, b], [b, c]]: (smaller eigenvalue,
/// larger eigenvalue, unit eigenvector of the smaller).
fn sym2_eigen(a: f64, b: f64, c: f64) -> (f64, f64, [f64; 2]) {
    let mean = 0.5 * (a + c);
    let half_diff = 0.5 * (a - c);
    let r = half_diff.hypot(b);
    let (lo, hi) = (mean - r, mean + r);
    // The eigenvector of `lo`: (b, lo − a), or (lo − c, b); the better conditioned one.
    let v1 = [b, lo - a];
    let v2 = [lo - c, b];
    let v = if v1[0].hypot(v1[1]) >= v2[0].hypot(v2[1]) {
        v1
    } else {
        v2
    };
    let n = v[0].hypot(v[1]);
    let dir = if n > 0.0 {
        [v[0] / n, v[1] / n]
    } else if a <= c {
        [1.0, 0.0]
    } else {
        [0.0, 1.0]
    };
    (lo, hi, dir)
}

/// The information matrix H = Σ n nᵀ of the endpoints `points` (in scan order, any frame) and
/// the number of endpoints that gave a normal.
pub fn normal_information(points: &[[f64; 2]]) -> ([f64; 3], usize) {
    let (mut hxx, mut hxy, mut hyy) = (0.0, 0.0, 0.0);
    let mut n_normals = 0;
    let reach2 = NEIGHBOUR_REACH * NEIGHBOUR_REACH;
    for (i, p) in points.iter().enumerate() {
        let lo = i.saturating_sub(NEIGHBOURS_EACH_SIDE);
        let hi = (i + NEIGHBOURS_EACH_SIDE + 1).min(points.len());
        let near = || {
            points[lo..hi]
                .iter()
                .filter(|q| (q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2) <= reach2)
        };
        let count = near().count();
        if count < MIN_NEIGHBOURS {
            continue;
        }
        let k = count as f64;
        let (mx, my) = near().fold((0.0, 0.0), |(x, y), q| (x + q[0], y + q[1]));
        let (mx, my) = (mx / k, my / k);
        let (sxx, sxy, syy) = near().fold((0.0, 0.0, 0.0), |(a, b, c), q| {
            let (dx, dy) = (q[0] - mx, q[1] - my);
            (a + dx * dx, b + dx * dy, c + dy * dy)
        });
        let (small, large, normal) = sym2_eigen(sxx, sxy, syy);
        if !large.is_finite() || large <= 0.0 || small > MAX_CURVATURE * large {
            continue;
        }
        hxx += normal[0] * normal[0];
        hxy += normal[0] * normal[1];
        hyy += normal[1] * normal[1];
        n_normals += 1;
    }
    ([hxx, hxy, hyy], n_normals)
}

/// The direction (unit, in the frame of `points`) a scan with endpoints `points` (in scan order)
/// leaves free, if it is degenerate (see the module documentation).
pub fn free_direction(points: &[[f64; 2]]) -> Option<[f64; 2]> {
    let ([a, b, c], n) = normal_information(points);
    if n < MIN_NORMALS {
        return None;
    }
    let (lo, hi, dir) = sym2_eigen(a, b, c);
    (hi > 0.0 && lo < DEGENERATE_RATIO * hi).then_some(dir)
}

/// `pose` moved along the unit world direction `dir` so that its position's coordinate along
/// it equals `anchor`'s (the heading kept).
pub fn along_to(pose: Pose, anchor: Pose, dir: [f64; 2]) -> Pose {
    let t = (pose[0] - anchor[0]) * dir[0] + (pose[1] - anchor[1]) * dir[1];
    [pose[0] - t * dir[0], pose[1] - t * dir[1], pose[2]]
}

/// A robot-frame direction in the world frame of a robot with heading `theta`.
pub fn to_world(dir: [f64; 2], theta: f64) -> [f64; 2] {
    let (s, c) = theta.sin_cos();
    [c * dir[0] - s * dir[1], s * dir[0] + c * dir[1]]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Endpoints of a robot at the origin between two walls at y = ±w/2, beams over 360°.
    fn corridor(width: f64, n: usize) -> Vec<[f64; 2]> {
        (0..n)
            .filter_map(|i| {
                let a = -std::f64::consts::PI + 2.0 * std::f64::consts::PI * i as f64 / n as f64;
                let s = a.sin();
                if s.abs() < 1e-3 {
                    return None;
                }
                let r = (0.5 * width / s.abs()).min(8.0);
                (r < 8.0).then(|| [r * a.cos(), r * s])
            })
            .collect()
    }

    /// A square room of side `side` around the origin.
    fn room(side: f64, n: usize) -> Vec<[f64; 2]> {
        (0..n)
            .map(|i| {
                let a = 2.0 * std::f64::consts::PI * i as f64 / n as f64;
                let (s, c) = a.sin_cos();
                let r = 0.5 * side / c.abs().max(s.abs());
                [r * c, r * s]
            })
            .collect()
    }

    #[test]
    fn a_corridor_leaves_its_axis_free() {
        let d = free_direction(&corridor(2.0, 360)).expect("degenerate");
        assert!(d[0].abs() > 0.999, "{d:?}");
    }

    #[test]
    fn a_rotated_corridor_leaves_its_rotated_axis_free() {
        let a = 0.7f64;
        let pts: Vec<[f64; 2]> = corridor(2.5, 360)
            .into_iter()
            .map(|p| to_world(p, a))
            .collect();
        let d = free_direction(&pts).expect("degenerate");
        assert!((d[0] * a.cos() + d[1] * a.sin()).abs() > 0.999, "{d:?}");
    }

    #[test]
    fn a_room_is_not_degenerate() {
        assert!(free_direction(&room(6.0, 360)).is_none());
    }

    #[test]
    fn a_corridor_with_an_end_wall_in_range_is_not_degenerate() {
        let mut pts = corridor(2.0, 360);
        // A wall across the corridor 3 m ahead.
        pts.extend((0..40).map(|i| [3.0, -1.0 + 2.0 * i as f64 / 40.0]));
        assert!(free_direction(&pts).is_none());
    }

    #[test]
    fn too_few_normals_say_nothing() {
        assert!(free_direction(&corridor(2.0, 360)[..10]).is_none());
    }

    #[test]
    fn along_to_keeps_the_other_coordinate_and_the_heading() {
        let p = along_to([3.0, 1.0, 0.4], [1.0, -2.0, 0.0], [1.0, 0.0]);
        assert_eq!(p, [1.0, 1.0, 0.4]);
    }
}
