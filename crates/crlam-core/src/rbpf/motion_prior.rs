//! The motion density RBPF-OGM's improved proposal multiplies into the scan-match likelihood.

use crate::motion::MotionModel;
use crate::pose::{compose, wrap, Pose};

/// Gaussian approximation of p(x | x', u) evaluated by the improved proposal: independent
/// normals on the residual from x' ⊕ u along and across the direction of travel and in heading.
/// Exact (up to the floor) for [`MotionModel::Gaussian`] and [`MotionModel::Gmapping`]; for
/// Thrun's model it linearises the
/// rot1/trans/rot2 noise and drops the across/heading correlation.
pub(crate) struct MotionPrior {
    mean: Pose,
    /// sin and cos of the direction of the along axis.
    frame: (f64, f64),
    sigma: [f64; 3],
}

impl MotionPrior {
    pub(crate) fn new(
        model: &MotionModel,
        prev: Pose,
        u: Pose,
        n_steps: usize,
        floor: [f64; 3],
    ) -> Self {
        let (phi, raw) = match *model {
            MotionModel::Gaussian { sigma } => {
                let k = (n_steps.max(1) as f64).sqrt();
                (prev[2], sigma.map(|s| k * s))
            }
            MotionModel::Thrun { alpha } => {
                let (r1, t, r2) = crate::motion::decompose(u);
                let s1 = (alpha[0] * r1 * r1 + alpha[1] * t * t).sqrt();
                let st = (alpha[2] * t * t + alpha[3] * (r1 * r1 + r2 * r2)).sqrt();
                let s2 = (alpha[0] * r2 * r2 + alpha[1] * t * t).sqrt();
                (prev[2] + r1, [st, t.abs() * s1, s1.hypot(s2)])
            }
            // Exact: independent normals on the increment in the previous pose's frame.
            MotionModel::Gmapping {
                srr,
                srt,
                str_,
                stt,
            } => (
                prev[2],
                crate::motion::gmapping_sigma([srr, srt, str_, stt], u),
            ),
        };
        Self {
            mean: compose(prev, u),
            frame: phi.sin_cos(),
            sigma: [
                raw[0].hypot(floor[0]),
                raw[1].hypot(floor[1]),
                raw[2].hypot(floor[2]),
            ],
        }
    }

    /// Independent normals with standard deviations `sigma` (along, across, heading; each
    /// combined with `floor` in quadrature) on the residual from `mean`, the along axis at
    /// heading `phi`.
    pub(crate) fn from_sigma(mean: Pose, phi: f64, sigma: [f64; 3], floor: [f64; 3]) -> Self {
        Self {
            mean,
            frame: phi.sin_cos(),
            sigma: [
                sigma[0].hypot(floor[0]),
                sigma[1].hypot(floor[1]),
                sigma[2].hypot(floor[2]),
            ],
        }
    }

    /// The variances (along, across, heading) of one odometry step `u` under `model`, as
    /// [`MotionPrior::new`] approximates it for one step: what per-scan draws accumulate.
    pub(crate) fn step_variance(model: &MotionModel, u: Pose) -> [f64; 3] {
        let p = Self::new(model, [0.0; 3], u, 1, [0.0; 3]);
        p.sigma.map(|s| s * s)
    }

    pub(crate) fn log_density(&self, x: Pose) -> f64 {
        let (s, c) = self.frame;
        let (dx, dy) = (x[0] - self.mean[0], x[1] - self.mean[1]);
        let r = [c * dx + s * dy, -s * dx + c * dy, wrap(x[2] - self.mean[2])];
        (0..3)
            .map(|i| {
                -0.5 * (r[i] / self.sigma[i]).powi(2) - self.sigma[i].ln() - 0.918_938_533_204_672_8
            })
            .sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn motion_prior_peaks_at_the_prediction_and_is_proper_without_motion() {
        let m = crate::rbpf::OgmFilterConfig::default_motion();
        let prev = [1.0, 2.0, 0.3];
        let u = [0.5, 0.0, 0.1];
        let p = MotionPrior::new(&m, prev, u, 1, [0.01; 3]);
        let at = p.log_density(compose(prev, u));
        assert!(at > p.log_density(compose(prev, [0.55, 0.0, 0.1])));
        assert!(at > p.log_density(compose(prev, [0.5, 0.02, 0.1])));
        let still = MotionPrior::new(&m, prev, [0.0; 3], 1, [0.01; 3]);
        assert!(still.log_density([1.01, 2.0, 0.3]).is_finite());
    }

    #[test]
    fn gaussian_prior_matches_the_model_density() {
        let m = MotionModel::Gaussian {
            sigma: [0.02, 0.03, 0.01],
        };
        let prev = [0.5, -1.0, 2.0];
        let u = [0.3, 0.1, -0.2];
        let p = MotionPrior::new(&m, prev, u, 2, [1e-9; 3]);
        for d in [[0.01, 0.0, 0.0], [0.0, -0.02, 0.01], [0.03, 0.01, -0.02]] {
            let x = compose(prev, [u[0] + d[0], u[1] + d[1], u[2] + d[2]]);
            let a = p.log_density(x);
            let b = m.log_density(prev, x, u, 2);
            assert!((a - b).abs() < 1e-6, "{a} vs {b}");
        }
    }
}
