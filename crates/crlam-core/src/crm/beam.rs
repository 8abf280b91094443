//! How a reading becomes a ray to traverse, and per-scan options and counters.

use crate::error::{config_err, CrlamError, Result};
use crate::sensor::{SensorModel, SensorModelKind};

/// How the beams of one scan update the map (crm-spec 3.3).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ScanUpdateMode {
    /// Every beam's coefficients from the pre-scan beliefs; factors multiplied per cell and
    /// normalised once (default).
    Batch,
    /// Beam after beam, each seeing the beliefs left by the previous ones (R1/R4 parity).
    Sequential,
}

impl ScanUpdateMode {
    /// Parses `"batch" | "sequential"`.
    pub fn parse(name: &str) -> Result<Self> {
        match name {
            "batch" => Ok(Self::Batch),
            "sequential" => Ok(Self::Sequential),
            other => Err(config_err(
                "scan_update",
                format!("unknown mode {other:?}; expected batch or sequential"),
            )),
        }
    }

    /// Canonical name.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Batch => "batch",
            Self::Sequential => "sequential",
        }
    }
}

/// How a batch scan computes each beam (the results agree to rounding).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BatchKernel {
    /// Likelihoods and factors only within a window around the reading; the cells before it
    /// are counted as passes, with a per-beam bound that falls back to the full sweep when the
    /// window could change η beyond 2^-60 (`crm::windowed`; `ijrr` mapping with midpoint causes,
    /// `mixture` weights). The default.
    Windowed,
    /// Every cell of every ray: its likelihood, the backward sweep and its factor (the
    /// reference the windowed kernel is tested against; every model).
    FullRay,
}

impl BatchKernel {
    /// Parses `"windowed" | "full_ray"`.
    pub fn parse(name: &str) -> Result<Self> {
        match name {
            "windowed" => Ok(Self::Windowed),
            "full_ray" => Ok(Self::FullRay),
            other => Err(config_err(
                "batch_kernel",
                format!("unknown kernel {other:?}; expected windowed or full_ray"),
            )),
        }
    }

    /// Canonical name.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Windowed => "windowed",
            Self::FullRay => "full_ray",
        }
    }
}

/// Options of a scan update or scan likelihood.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScanOptions {
    pub mode: ScanUpdateMode,
    /// Batch mode only: how each beam is computed.
    pub kernel: BatchKernel,
    /// Use every `beam_stride`-th beam (1 = all).
    pub beam_stride: usize,
    /// Treat a range of exactly 0 as a no-return (some drivers); otherwise it is dropped.
    pub zero_is_no_return: bool,
    /// Batch mode only: a cell that a beam of the scan makes more occupied ignores the scan's
    /// passes (the factors of beams whose readings lie far beyond it). Not the paper's update
    /// (crm-spec 3.3 multiplies every factor); off by default.
    pub hits_first: bool,
}

impl Default for ScanOptions {
    fn default() -> Self {
        Self {
            mode: ScanUpdateMode::Batch,
            kernel: BatchKernel::Windowed,
            beam_stride: 1,
            zero_is_no_return: false,
            hits_first: false,
        }
    }
}

/// Counters of one scan update (or of a sequence, when added up).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ScanStats {
    /// Beams considered (after the stride).
    pub n_beams: usize,
    /// Beams that updated the map.
    pub n_used: usize,
    /// Of the used beams, how many were no-returns.
    pub n_no_return: usize,
    /// Beams dropped: below z_min, negative, or 0 when 0 is not a no-return.
    pub n_dropped_short: usize,
    /// Beams skipped because no cause explains the reading (η = 0, crm-spec 3.6).
    pub n_skipped_eta: usize,
    /// Beams whose ray has no cell inside the map.
    pub n_empty_ray: usize,
    /// Cell updates applied (a cell crossed by b beams counts b times).
    pub n_cell_updates: usize,
    /// Cell updates skipped because every factor clipped to 0.
    pub n_frozen: usize,
}

impl ScanStats {
    /// Adds another set of counters.
    pub fn add(&mut self, o: &ScanStats) {
        self.n_beams += o.n_beams;
        self.n_used += o.n_used;
        self.n_no_return += o.n_no_return;
        self.n_dropped_short += o.n_dropped_short;
        self.n_skipped_eta += o.n_skipped_eta;
        self.n_empty_ray += o.n_empty_ray;
        self.n_cell_updates += o.n_cell_updates;
        self.n_frozen += o.n_frozen;
    }
}

/// A reading turned into a ray: where to start, how far to go, and the reading to explain.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BeamPlan {
    pub origin: [f64; 2],
    /// World-frame direction (rad).
    pub angle: f64,
    /// Reading (m); equals z_max for no-returns.
    pub z: f64,
    pub no_return: bool,
    /// Ray length to traverse (m).
    pub length: f64,
}

/// Why a reading was not turned into a ray.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BeamDrop {
    TooShort,
}

/// Plans the ray of one reading (crm-spec 2.1). NaN/inf or ≥ z_max are no-returns; below z_min
/// (or ≤ 0, unless 0 means no-return) the reading is dropped. `resolution` sets the `ijrr`
/// truncation z + 6σ + Δ beyond which cells carry no information.
pub fn plan_beam(
    model: &SensorModel,
    opts: &ScanOptions,
    resolution: f64,
    origin: [f64; 2],
    angle: f64,
    range: f64,
) -> std::result::Result<BeamPlan, BeamDrop> {
    let no_return = model.is_no_return(range) || (opts.zero_is_no_return && range == 0.0);
    if !no_return && (range <= 0.0 || range < model.z_min) {
        return Err(BeamDrop::TooShort);
    }
    let z = if no_return { model.z_max } else { range };
    let length = if no_return {
        model.z_max
    } else {
        match model.kind {
            SensorModelKind::Ijrr => (z + 6.0 * model.sigma_hit + resolution).min(model.z_max),
            // The authors' code ends the ray at the cell of the reading.
            SensorModelKind::AuthorsCode => z,
            SensorModelKind::Mixture => model.z_max,
        }
    };
    Ok(BeamPlan {
        origin,
        angle,
        z,
        no_return,
        length,
    })
}

/// Validates the arrays and options of a scan.
pub(crate) fn check_scan(
    angles: &[f64],
    ranges: &[f64],
    model: &SensorModel,
    opts: &ScanOptions,
) -> Result<()> {
    if angles.len() != ranges.len() {
        return Err(CrlamError::Shape(format!(
            "scan has {} beam angles but {} ranges",
            angles.len(),
            ranges.len()
        )));
    }
    if opts.beam_stride == 0 {
        return Err(config_err("beam_stride", "must be >= 1"));
    }
    if opts.hits_first && opts.mode != ScanUpdateMode::Batch {
        return Err(config_err(
            "hits_first",
            "needs the batch scan update: a sequential update applies each beam before the next",
        ));
    }
    if let Some((i, a)) = angles.iter().enumerate().find(|(_, a)| !a.is_finite()) {
        return Err(CrlamError::Shape(format!(
            "beam angle {i} is not finite ({a})"
        )));
    }
    model.validate()
}
