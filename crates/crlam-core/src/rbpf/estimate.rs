//! Point estimates of a weighted particle set other than the weighted mean.
//!
//! The weighted mean (crm-spec 4.3) is the filter's estimate. When the set splits into groups
//! of lineages whose maps disagree, the mean lies between the groups, where no particle is;
//! [`mode_seeking_pose`] instead follows the weighted kernel density to the mode that holds
//! the most weight near it. On a compact set it equals the weighted mean up to the kernel's
//! tails; with an infinite bandwidth it is the weighted mean exactly; with a bandwidth far
//! below the particle spacing it is the highest-weight particle.

use crate::error::{config_err, CrlamError, Result};
use crate::pose::{wrap, Pose};

/// The particle set an estimate was taken from: poses and normalised weights before resampling.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct WeighedSet {
    /// Particle poses.
    pub poses: Vec<Pose>,
    /// Normalised weights (sum 1), aligned with `poses`.
    pub weights: Vec<f64>,
    /// Each particle's node in the filter's [`crate::rbpf::PathTree`] at this scan
    /// ([`crate::rbpf::NO_NODE`] before the first processed scan).
    pub nodes: Vec<crate::rbpf::NodeId>,
}

/// Kernel bandwidths of [`mode_seeking_pose`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ModeBandwidth {
    /// Position bandwidth (m), > 0; `f64::INFINITY` ignores positions.
    pub xy: f64,
    /// Heading bandwidth (rad), > 0; `f64::INFINITY` ignores headings.
    pub theta: f64,
}

impl ModeBandwidth {
    fn validate(&self) -> Result<()> {
        for (field, v) in [("bandwidth_xy", self.xy), ("bandwidth_theta", self.theta)] {
            if v.is_nan() || v <= 0.0 {
                return Err(config_err(field, format!("must be > 0, got {v}")));
            }
        }
        Ok(())
    }

    /// Log of the Gaussian kernel between two poses (heading difference wrapped to (−π, π]).
    fn log_kernel(&self, a: &Pose, b: &Pose) -> f64 {
        let (dx, dy, dt) = (a[0] - b[0], a[1] - b[1], wrap(a[2] - b[2]));
        -0.5 * ((dx * dx + dy * dy) / (self.xy * self.xy) + dt * dt / (self.theta * self.theta))
    }
}

/// Mean-shift iterations stop when a step moves less than this many bandwidths (5 nm at 5 cm:
/// far below any pose error; mean shift converges only linearly, so a tighter bound costs
/// many more O(n) steps).
const SHIFT_TOL: f64 = 1e-7;
/// Mean shift converges geometrically; this cap only guards against cycling on the circle.
const MAX_SHIFTS: usize = 200;

/// The mode of the weighted Gaussian kernel density of a particle set that holds the densest
/// particle.
///
/// The start is the particle with the highest density Σ_j w_j k(p_i, p_j) (O(n²) kernel
/// evaluations, the lowest index on ties); mean shift then climbs from there: each step moves
/// to the kernel-weighted mean of the set around the current point (positions averaged,
/// headings by circular mean), so the result is the weighted mean of the particles near the
/// mode, with the weight of far groups cut by the kernel.
///
/// `weights` need not be normalised; they must be finite, ≥ 0 and not all zero.
pub fn mode_seeking_pose(
    poses: &[Pose],
    weights: &[f64],
    bandwidth: ModeBandwidth,
) -> Result<Pose> {
    bandwidth.validate()?;
    if poses.is_empty() {
        return Err(CrlamError::Shape("mode_seeking_pose: no particles".into()));
    }
    if poses.len() != weights.len() {
        return Err(CrlamError::Shape(format!(
            "mode_seeking_pose: {} poses but {} weights",
            poses.len(),
            weights.len()
        )));
    }
    for p in poses {
        for &v in p {
            if !v.is_finite() {
                return Err(CrlamError::NonFinite {
                    field: "poses",
                    value: v,
                });
            }
        }
    }
    for &v in weights {
        if !v.is_finite() {
            return Err(CrlamError::NonFinite {
                field: "weights",
                value: v,
            });
        }
        if v < 0.0 {
            return Err(config_err("weights", format!("must be >= 0, got {v}")));
        }
    }
    let total: f64 = weights.iter().sum();
    if total <= 0.0 {
        return Err(config_err("weights", "all zero"));
    }
    let start = densest_particle(poses, weights, &bandwidth);
    let mut m = poses[start];
    for _ in 0..MAX_SHIFTS {
        let Some(next) = kernel_mean(poses, weights, &bandwidth, &m) else {
            break;
        };
        let moved = (next[0] - m[0]).hypot(next[1] - m[1]) / bandwidth.xy
            + wrap(next[2] - m[2]).abs() / bandwidth.theta;
        m = next;
        if moved.is_nan() || moved <= SHIFT_TOL {
            break;
        }
    }
    Ok(m)
}

/// Index of the particle with the highest weighted kernel density (first on ties).
fn densest_particle(poses: &[Pose], w: &[f64], bw: &ModeBandwidth) -> usize {
    let n = poses.len();
    let mut density: Vec<f64> = w.to_vec(); // k(p_i, p_i) = 1
    for i in 0..n {
        for j in (i + 1)..n {
            let k = bw.log_kernel(&poses[i], &poses[j]).exp();
            density[i] += w[j] * k;
            density[j] += w[i] * k;
        }
    }
    density
        .iter()
        .enumerate()
        .fold(0, |b, (i, &d)| if d > density[b] { i } else { b })
}

/// Kernel-weighted mean pose around `m`; `None` when every kernel weight underflows to 0.
fn kernel_mean(poses: &[Pose], w: &[f64], bw: &ModeBandwidth, m: &Pose) -> Option<Pose> {
    let (mut sa, mut x, mut y, mut s, mut c) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for (p, &wi) in poses.iter().zip(w) {
        let a = wi * bw.log_kernel(p, m).exp();
        sa += a;
        x += a * p[0];
        y += a * p[1];
        s += a * p[2].sin();
        c += a * p[2].cos();
    }
    (sa > 0.0).then(|| [x / sa, y / sa, s.atan2(c)])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rbpf::weighted_mean_pose;

    const BW: ModeBandwidth = ModeBandwidth {
        xy: 0.05,
        theta: 0.025,
    };

    fn close(a: Pose, b: Pose, tol: f64) -> bool {
        (a[0] - b[0]).abs() < tol && (a[1] - b[1]).abs() < tol && wrap(a[2] - b[2]).abs() < tol
    }

    #[test]
    fn infinite_bandwidth_is_the_weighted_mean() {
        let poses = [[0.0, 0.0, 3.1], [2.0, 1.0, -3.1], [0.5, -1.0, 0.2]];
        let w = [0.2, 0.5, 0.3];
        let inf = ModeBandwidth {
            xy: f64::INFINITY,
            theta: f64::INFINITY,
        };
        let m = mode_seeking_pose(&poses, &w, inf).unwrap();
        assert!(close(m, weighted_mean_pose(&poses, &w), 1e-12));
    }

    #[test]
    fn tiny_bandwidth_is_the_highest_weight_particle() {
        let poses = [[0.0, 0.0, 0.0], [0.3, 0.0, 0.1], [0.6, 0.0, 0.2]];
        let w = [0.2, 0.5, 0.3];
        let tiny = ModeBandwidth {
            xy: 1e-4,
            theta: 1e-4,
        };
        assert!(close(
            mode_seeking_pose(&poses, &w, tiny).unwrap(),
            poses[1],
            1e-12
        ));
    }

    #[test]
    fn two_groups_give_the_mean_of_the_heavier_group() {
        // Group A (weight 0.6) around x = 0, group B (0.4) 0.5 m away: the weighted mean
        // (x ≈ 0.2) sits between them; the mode is A's own weighted mean.
        let a = [[0.00, 0.0, 0.00], [0.01, 0.0, 0.00], [0.02, 0.0, 0.01]];
        let wa = [0.1, 0.3, 0.2];
        let b = [[0.50, 0.0, 0.05], [0.51, 0.01, 0.05]];
        let wb = [0.25, 0.15];
        let poses: Vec<Pose> = a.iter().chain(b.iter()).copied().collect();
        let w: Vec<f64> = wa.iter().chain(wb.iter()).copied().collect();
        let m = mode_seeking_pose(&poses, &w, BW).unwrap();
        let mean_a = weighted_mean_pose(&a, &[1.0 / 6.0, 0.5, 1.0 / 3.0]);
        assert!(close(m, mean_a, 1e-3), "{m:?} vs {mean_a:?}");
        let mean = weighted_mean_pose(&poses, &w);
        assert!((mean[0] - 0.2).abs() < 0.01);
    }

    #[test]
    fn density_not_single_weight_picks_the_group() {
        // One heavy lone particle (0.3) against a tight group of four at 0.175 each: the group
        // holds more weight near it, so the mode is the group's, not the heaviest particle's.
        let poses = [
            [1.0, 0.0, 0.0],
            [0.0, 0.0, 0.0],
            [0.005, 0.0, 0.0],
            [0.0, 0.005, 0.0],
            [0.005, 0.005, 0.0],
        ];
        let w = [0.3, 0.175, 0.175, 0.175, 0.175];
        let m = mode_seeking_pose(&poses, &w, BW).unwrap();
        assert!(close(m, [0.0025, 0.0025, 0.0], 1e-6), "{m:?}");
    }

    #[test]
    fn headings_wrap_across_the_cut() {
        let poses = [[0.0, 0.0, 3.13], [0.0, 0.0, -3.13], [0.0, 0.0, 3.135]];
        let m = mode_seeking_pose(&poses, &[1.0, 1.0, 1.0], BW).unwrap();
        assert!(m[2].abs() > 3.12, "{m:?}");
    }

    #[test]
    fn rigid_motion_and_weight_scale_commute() {
        let poses = [
            [0.0, 0.0, 0.1],
            [0.04, 0.01, 0.12],
            [0.3, 0.2, 0.3],
            [0.02, -0.03, 0.09],
        ];
        let w = [0.3, 0.2, 0.35, 0.15];
        let m = mode_seeking_pose(&poses, &w, BW).unwrap();
        let t = [1.5, -2.0, 2.0];
        let moved: Vec<Pose> = poses.iter().map(|p| crate::pose::compose(t, *p)).collect();
        let w10: Vec<f64> = w.iter().map(|x| 10.0 * x).collect();
        let m2 = mode_seeking_pose(&moved, &w10, BW).unwrap();
        assert!(close(m2, crate::pose::compose(t, m), 1e-9), "{m2:?}");
    }

    #[test]
    fn bad_input_is_an_error() {
        let p = [[0.0; 3]];
        assert!(mode_seeking_pose(&[], &[], BW).is_err());
        assert!(mode_seeking_pose(&p, &[1.0, 1.0], BW).is_err());
        assert!(mode_seeking_pose(&p, &[0.0], BW).is_err());
        assert!(mode_seeking_pose(&p, &[-1.0], BW).is_err());
        assert!(mode_seeking_pose(&p, &[f64::NAN], BW).is_err());
        assert!(mode_seeking_pose(&[[f64::NAN, 0.0, 0.0]], &[1.0], BW).is_err());
        let zero = ModeBandwidth {
            xy: 0.0,
            theta: 1.0,
        };
        assert!(mode_seeking_pose(&p, &[1.0], zero).is_err());
        let nan = ModeBandwidth {
            xy: 1.0,
            theta: f64::NAN,
        };
        assert!(mode_seeking_pose(&p, &[1.0], nan).is_err());
    }
}
