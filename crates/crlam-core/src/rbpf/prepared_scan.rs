//! [`PreparedScan`]: the beams of one scan that take part in scan matching, in the robot frame,
//! built once per scan and shared by all particles (the matcher of [`super::scanmatch`] and the
//! patch bounds of [`super::match_surface`] read it).

use super::scanmatch_params::positive;
use crate::error::{config_err, Result};
use crate::grid::check_pose;
use crate::pose::Pose;

/// Ranges (m) above this are refused as a usable range: they would push endpoints towards the
/// index limits of the grid.
pub(crate) const MAX_USABLE_RANGE: f64 = 1e5;

/// One beam of a prepared scan, in the robot frame.
#[derive(Clone, Copy, Debug)]
pub(super) struct PreparedBeam {
    /// Endpoint of the reading.
    pub(super) end: [f64; 2],
    /// Unit direction of the beam.
    pub(super) dir: [f64; 2],
}

/// Which readings of a scan the matcher uses: every reading `0 < z < near`, and beyond `near`
/// every reading `z < far` that is not a no-return (`z < no_return_from`). Infinite and NaN
/// readings are never used.
///
/// `near` is where the particle maps are written (z_max): the readings there are the ones the
/// matcher always used. Beyond it a reading's endpoint falls on cells mapped earlier from closer
/// by (a corridor's end on a revisit), or on unknown cells that match nothing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BeamSelection {
    /// Readings below this range (m) are used.
    pub near: f64,
    /// Readings in `[near, far)` are used when they are returns.
    pub far: f64,
    /// Readings at or above this range (m) are no-returns (they are used only below `near`,
    /// where the map update takes them for hits too).
    pub no_return_from: f64,
}

impl BeamSelection {
    /// Readings below `range` only (the paper's matcher: z_max).
    pub fn below(range: f64) -> Self {
        Self {
            near: range,
            far: range,
            no_return_from: f64::INFINITY,
        }
    }

    /// Whether a reading `z` is used.
    #[inline]
    pub fn keeps(&self, z: f64) -> bool {
        z.is_finite() && z > 0.0 && (z < self.near || (z < self.far && z < self.no_return_from))
    }

    fn validate(&self) -> Result<()> {
        for (name, v) in [("usable_range", self.near), ("far_range", self.far)] {
            if !(positive(v) && v <= MAX_USABLE_RANGE) {
                return Err(config_err(
                    name,
                    format!("must be in (0, {MAX_USABLE_RANGE}], got {v}"),
                ));
            }
        }
        if self.no_return_from.is_nan() {
            return Err(config_err("no_return_from", "must not be NaN"));
        }
        Ok(())
    }
}

/// The beams of one scan that take part in matching (strided, selected by a [`BeamSelection`]),
/// precomputed in the robot frame so that evaluating a pose costs no trigonometry per beam.
/// Built once per scan and shared by all particles. The beams below the selection's `near`
/// range come first, in scan order, then the farther ones, in scan order.
#[derive(Clone, Debug, Default)]
pub struct PreparedScan {
    pub(super) beams: Vec<PreparedBeam>,
    /// Number of leading beams with a reading below `near`.
    n_near: usize,
    /// The robot-frame direction the scan leaves free, when the filter looks for one and the
    /// scan is degenerate ([`super::degeneracy`]).
    pub(crate) free_direction: Option<[f64; 2]>,
}

impl PreparedScan {
    /// Keeps beams `i` with `i % stride == 0` and a reading `0 < z < usable_range`.
    pub fn new(
        angles: &[f64],
        ranges: &[f64],
        laser_offset: Pose,
        usable_range: f64,
        stride: usize,
    ) -> Result<Self> {
        Self::select(
            angles,
            ranges,
            laser_offset,
            BeamSelection::below(usable_range),
            stride,
        )
    }

    /// Keeps beams `i` with `i % stride == 0` whose reading `selection` keeps.
    pub fn select(
        angles: &[f64],
        ranges: &[f64],
        laser_offset: Pose,
        selection: BeamSelection,
        stride: usize,
    ) -> Result<Self> {
        if angles.len() != ranges.len() {
            return Err(crate::error::CrlamError::Shape(format!(
                "{} angles but {} ranges",
                angles.len(),
                ranges.len()
            )));
        }
        selection.validate()?;
        if stride == 0 {
            return Err(config_err("beam_stride", "must be >= 1"));
        }
        check_pose(laser_offset)?;
        let (s, c) = laser_offset[2].sin_cos();
        let beam = |a: f64, z: f64| {
            let (sa, ca) = a.sin_cos();
            // Beam direction in the laser frame, rotated into the robot frame.
            let dir = [c * ca - s * sa, s * ca + c * sa];
            let end = [laser_offset[0] + z * dir[0], laser_offset[1] + z * dir[1]];
            PreparedBeam { end, dir }
        };
        let kept = || {
            angles
                .iter()
                .zip(ranges)
                .step_by(stride)
                .filter(|(a, z)| a.is_finite() && selection.keeps(**z))
        };
        let mut beams: Vec<PreparedBeam> = kept()
            .filter(|(_, z)| **z < selection.near)
            .map(|(&a, &z)| beam(a, z))
            .collect();
        let n_near = beams.len();
        beams.extend(
            kept()
                .filter(|(_, z)| **z >= selection.near)
                .map(|(&a, &z)| beam(a, z)),
        );
        Ok(Self {
            beams,
            n_near,
            free_direction: None,
        })
    }

    /// Number of beams used for matching.
    pub fn len(&self) -> usize {
        self.beams.len()
    }

    pub fn is_empty(&self) -> bool {
        self.beams.is_empty()
    }

    /// Number of beams with a reading below the selection's `near` range (the first ones).
    pub fn n_near(&self) -> usize {
        self.n_near
    }

    /// Endpoints of the used beams in the robot frame (m): those below `near` first.
    pub fn endpoints(&self) -> impl Iterator<Item = [f64; 2]> + '_ {
        self.beams.iter().map(|b| b.end)
    }

    /// Endpoints of the beams below the selection's `near` range, in the robot frame (m).
    pub fn near_endpoints(&self) -> impl Iterator<Item = [f64; 2]> + '_ {
        self.beams[..self.n_near].iter().map(|b| b.end)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rbpf::clam_config::{MatchRange, NO_RETURN_TOLERANCE};

    /// The readings (in scan order) that `sel` keeps, from the endpoints of a scan along +x.
    fn kept(ranges: &[f64], sel: BeamSelection, stride: usize) -> (Vec<f64>, usize) {
        let angles = vec![0.0; ranges.len()];
        let s = PreparedScan::select(&angles, ranges, [0.0; 3], sel, stride).unwrap();
        (s.endpoints().map(|e| e[0]).collect(), s.n_near())
    }

    #[test]
    fn below_a_range_keeps_the_positive_finite_readings_under_it() {
        let z = [
            0.5,
            8.0,
            7.99,
            f64::INFINITY,
            f64::NAN,
            0.0,
            -1.0,
            30.0,
            3.0,
        ];
        let (got, near) = kept(&z, BeamSelection::below(8.0), 1);
        assert_eq!(got, vec![0.5, 7.99, 3.0]);
        assert_eq!(near, 3);
        // `new` is the same selection.
        let angles = vec![0.0; z.len()];
        let s = PreparedScan::new(&angles, &z, [0.0; 3], 8.0, 1).unwrap();
        assert_eq!(s.endpoints().map(|e| e[0]).collect::<Vec<_>>(), got);
        // The stride applies before the selection: beams 0, 3, 6 (6 is 0.0: dropped).
        assert_eq!(kept(&z, BeamSelection::below(8.0), 3).0, vec![0.5]);
    }

    #[test]
    fn a_full_range_keeps_far_returns_after_the_near_ones_and_drops_no_returns() {
        // Largest reading so far 50.0 (a saturating laser's no-return value, as in ACES).
        let sel = MatchRange::Full.selection(8.0, 50.0);
        assert_eq!(sel.near, 8.0);
        assert_eq!(sel.no_return_from, 50.0 - NO_RETURN_TOLERANCE);
        let z = [12.0, 2.0, 50.0, 49.97, 49.9, f64::INFINITY, 7.0, 8.0, 1e6];
        let (got, near) = kept(&z, sel, 1);
        // Near readings first (scan order), then far returns (scan order); 50.0 and 49.97 are
        // no-returns, inf is one, 1e6 is beyond any usable range.
        assert_eq!(got, vec![2.0, 7.0, 12.0, 49.9, 8.0]);
        assert_eq!(near, 2);
        // Below z_max a reading is kept even at the no-return value: the map takes it for a hit.
        let small_room = MatchRange::Full.selection(8.0, 5.0);
        assert_eq!(
            kept(&[5.0, 4.99, 3.0], small_room, 1).0,
            vec![5.0, 4.99, 3.0]
        );
        // Before any reading there is no no-return value: every finite reading is kept.
        let first = MatchRange::Full.selection(8.0, f64::NEG_INFINITY);
        assert_eq!(first.no_return_from, f64::INFINITY);
        assert_eq!(kept(&[20.0, 2.0], first, 1).0, vec![2.0, 20.0]);
    }

    #[test]
    fn a_range_in_metres_bounds_the_far_readings() {
        let sel = MatchRange::Metres(20.0).selection(8.0, 81.83);
        let z = [25.0, 19.0, 81.83, 3.0];
        assert_eq!(kept(&z, sel, 1), (vec![3.0, 19.0], 1));
        // Below z_max it is the near range too.
        let short = MatchRange::Metres(4.0).selection(8.0, 81.83);
        assert_eq!((short.near, short.far), (4.0, 4.0));
        assert_eq!(kept(&[5.0, 3.0], short, 1), (vec![3.0], 1));
    }

    #[test]
    fn z_max_is_the_papers_selection_whatever_the_largest_reading() {
        for largest in [f64::NEG_INFINITY, 5.0, 81.83] {
            assert_eq!(
                MatchRange::ZMax.selection(8.0, largest),
                BeamSelection::below(8.0)
            );
        }
    }

    #[test]
    fn bad_selections_and_ranges_are_refused() {
        let angles = [0.0; 2];
        let z = [1.0, 2.0];
        for sel in [
            BeamSelection::below(0.0),
            BeamSelection::below(f64::NAN),
            BeamSelection {
                far: 2e5,
                ..BeamSelection::below(8.0)
            },
            BeamSelection {
                no_return_from: f64::NAN,
                ..BeamSelection::below(8.0)
            },
        ] {
            assert!(PreparedScan::select(&angles, &z, [0.0; 3], sel, 1).is_err());
        }
        for m in [0.0, -1.0, f64::INFINITY, f64::NAN, 2e5] {
            assert!(MatchRange::Metres(m).validate().is_err(), "{m}");
        }
        assert!(MatchRange::Metres(30.0).validate().is_ok());
        assert_eq!(MatchRange::parse("full").unwrap(), MatchRange::Full);
        assert_eq!(MatchRange::parse("z_max").unwrap(), MatchRange::ZMax);
        assert!(MatchRange::parse("8").is_err());
    }
}
