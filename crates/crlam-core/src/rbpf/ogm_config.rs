//! Configuration of the RBPF-OGM baseline ([`super::ogm::RbpfOgm`]): GMapping's parameters, their
//! defaults and their validation.

use super::common::UpdateTrigger;
use super::scanmatch::{FreeTest, MatcherParams, ProposalParams};
use crate::error::{config_err, Result};
use crate::grid::GridGeometry;
use crate::motion::MotionModel;
use crate::ogm::LogOddsParams;

/// When the motion model perturbs the particles.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MotionDraws {
    /// Once per processed scan, on the odometry increment since the previous processed scan.
    PerUpdate,
    /// At every incoming scan, on that scan's own odometry increment, processed or not: GMapping's
    /// `processScan` calls `drawFromMotion` for every reading. Noise that grows with the step
    /// (GMapping's and Thrun's models) then adds up in variance over k small steps instead of
    /// scaling with their sum, about 1/√k of one draw on the whole increment. The improved
    /// proposal's motion prior is the Gaussian with the per-step variances summed.
    PerScan,
}

impl MotionDraws {
    pub fn parse(s: &str) -> Result<Self> {
        match s {
            "per_update" => Ok(Self::PerUpdate),
            "per_scan" => Ok(Self::PerScan),
            other => Err(config_err(
                "motion_draws",
                format!("unknown value {other:?}; expected per_update or per_scan"),
            )),
        }
    }
}

/// Configuration of [`RbpfOgm`](super::ogm::RbpfOgm). GMapping's parameter names are given in brackets.
#[derive(Clone, Debug, PartialEq)]
pub struct OgmFilterConfig {
    /// \[particles\] 30.
    pub n_particles: usize,
    /// Odometry model. Default: Thrun's model with α = (0.04, 0.01, 0.01, 0.04), the squares of
    /// GMapping's srr 0.1, srt 0.2, str 0.1, stt 0.2 (its coefficients scale standard deviations,
    /// Thrun's α variances), which gives GMapping's noise for pure rotations and for the distance
    /// of pure translations. The cross terms are not GMapping's: α2 = 0.01 gives the heading
    /// σ = 0.1 rad per metre where GMapping's code has srt = 0.2, and α4 = 0.04 the distance
    /// σ = 0.2 m per radian where it has str = 0.1. [`MotionModel::gmapping`] is GMapping's own
    /// model; this default is kept because the published baseline results were made with it.
    pub motion: MotionModel,
    /// When the motion model draws: per processed scan (default) or per incoming scan (GMapping).
    pub motion_draws: MotionDraws,
    /// \[linearUpdate, angularUpdate\] Default: every scan. GMapping uses 1.0 m / 0.5 rad.
    pub trigger: UpdateTrigger,
    /// \[resampleThreshold\] Resample when N_eff < threshold · n. 0.5.
    pub resample_threshold: f64,
    /// \[ogain\] Weight smoothing: log-weights are divided by ogain · n before normalising. 3.
    /// 0 disables it (textbook weights).
    pub weight_smoothing: f64,
    /// \[delta\] Map origin and resolution. 0.05 m, as GMapping (its scan matcher steps and
    /// kernel are tuned for 5 cm cells).
    pub geometry: GridGeometry,
    /// Tile side of the copy-on-write map storage (cells). 32.
    pub tile_size: usize,
    /// Inverse sensor model of the maps. Its `z_max` is the usable range \[maxUrange\]: longer
    /// readings are cropped to it for mapping (free space only) and not used for matching.
    /// Default: [`LogOddsParams::new`] with z_max = 30 m.
    pub log_odds: LogOddsParams,
    /// \[maxrange\] Readings at or above this (and non-finite ones) are ignored entirely. 80 m.
    pub max_range: f64,
    /// Scan matcher (score, likelihood, hill climbing, beam stride).
    pub matcher: MatcherParams,
    /// Improved proposal (minimum score, lattice).
    pub proposal: ProposalParams,
    /// Standard deviations (m along, m across, rad) added in quadrature to the motion prior used
    /// inside the improved proposal. Thrun's model has zero variance when the odometry did not
    /// move, which would make the prior a point mass and every lattice pose impossible; the floor
    /// stands for unmodelled slip per processed scan. (0.01, 0.01, 0.01).
    pub motion_floor: [f64; 3],
    /// Seed of all random streams.
    pub seed: u64,
    /// Standard deviations (m, m, rad) of the initial particle spread around the initial pose.
    /// 0 (GMapping starts all particles at the same pose).
    pub init_sigma: [f64; 3],
}

impl Default for OgmFilterConfig {
    fn default() -> Self {
        Self {
            n_particles: 30,
            motion: Self::default_motion(),
            motion_draws: MotionDraws::PerUpdate,
            trigger: UpdateTrigger::every_scan(),
            resample_threshold: 0.5,
            weight_smoothing: 3.0,
            geometry: GridGeometry {
                origin: [0.0, 0.0],
                resolution: 0.05,
            },
            tile_size: 32,
            log_odds: LogOddsParams::new(30.0),
            max_range: 80.0,
            matcher: MatcherParams::default(),
            proposal: ProposalParams::default(),
            motion_floor: [0.01, 0.01, 0.01],
            seed: 0,
            init_sigma: [0.0; 3],
        }
    }
}

impl OgmFilterConfig {
    /// The baseline's default odometry noise: Thrun's α = (0.04, 0.01, 0.01, 0.04) (see
    /// [`OgmFilterConfig::motion`] for how it differs from GMapping's own model).
    pub fn default_motion() -> MotionModel {
        MotionModel::Thrun {
            alpha: [0.04, 0.01, 0.01, 0.04],
        }
    }

    /// GMapping's map and match test: counting cells, occupied when their hit rate exceeds
    /// `fullness_threshold` ([`LogOddsParams::hit_rate`], at this config's usable range), and a
    /// match's companion cell free unless occupied ([`FreeTest::NotOccupied`]).
    pub fn with_hit_rate_map(mut self, fullness_threshold: f64) -> Result<Self> {
        self.log_odds = LogOddsParams::hit_rate(self.log_odds.z_max, fullness_threshold)?;
        self.matcher.free_test = FreeTest::NotOccupied;
        Ok(self)
    }

    /// [`Self::with_hit_rate_map`] with GMapping's hit means as well: the matcher measures each
    /// beam's distance to the mean of the hits of the matched cell ([`LogOddsParams::hit_means`]),
    /// which is GMapping's cell (`PointAccumulator`) in full. Four values per cell.
    pub fn with_gmapping_map(self, fullness_threshold: f64) -> Result<Self> {
        let mut cfg = self.with_hit_rate_map(fullness_threshold)?;
        cfg.log_odds.hit_means = true;
        Ok(cfg)
    }

    /// Checks every field; the error names the offending one.
    pub fn validate(&self) -> Result<()> {
        if self.n_particles == 0 {
            return Err(config_err("n_particles", "must be >= 1"));
        }
        crate::limits::check_particles("RBPF-OGM n_particles", self.n_particles)?;
        self.motion.validate()?;
        self.trigger.validate()?;
        if !(0.0..=1.0).contains(&self.resample_threshold) {
            return Err(config_err(
                "resample_threshold",
                format!("must be in [0, 1], got {}", self.resample_threshold),
            ));
        }
        if !(self.weight_smoothing.is_finite() && self.weight_smoothing >= 0.0) {
            return Err(config_err(
                "weight_smoothing",
                "must be finite and >= 0 (0 disables it)",
            ));
        }
        GridGeometry::new(self.geometry.origin, self.geometry.resolution)?;
        if !(self.tile_size.is_power_of_two() && (4..=256).contains(&self.tile_size)) {
            return Err(config_err(
                "tile_size",
                format!("must be a power of two in 4..=256, got {}", self.tile_size),
            ));
        }
        self.log_odds.validate()?;
        if !(self.max_range > 0.0 && self.max_range >= self.log_odds.z_max) {
            return Err(config_err(
                "max_range",
                format!(
                    "must be >= the usable range log_odds.z_max = {}, got {}",
                    self.log_odds.z_max, self.max_range
                ),
            ));
        }
        self.matcher.validate()?;
        self.proposal.validate()?;
        if !self.motion_floor.iter().all(|v| v.is_finite() && *v > 0.0) {
            return Err(config_err("motion_floor", "must be finite and > 0"));
        }
        if !self.init_sigma.iter().all(|v| v.is_finite() && *v >= 0.0) {
            return Err(config_err("init_sigma", "must be finite and >= 0"));
        }
        Ok(())
    }
}
