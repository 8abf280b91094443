//! Pieces shared by the particle filters.

use crate::error::{config_err, CrlamError, Result};
use crate::pose::{between, Pose};

/// One laser scan with the odometry pose at its time.
#[derive(Clone, Copy, Debug)]
pub struct ScanInput<'a> {
    /// Odometry pose of the robot (m, m, rad) when the scan was taken.
    pub odom: Pose,
    /// Beam bearings in the laser frame (rad).
    pub angles: &'a [f64],
    /// Ranges (m); `inf`/NaN/≥ z_max are no-returns.
    pub ranges: &'a [f64],
    /// Laser pose in the robot frame.
    pub laser_offset: Pose,
}

impl ScanInput<'_> {
    /// Checks the arrays and poses.
    pub fn validate(&self) -> Result<()> {
        if self.angles.len() != self.ranges.len() {
            return Err(CrlamError::Shape(format!(
                "scan has {} beam angles but {} ranges",
                self.angles.len(),
                self.ranges.len()
            )));
        }
        for (i, v) in self.odom.iter().chain(self.laser_offset.iter()).enumerate() {
            if !v.is_finite() {
                return Err(CrlamError::NonFinite {
                    field: if i < 3 {
                        "odometry pose"
                    } else {
                        "laser offset"
                    },
                    value: *v,
                });
            }
        }
        Ok(())
    }
}

/// What one call of a filter's `process` did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FilterStep {
    /// Whether the scan was processed (triggered) or only carried by odometry.
    pub processed: bool,
    /// The robot pose estimate at this scan: the weighted mean after a processed scan, else the
    /// last estimate composed with the odometry increment since then.
    pub estimate: Pose,
    /// N_eff after weighting (before resampling); NaN when not processed.
    pub neff: f64,
    pub resampled: bool,
}

/// Where an improved proposal puts the particle once it has the likelihood × motion density on a
/// lattice around the scan match.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum ProposalPose {
    /// Draw from the Gaussian fitted on the lattice (Grisetti et al. 2007, Eqs. 9–11).
    #[default]
    Sample,
    /// Take the scan match itself, with no draw: what GMapping's released code does (it sets the
    /// pose to the optimiser's result). The weight is the same lattice normaliser as for
    /// `Sample`; the particles' spread then comes only from their different maps and from the
    /// climb's start, a motion-model sample in both filters.
    Match,
}

impl ProposalPose {
    pub fn parse(name: &str) -> Result<Self> {
        match name {
            "sample" => Ok(Self::Sample),
            "match" => Ok(Self::Match),
            other => Err(config_err(
                "proposal_pose",
                format!("unknown value {other:?}; expected sample or match"),
            )),
        }
    }
}

/// Decides which scans are processed: the first one, then whenever the odometry since the last
/// processed scan has moved at least `linear` metres or turned `angular` radians (GMapping's
/// linearUpdate / angularUpdate). Zero thresholds process every scan.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UpdateTrigger {
    pub linear: f64,
    pub angular: f64,
}

impl UpdateTrigger {
    /// Process every scan.
    pub fn every_scan() -> Self {
        Self {
            linear: 0.0,
            angular: 0.0,
        }
    }

    pub fn validate(&self) -> Result<()> {
        if !(self.linear.is_finite()
            && self.linear >= 0.0
            && self.angular.is_finite()
            && self.angular >= 0.0)
        {
            return Err(config_err(
                "update_trigger",
                "linear and angular thresholds must be finite and >= 0",
            ));
        }
        Ok(())
    }

    /// True if a path of `travelled` metres with `turned` radians of rotation triggers an update.
    pub fn fires(&self, travelled: f64, turned: f64) -> bool {
        (self.linear == 0.0 && self.angular == 0.0)
            || travelled >= self.linear
            || turned >= self.angular
    }
}

/// Accumulates odometry between processed scans: the increment since the last processed scan
/// and the path length and rotation travelled (summed per raw step, as GMapping does).
#[derive(Clone, Copy, Debug, Default)]
pub struct OdometryTracker {
    last_processed: Option<Pose>,
    previous: Option<Pose>,
    travelled: f64,
    turned: f64,
    steps: usize,
}

impl OdometryTracker {
    /// Feeds the odometry pose of a new scan; returns (increment since the last processed scan,
    /// raw steps merged, whether `trigger` fires). The first scan always fires.
    pub fn observe(&mut self, odom: Pose, trigger: &UpdateTrigger) -> (Pose, usize, bool) {
        let Some(last) = self.last_processed else {
            return ([0.0; 3], 0, true);
        };
        if let Some(prev) = self.previous {
            let d = between(prev, odom);
            self.travelled += d[0].hypot(d[1]);
            self.turned += d[2].abs();
            self.steps += 1;
        }
        self.previous = Some(odom);
        let fires = trigger.fires(self.travelled, self.turned);
        (between(last, odom), self.steps.max(1), fires)
    }

    /// Marks the scan with odometry `odom` as processed.
    pub fn processed(&mut self, odom: Pose) {
        self.last_processed = Some(odom);
        self.previous = Some(odom);
        self.travelled = 0.0;
        self.turned = 0.0;
        self.steps = 0;
    }
}

/// (bytes of distinct tiles, distinct tiles, tile references) over a set of grids: what the
/// particle maps really occupy with copy-on-write sharing (equal addresses are one tile).
pub fn distinct_tile_memory<'a, T: Copy + Send + Sync + 'a>(
    grids: impl Iterator<Item = &'a crate::grid::TiledGrid<T>>,
) -> (usize, usize, usize) {
    let mut seen = std::collections::HashSet::new();
    let (mut bytes, mut refs) = (0, 0);
    for g in grids {
        for (addr, b) in g.tile_addresses() {
            refs += 1;
            if seen.insert(addr) {
                bytes += b;
            }
        }
    }
    (bytes, seen.len(), refs)
}

/// Weighted mean pose with a circular mean for the heading (crm-spec 4.3).
pub fn weighted_mean_pose(poses: &[Pose], w: &[f64]) -> Pose {
    let (mut x, mut y, mut s, mut c) = (0.0, 0.0, 0.0, 0.0);
    for (p, &wi) in poses.iter().zip(w) {
        x += wi * p[0];
        y += wi * p[1];
        s += wi * p[2].sin();
        c += wi * p[2].cos();
    }
    [x, y, s.atan2(c)]
}

/// What every particle filter offers its callers (the CLI, the experiments, the Python classes):
/// feed scans, read the estimate and the particle set.
pub trait ParticleFilter {
    /// Feeds one scan; processes it when the update trigger fires.
    fn process(&mut self, scan: &ScanInput) -> crate::error::Result<FilterStep>;
    /// Weighted mean pose (circular heading) at the last processed scan.
    fn estimate(&self) -> crate::pose::Pose;
    /// Index of the highest-weight particle.
    fn best_index(&self) -> usize;
    /// Resampling events so far.
    fn n_resamples(&self) -> usize;
    /// Processed scans, the first one included.
    fn n_processed(&self) -> usize;
    /// Particles in the set.
    fn n_particles(&self) -> usize;
    /// Particle poses.
    fn poses(&self) -> Vec<crate::pose::Pose>;
    /// Particle log-weights as the filter stores them (RBPF-OGM: before its weight smoothing).
    fn log_weights(&self) -> Vec<f64>;
    /// Normalised weights of the current particles, the ones behind N_eff, resampling and the
    /// estimate (RBPF-OGM: after GMapping's weight smoothing; uniform right after resampling).
    fn weights(&self) -> Vec<f64>;
    /// (bytes of distinct map tiles, distinct tiles, tile references) over all particles.
    fn map_memory(&self) -> (usize, usize, usize);
    /// Frees the particles' maps once the run's map is written; the filter then refuses scans.
    fn release_maps(&mut self) -> crate::error::Result<()>;
    /// Whether [`Self::release_maps`] was called.
    fn maps_released(&self) -> bool;
    /// The best particle's pose at every processed scan (the first one included), in order.
    fn best_path(&self) -> Vec<crate::pose::Pose>;
    /// The proposal means along the best particle's path, when the filter draws its poses from a
    /// fitted proposal (see [`crate::rbpf::PathTree`]).
    fn best_path_means(&self) -> Option<Vec<crate::pose::Pose>>;
    /// Poses and normalised weights of the last processed scan before resampling, for point
    /// estimates other than the weighted mean (e.g. [`crate::rbpf::mode_seeking_pose`]).
    fn weighed_set(&self) -> &crate::rbpf::WeighedSet;
    /// Smoothed means of the weighed set's lineages for lags 0..=max_lag processed scans
    /// (see [`crate::rbpf::PathTree::ancestor_means`]); `None` for `proposal_means` when the
    /// filter does not record proposal means.
    fn ancestor_means(
        &self,
        max_lag: usize,
        proposal_means: bool,
    ) -> Option<Vec<crate::pose::Pose>>;
}

/// The error of a filter whose maps were released ([`ParticleFilter::release_maps`]) when it is
/// given a scan or a correction; `Ok` while it keeps its maps.
pub(crate) fn check_maps_kept(maps_released: bool) -> crate::error::Result<()> {
    if maps_released {
        return Err(crate::error::config_err(
            "filter",
            "the particles' maps were released after the run's outputs were written: \
             the filter takes no more scans or corrections",
        ));
    }
    Ok(())
}

/// Implements [`ParticleFilter`] for a filter type with inherent methods of the same names plus
/// `particles()` whose items have `pose` and `log_w`.
macro_rules! impl_particle_filter {
    ($t:ty) => {
        impl $crate::rbpf::common::ParticleFilter for $t {
            fn process(
                &mut self,
                scan: &$crate::rbpf::common::ScanInput,
            ) -> $crate::error::Result<$crate::rbpf::common::FilterStep> {
                <$t>::process(self, scan)
            }
            fn estimate(&self) -> $crate::pose::Pose {
                <$t>::estimate(self)
            }
            fn best_index(&self) -> usize {
                <$t>::best_index(self)
            }
            fn n_resamples(&self) -> usize {
                <$t>::n_resamples(self)
            }
            fn n_processed(&self) -> usize {
                <$t>::n_processed(self)
            }
            fn n_particles(&self) -> usize {
                self.particles().len()
            }
            fn poses(&self) -> Vec<$crate::pose::Pose> {
                self.particles().iter().map(|p| p.pose).collect()
            }
            fn log_weights(&self) -> Vec<f64> {
                self.particles().iter().map(|p| p.log_w).collect()
            }
            fn weights(&self) -> Vec<f64> {
                <$t>::weights(self)
            }
            fn map_memory(&self) -> (usize, usize, usize) {
                <$t>::map_memory(self)
            }
            fn release_maps(&mut self) -> $crate::error::Result<()> {
                <$t>::release_maps(self)
            }
            fn maps_released(&self) -> bool {
                <$t>::maps_released(self)
            }
            fn best_path(&self) -> Vec<$crate::pose::Pose> {
                <$t>::best_path(self)
            }
            fn best_path_means(&self) -> Option<Vec<$crate::pose::Pose>> {
                <$t>::best_path_means(self)
            }
            fn weighed_set(&self) -> &$crate::rbpf::WeighedSet {
                <$t>::weighed_set(self)
            }
            fn ancestor_means(
                &self,
                max_lag: usize,
                proposal_means: bool,
            ) -> Option<Vec<$crate::pose::Pose>> {
                <$t>::ancestor_means(self, max_lag, proposal_means)
            }
        }
    };
}
pub(crate) use impl_particle_filter;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tracker_carries_odometry_between_processed_scans() {
        let trig = UpdateTrigger {
            linear: 0.5,
            angular: 0.5,
        };
        let mut t = OdometryTracker::default();
        assert!(t.observe([0.0; 3], &trig).2);
        t.processed([0.0; 3]);
        let (u, n, fire) = t.observe([0.3, 0.0, 0.0], &trig);
        assert!(!fire && n == 1 && (u[0] - 0.3).abs() < 1e-12);
        let (u, n, fire) = t.observe([0.6, 0.0, 0.0], &trig);
        assert!(fire && n == 2 && (u[0] - 0.6).abs() < 1e-12);
        t.processed([0.6, 0.0, 0.0]);
        let (_, _, fire) = t.observe([0.6, 0.0, 0.6], &trig);
        assert!(fire);
    }

    #[test]
    fn circular_mean_across_the_cut() {
        let m = weighted_mean_pose(&[[0.0, 0.0, 3.1], [2.0, 0.0, -3.1]], &[0.5, 0.5]);
        assert!((m[0] - 1.0).abs() < 1e-12);
        assert!(m[2].abs() > 3.1);
    }
}
