//! Parameters of the GMapping-style scan matcher ([`super::scanmatch::ScanMatcher`]) and of the
//! improved proposal built on it, with their defaults and validation.

use super::common::ProposalPose;
use crate::error::{config_err, Result};

/// Largest lattice half-width (in steps) of the proposal: (2·3+1)³ = 343 poses per particle.
const MAX_HALF_STEPS: usize = 3;

/// When a companion cell counts as free (see the module documentation).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FreeTest {
    /// Seen free: log-odds < 0. Unknown cells are not free.
    Observed,
    /// Not occupied: log-odds <= 0, unknown cells included (GMapping).
    NotOccupied,
}

impl FreeTest {
    pub fn parse(s: &str) -> Result<Self> {
        match s {
            "observed" => Ok(Self::Observed),
            "not_occupied" => Ok(Self::NotOccupied),
            _ => Err(config_err(
                "matcher.free_test",
                format!("must be 'observed' or 'not_occupied', got {s:?}"),
            )),
        }
    }
}

/// Parameters of the scan matcher (GMapping names in brackets).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MatcherParams {
    /// \[sigma\] Score kernel, m²: score per beam exp(−d²/score_sigma). 0.05.
    pub score_sigma: f64,
    /// \[lsigma\] Likelihood kernel, m²: log-lik per beam −d²/likelihood_sigma. 0.075.
    pub likelihood_sigma: f64,
    /// \[nullLikelihood\] Log-lik numerator of an unmatched beam (< 0). −0.5.
    pub null_likelihood: f64,
    /// \[kernelSize\] Half-width k of the search window in cells. 1.
    pub kernel_size: usize,
    /// \[lstep\] Initial translational step of the hill climbing (m). 0.05.
    pub lstep: f64,
    /// \[astep\] Initial rotational step (rad). 0.05.
    pub astep: f64,
    /// \[iterations\] Number of step halvings before the search stops. 5.
    pub iterations: usize,
    /// \[lskip + 1\] Use every `beam_stride`-th beam for score and likelihood. 1.
    pub beam_stride: usize,
    /// When the companion cell of a match counts as free. [`FreeTest::Observed`].
    pub free_test: FreeTest,
}

impl Default for MatcherParams {
    fn default() -> Self {
        Self {
            score_sigma: 0.05,
            likelihood_sigma: 0.075,
            null_likelihood: -0.5,
            kernel_size: 1,
            lstep: 0.05,
            astep: 0.05,
            iterations: 5,
            beam_stride: 1,
            free_test: FreeTest::Observed,
        }
    }
}

pub(super) fn positive(v: f64) -> bool {
    v.is_finite() && v > 0.0
}

impl MatcherParams {
    pub fn validate(&self) -> Result<()> {
        if !positive(self.score_sigma) {
            return Err(config_err("matcher.score_sigma", "must be finite and > 0"));
        }
        if !positive(self.likelihood_sigma) {
            return Err(config_err(
                "matcher.likelihood_sigma",
                "must be finite and > 0",
            ));
        }
        if !(self.null_likelihood.is_finite() && self.null_likelihood < 0.0) {
            return Err(config_err(
                "matcher.null_likelihood",
                "must be finite and < 0",
            ));
        }
        if self.kernel_size > 5 {
            return Err(config_err(
                "matcher.kernel_size",
                format!("at most 5 cells, got {}", self.kernel_size),
            ));
        }
        if !(positive(self.lstep) && positive(self.astep)) {
            return Err(config_err(
                "matcher.lstep/astep",
                "steps must be finite and > 0",
            ));
        }
        if self.iterations > 30 {
            return Err(config_err("matcher.iterations", "at most 30 halvings"));
        }
        if self.beam_stride == 0 {
            return Err(config_err("matcher.beam_stride", "must be >= 1"));
        }
        Ok(())
    }
}

/// Parameters of the improved proposal: the likelihood × motion prior is evaluated on a lattice
/// of (2h+1)³ poses centred on the match, spanning ±`range` (world x, y, and heading).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProposalParams {
    /// \[minimumScore\] A match is accepted when its score exceeds this. 0 (GMapping's default):
    /// at least one beam must match.
    pub min_score: f64,
    /// Half-width h of the lattice in steps (1..=3); K = (2h+1)³ poses. 1 (K = 27, as GMapping).
    pub half_steps: usize,
    /// Half-extent of the lattice (m, m, rad). (0.05, 0.05, 0.025): one cell of 5 cm and half
    /// the angular step, wider than GMapping's 5 cm defaults (±0.01 m, ±0.005 rad), whose
    /// lattice is much narrower than the likelihood and so yields near-zero covariances.
    pub range: [f64; 3],
    /// Standard deviations (m, m, rad) added in quadrature to the fitted covariance, so that it
    /// stays positive definite when the likelihood is sharper than the lattice spacing.
    pub regularization: [f64; 3],
    /// Draw the new pose from the fitted Gaussian (default) or keep the match (GMapping's code).
    pub pose: ProposalPose,
}

impl Default for ProposalParams {
    fn default() -> Self {
        Self {
            min_score: 0.0,
            half_steps: 1,
            range: [0.05, 0.05, 0.025],
            regularization: [0.005, 0.005, 0.0025],
            pose: ProposalPose::Sample,
        }
    }
}

impl ProposalParams {
    pub fn validate(&self) -> Result<()> {
        if !self.min_score.is_finite() {
            return Err(config_err("proposal.min_score", "must be finite"));
        }
        if !(1..=MAX_HALF_STEPS).contains(&self.half_steps) {
            return Err(config_err(
                "proposal.half_steps",
                format!("must be in 1..={MAX_HALF_STEPS}, got {}", self.half_steps),
            ));
        }
        if !self.range.iter().all(|&v| positive(v)) {
            return Err(config_err("proposal.range", "must be finite and > 0"));
        }
        if !self.regularization.iter().all(|&v| positive(v)) {
            return Err(config_err(
                "proposal.regularization",
                "must be finite and > 0",
            ));
        }
        Ok(())
    }
}
