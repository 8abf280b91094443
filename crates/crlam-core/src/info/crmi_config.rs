//! Settings of CRMI ([`super::crmi::Crmi`]): the sensor model, beams, range bins and their
//! quadrature, the rule for cells crossed by several beams, and the hit support cut. The
//! channel ([`super::crmi_channel`]) and the pose evaluation ([`super::crmi`]) read them.

use crate::error::{config_err, Result};
use crate::info::lattice::BeamAngles;
use crate::info::InfoUnits;
use crate::sensor::{SensorModel, SensorModelKind};

/// The hit Gaussian is cut at ± this many σ (tail mass 2e-9) and renormalised over its support.
pub const SUPPORT_SIGMAS: f64 = 6.0;

/// How bin masses are computed from the sensor densities.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CrmiQuadrature {
    /// Exact CDF differences (default; crm-spec 5.2).
    Cdf,
    /// Density at the bin centre × bin width, P(q) renormalised, I clipped at 0 (parity with a
    /// midpoint rule; mis-normalised for σ ≲ λ_z/2, crm-spec 5.2).
    Midpoint,
}

impl CrmiQuadrature {
    /// Parses `"cdf" | "midpoint"`.
    pub fn parse(name: &str) -> Result<Self> {
        match name {
            "cdf" | "exact" => Ok(Self::Cdf),
            "midpoint" => Ok(Self::Midpoint),
            other => Err(config_err(
                "crmi_quadrature",
                format!("unknown quadrature {other:?}; expected cdf or midpoint"),
            )),
        }
    }

    pub fn name(&self) -> &'static str {
        match self {
            Self::Cdf => "cdf",
            Self::Midpoint => "midpoint",
        }
    }
}

/// How a cell crossed by several beams of one candidate counts (crm-spec 5.2).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CellDedupe {
    /// Once per beam (R3's Eq. 3; default).
    Sum,
    /// The largest per-beam value only (ablation).
    Max,
}

impl CellDedupe {
    /// Parses `"sum" | "max"`.
    pub fn parse(name: &str) -> Result<Self> {
        match name {
            "sum" => Ok(Self::Sum),
            "max" => Ok(Self::Max),
            other => Err(config_err(
                "dedupe_cells",
                format!("unknown rule {other:?}; expected sum or max"),
            )),
        }
    }

    pub fn name(&self) -> &'static str {
        match self {
            Self::Sum => "sum",
            Self::Max => "max",
        }
    }
}

/// Settings of CRMI at a candidate pose.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CrmiConfig {
    /// The model that updates the map (`ijrr` or `mixture`); its z_max is the beam length.
    pub model: SensorModel,
    /// Beams per candidate (n_z = 10 in the paper).
    pub n_beams: usize,
    pub beam_angles: BeamAngles,
    /// Range bin width λ_z (m).
    pub lambda_z: f64,
    pub quadrature: CrmiQuadrature,
    pub dedupe: CellDedupe,
    pub units: InfoUnits,
    /// The virtual scan of the map mutation hits the first cell whose mean exceeds this.
    pub hit_threshold: f64,
}

impl CrmiConfig {
    /// The spec's defaults (ijrr, 10 distinct beams, λ_z = 0.1 m, CDF bins, bits) for a grid of
    /// resolution `resolution` (m) and a sensor range `z_max` (m).
    pub fn new(z_max: f64, resolution: f64) -> Self {
        Self {
            model: SensorModel::with_defaults(SensorModelKind::Ijrr, z_max, resolution),
            n_beams: 10,
            beam_angles: BeamAngles::Distinct,
            lambda_z: 0.1,
            quadrature: CrmiQuadrature::Cdf,
            dedupe: CellDedupe::Sum,
            units: InfoUnits::Bits,
            hit_threshold: 0.5,
        }
    }

    pub fn validate(&self) -> Result<()> {
        self.model.validate()?;
        if self.model.kind == SensorModelKind::AuthorsCode {
            return Err(config_err(
                "model",
                "CRMI needs a proper channel: use ijrr or mixture (authors_code is not normalised)",
            ));
        }
        if self.n_beams == 0 || self.n_beams > 100_000 {
            return Err(config_err(
                "n_beams",
                format!("must be in [1, 100000], got {}", self.n_beams),
            ));
        }
        let bins = self.model.z_max / self.lambda_z;
        if !(self.lambda_z.is_finite() && self.lambda_z > 0.0 && bins <= 1e6) {
            return Err(config_err(
                "lambda_z",
                format!(
                    "must be > 0 with at most 1e6 bins up to z_max, got {}",
                    self.lambda_z
                ),
            ));
        }
        if !(self.hit_threshold > 0.0 && self.hit_threshold < 1.0) {
            return Err(config_err(
                "hit_threshold",
                format!("must be in (0, 1), got {}", self.hit_threshold),
            ));
        }
        Ok(())
    }

    /// Number of range bins Q (the atom is bin Q).
    pub fn n_bins(&self) -> usize {
        (self.model.z_max / self.lambda_z - 1e-9).ceil().max(1.0) as usize
    }
}
