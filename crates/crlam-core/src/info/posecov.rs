//! Pose-covariance propagation along planner edges (planner-spec 3.9): the EKF prediction step
//! that gives every tree node a 3×3 covariance of (x, y, θ), used by UGPVR and for the uncertainty
//! ellipses. There is no measurement update, so the uncertainty only grows with depth.

use crate::error::{config_err, CrlamError, Result};

/// A covariance of (x, y, θ) in (m², m², rad²), row-major and symmetric.
pub type Cov3 = [[f64; 3]; 3];

/// χ²₂ quantile of the 90 % region, −2 ln 0.1 = 4.605 (the ellipse radius is its square root).
pub const CHI2_2DOF_90: f64 = 4.605_170_185_988_091;

/// The θ-column of the motion Jacobian F (planner-spec 3.9).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PoseJacobian {
    /// The reference code's coupling `(−sin h·dx − cos h·dy, cos h·dx − sin h·dy)`
    /// = d·(−sin 2h, cos 2h): the travel angle is doubled.
    Reference,
    /// The unicycle Jacobian d·(−sin h, cos h) = (−dy, dx) (clean).
    Unicycle,
}

impl PoseJacobian {
    /// Parses `"reference" | "unicycle" | "clean"`.
    pub fn parse(name: &str) -> Result<Self> {
        match name {
            "reference" => Ok(Self::Reference),
            "unicycle" | "clean" => Ok(Self::Unicycle),
            other => Err(config_err(
                "pose_jacobian",
                format!("unknown mode {other:?}; expected reference or unicycle (clean)"),
            )),
        }
    }

    /// Canonical name.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Reference => "reference",
            Self::Unicycle => "unicycle",
        }
    }
}

/// The motion noise Q added once per edge, whatever its length (planner-spec 3.1, 3.9).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EdgeNoise {
    q: Cov3,
}

impl Default for EdgeNoise {
    /// diag(0.1² m², 0.1² m², (0.15°)² rad²) = diag(0.01, 0.01, 6.854e-6).
    fn default() -> Self {
        let sd_theta = 0.15_f64.to_radians();
        Self {
            q: diag([0.01, 0.01, sd_theta * sd_theta]),
        }
    }
}

impl EdgeNoise {
    /// Noise with covariance `q` (m², m², rad²): finite, symmetric and PSD.
    pub fn new(q: Cov3) -> Result<Self> {
        check_covariance("edge_noise", &q)?;
        Ok(Self { q })
    }

    /// Independent noise with standard deviations (m, m, rad), each finite and ≥ 0.
    pub fn diagonal(sd: [f64; 3]) -> Result<Self> {
        Self::new(diagonal_covariance(sd)?)
    }

    /// The covariance Q (m², m², rad²).
    pub fn q(&self) -> &Cov3 {
        &self.q
    }
}

fn diag(d: [f64; 3]) -> Cov3 {
    [[d[0], 0.0, 0.0], [0.0, d[1], 0.0], [0.0, 0.0, d[2]]]
}

/// The reference root covariance Σ₀ = diag(0.4², 0.1², 0) (m², m², rad²).
pub fn root_covariance() -> Cov3 {
    diag([0.16, 0.01, 0.0])
}

/// A diagonal covariance from standard deviations (m, m, rad), each finite and ≥ 0: a custom
/// root covariance.
pub fn diagonal_covariance(sd: [f64; 3]) -> Result<Cov3> {
    for s in sd {
        if !(s.is_finite() && s >= 0.0) {
            return Err(CrlamError::NonFinite {
                field: "standard_deviation",
                value: s,
            });
        }
    }
    Ok(diag([sd[0] * sd[0], sd[1] * sd[1], sd[2] * sd[2]]))
}

/// Checks that a covariance is finite, symmetric and positive semi-definite (every principal
/// minor ≥ 0, up to a round-off tolerance relative to the largest diagonal entry).
pub fn check_covariance(field: &'static str, s: &Cov3) -> Result<()> {
    for row in s {
        for &v in row {
            if !v.is_finite() {
                return Err(CrlamError::NonFinite { field, value: v });
            }
        }
    }
    let scale = s[0][0].abs().max(s[1][1].abs()).max(s[2][2].abs());
    let tol = 1e-10 * scale.max(f64::MIN_POSITIVE);
    for i in 0..3 {
        for j in 0..i {
            if (s[i][j] - s[j][i]).abs() > tol {
                return Err(config_err(field, "covariance must be symmetric"));
            }
        }
    }
    let m2 = |i: usize, j: usize| s[i][i] * s[j][j] - s[i][j] * s[j][i];
    let det = s[0][0] * m2(1, 2) - s[0][1] * (s[1][0] * s[2][2] - s[1][2] * s[2][0])
        + s[0][2] * (s[1][0] * s[2][1] - s[1][1] * s[2][0]);
    let psd = (0..3).all(|i| s[i][i] >= -tol)
        && m2(0, 1) >= -tol * scale
        && m2(0, 2) >= -tol * scale
        && m2(1, 2) >= -tol * scale
        && det >= -tol * scale * scale;
    if !psd {
        return Err(config_err(
            field,
            "covariance must be positive semi-definite",
        ));
    }
    Ok(())
}

/// Σ_new = F Σ Fᵀ + W Q Wᵀ for the edge `from` → `to` (m) (planner-spec 3.9). F is the identity
/// plus the θ-column coupling of `jacobian`; W rotates the xy-block of Q by the travel heading
/// h = atan2(dy, dx). The result is exactly symmetric and σ_θ² grows by exactly Q_θθ.
pub fn propagate_covariance(
    sigma: &Cov3,
    from: [f64; 2],
    to: [f64; 2],
    noise: &EdgeNoise,
    jacobian: PoseJacobian,
) -> Cov3 {
    let (dx, dy) = (to[0] - from[0], to[1] - from[1]);
    let h = dy.atan2(dx);
    let (sh, ch) = h.sin_cos();
    let a = match jacobian {
        PoseJacobian::Reference => [-sh * dx - ch * dy, ch * dx - sh * dy],
        PoseJacobian::Unicycle => [-dy, dx],
    };
    // F Σ Fᵀ with F = I + a e₃ᵀ (a₃ = 0): row/column i < 2 picks up a_i times row/column θ.
    let g = |i: usize, j: usize| -> f64 {
        let ai = if i < 2 { a[i] } else { 0.0 };
        let aj = if j < 2 { a[j] } else { 0.0 };
        let row_j = sigma[i][j] + ai * sigma[2][j];
        let row_t = sigma[i][2] + ai * sigma[2][2];
        row_j + aj * row_t
    };
    // W Q Wᵀ in the double-angle form, so that an isotropic Q_xy is added exactly.
    let q = &noise.q;
    let (c2, s2) = (ch * ch - sh * sh, 2.0 * sh * ch);
    let mean = 0.5 * (q[0][0] + q[1][1]);
    let half_diff = 0.5 * (q[0][0] - q[1][1]);
    let wq = [
        [
            mean + half_diff * c2 - q[0][1] * s2,
            half_diff * s2 + q[0][1] * c2,
            ch * q[0][2] - sh * q[1][2],
        ],
        [
            0.0,
            mean - half_diff * c2 + q[0][1] * s2,
            sh * q[0][2] + ch * q[1][2],
        ],
        [0.0, 0.0, q[2][2]],
    ];
    let mut out = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in i..3 {
            out[i][j] = g(i, j) + wq[i][j];
            out[j][i] = out[i][j];
        }
    }
    out
}

/// The 2×2 position block (m²).
pub fn xy_block(s: &Cov3) -> [[f64; 2]; 2] {
    [[s[0][0], s[0][1]], [s[1][0], s[1][1]]]
}

/// The 90 % confidence ellipse of a 2-D position covariance (m²): (major semi-axis (m), minor
/// semi-axis (m), angle of the major axis from +x (rad)). The semi-axes are √(4.605 λ) for the
/// eigenvalues λ; negative round-off eigenvalues count as 0.
pub fn ellipse_axes_90(sigma_xy: [[f64; 2]; 2]) -> (f64, f64, f64) {
    let (a, c) = (sigma_xy[0][0], sigma_xy[1][1]);
    let b = 0.5 * (sigma_xy[0][1] + sigma_xy[1][0]);
    let mean = 0.5 * (a + c);
    let radius = (0.25 * (a - c) * (a - c) + b * b).sqrt();
    let major = (mean + radius).max(0.0);
    let minor = (mean - radius).max(0.0);
    let angle = 0.5 * (2.0 * b).atan2(a - c);
    (
        (CHI2_2DOF_90 * major).sqrt(),
        (CHI2_2DOF_90 * minor).sqrt(),
        angle,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    fn is_psd(s: &Cov3) -> bool {
        check_covariance("test", s).is_ok()
    }

    /// An independent form of 3.9: explicit matrices and plain triple loops.
    fn brute(s: &Cov3, from: [f64; 2], to: [f64; 2], q: &Cov3, jac: PoseJacobian) -> Cov3 {
        let (dx, dy) = (to[0] - from[0], to[1] - from[1]);
        let d = dx.hypot(dy);
        let h = dy.atan2(dx);
        let (a1, a2) = match jac {
            PoseJacobian::Reference => (-d * (2.0 * h).sin(), d * (2.0 * h).cos()),
            PoseJacobian::Unicycle => (-d * h.sin(), d * h.cos()),
        };
        let f = [[1.0, 0.0, a1], [0.0, 1.0, a2], [0.0, 0.0, 1.0]];
        let w = [
            [h.cos(), -h.sin(), 0.0],
            [h.sin(), h.cos(), 0.0],
            [0.0, 0.0, 1.0],
        ];
        let sandwich = |m: &Cov3, c: &Cov3| {
            let mut out = [[0.0; 3]; 3];
            for i in 0..3 {
                for j in 0..3 {
                    for k in 0..3 {
                        for l in 0..3 {
                            out[i][j] += m[i][k] * c[k][l] * m[j][l];
                        }
                    }
                }
            }
            out
        };
        let (p, r) = (sandwich(&f, s), sandwich(&w, q));
        let mut out = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                out[i][j] = p[i][j] + r[i][j];
            }
        }
        out
    }

    #[test]
    fn defaults_match_the_reference() {
        let q = EdgeNoise::default();
        assert_eq!(q.q()[0][0], 0.01);
        assert!((q.q()[2][2] - 6.854e-6).abs() < 1e-9);
        assert_eq!(root_covariance()[0][0], 0.16);
        assert_eq!(root_covariance()[2][2], 0.0);
        assert_eq!(
            PoseJacobian::parse("clean").unwrap(),
            PoseJacobian::Unicycle
        );
        assert!(PoseJacobian::parse("x").is_err());
        assert!(EdgeNoise::diagonal([0.1, f64::NAN, 0.0]).is_err());
        let bad = [[1.0, 2.0, 0.0], [2.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        assert!(EdgeNoise::new(bad).is_err());
    }

    #[test]
    fn root_children_grow_by_exactly_q_xy() {
        let q = EdgeNoise::default();
        let mut rng = Rng::new(3);
        for jac in [PoseJacobian::Reference, PoseJacobian::Unicycle] {
            for _ in 0..100 {
                let to = [10.0 + 6.0 * rng.normal(), 2.0 + 6.0 * rng.normal()];
                let s = propagate_covariance(&root_covariance(), [10.0, 2.0], to, &q, jac);
                assert_eq!(s[0][0], 0.16 + 0.01);
                assert_eq!(s[1][1], 0.01 + 0.01);
                assert_eq!(s[0][1], 0.0);
                assert_eq!(s[2][2], q.q()[2][2]);
            }
        }
    }

    #[test]
    fn straight_chain_regression() {
        let q = EdgeNoise::default();
        let mut s = root_covariance();
        for k in 0..40 {
            let x = 3.0 * k as f64;
            s = propagate_covariance(&s, [x, 0.0], [x + 3.0, 0.0], &q, PoseJacobian::Reference);
        }
        assert!((s[0][0] - 0.56).abs() < 1e-12, "{}", s[0][0]);
        assert!((s[1][1] - 1.6770).abs() < 5e-5, "{}", s[1][1]);
        assert!((s[2][2] - 40.0 * q.q()[2][2]).abs() < 1e-15);
    }

    #[test]
    fn random_chains_match_an_independent_implementation() {
        let mut rng = Rng::new(11);
        let noises = [
            EdgeNoise::default(),
            EdgeNoise::new([
                [0.02, 0.004, 1e-4],
                [0.004, 0.01, -2e-4],
                [1e-4, -2e-4, 1e-3],
            ])
            .unwrap(),
        ];
        for chain in 0..40 {
            let jac = if chain % 2 == 0 {
                PoseJacobian::Reference
            } else {
                PoseJacobian::Unicycle
            };
            let q = &noises[chain % 4 / 2];
            let mut s = root_covariance();
            let mut p = [10.0, 2.0];
            for _ in 0..40 {
                let ang = 2.0 * std::f64::consts::PI * rng.uniform();
                let len = 0.5 + 2.5 * rng.uniform();
                let next = [p[0] + len * ang.cos(), p[1] + len * ang.sin()];
                let old = s;
                s = propagate_covariance(&old, p, next, q, jac);
                let want = brute(&old, p, next, q.q(), jac);
                for i in 0..3 {
                    for j in 0..3 {
                        let tol = 1e-12 * (1.0 + want[i][j].abs());
                        assert!((s[i][j] - want[i][j]).abs() < tol, "{i}{j}");
                        assert_eq!(s[i][j], s[j][i]);
                    }
                }
                assert_eq!(s[2][2], old[2][2] + q.q()[2][2]);
                assert!(is_psd(&s));
                p = next;
            }
        }
    }

    use PoseJacobian as Jac;

    #[test]
    fn the_two_jacobians_differ_across_but_agree_along_the_axis() {
        let q = EdgeNoise::default();
        let s0 = propagate_covariance(
            &root_covariance(),
            [0.0, 0.0],
            [1.0, 0.0],
            &q,
            Jac::Unicycle,
        );
        // Heading 90°: the unicycle spreads x (across), the reference y (along).
        let u = propagate_covariance(&s0, [0.0, 0.0], [0.0, 3.0], &q, Jac::Unicycle);
        let r = propagate_covariance(&s0, [0.0, 0.0], [0.0, 3.0], &q, Jac::Reference);
        let extra = 9.0 * s0[2][2];
        assert!((u[0][0] - (s0[0][0] + 0.01 + extra)).abs() < 1e-15);
        assert!((r[1][1] - (s0[1][1] + 0.01 + extra)).abs() < 1e-15);
        assert!((u[0][0] + u[1][1] - r[0][0] - r[1][1]).abs() < 1e-15);
    }

    #[test]
    fn ellipse_axes() {
        let (a, b, ang) = ellipse_axes_90([[0.16, 0.0], [0.0, 0.01]]);
        assert!((a - 0.4 * 2.145_966).abs() < 1e-6 && (b - 0.1 * 2.145_966).abs() < 1e-6);
        assert!(ang.abs() < 1e-15);
        let (a, b, ang) = ellipse_axes_90([[0.01, 0.0], [0.0, 0.16]]);
        assert!(a > b && (ang.abs() - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        // Correlated: the semi-axes follow the eigenvalues 2 and 0 of [[1, 1], [1, 1]].
        let (a, b, ang) = ellipse_axes_90([[1.0, 1.0], [1.0, 1.0]]);
        assert!((a - (2.0 * CHI2_2DOF_90).sqrt()).abs() < 1e-12 && b < 1e-7);
        assert!((ang - std::f64::consts::FRAC_PI_4).abs() < 1e-12);
        assert!((CHI2_2DOF_90 + 2.0 * 0.1f64.ln()).abs() < 1e-15);
    }
}
