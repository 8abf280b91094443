//! The scan-matched proposal of a spread set: each particle climbs to the nearby pose whose
//! beam endpoints fit the map best before it is weighed.
//!
//! A global start spreads a few tens of thousands of particles over a building, about one per
//! 0.5 m × 10° (the KLD bin) of its pose space, so the one nearest the true pose is typically a
//! few decimetres and degrees off. Moved only by the odometry's noise, which is centimetres per
//! step, it stays that far off, and a look-alike place where some particle happens to sit closer
//! to the best fit then outweighs the true one. The climb moves every particle of a spread set to
//! the local maximum of a cheap score before the CRM likelihood weighs it, so that each place is
//! weighed at its best pose near the particle: the particles that fall into the true pose's basin
//! all end on it. This is GMapping's proposal (scan matching from the motion's draw, the weight at
//! the matched pose), used only while the set is spread; once it gathers, the particles move by
//! the motion model alone, as in AMCL.
//!
//! The score is the likelihood field of the endpoints: Σ over the beams with a range reading of
//! exp(−d² / 2σ²), d the distance from the endpoint to the nearest cell with m̂ ≥ 0.5 (more
//! likely occupied than not) and σ the scan's hit σ. The field holds the score per cell for one σ
//! and is filled again when σ changes. The climb is GMapping's: from the pose, try a step forward
//! and back along x, y and θ, move to the best of the six while it raises the score, else halve
//! the steps; stop after `refinements` halvings or `max_moves` evaluations of six.

use crate::grid::{floor_to_i64, CellRect, GridGeometry};
use crate::mcl::field::MeanField;
use crate::pose::{compose, wrap, Pose};

/// m̂ from which a cell counts as occupied for the endpoint score.
pub const OCCUPIED: f64 = 0.5;

/// How a particle climbs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClimbSettings {
    /// First step along x and y (m).
    pub step_xy: f64,
    /// First step in heading (rad).
    pub step_theta: f64,
    /// Halvings of the steps before the climb stops.
    pub refinements: usize,
    /// Largest number of moves (each evaluates six poses).
    pub max_moves: usize,
}

/// The endpoint score of a map for one σ: exp(−d² / 2σ²) per cell of the map's rectangle.
#[derive(Clone, Debug)]
pub struct EndpointField {
    geometry: GridGeometry,
    rect: CellRect,
    /// Squared distance (m²) from each cell centre to the nearest occupied cell, row-major.
    d2: Vec<f64>,
    /// The σ `score` was filled for.
    sigma: f64,
    /// exp(−d² / 2σ²) per cell (f32: the climb compares sums of them, and it halves the memory).
    score: Vec<f32>,
}

impl EndpointField {
    /// The distances of `field` (an exact Euclidean distance transform); the score is filled at
    /// the first [`Self::set_sigma`].
    pub fn new(field: &MeanField) -> Self {
        let d2 = field
            .occupied_distance(OCCUPIED)
            .into_iter()
            .map(|d| d * d)
            .collect();
        Self {
            geometry: *field.geometry(),
            rect: field.rect(),
            d2,
            sigma: f64::NAN,
            score: Vec::new(),
        }
    }

    /// Fills the score for `sigma` (m) unless it holds it already.
    pub fn set_sigma(&mut self, sigma: f64) {
        if sigma == self.sigma {
            return;
        }
        let k = -0.5 / (sigma * sigma);
        self.score = self.d2.iter().map(|&d2| (k * d2).exp() as f32).collect();
        self.sigma = sigma;
    }

    /// The σ the score holds (NaN before [`Self::set_sigma`]).
    pub fn sigma(&self) -> f64 {
        self.sigma
    }

    /// Score of the endpoints `points` (sensor frame, m) seen from `sensor`: 0 outside the map.
    pub fn score(&self, sensor: Pose, points: &[[f64; 2]]) -> f64 {
        let (s, c) = sensor[2].sin_cos();
        let g = &self.geometry;
        let inv = 1.0 / g.resolution;
        let (ox, oy) = (
            (sensor[0] - g.origin[0]) * inv,
            (sensor[1] - g.origin[1]) * inv,
        );
        let (c, s) = (c * inv, s * inv);
        let r = self.rect;
        let mut sum = 0.0f32;
        for p in points {
            let ix = floor_to_i64(ox + c * p[0] - s * p[1]) - r.ix0;
            let iy = floor_to_i64(oy + s * p[0] + c * p[1]) - r.iy0;
            if (ix as u64) < r.nx as u64 && (iy as u64) < r.ny as u64 {
                sum += self.score[(iy * r.nx + ix) as usize];
            }
        }
        sum as f64
    }

    /// The pose near `pose` (robot frame; the sensor at `compose(pose, offset)`) where the
    /// endpoints score highest, by the climb of the module documentation. Returns `pose` itself
    /// when no move raises the score.
    pub fn climb(
        &self,
        settings: &ClimbSettings,
        pose: Pose,
        offset: Pose,
        points: &[[f64; 2]],
    ) -> Pose {
        let mut best_pose = pose;
        let mut best = self.score(compose(pose, offset), points);
        let (mut sxy, mut sth) = (settings.step_xy, settings.step_theta);
        let mut halvings = 0;
        for _ in 0..settings.max_moves {
            let here = best_pose;
            let mut moved = false;
            for (dx, dy, dth) in [
                (sxy, 0.0, 0.0),
                (-sxy, 0.0, 0.0),
                (0.0, sxy, 0.0),
                (0.0, -sxy, 0.0),
                (0.0, 0.0, sth),
                (0.0, 0.0, -sth),
            ] {
                let q = [here[0] + dx, here[1] + dy, wrap(here[2] + dth)];
                let v = self.score(compose(q, offset), points);
                if v > best {
                    best = v;
                    best_pose = q;
                    moved = true;
                }
            }
            if !moved {
                if halvings == settings.refinements {
                    break;
                }
                halvings += 1;
                sxy *= 0.5;
                sth *= 0.5;
            }
        }
        best_pose
    }
}

/// The endpoints (sensor frame, m) of the beams `beams` of a scan with a range reading in
/// [z_min, z_max): the readings the endpoint score can place.
pub fn endpoints(
    angles: &[f64],
    ranges: &[f64],
    beams: &[usize],
    z_min: f64,
    z_max: f64,
) -> Vec<[f64; 2]> {
    beams
        .iter()
        .filter_map(|&b| {
            let (a, r) = (*angles.get(b)?, *ranges.get(b)?);
            (r.is_finite() && r >= z_min && r > 0.0 && r < z_max)
                .then(|| [r * a.cos(), r * a.sin()])
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 6 m x 6 m room (0.05 m cells) with walls one cell thick.
    fn room() -> MeanField {
        let n = 120;
        let mut m = vec![0.01; n * n];
        for i in 0..n {
            for j in [0, n - 1] {
                m[i * n + j] = 0.95;
                m[j * n + i] = 0.95;
            }
        }
        // A pillar that breaks the room's symmetry.
        for iy in 30..36 {
            for ix in 80..86 {
                m[iy * n + ix] = 0.95;
            }
        }
        MeanField::from_means(
            GridGeometry {
                origin: [0.0, 0.0],
                resolution: 0.05,
            },
            CellRect {
                ix0: 0,
                iy0: 0,
                nx: n as i64,
                ny: n as i64,
            },
            m,
            0.5,
            0.25,
            8,
        )
        .unwrap()
    }

    /// The endpoints of 180 beams from `pose`, cast on the room's cells.
    fn scan_from(f: &MeanField, pose: Pose) -> Vec<[f64; 2]> {
        (0..180)
            .filter_map(|i| {
                let a = -std::f64::consts::FRAC_PI_2 + i as f64 * std::f64::consts::PI / 179.0;
                let (dx, dy) = ((pose[2] + a).cos(), (pose[2] + a).sin());
                (1..900).map(|k| k as f64 * 0.01).find_map(|r| {
                    let (x, y) = (pose[0] + r * dx, pose[1] + r * dy);
                    (f.mean_at_point(x, y) > 0.5).then_some([r * a.cos(), r * a.sin()])
                })
            })
            .collect()
    }

    /// The room and its endpoint score at σ = 0.2 m.
    fn scored_room() -> (MeanField, EndpointField) {
        let f = room();
        let mut e = EndpointField::new(&f);
        e.set_sigma(0.2);
        (f, e)
    }

    const SETTINGS: ClimbSettings = ClimbSettings {
        step_xy: 0.25,
        step_theta: 0.087,
        refinements: 3,
        max_moves: 40,
    };

    #[test]
    fn the_score_is_highest_at_the_true_pose() {
        let (f, e) = scored_room();
        let truth = [2.0, 3.0, 0.3];
        let pts = scan_from(&f, truth);
        assert!(pts.len() > 150);
        let at = e.score(truth, &pts);
        for off in [[0.2, 0.0, 0.0], [0.0, -0.2, 0.0], [0.0, 0.0, 0.1]] {
            let q = [truth[0] + off[0], truth[1] + off[1], truth[2] + off[2]];
            assert!(e.score(q, &pts) < at, "{off:?}");
        }
        // Every endpoint on a wall cell or next to one scores near 1.
        assert!(at > 0.9 * pts.len() as f64, "{at}");
    }

    #[test]
    fn a_particle_in_the_basin_climbs_onto_the_true_pose() {
        let (f, e) = scored_room();
        let truth = [2.0, 3.0, 0.3];
        let pts = scan_from(&f, truth);
        for start in [[2.3, 2.7, 0.45], [1.7, 3.2, 0.2], [2.2, 3.3, 0.15]] {
            let p = e.climb(&SETTINGS, start, [0.0; 3], &pts);
            let err = (p[0] - truth[0]).hypot(p[1] - truth[1]);
            assert!(
                err < 0.06 && wrap(p[2] - truth[2]).abs() < 0.03,
                "{start:?} -> {p:?}"
            );
        }
    }

    #[test]
    fn the_climb_uses_the_laser_offset() {
        let (f, e) = scored_room();
        let offset = [0.3, -0.1, 0.2];
        let robot = [2.5, 2.5, -0.4];
        let pts = scan_from(&f, compose(robot, offset));
        let p = e.climb(&SETTINGS, [2.65, 2.4, -0.3], offset, &pts);
        assert!((p[0] - robot[0]).hypot(p[1] - robot[1]) < 0.06, "{p:?}");
        assert!(wrap(p[2] - robot[2]).abs() < 0.03, "{p:?}");
    }

    #[test]
    fn a_pose_at_the_optimum_stays() {
        let (f, e) = scored_room();
        let pts = scan_from(&f, [3.0, 2.0, 1.0]);
        let once = e.climb(&SETTINGS, [3.1, 2.1, 1.05], [0.0; 3], &pts);
        assert_eq!(e.climb(&SETTINGS, once, [0.0; 3], &pts), once);
    }

    #[test]
    fn the_score_follows_sigma_and_ignores_points_off_the_map() {
        let (_, mut e) = scored_room();
        // An endpoint at the centre of cell (6, 36), 0.3 m from the centre of the nearest
        // wall cell (0, 36).
        let p = [[-1.0, 0.0]];
        let sensor = [1.325, 1.825, 0.0];
        let d: f64 = 0.3;
        let want = (-d * d / (2.0 * 0.04)).exp();
        assert!((e.score(sensor, &p) - want).abs() < 1e-6);
        e.set_sigma(0.5);
        let want = (-d * d / (2.0 * 0.25)).exp();
        assert!((e.score(sensor, &p) - want).abs() < 1e-6);
        assert_eq!(e.score([100.0, 100.0, 0.0], &p), 0.0);
    }

    #[test]
    fn endpoints_keep_the_range_readings() {
        let angles = [0.0, 0.5, 1.0, 1.5];
        let ranges = [1.0, f64::INFINITY, 30.0, 0.01];
        let pts = endpoints(&angles, &ranges, &[0, 1, 2, 3], 0.02, 20.0);
        assert_eq!(pts, vec![[1.0, 0.0]]);
        assert!(endpoints(&angles, &ranges, &[1, 2], 0.0, 20.0).is_empty());
    }
}
