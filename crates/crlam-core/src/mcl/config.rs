//! The localizer's settings ([`MclConfig`]) and their checks.

use crate::error::{config_err, Result};
use crate::mcl::baseline::Measurement;
use crate::mcl::kld::KldSettings;
use crate::mcl::likelihood::LikelihoodSettings;
use crate::motion::MotionModel;
use crate::rbpf::UpdateTrigger;

/// Settings of the localizer.
#[derive(Clone, Debug, PartialEq)]
pub struct MclConfig {
    /// The measurement model: the CRM likelihood (`likelihood`) or one of AMCL's (which read
    /// only z_min and z_max of `likelihood.model`).
    pub measurement: Measurement,
    pub likelihood: LikelihoodSettings,
    pub motion: MotionModel,
    pub trigger: UpdateTrigger,
    /// The trigger while the set is spread (its spread, as for the annealing of the hit term,
    /// above `spread_limit`): scans of nearly the same view are not independent evidence, and a
    /// spread set that weighs each of them as such collapses onto whichever place fits best by
    /// chance. AMCL processes every scan this way (update_min_d 0.25 m, update_min_a 0.2 rad).
    pub spread_trigger: UpdateTrigger,
    /// Spread (m) above which the set counts as spread.
    pub spread_limit: f64,
    pub kld: KldSettings,
    /// Rate of the long-term average of the fit (AMCL's `recovery_alpha_slow`); 0 with
    /// `alpha_fast` 0 turns recovery off.
    pub alpha_slow: f64,
    /// Rate of the short-term average (`recovery_alpha_fast`), above `alpha_slow`.
    pub alpha_fast: f64,
    /// Weight tempering τ: a scan multiplies the weights by exp(Σ log η / τ).
    pub tempering: f64,
    /// Annealing of the hit term: a scan is weighed with σ_hit = clamp(`anneal` · s, σ, `sigma_max`)
    /// where σ is the model's and s the spread of the weighted set at the last scan: of its
    /// heaviest cluster when that holds at least half the weight, else of the whole set (the RMS
    /// distance of the particles from their mean position plus 1 m times their circular heading
    /// spread in radians; a set split in several places has the spread of all). A few random
    /// particles of recovery that gain some weight do not widen it. Particles spread over metres
    /// (a global start) are weighed with a wide hit term, which a particle decimetres from the
    /// true pose still fits; once they gather, σ returns to the model's. `sigma_max` ≤ σ turns
    /// it off.
    pub sigma_max: f64,
    pub anneal: f64,
    /// Smallest share of the effective sample size a scan may leave while the set is spread (see
    /// `spread_limit`): when the weights at τ would bring N_eff below `min_neff` times its value
    /// before the scan (the particle count right after resampling), the scan is tempered more (τ
    /// raised until they do not). A gathered set keeps τ. 0 turns this off.
    pub min_neff: f64,
    /// Every n-th beam of a scan.
    pub beam_stride: usize,
    /// At most this many of those, spread evenly (0: all).
    pub max_beams: usize,
    /// Resample when N_eff < threshold · n (1: at every processed scan) or when recovery injects.
    pub resample_threshold: f64,
    /// Smallest particle count of a competing hypothesis: when, at a resampling, more than one
    /// cluster holds at least `keep_ratio` times the heaviest cluster's weight, each of those
    /// keeps at least `min_cluster` particles (extra draws from within it, as long as the set is
    /// below `n_max`) and the particles of every cluster share its weight (each gets the
    /// cluster's weight over its count), so the clusters' weights pass through the resampling
    /// unchanged. A hypothesis the scans have not yet ruled out is then neither lost to the
    /// random draw nor decided by it, and the second-heaviest cluster's weight stays a measure
    /// of the evidence against it (the convergence rule's odds). With one such cluster the
    /// resampling is AMCL's (equal weights), and so it is while recovery injects random
    /// particles (they come and go; a place they find competes once it holds on without them).
    /// 0 turns this off.
    pub min_cluster: usize,
    /// See `min_cluster`: the weight, relative to the heaviest cluster's, down to which a
    /// cluster counts as a competing hypothesis (in (0, 1]).
    pub keep_ratio: f64,
    /// Smallest particle count of a pose bin (the KLD histogram's boxes) while the set is spread
    /// (above `spread_limit`): at a resampling without random particles, every bin holding at
    /// least `keep_ratio` times the heaviest bin's weight first gets `min_bin` draws from within
    /// it (heaviest bins first, up to `n_max`), then KLD sampling draws the rest, and the
    /// particles of every bin share its weight, so the bins' weights pass through the
    /// resampling unchanged. While the set is spread a cluster is a whole corridor or room (its
    /// bins touch), and the `min_cluster` floor cannot keep a place inside it; this floor keeps
    /// the few particles near each place the scans have not yet ruled out. 0 turns this off.
    pub min_bin: usize,
    /// Size (m) of a place while the set is spread: when it is above 0 (and `min_cluster` is on,
    /// `min_bin` off), a resampling of a spread set without random particles keeps the
    /// `min_cluster` floor per place instead of per cluster. A place is a cell of `place_xy` ×
    /// `place_xy` metres and `place_theta` radians of the pose space (a fixed grid); every place
    /// holding at least `keep_ratio` times the heaviest place's weight first gets `min_cluster`
    /// draws from within it by weight (heaviest places first, up to `n_max`), then KLD sampling
    /// draws the rest, and the particles of every place share its weight, so the places' weights
    /// pass through the resampling unchanged. While the set is spread AMCL's clusters join whole
    /// rooms and corridors (their bins touch), so a floor per cluster cannot keep a place inside
    /// one; a place of bounded size keeps the best particles near each pose the scans have not
    /// yet ruled out. Once one cluster remains, the floor is per cluster again. 0: off.
    pub place_xy: f64,
    /// Heading extent (rad) of a place (see `place_xy`); sectors count from −π.
    pub place_theta: f64,
    /// Largest particle count while the set is spread (above `spread_limit`) and recovery does
    /// not inject: a global start draws this many, and KLD sampling may keep up to this many
    /// until the set gathers (then `kld.n_max` again). A set spread over a building asks KLD for
    /// far more than AMCL's 5,000 (one per occupied bin and more); with too few, a place has no
    /// particle near enough to its true pose to win. 0: `kld.n_max` throughout.
    pub spread_max: usize,
    /// The scan-matched proposal while the set is spread (above `spread_limit`): after its
    /// motion draw, each particle climbs to the nearby pose where the scan's endpoints fit the
    /// map best, and is weighed there ([`super::climb`]). The climb starts with steps of half
    /// a KLD bin (the spacing of a spread set) and halves them until the step along x and y is
    /// at most the map's cell. A gathered set moves by the motion model alone.
    pub spread_climb: bool,
    pub seed: u64,
}

impl MclConfig {
    pub fn validate(&self) -> Result<()> {
        self.likelihood.validate()?;
        self.measurement.validate()?;
        self.motion.validate()?;
        self.trigger.validate()?;
        self.spread_trigger.validate()?;
        if !(self.spread_limit.is_finite() && self.spread_limit >= 0.0) {
            return Err(config_err("spread_limit", "must be finite and >= 0"));
        }
        self.kld.validate()?;
        let unit = |v: f64| v.is_finite() && (0.0..=1.0).contains(&v);
        if !(unit(self.alpha_slow) && unit(self.alpha_fast)) {
            return Err(config_err(
                "recovery_alpha",
                "alpha_slow and alpha_fast must be in [0, 1]",
            ));
        }
        if self.alpha_slow > 0.0 && self.alpha_fast <= self.alpha_slow {
            return Err(config_err(
                "recovery_alpha",
                format!(
                    "alpha_fast ({}) must exceed alpha_slow ({})",
                    self.alpha_fast, self.alpha_slow
                ),
            ));
        }
        if !(self.tempering.is_finite() && self.tempering > 0.0) {
            return Err(config_err(
                "tempering",
                format!("must be > 0, got {}", self.tempering),
            ));
        }
        if self.beam_stride == 0 {
            return Err(config_err("beam_stride", "must be >= 1"));
        }
        if !(self.sigma_max.is_finite()
            && self.sigma_max >= 0.0
            && self.anneal.is_finite()
            && self.anneal >= 0.0)
        {
            return Err(config_err(
                "sigma_max",
                "sigma_max and anneal must be finite and >= 0",
            ));
        }
        if !(self.min_neff.is_finite() && (0.0..1.0).contains(&self.min_neff)) {
            return Err(config_err(
                "min_neff",
                format!("must be in [0, 1), got {}", self.min_neff),
            ));
        }
        if !unit(self.resample_threshold) {
            return Err(config_err("resample_threshold", "must be in [0, 1]"));
        }
        if self.spread_max > 10_000_000 {
            return Err(config_err(
                "spread_max",
                format!("must be at most 10,000,000, got {}", self.spread_max),
            ));
        }
        if !(self.place_xy.is_finite() && self.place_xy >= 0.0) {
            return Err(config_err(
                "place_xy",
                format!("must be finite and >= 0 (0: off), got {}", self.place_xy),
            ));
        }
        if self.place_xy > 0.0 && !(self.place_theta.is_finite() && self.place_theta > 0.0) {
            return Err(config_err(
                "place_theta",
                format!("must be finite and > 0, got {}", self.place_theta),
            ));
        }
        if !(self.keep_ratio.is_finite() && self.keep_ratio > 0.0 && self.keep_ratio <= 1.0) {
            return Err(config_err(
                "keep_ratio",
                format!("must be in (0, 1], got {}", self.keep_ratio),
            ));
        }
        Ok(())
    }

    /// True when recovery can inject particles.
    pub fn recovery(&self) -> bool {
        self.alpha_slow > 0.0
    }
}
