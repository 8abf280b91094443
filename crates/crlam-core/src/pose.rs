//! SE(2) pose algebra on `[x, y, θ]` (m, m, rad); headings wrapped to (−π, π].

use std::f64::consts::PI;

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
}
