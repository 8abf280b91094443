//! The GP machinery of GPVR/UGPVR (planner-spec 5.1, 5.3): the Matérn kernel with the reference
//! hyperparameters, a dense Cholesky, posterior variances, BCM fusion, Gauss–Hermite nodes and the
//! expected kernel of uncertain training inputs, plus the named reference/clean switches.

use std::f64::consts::PI;
use std::sync::OnceLock;

use crate::error::{config_err, CrlamError, Result};

/// An enum of named modes with `parse` (canonical name or alias) and `name`.
macro_rules! named_modes {
    ($(#[$m:meta])* $name:ident, $field:literal,
     { $($(#[$vm:meta])* $var:ident = $canon:literal $(| $alias:literal)*),+ $(,)? }) => {
        $(#[$m])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq)]
        pub enum $name { $($(#[$vm])* $var),+ }
        impl $name {
            /// Parses the canonical name or an alias.
            pub fn parse(name: &str) -> Result<Self> {
                match name {
                    $($canon $(| $alias)* => Ok(Self::$var),)+
                    other => Err(config_err($field, format!(
                        "unknown mode {other:?}; expected one of {:?}", [$($canon),+]))),
                }
            }
            /// Canonical name.
            pub fn name(&self) -> &'static str {
                match self { $(Self::$var => $canon),+ }
            }
        }
    };
}

named_modes!(
    /// Smoothness of the Matérn kernel.
    Matern, "matern", {
        /// ν = 5/2, g(t) = 1 + t + t²/3 (IIG reference).
        Nu52 = "matern52" | "5/2",
        /// ν = 3/2, g(t) = 1 + t (incremental GPOM).
        Nu32 = "matern32" | "3/2",
    }
);
named_modes!(
    /// A preset of every reference-vs-clean switch.
    Mode, "mode", {
        /// Figure parity with the reference planner.
        Reference = "reference",
        /// The behaviour the papers describe.
        Clean = "clean",
    }
);
named_modes!(
    /// Where the free points of a beam lie (planner-spec 5.2 step 2).
    FreePoints, "free_points", {
        /// \[REF\] on the segment from the world origin (0, 0) to each hit; the first free point of
        /// a beam uses its own N, all the others the N of the last hit.
        WorldOrigin = "world_origin" | "reference",
        /// \[CLEAN\] on the segment from the robot to each hit, N per beam.
        Robot = "robot" | "clean",
    }
);
named_modes!(
    /// Which test points are fused into the variance map (planner-spec 5.2 step 5).
    Fusion, "fusion", {
        /// \[REF\] the hits only.
        HitsOnly = "hits_only" | "reference",
        /// \[CLEAN\] every test point.
        AllPoints = "all_points" | "clean",
    }
);
named_modes!(
    /// The expected kernel of UGPVR (planner-spec 5.3).
    UgpvrKernel, "ugpvr_kernel", {
        /// \[REF\] weights / (2π), offsets R·ξ with the upper factor RᵀR = Σ: about half the
        /// expected kernel, applied to K and K* but not k(t, t).
        ReferenceHalf = "reference_half" | "reference",
        /// \[CLEAN\] weights / π, offsets √2·L·ξ with L Lᵀ = Σ: E_{u∼N(x,Σ)} k(u, z); K unchanged.
        Expected = "expected" | "clean",
    }
);

/// GP hyperparameters: isotropic Matérn kernel k(r) = σ_f² g(t) e^{−t}, t = √ν′ r / ℓ.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GpHyper {
    /// ℓ (m).
    pub length_scale: f64,
    /// σ_f (occupancy-target units; the prior variance is σ_f²).
    pub sigma_f: f64,
    /// Observation noise σ_n.
    pub sigma_n: f64,
    /// Kernel smoothness ν.
    pub matern: Matern,
}

impl Default for GpHyper {
    fn default() -> Self {
        Self::reference()
    }
}

impl GpHyper {
    /// The reference values (log ℓ = 1.18243, log σ_f = −0.83593, log σ_n = −5.29342): ℓ = 3.2623 m,
    /// σ_f² = 0.18790, σ_n = 5.0245e-3, Matérn 5/2.
    pub fn reference() -> Self {
        Self {
            length_scale: 1.18243_f64.exp(),
            sigma_f: (-0.83593_f64).exp(),
            sigma_n: (-5.29342_f64).exp(),
            matern: Matern::Nu52,
        }
    }

    /// Every parameter finite and > 0.
    pub fn validate(&self) -> Result<()> {
        for (field, v) in [
            ("length_scale", self.length_scale),
            ("sigma_f", self.sigma_f),
            ("sigma_n", self.sigma_n),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(config_err(
                    field,
                    format!("must be finite and > 0, got {v}"),
                ));
            }
        }
        Ok(())
    }

    /// k(r) at distance `r` (m).
    pub fn kernel(&self, r: f64) -> f64 {
        self.eval().at_sq(r * r)
    }

    pub(crate) fn eval(&self) -> KernelEval {
        let nu = match self.matern {
            Matern::Nu52 => 5.0_f64,
            Matern::Nu32 => 3.0,
        };
        KernelEval {
            sf2: self.sigma_f * self.sigma_f,
            rate: nu.sqrt() / self.length_scale,
            nu52: self.matern == Matern::Nu52,
        }
    }
}

/// The kernel with its constants folded, for the inner loops.
#[derive(Clone, Copy)]
pub(crate) struct KernelEval {
    sf2: f64,
    rate: f64,
    nu52: bool,
}

impl KernelEval {
    #[inline(always)]
    fn at_sq(&self, r2: f64) -> f64 {
        let t = self.rate * r2.sqrt();
        let g = if self.nu52 {
            1.0 + t * (1.0 + t * (1.0 / 3.0))
        } else {
            1.0 + t
        };
        self.sf2 * g * (-t).exp()
    }

    #[inline(always)]
    pub(crate) fn at(&self, a: [f64; 2], b: [f64; 2]) -> f64 {
        let (dx, dy) = (a[0] - b[0], a[1] - b[1]);
        self.at_sq(dx * dx + dy * dy)
    }
}

/// Dot product with four independent accumulators (the inner loop of the factorisation and the
/// solves).
#[inline]
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let mut acc = [0.0; 4];
    for (x, y) in a.chunks_exact(4).zip(b.chunks_exact(4)) {
        for l in 0..4 {
            acc[l] += x[l] * y[l];
        }
    }
    let mut s = (acc[0] + acc[1]) + (acc[2] + acc[3]);
    for k in n - n % 4..n {
        s += a[k] * b[k];
    }
    s
}

/// In-place lower Cholesky factor of the symmetric `n × n` row-major matrix `a` (only the lower
/// triangle is read; the strict upper triangle is left as is). Errors if `a` is not positive
/// definite (a pivot ≤ 0 or not finite).
pub fn cholesky_lower(a: &mut [f64], n: usize) -> Result<()> {
    if a.len() != n * n {
        return Err(CrlamError::Shape(format!(
            "{} entries for {n} x {n}",
            a.len()
        )));
    }
    for i in 0..n {
        let (done, rest) = a.split_at_mut(i * n);
        let row_i = &mut rest[..n];
        for j in 0..i {
            let s = row_i[j] - dot(&row_i[..j], &done[j * n..j * n + j]);
            row_i[j] = s / done[j * n + j];
        }
        let d = row_i[i] - dot(&row_i[..i], &row_i[..i]);
        if !(d > 0.0 && d.is_finite()) {
            return Err(config_err(
                "matrix",
                format!("not positive definite (pivot {d:e} at row {i})"),
            ));
        }
        row_i[i] = d.sqrt();
    }
    Ok(())
}

/// Solves L v = b in place for the lower factor `l` of [`cholesky_lower`].
fn forward_substitute(l: &[f64], n: usize, b: &mut [f64]) {
    for i in 0..n {
        let s = b[i] - dot(&l[i * n..i * n + i], &b[..i]);
        b[i] = s / l[i * n + i];
    }
}

/// Posterior variances s²(t_j) = k(t,t) − K*ᵀ(c·K + σ_n²I)⁻¹K* for j < `n_wanted`, through the
/// Cholesky of c·K/σ_n² + I (GPML's form). `cross(i, j)` is the training–test covariance and
/// `c` scales the training block. s² excludes the observation noise.
pub(crate) fn posterior_prefix(
    hyper: &GpHyper,
    train: &[[f64; 2]],
    train_scale: f64,
    n_wanted: usize,
    cross: impl Fn(usize, usize) -> f64,
) -> Result<Vec<f64>> {
    let n = train.len();
    let k = hyper.eval();
    let inv_sn2 = train_scale / (hyper.sigma_n * hyper.sigma_n);
    let mut a = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..i {
            a[i * n + j] = inv_sn2 * k.at(train[i], train[j]);
        }
        a[i * n + i] = inv_sn2 * k.sf2 + 1.0;
    }
    cholesky_lower(&mut a, n)?;
    let inv_sn = 1.0 / hyper.sigma_n;
    let mut b = vec![0.0; n];
    Ok((0..n_wanted)
        .map(|j| {
            for (i, bi) in b.iter_mut().enumerate() {
                *bi = cross(i, j) * inv_sn;
            }
            forward_substitute(&a, n, &mut b);
            k.sf2 - dot(&b, &b)
        })
        .collect())
}

/// Posterior variances at every test point (m) given training inputs (m); `expected` = `None`
/// for the plain kernel. Targets are not needed for a variance.
pub fn posterior_variances(
    hyper: &GpHyper,
    train: &[[f64; 2]],
    test: &[[f64; 2]],
    expected: Option<&ExpectedKernel>,
) -> Result<Vec<f64>> {
    hyper.validate()?;
    let k = hyper.eval();
    match expected {
        None => posterior_prefix(hyper, train, 1.0, test.len(), |i, j| {
            k.at(train[i], test[j])
        }),
        Some(e) => posterior_prefix(hyper, train, e.train_scale, test.len(), |i, j| {
            e.eval_with(&k, train[i], test[j])
        }),
    }
}

/// Bayesian Committee Machine fusion of two variances in information form, (1/a + 1/b)⁻¹. A
/// side that is zero (or not a finite positive number) carries no usable information: the other
/// side is returned.
pub fn bcm_fuse(a: f64, b: f64) -> f64 {
    let usable = |v: f64| v > 0.0 && v.is_finite();
    match (usable(a), usable(b)) {
        (true, true) => 1.0 / (1.0 / a + 1.0 / b),
        (_, false) => a,
        (false, true) => b,
    }
}

/// Gauss–Hermite order of UGPVR (per axis).
pub const GH_ORDER: usize = 11;
/// Quadrature pairs with w_a w_b at or below this are skipped (109 of 121 remain for N = 11).
pub const GH_PAIR_THRESHOLD: f64 = 1e-8;

/// Orthonormal Hermite values (p̃_{n−1}(x), p̃_n(x), Σ_{k<n} p̃_k(x)²) for the weight e^{−x²}.
fn hermite_orthonormal(n: usize, x: f64) -> (f64, f64, f64) {
    let (mut prev, mut cur, mut sumsq) = (0.0, PI.powf(-0.25), 0.0);
    for k in 0..n {
        sumsq += cur * cur;
        let kf = k as f64;
        let next = (2.0 / (kf + 1.0)).sqrt() * x * cur - (kf / (kf + 1.0)).sqrt() * prev;
        prev = cur;
        cur = next;
    }
    (prev, cur, sumsq)
}

/// Gauss–Hermite rule for ∫ e^{−x²} f(x) dx (Σ w = √π): nodes ascending and weights, for
/// `1 ≤ n ≤ 100`. The roots of H_n are bracketed on a fine grid over |x| < √(2n+1), bisected and
/// polished by Newton steps on the orthonormal recurrence; w_i = 1 / Σ_{k<n} p̃_k(x_i)².
pub fn gauss_hermite(n: usize) -> Result<(Vec<f64>, Vec<f64>)> {
    if !(1..=100).contains(&n) {
        return Err(config_err("order", format!("must be in 1..=100, got {n}")));
    }
    let pn = |x: f64| hermite_orthonormal(n, x).1;
    let bound = (2.0 * n as f64 + 1.0).sqrt() + 0.5;
    // The grid is shifted off 0 so that no grid point is a root; root gaps exceed 0.1 for n ≤ 100.
    let step = 1e-3;
    let mut nodes = Vec::with_capacity(n);
    let (mut lo, mut f_lo) = (-bound - 1.234_567e-4, pn(-bound - 1.234_567e-4));
    while lo < bound {
        let hi = lo + step;
        let f_hi = pn(hi);
        if f_lo * f_hi < 0.0 {
            let (mut a, mut b, fa) = (lo, hi, f_lo);
            for _ in 0..60 {
                let mid = 0.5 * (a + b);
                if pn(mid) * fa > 0.0 {
                    a = mid;
                } else {
                    b = mid;
                }
            }
            let mut x = 0.5 * (a + b);
            for _ in 0..2 {
                let (p_prev, p, _) = hermite_orthonormal(n, x);
                let dp = (2.0 * n as f64).sqrt() * p_prev;
                if dp != 0.0 && (p / dp).abs() < step {
                    x -= p / dp;
                }
            }
            nodes.push(x);
        }
        (lo, f_lo) = (hi, f_hi);
    }
    if nodes.len() != n {
        return Err(config_err(
            "order",
            format!("found {} of {n} roots", nodes.len()),
        ));
    }
    let weights = nodes
        .iter()
        .map(|&x| 1.0 / hermite_orthonormal(n, x).2)
        .collect();
    Ok((nodes, weights))
}

fn gh_rule() -> &'static (Vec<f64>, Vec<f64>) {
    static RULE: OnceLock<(Vec<f64>, Vec<f64>)> = OnceLock::new();
    // N = 11 is inside the checked range (a test pins the rule), so the fallback is never used.
    RULE.get_or_init(|| gauss_hermite(GH_ORDER).unwrap_or_default())
}

/// The expected kernel k̃(x, z) = Σ_q w_q k(x + δ_q, z) for one input covariance: the training
/// ("x") argument carries the pose uncertainty, the test argument does not (planner-spec 5.3).
#[derive(Clone, Debug, PartialEq)]
pub struct ExpectedKernel {
    dx: Vec<f64>,
    dy: Vec<f64>,
    w: Vec<f64>,
    pub(crate) train_scale: f64,
}

impl ExpectedKernel {
    /// The quadrature for `mode` and the position covariance `sigma_xy` (m²). `Ok(None)` means
    /// the plain kernel applies: \[REF\] Σ is not positive definite (its Cholesky fails);
    /// \[CLEAN\] Σ = 0 (a PSD singular Σ uses its semi-definite lower factor). Errors on a
    /// non-finite, asymmetric or (clean) non-PSD Σ.
    pub fn new(mode: UgpvrKernel, sigma_xy: [[f64; 2]; 2]) -> Result<Option<Self>> {
        let [[a, b], [b2, c]] = sigma_xy;
        for v in [a, b, b2, c] {
            if !v.is_finite() {
                return Err(CrlamError::NonFinite {
                    field: "sigma_xy",
                    value: v,
                });
            }
        }
        let scale = a.abs().max(c.abs());
        let tol = 1e-10 * scale;
        if (b - b2).abs() > tol {
            return Err(config_err("sigma_xy", "covariance must be symmetric"));
        }
        // Offsets δ = M·(ξ_a, ξ_b): M = R (upper, RᵀR = Σ) for REF, √2·L (lower) for CLEAN.
        let (m, norm) = match mode {
            UgpvrKernel::ReferenceHalf => {
                let d = c - b * b / a;
                if !(a > 0.0 && d > 0.0) {
                    return Ok(None);
                }
                let r11 = a.sqrt();
                ([[r11, b / r11], [0.0, d.sqrt()]], 1.0 / (2.0 * PI))
            }
            UgpvrKernel::Expected => {
                if a < -tol || c < -tol || a * c - b2 * b2 < -tol * scale {
                    return Err(config_err("sigma_xy", "covariance must be PSD"));
                }
                let l11 = a.max(0.0).sqrt();
                let l21 = if l11 > 0.0 { b2 / l11 } else { 0.0 };
                let l22 = (c - l21 * l21).max(0.0).sqrt();
                if l11 == 0.0 && l22 == 0.0 {
                    return Ok(None);
                }
                let s = std::f64::consts::SQRT_2;
                ([[s * l11, 0.0], [s * l21, s * l22]], 1.0 / PI)
            }
        };
        let (xi, wi) = gh_rule();
        let mut out = Self {
            dx: Vec::new(),
            dy: Vec::new(),
            w: Vec::new(),
            train_scale: 1.0,
        };
        let mut raw_sum = 0.0;
        for (xa, wa) in xi.iter().zip(wi) {
            for (xb, wb) in xi.iter().zip(wi) {
                if wa * wb > GH_PAIR_THRESHOLD {
                    out.dx.push(m[0][0] * xa + m[0][1] * xb);
                    out.dy.push(m[1][0] * xa + m[1][1] * xb);
                    out.w.push(wa * wb * norm);
                    raw_sum += wa * wb;
                }
            }
        }
        // Zero-weight padding to a multiple of 4 for the 4-lane inner loop.
        while !out.w.len().is_multiple_of(4) {
            out.dx.push(0.0);
            out.dy.push(0.0);
            out.w.push(0.0);
        }
        // K(u, u) = K(x, x) for a shift common to every training input: REF scales K by the
        // weight sum (≈ ½); the exact expectation leaves it unchanged.
        if mode == UgpvrKernel::ReferenceHalf {
            out.train_scale = raw_sum * norm;
        }
        Ok(Some(out))
    }

    /// Number of quadrature pairs kept.
    pub fn n_pairs(&self) -> usize {
        self.w.iter().filter(|&&w| w > 0.0).count()
    }

    /// Σ of the normalised weights (≈ 1 for `Expected`, ≈ ½ for `ReferenceHalf`).
    pub fn weight_sum(&self) -> f64 {
        self.w.iter().sum()
    }

    /// The factor applied to the training block K (1 for `Expected`, the weight sum for REF).
    pub fn train_scale(&self) -> f64 {
        self.train_scale
    }

    /// k̃(x, z) with the uncertainty on `x` (m).
    pub fn eval(&self, hyper: &GpHyper, x: [f64; 2], z: [f64; 2]) -> f64 {
        self.eval_with(&hyper.eval(), x, z)
    }

    #[inline]
    pub(crate) fn eval_with(&self, k: &KernelEval, x: [f64; 2], z: [f64; 2]) -> f64 {
        let (ex, ey) = (x[0] - z[0], x[1] - z[1]);
        // Four independent lanes (the pairs are zero-padded to a multiple of 4) keep several
        // exp calls in flight instead of one serial accumulation.
        let mut acc = [0.0; 4];
        for ((ox, oy), w) in self
            .dx
            .chunks_exact(4)
            .zip(self.dy.chunks_exact(4))
            .zip(self.w.chunks_exact(4))
        {
            for l in 0..4 {
                let (u, v) = (ex + ox[l], ey + oy[l]);
                acc[l] += w[l] * k.at_sq(u * u + v * v);
            }
        }
        (acc[0] + acc[1]) + (acc[2] + acc[3])
    }
}
