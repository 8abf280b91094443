//! Settings of RBPF-CLAM ([`super::clam::RbpfClam`]): the filter's [`ClamConfig`], its proposal
//! ([`ClamProposal`]) with the scan-match proposal's [`ScanMatchSettings`], and the scan options
//! they give the map updates. The filter ([`super::clam`]) and both proposals
//! ([`super::proposal`], [`super::clam_match`]) read them.

use crate::crm::{BatchKernel, CrmConfig, ScanOptions, ScanUpdateMode};
use crate::error::{config_err, Result};
use crate::motion::MotionModel;
use crate::rbpf::common::{ProposalPose, UpdateTrigger};
use crate::rbpf::correlative::CorrelativeSettings;
use crate::rbpf::prepared_scan::{BeamSelection, MAX_USABLE_RANGE};
use crate::rbpf::scanmatch_params::{MatcherParams, ProposalParams};
use crate::sensor::SensorModel;

/// How particles are moved before weighting.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ClamProposal {
    /// The paper's proposal: sample the odometry motion model.
    Odometry,
    /// The CRM analogue of GMapping's improved proposal: hill-climb the predictive scan
    /// log-likelihood × motion density from the odometry guess, evaluate it on a 3×3×3 lattice
    /// around the mode, fit a Gaussian there and sample from it; the weight increment is the log
    /// of the lattice normaliser. With `pose: Match` the climb starts from a motion-model sample
    /// and its mode is the new pose (GMapping's released code), with the same weight.
    LikelihoodMode {
        /// Initial hill-climbing steps (m, m, rad), halved `iterations` times.
        step: [f64; 3],
        iterations: usize,
        /// Beam stride used while matching (the final weight uses `weight_stride`).
        match_stride: usize,
        /// Spacing (m, m, rad) of the 3×3×3 lattice around the mode that the Gaussian is fitted
        /// to and whose sum is the weight. Half the initial step by default; a lattice much wider
        /// than the likelihood's peak sees only the mode, so the fit degenerates to the mode plus
        /// the floor (a tenth of the spacing) and the weight to the peak height.
        lattice: [f64; 3],
        /// Draw from the fitted Gaussian (default) or keep the climb's mode.
        pose: ProposalPose,
        /// Probability ε that the odometry increment is an outlier. The climb and the lattice
        /// then use the robust motion density (1 − ε)·p(x | x', u) + ε·u₀, with u₀ = 1 per
        /// m²·rad (a uniform over a 1 m × 1 m × 1 rad box): within a few σ of the odometry
        /// guess it is the motion model, farther away a floor of log ε, so a scan whose
        /// likelihood gains more than that may move the pose as far as the climb reaches (a loop
        /// closure), however tight the motion model. 0 (default): the motion model alone.
        motion_outlier: f64,
    },
    /// GMapping's improved proposal on the CRM: hill-climb and sample the scan's endpoint match
    /// against the particle map's expected occupancy, weigh once by the CRM predictive
    /// likelihood (see [`crate::rbpf::clam_match`]). Tens of times cheaper than `LikelihoodMode`.
    ScanMatch(ScanMatchSettings),
}

impl ClamProposal {
    /// Defaults of the improved proposal: 0.1 m / 0.05 rad steps, 4 halvings, every 3rd beam,
    /// a lattice at half the step (0.05 m / 0.025 rad), a draw from the fitted Gaussian.
    pub fn likelihood_mode() -> Self {
        Self::likelihood_mode_with(ProposalPose::Sample)
    }

    /// The improved proposal with the defaults above and the given pose rule.
    pub fn likelihood_mode_with(pose: ProposalPose) -> Self {
        Self::LikelihoodMode {
            step: [0.1, 0.1, 0.05],
            iterations: 4,
            match_stride: 3,
            lattice: [0.05, 0.05, 0.025],
            pose,
            motion_outlier: 0.0,
        }
    }
}

/// Settings of RBPF-CLAM (crm-spec 9).
#[derive(Clone, Debug, PartialEq)]
pub struct ClamConfig {
    pub n_particles: usize,
    pub motion: MotionModel,
    pub trigger: UpdateTrigger,
    pub crm: CrmConfig,
    pub mapping_model: SensorModel,
    pub weight_model: SensorModel,
    pub scan_update: ScanUpdateMode,
    /// How batch scans compute each beam (the results agree to rounding).
    pub batch_kernel: BatchKernel,
    /// Batch map updates keep the scan's hits first: a cell a beam makes more occupied drops the
    /// scan's factors that make it less occupied ([`crate::crm::ScanOptions::hits_first`];
    /// the paper: false).
    pub hits_first: bool,
    /// Beams used for the weights (every n-th; the paper: 1).
    pub weight_stride: usize,
    /// Beams used for the map update (every n-th; the paper: 1).
    pub map_stride: usize,
    /// Weight tempering τ_T: Δ log w = Σ log η / τ_T (the paper: 1). With the likelihood-mode
    /// proposal it divides the log of the lattice normaliser; the proposal itself always targets
    /// the untempered likelihood × motion density.
    pub tempering: f64,
    /// Beam count b at which `tempering` applies as given: a scan whose weight uses n beams is
    /// tempered by τ_T·n/b, so every scan carries the same weight spread whatever the laser's
    /// beam count (a 720-beam scan has about four times the log-likelihood range of a 180-beam
    /// one). `None` (the paper): τ_T for every scan.
    pub tempering_beams: Option<f64>,
    pub resample_threshold: f64,
    /// Standard deviations (m, m, rad) of the initial particle cloud around the first pose.
    pub init_sigma: [f64; 3],
    pub proposal: ClamProposal,
    pub seed: u64,
    /// Update a particle's map only once resampling has kept it (every particle when there is no
    /// resampling). Exact: the weights use the pre-update maps and the updates do not depend on
    /// the weights, so the results are the same bit for bit; with peaked weights most particles
    /// are dropped and their updates are saved, and weighing alone runs sixteen beams at a time in
    /// lanes.
    /// On by default; off, the odometry proposal fuses weight and update into one walk of each
    /// beam (the reference the tests compare with).
    pub defer_map_updates: bool,
}

impl ClamConfig {
    /// The paper's settings on a grid: 100 particles, Gaussian odometry noise 0.01, every scan,
    /// every beam, no tempering, `ijrr` mapping and `mixture` weights.
    pub fn paper(crm: CrmConfig, z_max: f64) -> Self {
        let res = crm.geometry.resolution;
        Self {
            n_particles: 100,
            motion: MotionModel::paper(),
            trigger: UpdateTrigger::every_scan(),
            mapping_model: SensorModel::with_defaults(
                crate::sensor::SensorModelKind::Ijrr,
                z_max,
                res,
            ),
            weight_model: SensorModel::with_defaults(
                crate::sensor::SensorModelKind::Mixture,
                z_max,
                res,
            ),
            crm,
            scan_update: ScanUpdateMode::Batch,
            batch_kernel: BatchKernel::Windowed,
            hits_first: false,
            weight_stride: 1,
            map_stride: 1,
            tempering: 1.0,
            tempering_beams: None,
            resample_threshold: 0.5,
            init_sigma: [0.0; 3],
            proposal: ClamProposal::Odometry,
            seed: 0,
            defer_map_updates: true,
        }
    }

    /// The tempering of a scan of `n_beams` beams (see [`Self::tempering_beams`]).
    pub fn tempering_for(&self, n_beams: usize) -> f64 {
        match self.tempering_beams {
            None => self.tempering,
            Some(b) => {
                let weighed = n_beams.div_ceil(self.weight_stride).max(1);
                self.tempering * weighed as f64 / b
            }
        }
    }

    pub fn validate(&self) -> Result<()> {
        if self.n_particles == 0 {
            return Err(config_err("n_particles", "must be >= 1"));
        }
        crate::limits::check_particles("RBPF-CLAM n_particles", self.n_particles)?;
        if self.weight_stride == 0 || self.map_stride == 0 {
            return Err(config_err("beam_stride", "must be >= 1"));
        }
        if !(self.tempering.is_finite() && self.tempering > 0.0) {
            return Err(config_err(
                "tempering",
                format!("must be finite and > 0, got {}", self.tempering),
            ));
        }
        if let Some(b) = self.tempering_beams {
            if !(b.is_finite() && b >= 1.0) {
                return Err(config_err(
                    "tempering_beams",
                    format!("must be finite and >= 1, got {b}"),
                ));
            }
        }
        if !(0.0..=1.0).contains(&self.resample_threshold) {
            return Err(config_err("resample_threshold", "must be in [0, 1]"));
        }
        if self
            .init_sigma
            .iter()
            .any(|s| !(s.is_finite() && *s >= 0.0))
        {
            return Err(config_err("init_sigma", "must be finite and >= 0"));
        }
        if let ClamProposal::LikelihoodMode {
            step,
            match_stride,
            lattice,
            motion_outlier,
            ..
        } = self.proposal
        {
            let positive = |v: &[f64; 3]| v.iter().all(|s| s.is_finite() && *s > 0.0);
            if match_stride == 0 || !positive(&step) || !positive(&lattice) {
                return Err(config_err(
                    "proposal",
                    "steps and lattice spacings must be finite and > 0, the match stride >= 1",
                ));
            }
            if !(0.0..1.0).contains(&motion_outlier) {
                return Err(config_err(
                    "motion_outlier",
                    format!("must be in [0, 1), got {motion_outlier}"),
                ));
            }
        }
        if let ClamProposal::ScanMatch(settings) = &self.proposal {
            settings.validate()?;
        }
        self.motion.validate()?;
        self.trigger.validate()?;
        self.mapping_model.validate()?;
        self.weight_model.validate()?;
        Ok(())
    }
}

/// The measurement model of the scan-match proposal's weights.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum ScanMatchWeight {
    /// The paper's: the CRM predictive likelihood of the scan, as the importance weight of the
    /// drawn pose (see the module documentation).
    #[default]
    Crm,
    /// GMapping's: the log of the lattice normaliser of the endpoint likelihood × motion
    /// density (Grisetti et al. 2007, Eq. 12), the same model the proposal was fitted to, so the
    /// weight does not depend on the draw. The CRM is then the map, not the weight's model.
    Endpoint,
}

impl ScanMatchWeight {
    pub fn parse(s: &str) -> Result<Self> {
        match s {
            "crm" => Ok(Self::Crm),
            "endpoint" => Ok(Self::Endpoint),
            _ => Err(crate::error::config_err(
                "scan_match_weight",
                format!("must be 'crm' or 'endpoint', got {s:?}"),
            )),
        }
    }
}

/// What the scan-match proposal's hill climb maximises before the lattice is laid around its end.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum MatchClimb {
    /// GMapping's: the endpoint score alone (Σ exp(−d²/σ) over the beams). Where the scan does not
    /// fix the pose (along a corridor, a hall's walls beyond the map's range) the climb follows
    /// whatever the score's small features say, however far from the odometry's guess, and every
    /// particle that climbs from the same guess slides with it.
    #[default]
    Score,
    /// The function the lattice evaluates: GMapping's endpoint log-likelihood plus the log of the
    /// motion density. Where the scan fixes the pose it is the scan's peak (the likelihood is
    /// far sharper than the motion model); along the directions it leaves free the motion
    /// density decides and the climb stays at the odometry's guess. The lattice and the Gaussian
    /// drawn from are then centred on the mode of the proposal's own target.
    Posterior,
}

impl MatchClimb {
    pub fn parse(s: &str) -> Result<Self> {
        match s {
            "score" => Ok(Self::Score),
            "posterior" => Ok(Self::Posterior),
            _ => Err(crate::error::config_err(
                "match_climb",
                format!("must be 'score' or 'posterior', got {s:?}"),
            )),
        }
    }
}

/// What the scan-match proposal does where the scan leaves a direction free
/// ([`crate::rbpf::degeneracy`]: a featureless corridor's axis).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Degeneracy {
    /// Nothing: the climb and the weight read the scan in every direction (the paper's and
    /// GMapping's).
    #[default]
    Off,
    /// Solution remapping (Zhang, Kaess and Singh 2016): along the free direction the match (and
    /// the correlative front end's correction) keeps the odometry's prediction, and the
    /// importance weight reads the scan at the drawn pose moved back along it to the
    /// prediction, so that the map's unevenness along the direction ranks no particle. Scans
    /// that constrain every direction are matched and weighed as with `Off`.
    Remap,
}

impl Degeneracy {
    pub fn parse(s: &str) -> Result<Self> {
        match s {
            "off" => Ok(Self::Off),
            "remap" => Ok(Self::Remap),
            _ => Err(crate::error::config_err(
                "degeneracy",
                format!("must be 'off' or 'remap', got {s:?}"),
            )),
        }
    }
}

/// A reading within this distance (m) of the largest reading of the log so far is a no-return
/// (see [`MatchRange::Full`]). A laser that sees nothing reports one fixed reading, its maximum
/// (Intel: 81.83 m, ACES: 50.00 m, both logged to the centimetre), the largest of the log; 5 cm
/// absorbs the rounding of the logged value. Until the log's first no-return, the readings
/// within 5 cm of the farthest return so far are left out instead: a few beams, and only beyond
/// z_max.
pub const NO_RETURN_TOLERANCE: f64 = 0.05;

/// Which readings the scan-match proposal's endpoint matcher uses. The map update and the CRM
/// likelihood use the readings below z_max whatever this says: memory and the map update's cost
/// do not change.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub enum MatchRange {
    /// The paper's range: readings below z_max (the smaller of the mapping and weight models').
    #[default]
    ZMax,
    /// Every reading that returned, at its measured range. Below z_max, every reading (as
    /// `ZMax`); beyond it, every finite reading except the no-returns: readings within
    /// [`NO_RETURN_TOLERANCE`] of the largest reading the filter has been given so far. (Readings
    /// at or above a scan's stated maximum range are given as `inf` by the readers and never
    /// used.) The far endpoints land on cells mapped earlier from closer by (a corridor's end on a
    /// revisit, which tells a periodic corridor's positions apart) or on unknown cells, which
    /// match nothing, as in GMapping. The weight scores them too, with the endpoint likelihood
    /// (the CRM's is for the readings below z_max, where the map is): the target then holds the
    /// evidence the proposal was fitted to, and a particle whose far endpoints fall on the mapped
    /// end of a corridor outweighs one a door period off, which the CRM within 8 m cannot tell
    /// apart.
    Full,
    /// As `Full`, up to this range (m): readings below it.
    Metres(f64),
}

impl MatchRange {
    /// Parses `"z_max"` or `"full"` (a range in metres is [`MatchRange::Metres`]).
    pub fn parse(s: &str) -> Result<Self> {
        match s {
            "z_max" => Ok(Self::ZMax),
            "full" => Ok(Self::Full),
            _ => Err(config_err(
                "match_range",
                format!("must be 'z_max', 'full' or a range in metres, got {s:?}"),
            )),
        }
    }

    pub fn validate(&self) -> Result<()> {
        if let Self::Metres(m) = *self {
            if !(m.is_finite() && m > 0.0 && m <= MAX_USABLE_RANGE) {
                return Err(config_err(
                    "match_range",
                    format!("a range must be in (0, {MAX_USABLE_RANGE}] m, got {m}"),
                ));
            }
        }
        Ok(())
    }

    /// The readings the matcher uses when the maps are written below `z_max` and the largest
    /// finite reading given to the filter so far is `largest` (−∞ before any).
    pub fn selection(&self, z_max: f64, largest: f64) -> BeamSelection {
        let no_return_from = if largest.is_finite() {
            largest - NO_RETURN_TOLERANCE
        } else {
            f64::INFINITY
        };
        let (near, far) = match *self {
            Self::ZMax => return BeamSelection::below(z_max),
            Self::Full => (z_max, MAX_USABLE_RANGE.max(z_max)),
            Self::Metres(m) => (z_max.min(m), m),
        };
        BeamSelection {
            near,
            far,
            no_return_from,
        }
    }
}

/// Settings of the scan-match proposal.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScanMatchSettings {
    /// The endpoint matcher (GMapping's score and likelihood kernels, window, steps).
    pub matcher: MatcherParams,
    /// The lattice around the match, the acceptance score and the pose rule.
    pub lattice: ProposalParams,
    /// Expected occupancy above which the matcher reads a cell as occupied (0.5: the uniform
    /// prior's mean, so "more evidence of a wall than of free space").
    pub occupied_above: f64,
    /// The weights' measurement model.
    pub weight: ScanMatchWeight,
    /// The readings the endpoint matcher uses.
    pub match_range: MatchRange,
    /// Whether each particle keeps the mean of the hits of every cell ([`HitMeans`]) and the
    /// matcher measures a beam's distance to that mean instead of the cell's centre (GMapping's
    /// matcher).
    ///
    /// [`HitMeans`]: crate::rbpf::HitMeans
    pub hit_means: bool,
    /// A correlative search over a wide window around the odometry's guess on the best
    /// particle's map, before the particles' proposals (see [`crate::rbpf::correlative`]): a
    /// confident match replaces the odometry increment every particle starts from. `None`: the
    /// odometry increment as given (the paper's and GMapping's).
    pub front_end: Option<CorrelativeSettings>,
    /// What the hill climb maximises (GMapping's score by default).
    pub climb: MatchClimb,
    /// What the proposal and the weight do along a direction the scan leaves free.
    pub degeneracy: Degeneracy,
}

impl Default for ScanMatchSettings {
    fn default() -> Self {
        Self {
            matcher: MatcherParams::default(),
            lattice: ProposalParams::default(),
            occupied_above: 0.5,
            weight: ScanMatchWeight::Crm,
            match_range: MatchRange::ZMax,
            hit_means: false,
            front_end: None,
            climb: MatchClimb::Score,
            degeneracy: Degeneracy::Off,
        }
    }
}

impl ScanMatchSettings {
    pub fn validate(&self) -> Result<()> {
        self.matcher.validate()?;
        self.lattice.validate()?;
        self.match_range.validate()?;
        if let Some(front_end) = &self.front_end {
            front_end.validate()?;
        }
        if !(self.occupied_above.is_finite() && (0.0..1.0).contains(&self.occupied_above)) {
            return Err(crate::error::config_err(
                "occupied_above",
                format!("must be in [0, 1), got {}", self.occupied_above),
            ));
        }
        Ok(())
    }
}

/// The map-update options of a scan under `cfg`, every `stride`-th beam.
pub(crate) fn scan_opts(cfg: &ClamConfig, stride: usize) -> ScanOptions {
    ScanOptions {
        mode: cfg.scan_update,
        kernel: cfg.batch_kernel,
        beam_stride: stride,
        hits_first: cfg.hits_first,
        ..ScanOptions::default()
    }
}
