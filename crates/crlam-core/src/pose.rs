//! SE(2) pose algebra on `[x, y, θ]` (m, m, rad); headings wrapped to (−π, π].

use std::f64::consts::PI;

use crate::error::{config_err, Result};
use crate::rng::Rng;

/// A planar pose (x, y, θ).
pub type Pose = [f64; 3];

/// Wraps an angle to (−π, π].
#[inline]
pub fn wrap(a: f64) -> f64 {
    let w = (a + PI).rem_euclid(2.0 * PI) - PI;
    if w <= -PI {
        w + 2.0 * PI
    } else {
        w
    }
}

/// a ⊕ b: `b`, expressed in the frame of `a`, in the world frame.
#[inline]
pub fn compose(a: Pose, b: Pose) -> Pose {
    let (s, c) = a[2].sin_cos();
    [
        a[0] + c * b[0] - s * b[1],
        a[1] + s * b[0] + c * b[1],
        wrap(a[2] + b[2]),
    ]
}

/// a⁻¹.
#[inline]
pub fn inverse(a: Pose) -> Pose {
    let (s, c) = a[2].sin_cos();
    [-(c * a[0] + s * a[1]), s * a[0] - c * a[1], wrap(-a[2])]
}

/// a⁻¹ ⊕ b: `b` in the frame of `a` (the odometry increment from a to b).
#[inline]
pub fn between(a: Pose, b: Pose) -> Pose {
    compose(inverse(a), b)
}

/// The lower-triangular L with L Lᵀ = `cov`, a pose covariance (m², m·rad, rad²; symmetric,
/// positive semidefinite: a zero variance gets a zero column).
pub fn covariance_factor(cov: &[[f64; 3]; 3]) -> Result<[[f64; 3]; 3]> {
    for i in 0..3 {
        for j in 0..3 {
            if !cov[i][j].is_finite()
                || (cov[i][j] - cov[j][i]).abs() > 1e-9 * (1.0 + cov[i][j].abs())
            {
                return Err(config_err(
                    "initial_cov",
                    "must be a finite symmetric 3 x 3 matrix",
                ));
            }
        }
    }
    let mut l = [[0.0; 3]; 3];
    for j in 0..3 {
        let mut d = cov[j][j];
        for k in 0..j {
            d -= l[j][k] * l[j][k];
        }
        if d < -1e-9 * (1.0 + cov[j][j].abs()) {
            return Err(config_err("initial_cov", "must be positive semidefinite"));
        }
        let d = d.max(0.0).sqrt();
        l[j][j] = d;
        for i in j + 1..3 {
            let mut s = cov[i][j];
            for k in 0..j {
                s -= l[i][k] * l[j][k];
            }
            l[i][j] = if d > 0.0 { s / d } else { 0.0 };
        }
    }
    Ok(l)
}

/// A draw from N(mean, L Lᵀ) (`factor` from [`covariance_factor`]), heading wrapped.
pub fn draw_pose(mean: Pose, factor: &[[f64; 3]; 3], rng: &mut Rng) -> Pose {
    let e = [rng.normal(), rng.normal(), rng.normal()];
    let mut p = mean;
    for i in 0..3 {
        for k in 0..=i {
            p[i] += factor[i][k] * e[k];
        }
    }
    p[2] = wrap(p[2]);
    p
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips() {
        let a = [1.0, -2.0, 2.9];
        let b = [0.3, 0.7, -3.0];
        let c = compose(a, between(a, b));
        for i in 0..3 {
            assert!((c[i] - b[i]).abs() < 1e-12);
        }
        let z = compose(a, inverse(a));
        assert!(z.iter().all(|v| v.abs() < 1e-12));
        assert_eq!(wrap(PI), PI);
        assert_eq!(wrap(-PI), PI);
        assert!((wrap(7.0) - (7.0 - 2.0 * PI)).abs() < 1e-12);
    }

    #[test]
    fn covariance_draws() {
        let cov = [[0.04, 0.01, 0.0], [0.01, 0.09, 0.002], [0.0, 0.002, 0.01]];
        let l = covariance_factor(&cov).unwrap();
        let mut rng = Rng::new(1);
        let n = 20_000;
        let draws: Vec<Pose> = (0..n)
            .map(|_| draw_pose([1.0, 2.0, 0.0], &l, &mut rng))
            .collect();
        let mean = |i: usize| draws.iter().map(|p| p[i]).sum::<f64>() / n as f64;
        let m = [mean(0), mean(1), mean(2)];
        for i in 0..3 {
            for j in 0..3 {
                let c = draws
                    .iter()
                    .map(|p| (p[i] - m[i]) * (p[j] - m[j]))
                    .sum::<f64>()
                    / n as f64;
                assert!((c - cov[i][j]).abs() < 0.004, "{i} {j}: {c}");
            }
        }
        let singular = [[0.0, 0.0, 0.0], [0.0, 0.01, 0.0], [0.0, 0.0, 0.0]];
        let l = covariance_factor(&singular).unwrap();
        let p = draw_pose([1.0, 2.0, 0.5], &l, &mut rng);
        assert!(p[0] == 1.0 && p[2] == 0.5 && p[1] != 2.0);
        assert!(covariance_factor(&[[0.01, 0.5, 0.0], [0.0, 0.01, 0.0], [0.0, 0.0, 0.0]]).is_err());
        assert!(covariance_factor(&[[-1.0, 0.0, 0.0], [0.0, 0.01, 0.0], [0.0, 0.0, 0.0]]).is_err());
    }
}
