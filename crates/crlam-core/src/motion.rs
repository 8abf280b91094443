//! Odometry motion models: sampling the proposal and evaluating its density (crm-spec 4.4).

use crate::error::{config_err, Result};
use crate::pose::{between, compose, wrap, Pose};
use crate::rng::Rng;

/// A model of how the true increment deviates from the odometry increment.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum MotionModel {
    /// x_k = x_{k−1} ⊕ (u + ε), ε ~ N(0, diag(σ²)) per odometry step (the spec's model; the
    /// paper's Σ_u = 0.01² I). Over `n` raw steps merged into one update the variance is n·σ².
    Gaussian { sigma: [f64; 3] },
    /// Thrun's four-parameter odometry model (rot1, trans, rot2 perturbed with variances
    /// α1·rot² + α2·trans² and α3·trans² + α4·(rot1² + rot2²)).
    Thrun { alpha: [f64; 4] },
    /// GMapping's model (`MotionModel::drawFromMotion` of openslam_gmapping): independent
    /// normals on the increment (dx, dy, dθ) in the frame of the previous pose, with standard
    /// deviations σx = srr·|dx| + str·|dθ| + 0.3·srr·|dy|, σy = srr·|dy| + str·|dθ| + 0.3·srr·|dx|,
    /// σθ = stt·|dθ| + srt·√(dx² + dy²). Coefficients are standard deviations (not variances)
    /// and add linearly; `srt` is rotation per metre, `str` translation per radian.
    Gmapping {
        srr: f64,
        srt: f64,
        str_: f64,
        stt: f64,
    },
}

impl MotionModel {
    /// The paper's Gaussian increment noise, σ = 0.01 (m, m, rad) per step.
    pub fn paper() -> Self {
        Self::Gaussian {
            sigma: [0.01, 0.01, 0.01],
        }
    }

    /// GMapping's defaults: srr 0.1, srt 0.2, str 0.1, stt 0.2.
    pub fn gmapping() -> Self {
        Self::Gmapping {
            srr: 0.1,
            srt: 0.2,
            str_: 0.1,
            stt: 0.2,
        }
    }

    /// Checks the parameters.
    pub fn validate(&self) -> Result<()> {
        let ok = |v: &f64| v.is_finite() && *v >= 0.0;
        match self {
            Self::Gaussian { sigma } if sigma.iter().all(ok) => Ok(()),
            Self::Thrun { alpha } if alpha.iter().all(ok) => Ok(()),
            Self::Gmapping {
                srr,
                srt,
                str_,
                stt,
            } if [*srr, *srt, *str_, *stt].iter().all(ok) => Ok(()),
            _ => Err(config_err(
                "motion",
                "noise parameters must be finite and >= 0",
            )),
        }
    }

    /// Samples the pose after the odometry increment `u` (in the frame of `pose`), merged from
    /// `n_steps` raw odometry steps.
    pub fn sample(&self, pose: Pose, u: Pose, n_steps: usize, rng: &mut Rng) -> Pose {
        match *self {
            Self::Gaussian { sigma } => {
                let k = (n_steps.max(1) as f64).sqrt();
                perturb_increment(pose, u, sigma.map(|s| k * s), rng)
            }
            Self::Thrun { alpha } => {
                let (rot1, trans, rot2) = decompose(u);
                let s_rot1 = (alpha[0] * rot1 * rot1 + alpha[1] * trans * trans).sqrt();
                let s_trans =
                    (alpha[2] * trans * trans + alpha[3] * (rot1 * rot1 + rot2 * rot2)).sqrt();
                let s_rot2 = (alpha[0] * rot2 * rot2 + alpha[1] * trans * trans).sqrt();
                let r1 = rot1 - s_rot1 * rng.normal();
                let t = trans - s_trans * rng.normal();
                let r2 = rot2 - s_rot2 * rng.normal();
                compose(pose, recompose(r1, t, r2))
            }
            // GMapping perturbs the whole increment between processed scans at once.
            Self::Gmapping {
                srr,
                srt,
                str_,
                stt,
            } => perturb_increment(pose, u, gmapping_sigma([srr, srt, str_, stt], u), rng),
        }
    }

    /// log p(next | prev, u) for the Gaussian model (Jacobian 1, crm-spec 4.4), and Thrun's
    /// textbook density (product of the three component normals) for the other.
    pub fn log_density(&self, prev: Pose, next: Pose, u: Pose, n_steps: usize) -> f64 {
        let d = between(prev, next);
        match *self {
            Self::Gaussian { sigma } => {
                let k = (n_steps.max(1) as f64).sqrt();
                increment_log_density(d, u, sigma.map(|s| k * s))
            }
            Self::Thrun { alpha } => {
                let (rot1, trans, rot2) = decompose(u);
                let (h1, ht, h2) = decompose(d);
                let s1 = (alpha[0] * rot1 * rot1 + alpha[1] * trans * trans).sqrt();
                let st = (alpha[2] * trans * trans + alpha[3] * (rot1 * rot1 + rot2 * rot2)).sqrt();
                let s2 = (alpha[0] * rot2 * rot2 + alpha[1] * trans * trans).sqrt();
                log_normal(wrap(rot1 - h1), s1)
                    + log_normal(trans - ht, st)
                    + log_normal(wrap(rot2 - h2), s2)
            }
            Self::Gmapping {
                srr,
                srt,
                str_,
                stt,
            } => increment_log_density(d, u, gmapping_sigma([srr, srt, str_, stt], u)),
        }
    }
}

/// Standard deviations (x, y, θ) of [`MotionModel::Gmapping`]'s noise on the increment `u`,
/// from (srr, srt, str, stt).
pub(crate) fn gmapping_sigma(c: [f64; 4], u: Pose) -> [f64; 3] {
    let [srr, srt, str_, stt] = c;
    let (ax, ay, at) = (u[0].abs(), u[1].abs(), wrap(u[2]).abs());
    [
        srr * ax + str_ * at + 0.3 * srr * ay,
        srr * ay + str_ * at + 0.3 * srr * ax,
        stt * at + srt * u[0].hypot(u[1]),
    ]
}

/// `pose` ⊕ (u + ε) with independent normal ε of standard deviations `sigma`.
fn perturb_increment(pose: Pose, u: Pose, sigma: [f64; 3], rng: &mut Rng) -> Pose {
    let e = [
        u[0] + sigma[0] * rng.normal(),
        u[1] + sigma[1] * rng.normal(),
        u[2] + sigma[2] * rng.normal(),
    ];
    // compose wraps the heading.
    compose(pose, e)
}

/// log density of the increment `d` under independent normals around `u`.
fn increment_log_density(d: Pose, u: Pose, sigma: [f64; 3]) -> f64 {
    let r = [d[0] - u[0], d[1] - u[1], wrap(d[2] - u[2])];
    (0..3).map(|i| log_normal(r[i], sigma[i])).sum()
}

fn log_normal(x: f64, sigma: f64) -> f64 {
    if sigma <= 0.0 {
        return if x == 0.0 { 0.0 } else { f64::NEG_INFINITY };
    }
    -0.5 * (x / sigma).powi(2) - sigma.ln() - 0.918_938_533_204_672_8
}

/// (rot1, trans, rot2) of an increment; backward motion keeps rot1 small with a negative trans.
pub(crate) fn decompose(u: Pose) -> (f64, f64, f64) {
    let trans = u[0].hypot(u[1]);
    if trans < 1e-9 {
        return (0.0, 0.0, wrap(u[2]));
    }
    let mut rot1 = u[1].atan2(u[0]);
    let mut t = trans;
    if rot1.abs() > std::f64::consts::FRAC_PI_2 {
        rot1 = wrap(rot1 + std::f64::consts::PI);
        t = -trans;
    }
    (rot1, t, wrap(u[2] - rot1))
}

fn recompose(rot1: f64, trans: f64, rot2: f64) -> Pose {
    [trans * rot1.cos(), trans * rot1.sin(), wrap(rot1 + rot2)]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decomposition_round_trips_forward_and_backward() {
        for u in [
            [0.3, 0.1, 0.2],
            [-0.2, 0.05, -0.1],
            [0.0, 0.0, 0.5],
            [0.1, -0.3, 3.0],
        ] {
            let (a, t, b) = decompose(u);
            let v = recompose(a, t, b);
            for i in 0..3 {
                assert!((wrap(v[i] - u[i])).abs() < 1e-12, "{u:?} -> {v:?}");
            }
        }
    }

    #[test]
    fn gaussian_samples_match_the_density_moments() {
        let m = MotionModel::Gaussian {
            sigma: [0.02, 0.01, 0.03],
        };
        let mut rng = Rng::new(3);
        let p0 = [1.0, 2.0, 0.5];
        let u = [0.4, 0.0, 0.1];
        let n = 50_000;
        let mut acc = [0.0; 3];
        let mut acc2 = [0.0; 3];
        for _ in 0..n {
            let d = between(p0, m.sample(p0, u, 4, &mut rng));
            for i in 0..3 {
                let r = d[i] - u[i];
                acc[i] += r;
                acc2[i] += r * r;
            }
        }
        let s = [0.04, 0.02, 0.06];
        for i in 0..3 {
            assert!((acc[i] / n as f64).abs() < 3e-3 * s[i] / 0.01);
            assert!(((acc2[i] / n as f64).sqrt() - s[i]).abs() < 0.02 * s[i]);
        }
        assert!(
            m.log_density(p0, compose(p0, u), u, 1)
                > m.log_density(p0, compose(p0, [0.5, 0.0, 0.1]), u, 1)
        );
    }

    #[test]
    fn gmapping_noise_follows_its_formula() {
        let m = MotionModel::gmapping();
        let c = [0.1, 0.2, 0.1, 0.2];
        // 1 m straight: σx 0.1, σy 0.03, σθ 0.2 rad (srt is rotation per metre).
        let s = gmapping_sigma(c, [1.0, 0.0, 0.0]);
        assert!((s[0] - 0.1).abs() < 1e-12 && (s[1] - 0.03).abs() < 1e-12);
        assert!((s[2] - 0.2).abs() < 1e-12);
        // 0.5 rad in place: σx = σy = str·0.5, σθ = stt·0.5.
        let s = gmapping_sigma(c, [0.0, 0.0, -0.5]);
        assert!((s[0] - 0.05).abs() < 1e-12 && (s[1] - 0.05).abs() < 1e-12);
        assert!((s[2] - 0.1).abs() < 1e-12);
        let mut rng = Rng::new(11);
        let p0 = [1.0, -2.0, 2.0];
        let u = [0.8, 0.1, 0.3];
        let want = gmapping_sigma(c, u);
        let n = 40_000;
        let mut acc2 = [0.0; 3];
        for _ in 0..n {
            let d = between(p0, m.sample(p0, u, 3, &mut rng));
            let r = [d[0] - u[0], d[1] - u[1], wrap(d[2] - u[2])];
            for i in 0..3 {
                acc2[i] += r[i] * r[i];
            }
        }
        for i in 0..3 {
            assert!(((acc2[i] / n as f64).sqrt() - want[i]).abs() < 0.02 * want[i]);
        }
        // The density is the product of those normals, peaked at the odometry.
        let at = m.log_density(p0, compose(p0, u), u, 1);
        let expect: f64 = want.iter().map(|s| -s.ln() - 0.918_938_533_204_672_8).sum();
        assert!((at - expect).abs() < 1e-9);
        assert!(MotionModel::Gmapping {
            srr: 0.1,
            srt: f64::NAN,
            str_: 0.1,
            stt: 0.2
        }
        .validate()
        .is_err());
    }

    #[test]
    fn thrun_noise_grows_with_motion() {
        let m = MotionModel::Thrun {
            alpha: [0.1, 0.1, 0.1, 0.1],
        };
        let mut rng = Rng::new(5);
        let spread = |u: Pose, rng: &mut Rng| {
            let xs: Vec<f64> = (0..2000)
                .map(|_| m.sample([0.0; 3], u, 1, rng)[0])
                .collect();
            let mean = xs.iter().sum::<f64>() / xs.len() as f64;
            (xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / xs.len() as f64).sqrt()
        };
        assert!(spread([1.0, 0.0, 0.0], &mut rng) > 3.0 * spread([0.1, 0.0, 0.0], &mut rng));
        assert!(MotionModel::Thrun {
            alpha: [-1.0, 0.0, 0.0, 0.0]
        }
        .validate()
        .is_err());
    }
}
