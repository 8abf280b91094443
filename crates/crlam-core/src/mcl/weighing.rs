//! How a scan is weighed by the localizer: the climb's steps, the adaptive tempering and the
//! spread of a weighted set.

use crate::error::Result;
use crate::mcl::baseline::{
    beam_model_scan, likelihood_field_scan, DistanceField, Measurement, RangeLimits,
};
use crate::mcl::climb::ClimbSettings;
use crate::mcl::config::MclConfig;
use crate::mcl::field::MeanField;
use crate::mcl::likelihood::{scan_log_likelihood, LikelihoodSettings, ScanFit};
use crate::pose::Pose;
use crate::resample::{effective_sample_size, normalize_log_weights};
use crate::sensor::SensorModel;

/// The climb of a spread set: first steps of half a KLD bin, halved until the step along x and
/// y is at most the map's cell; at most 40 moves (240 evaluations of the score).
pub(super) fn climb_settings(cfg: &MclConfig, field: &MeanField) -> ClimbSettings {
    let step_xy = 0.5 * cfg.kld.bin_xy;
    let cell = field.geometry().resolution;
    let mut refinements = 0;
    while refinements < 16 && step_xy / f64::from(1u32 << refinements) > cell {
        refinements += 1;
    }
    ClimbSettings {
        step_xy,
        step_theta: 0.5 * cfg.kld.bin_theta,
        refinements,
        max_moves: 40,
    }
}

/// The tempering of a scan: `base`, or, when the weights `prior + ll / base` would have an
/// effective sample size below `min_neff` times that of `prior`, the smallest τ > base (to
/// 0.1 %, by bisection on log τ; N_eff grows with τ towards the prior's) at which they have it.
pub(super) fn adaptive_tempering(prior: &[f64], ll: &[f64], base: f64, min_neff: f64) -> f64 {
    let n = ll.len();
    if min_neff <= 0.0 || n == 0 {
        return base;
    }
    let target = min_neff * effective_sample_size(&normalize_log_weights(prior));
    let neff = |tau: f64| {
        let lw: Vec<f64> = prior.iter().zip(ll).map(|(p, l)| p + l / tau).collect();
        effective_sample_size(&normalize_log_weights(&lw))
    };
    if neff(base) >= target {
        return base;
    }
    let mut hi = base * 2.0;
    while neff(hi) < target {
        if hi > base * 1e12 {
            return hi;
        }
        hi *= 2.0;
    }
    let mut lo = hi / 2.0;
    while hi / lo > 1.001 {
        let mid = (lo * hi).sqrt();
        if neff(mid) >= target {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    hi
}

/// The weighted set's RMS distance from its mean position plus 1 m times its circular heading
/// spread sqrt(−2 ln R) (rad).
pub(super) fn set_spread(poses: &[Pose], w: &[f64]) -> f64 {
    let (mut x, mut y, mut c, mut s) = (0.0, 0.0, 0.0, 0.0);
    for (p, &wi) in poses.iter().zip(w) {
        x += wi * p[0];
        y += wi * p[1];
        c += wi * p[2].cos();
        s += wi * p[2].sin();
    }
    let var: f64 = poses
        .iter()
        .zip(w)
        .map(|(p, &wi)| wi * ((p[0] - x).powi(2) + (p[1] - y).powi(2)))
        .sum();
    let r = c.hypot(s).clamp(1e-300, 1.0);
    var.max(0.0).sqrt() + (-2.0 * r.ln()).max(0.0).sqrt()
}

/// The measurement model of one scan: the CRM likelihood or AMCL's, with the scan's hit σ.
pub(super) struct ScanWeigher<'a> {
    pub measurement: Measurement,
    pub field: &'a MeanField,
    pub distance_field: Option<&'a DistanceField>,
    /// The CRM's settings with the scan's σ_hit.
    pub likelihood: LikelihoodSettings,
    pub sigma_hit: f64,
}

impl<'a> ScanWeigher<'a> {
    /// The weigher of `cfg`'s model on `field` with the hit σ `sigma_hit`.
    pub fn new(
        cfg: &MclConfig,
        field: &'a MeanField,
        distance_field: Option<&'a DistanceField>,
        sigma_hit: f64,
    ) -> Self {
        Self {
            measurement: cfg.measurement,
            field,
            distance_field,
            likelihood: LikelihoodSettings {
                model: SensorModel {
                    sigma_hit,
                    ..cfg.likelihood.model
                },
                ..cfg.likelihood
            },
            sigma_hit,
        }
    }

    /// The fit of the beams `beams` of a scan seen from the sensor pose `sensor`.
    pub fn fit(
        &self,
        sensor: Pose,
        angles: &[f64],
        ranges: &[f64],
        beams: &[usize],
    ) -> Result<ScanFit> {
        let model = &self.likelihood.model;
        let limits = RangeLimits {
            z_min: model.z_min,
            z_max: model.z_max,
        };
        let sigma = self.sigma_hit;
        match (&self.measurement, self.distance_field) {
            (Measurement::LikelihoodField(p), Some(table)) => {
                likelihood_field_scan(table, p, sigma, limits, sensor, angles, ranges, beams)
            }
            (Measurement::Beam(p), _) => {
                beam_model_scan(self.field, p, sigma, limits, sensor, angles, ranges, beams)
            }
            _ => scan_log_likelihood(self.field, &self.likelihood, sensor, angles, ranges, beams),
        }
    }
}
