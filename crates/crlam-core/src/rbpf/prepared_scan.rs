//! [`PreparedScan`]: the beams of one scan that take part in scan matching, in the robot frame,
//! built once per scan and shared by all particles (the matcher of [`super::scanmatch`] and the
//! patch bounds of [`super::match_surface`] read it).

use super::scanmatch_params::positive;
use crate::error::{config_err, Result};
use crate::grid::check_pose;
use crate::pose::Pose;

/// Ranges (m) above this are refused as a usable range: they would push endpoints towards the
/// index limits of the grid.
const MAX_USABLE_RANGE: f64 = 1e5;

/// One beam of a prepared scan, in the robot frame.
#[derive(Clone, Copy, Debug)]
pub(super) struct PreparedBeam {
    /// Endpoint of the reading.
    pub(super) end: [f64; 2],
    /// Unit direction of the beam.
    pub(super) dir: [f64; 2],
}

/// The beams of one scan that take part in matching (strided, hits below the usable range),
/// precomputed in the robot frame so that evaluating a pose costs no trigonometry per beam.
/// Built once per scan and shared by all particles.
#[derive(Clone, Debug, Default)]
pub struct PreparedScan {
    pub(super) beams: Vec<PreparedBeam>,
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
        if angles.len() != ranges.len() {
            return Err(crate::error::CrlamError::Shape(format!(
                "{} angles but {} ranges",
                angles.len(),
                ranges.len()
            )));
        }
        if !(positive(usable_range) && usable_range <= MAX_USABLE_RANGE) {
            return Err(config_err(
                "usable_range",
                format!("must be in (0, {MAX_USABLE_RANGE}], got {usable_range}"),
            ));
        }
        if stride == 0 {
            return Err(config_err("beam_stride", "must be >= 1"));
        }
        check_pose(laser_offset)?;
        let (s, c) = laser_offset[2].sin_cos();
        let beams = angles
            .iter()
            .zip(ranges)
            .step_by(stride)
            .filter(|(a, z)| a.is_finite() && z.is_finite() && **z > 0.0 && **z < usable_range)
            .map(|(&a, &z)| {
                let (sa, ca) = a.sin_cos();
                // Beam direction in the laser frame, rotated into the robot frame.
                let dir = [c * ca - s * sa, s * ca + c * sa];
                let end = [laser_offset[0] + z * dir[0], laser_offset[1] + z * dir[1]];
                PreparedBeam { end, dir }
            })
            .collect();
        Ok(Self { beams })
    }

    /// Number of beams used for matching.
    pub fn len(&self) -> usize {
        self.beams.len()
    }

    pub fn is_empty(&self) -> bool {
        self.beams.is_empty()
    }

    /// Endpoints of the used beams in the robot frame (m).
    pub fn endpoints(&self) -> impl Iterator<Item = [f64; 2]> + '_ {
        self.beams.iter().map(|b| b.end)
    }
}
