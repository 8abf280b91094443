//! One scan matcher on one grid, without particles: the building block of the scan-matching
//! odometry front end (Python's `crlam.slam.scan_odometry`, which decides which scans the local map
//! holds and where each match starts).
//!
//! The grid and the matcher are GMapping's, as in RBPF-OGM with `map_model = "gmapping"`
//! ([`OgmFilterConfig::with_gmapping_map`](super::OgmFilterConfig::with_gmapping_map)): counting
//! cells occupied above a 0.1 hit rate that keep the mean of their hits, a companion cell free
//! unless occupied, and the hill climbing of [`ScanMatcher::optimize`] from the given start.

use super::scanmatch::{FreeTest, MatcherParams, PreparedScan, ScanMatcher};
use crate::error::{CrlamError, Result};
use crate::grid::{check_pose, GridGeometry};
use crate::ogm::{LogOddsGrid, LogOddsParams};
use crate::pose::{compose, Pose};

/// GMapping's fullnessThreshold: a cell is occupied above this hit rate.
const FULLNESS_THRESHOLD: f64 = 0.1;
/// Tile side of the grid (cells).
const TILE_SIZE: usize = 32;

/// The result of one match.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LocalMatch {
    /// The matched robot pose (the start itself when no beam matched).
    pub pose: Pose,
    /// The matcher's score at `pose` (Σ over matched beams of exp(−d²/score_sigma)).
    pub score: f64,
    /// Beams that found a matching cell at `pose`.
    pub matched: usize,
    /// Beams that took part (finite readings below the usable range).
    pub used: usize,
}

/// A grid that scans are inserted into at given poses and matched against.
#[derive(Clone, Debug)]
pub struct LocalMapMatcher {
    matcher: ScanMatcher,
    empty: LogOddsGrid,
    map: LogOddsGrid,
    usable_range: f64,
    n_inserted: usize,
}

impl LocalMapMatcher {
    /// An empty grid of `resolution` (m) whose scans are used up to `usable_range` (m; longer
    /// readings clear free space up to it and are not matched), matched with `params`
    /// (GMapping's defaults: [`MatcherParams::default`]; the free test is set to GMapping's).
    pub fn new(resolution: f64, usable_range: f64, params: MatcherParams) -> Result<Self> {
        let geometry = GridGeometry::new([0.0, 0.0], resolution)?;
        let mut log_odds = LogOddsParams::hit_rate(usable_range, FULLNESS_THRESHOLD)?;
        log_odds.hit_means = true;
        let matcher = ScanMatcher::new(MatcherParams {
            free_test: FreeTest::NotOccupied,
            ..params
        })?;
        let empty = LogOddsGrid::new(geometry, log_odds, TILE_SIZE, None)?;
        Ok(Self {
            matcher,
            map: empty.clone(),
            empty,
            usable_range,
            n_inserted: 0,
        })
    }

    /// Scans inserted since the grid was last cleared.
    pub fn n_inserted(&self) -> usize {
        self.n_inserted
    }

    /// Forgets every inserted scan.
    pub fn clear(&mut self) {
        self.map = self.empty.clone();
        self.n_inserted = 0;
    }

    /// The grid (log-odds of the hit-rate cells; see [`LogOddsParams::hit_rate`]).
    pub fn map(&self) -> &LogOddsGrid {
        &self.map
    }

    /// Hill-climbs the scan (bearings in the laser frame, ranges in m, `inf` = no return) on the
    /// grid from the robot pose `start`.
    pub fn match_scan(
        &self,
        start: Pose,
        angles: &[f64],
        ranges: &[f64],
        laser_offset: Pose,
    ) -> Result<LocalMatch> {
        check_pose(start)?;
        let prepared = PreparedScan::new(
            angles,
            ranges,
            laser_offset,
            self.usable_range,
            self.matcher.params.beam_stride,
        )?;
        let surface = self.matcher.surface(&self.map, &prepared, start);
        let (pose, score) = self.matcher.optimize(&surface, &prepared, start)?;
        let matched = self.matcher.evaluate(&surface, &prepared, pose)?.matched;
        Ok(LocalMatch {
            pose,
            score,
            matched,
            used: prepared.len(),
        })
    }

    /// Integrates the scan with the robot at `pose`: every finite positive reading (those at or
    /// beyond the usable range clear free space up to it); no-returns (`inf`, NaN) are left out,
    /// as GMapping leaves out readings at its maximum range.
    pub fn insert(
        &mut self,
        pose: Pose,
        angles: &[f64],
        ranges: &[f64],
        laser_offset: Pose,
    ) -> Result<()> {
        check_pose(pose)?;
        check_pose(laser_offset)?;
        if angles.len() != ranges.len() {
            return Err(CrlamError::Shape(format!(
                "{} angles but {} ranges",
                angles.len(),
                ranges.len()
            )));
        }
        let (a, z): (Vec<f64>, Vec<f64>) = angles
            .iter()
            .zip(ranges)
            .filter(|(a, z)| a.is_finite() && z.is_finite())
            .map(|(a, z)| (*a, *z))
            .unzip();
        self.map.update_scan(compose(pose, laser_offset), &a, &z)?;
        self.n_inserted += 1;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Ranges from `pose` (robot = laser) to the walls of the box [0, 4] x [0, 3].
    fn box_scan(pose: Pose, angles: &[f64]) -> Vec<f64> {
        angles
            .iter()
            .map(|a| {
                let (s, c) = (pose[2] + a).sin_cos();
                let mut t = f64::INFINITY;
                for (d, lo, hi) in [(c, pose[0], 4.0 - pose[0]), (s, pose[1], 3.0 - pose[1])] {
                    if d > 1e-12 {
                        t = t.min(hi / d);
                    } else if d < -1e-12 {
                        t = t.min(lo / -d);
                    }
                }
                t
            })
            .collect()
    }

    #[test]
    fn matching_recovers_a_small_offset_and_an_empty_grid_keeps_the_start() {
        let angles: Vec<f64> = (0..360).map(|i| (i as f64).to_radians() - 3.1).collect();
        let mut m = LocalMapMatcher::new(0.05, 8.0, MatcherParams::default()).unwrap();
        let start = [1.0, 1.0, 0.0];
        let empty = m
            .match_scan(start, &angles, &box_scan(start, &angles), [0.0; 3])
            .unwrap();
        assert_eq!(empty.pose, start);
        assert_eq!(empty.matched, 0);
        m.insert(start, &angles, &box_scan(start, &angles), [0.0; 3])
            .unwrap();
        assert_eq!(m.n_inserted(), 1);
        let truth = [1.3, 1.1, 0.05];
        let guess = [1.25, 1.15, 0.02];
        let r = m
            .match_scan(guess, &angles, &box_scan(truth, &angles), [0.0; 3])
            .unwrap();
        assert!((r.pose[0] - truth[0]).abs() < 0.02, "{r:?}");
        assert!((r.pose[1] - truth[1]).abs() < 0.02, "{r:?}");
        assert!((r.pose[2] - truth[2]).abs() < 0.01, "{r:?}");
        assert!(r.matched as f64 > 0.9 * r.used as f64, "{r:?}");
        m.clear();
        assert_eq!(m.n_inserted(), 0);
        assert_eq!(
            m.match_scan(guess, &angles, &box_scan(truth, &angles), [0.0; 3])
                .unwrap()
                .matched,
            0
        );
    }

    #[test]
    fn bad_input_is_an_error() {
        let mut m = LocalMapMatcher::new(0.05, 8.0, MatcherParams::default()).unwrap();
        assert!(m.insert([0.0; 3], &[0.0, 0.1], &[1.0], [0.0; 3]).is_err());
        assert!(m
            .insert([f64::NAN, 0.0, 0.0], &[0.0], &[1.0], [0.0; 3])
            .is_err());
        assert!(m
            .match_scan([0.0; 3], &[0.0], &[1.0, 2.0], [0.0; 3])
            .is_err());
        assert!(LocalMapMatcher::new(0.0, 8.0, MatcherParams::default()).is_err());
        assert!(LocalMapMatcher::new(0.05, f64::NAN, MatcherParams::default()).is_err());
    }
}
