//! Cause-conditional range likelihoods L_l(z), L_∞(z) (crm-spec 2.3).
//!
//! A reading is either a range `z ∈ [0, z_max)` (a density, 1/m) or the no-return atom
//! `z = z_max` (a probability mass). On-ray causes sit at distance `d` (the chord midpoint); the
//! ∞ cause means "nothing within range". Each model is a proper distribution over the reading.

use crate::error::{config_err, Result};
pub use crate::numeric::normal_cdf;
use crate::raycast::RayCell;

mod reading;
pub use reading::MixtureReading;

const LN_SQRT_2PI: f64 = 0.918_938_533_204_672_8;
pub(crate) const SQRT_2PI: f64 = 2.506_628_274_631_000_5;
/// Beyond this many σ a Gaussian factor exp(−u²/2) is below 1e-300 and is taken as 0 in the
/// linear-space sweep (the log-space sweep keeps it).
pub const GAUSS_CUTOFF_SIGMAS: f64 = 37.0;
/// Φ(−8.3) < 1e-16: closer than this many σ to 0 or z_max the truncation normaliser is computed,
/// elsewhere it equals 1 to rounding.
pub(crate) const TRUNC_SIGMAS: f64 = 8.3;
/// From this many σ on, [`normal_cdf`] is exactly 1 (and 0 at −x): `libm::erfc` returns 0 for
/// arguments of 28 and more (28 √2 ≈ 39.6 σ) and 2 for −28 and less.
const EXACT_TAIL_SIGMAS: f64 = 40.0;

/// Which cause model to use.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SensorModelKind {
    /// Agha-mohammadi's pure-hit model: an on-ray cause gives a truncated Gaussian around its
    /// distance and never a no-return; the ∞ cause always gives a no-return.
    Ijrr,
    /// Thrun's beam mixture (hit, short, max, random) with the ∞ cause of crm-spec 2.3.
    Mixture,
    /// The authors' MATLAB `beamSensorModel` and update (crm-spec 3.4), for parity runs.
    AuthorsCode,
}

impl SensorModelKind {
    /// Parses `"ijrr" | "mixture" | "authors_code"`.
    pub fn parse(name: &str) -> Result<Self> {
        match name {
            "ijrr" => Ok(Self::Ijrr),
            "mixture" => Ok(Self::Mixture),
            "authors_code" => Ok(Self::AuthorsCode),
            other => Err(config_err(
                "model",
                format!("unknown sensor model {other:?}; expected ijrr, mixture or authors_code"),
            )),
        }
    }

    /// Canonical name.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Ijrr => "ijrr",
            Self::Mixture => "mixture",
            Self::AuthorsCode => "authors_code",
        }
    }
}

/// Where, within a traversed cell, an on-ray cause may return the beam.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CauseKernel {
    /// At the chord midpoint d_l, with σ_hit widened by the quantisation term (crm-spec 2.1,
    /// 2.3; the default).
    Midpoint,
    /// Uniformly along the chord [t_in, t_out], convolved with N(0, σ²): the hit density is
    /// [Φ((z − t_in)/σ) − Φ((z − t_out)/σ)] / (t_out − t_in). Long grazing chords then spread
    /// their evidence over the whole chord instead of its midpoint (an option, not the spec).
    Chord,
}

impl CauseKernel {
    /// Parses `"midpoint" | "chord"`.
    pub fn parse(name: &str) -> Result<Self> {
        match name {
            "midpoint" => Ok(Self::Midpoint),
            "chord" => Ok(Self::Chord),
            other => Err(config_err(
                "cause_kernel",
                format!("unknown kernel {other:?}; expected midpoint or chord"),
            )),
        }
    }

    /// Canonical name.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Midpoint => "midpoint",
            Self::Chord => "chord",
        }
    }
}

/// Parameters of a range sensor model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SensorModel {
    pub kind: SensorModelKind,
    /// Placement of the cause inside a cell.
    pub kernel: CauseKernel,
    /// Maximum range (m); readings at or above it are no-returns.
    pub z_max: f64,
    /// Minimum valid range (m); shorter readings are dropped.
    pub z_min: f64,
    /// Hit standard deviation σ (m).
    pub sigma_hit: f64,
    pub w_hit: f64,
    pub w_short: f64,
    pub w_max: f64,
    pub w_rand: f64,
    /// Rate λ (1/m) of short readings.
    pub lambda_short: f64,
}

/// σ_hit = sqrt(σ_r² + Δ²/12): range noise plus the quantisation of the cause distance (2.3).
pub fn default_sigma_hit(sigma_range: f64, resolution: f64) -> f64 {
    (sigma_range * sigma_range + resolution * resolution / 12.0).sqrt()
}

impl SensorModel {
    /// The spec's defaults for `kind` at grid resolution `resolution` (σ_r = 0.01 m; the
    /// authors' code uses σ = 0.1·Δ).
    pub fn with_defaults(kind: SensorModelKind, z_max: f64, resolution: f64) -> Self {
        let (w_hit, w_short, w_max, w_rand) = match kind {
            SensorModelKind::Ijrr => (1.0, 0.0, 0.0, 0.0),
            _ => (0.7, 0.1, 0.1, 0.1),
        };
        let sigma_hit = match kind {
            SensorModelKind::AuthorsCode => 0.1 * resolution,
            _ => default_sigma_hit(0.01, resolution),
        };
        Self {
            kind,
            kernel: CauseKernel::Midpoint,
            z_max,
            z_min: 0.0,
            sigma_hit,
            w_hit,
            w_short,
            w_max,
            w_rand,
            lambda_short: 0.2,
        }
    }

    /// Checks every parameter.
    pub fn validate(&self) -> Result<()> {
        let pos = |v: f64| v.is_finite() && v > 0.0;
        if !pos(self.z_max) {
            return Err(config_err(
                "z_max",
                format!("must be finite and > 0, got {}", self.z_max),
            ));
        }
        if !(self.z_min.is_finite() && self.z_min >= 0.0 && self.z_min < self.z_max) {
            return Err(config_err(
                "z_min",
                format!("must be in [0, z_max), got {}", self.z_min),
            ));
        }
        if !pos(self.sigma_hit) {
            return Err(config_err(
                "sigma_hit",
                format!("must be finite and > 0, got {}", self.sigma_hit),
            ));
        }
        if !pos(self.lambda_short) {
            return Err(config_err(
                "lambda_short",
                format!("must be finite and > 0, got {}", self.lambda_short),
            ));
        }
        let ws = [self.w_hit, self.w_short, self.w_max, self.w_rand];
        if ws.iter().any(|w| !(w.is_finite() && *w >= 0.0)) {
            return Err(config_err(
                "weights",
                "mixture weights must be finite and >= 0",
            ));
        }
        let s: f64 = ws.iter().sum();
        if (s - 1.0).abs() > 1e-9 {
            return Err(config_err(
                "weights",
                format!("mixture weights must sum to 1, got {s}"),
            ));
        }
        if self.kind == SensorModelKind::Ijrr && self.w_hit != 1.0 {
            return Err(config_err(
                "weights",
                "the ijrr model is pure hit (w_hit = 1)",
            ));
        }
        Ok(())
    }

    /// True if the reading counts as a no-return (at or beyond z_max, or not finite).
    #[inline]
    pub fn is_no_return(&self, z: f64) -> bool {
        !(z.is_finite() && z < self.z_max)
    }

    /// log of the truncation normaliser Z_h(d) = Φ((z_max − d)/σ) − Φ(−d/σ).
    #[inline]
    fn log_trunc_norm(&self, d: f64) -> f64 {
        let s = self.sigma_hit;
        if d > TRUNC_SIGMAS * s && self.z_max - d > TRUNC_SIGMAS * s {
            return 0.0;
        }
        // Φ(x) is 1 and Φ(−x) is 0 exactly for x ≥ EXACT_TAIL_SIGMAS: no erfc call.
        let hi = if self.z_max - d >= EXACT_TAIL_SIGMAS * s {
            1.0
        } else {
            normal_cdf((self.z_max - d) / s)
        };
        let lo = if d >= EXACT_TAIL_SIGMAS * s {
            0.0
        } else {
            normal_cdf(-d / s)
        };
        (hi - lo).max(1e-300).ln()
    }

    /// log of the (truncated) hit density φ̃(z; d).
    #[inline]
    pub fn log_hit_density(&self, z: f64, d: f64) -> f64 {
        let u = (z - d) / self.sigma_hit;
        -0.5 * u * u - self.sigma_hit.ln() - LN_SQRT_2PI - self.log_trunc_norm(d)
    }

    /// Cause distances d with d > lo and z_max − d > TRUNC_SIGMAS σ, where the hit density's
    /// truncation normaliser is 1 in double precision and [`Self::hit_density`] is the plain
    /// Gaussian: (lo, hi) with lo < d < hi.
    pub(crate) fn untruncated_hit_range(&self) -> (f64, f64) {
        let edge = TRUNC_SIGMAS * self.sigma_hit;
        (edge, self.z_max - edge)
    }

    /// Hit density φ̃(z; d), 0 beyond [`GAUSS_CUTOFF_SIGMAS`].
    #[inline]
    pub fn hit_density(&self, z: f64, d: f64) -> f64 {
        let u = (z - d) / self.sigma_hit;
        if u.abs() > GAUSS_CUTOFF_SIGMAS {
            return 0.0;
        }
        let s = self.sigma_hit;
        let peak = (-0.5 * u * u).exp() / (s * SQRT_2PI);
        if d > TRUNC_SIGMAS * s && self.z_max - d > TRUNC_SIGMAS * s {
            peak
        } else {
            peak * (-self.log_trunc_norm(d)).exp()
        }
    }

    /// [`Self::hit_density`] with the Gaussian's exponential from
    /// [`crate::numeric::fastmath::exp_table`] (within 2 ulp of libm's; no call): for hot loops
    /// that agree with the full sweep to rounding, not bit for bit.
    #[inline]
    pub fn hit_density_fast(&self, z: f64, d: f64) -> f64 {
        let u = (z - d) / self.sigma_hit;
        if u.abs() > GAUSS_CUTOFF_SIGMAS {
            return 0.0;
        }
        let s = self.sigma_hit;
        let peak = crate::numeric::fastmath::exp_table(-0.5 * u * u) / (s * SQRT_2PI);
        if d > TRUNC_SIGMAS * s && self.z_max - d > TRUNC_SIGMAS * s {
            peak
        } else {
            peak * (-self.log_trunc_norm(d)).exp()
        }
    }

    /// Distance (m) from a reading beyond which the mixture's hit term w_h φ̃ is below 2^-60
    /// of its floor w_r/z_max, which bounds every L_l from below: hit terms of causes farther
    /// away cannot change η in double precision. Capped at the [`GAUSS_CUTOFF_SIGMAS`] cutoff,
    /// beyond which [`Self::hit_density`] is 0 anyway (and that cap when w_r = 0).
    pub fn negligible_hit_distance(&self) -> f64 {
        let tail_eps = 1.0 / (1u64 << 60) as f64;
        let floor = self.w_rand / self.z_max;
        // The truncation normaliser is at least 1/2, so φ̃ ≤ 2 φ_peak e^{−u²/2}.
        let peak2 = 2.0 / (self.sigma_hit * SQRT_2PI);
        let sigmas = if floor > 0.0 {
            let ratio = self.w_hit * peak2 / (tail_eps * floor);
            if ratio > 1.0 {
                (2.0 * ratio.ln()).sqrt()
            } else {
                0.0
            }
        } else {
            GAUSS_CUTOFF_SIGMAS
        };
        sigmas.min(GAUSS_CUTOFF_SIGMAS) * self.sigma_hit
    }

    /// Short-reading density ε(z; d) = λ e^{−λz} / (1 − e^{−λd}) on [0, d].
    #[inline]
    pub fn short_density(&self, z: f64, d: f64) -> f64 {
        if z > d || d <= 0.0 {
            return 0.0;
        }
        let l = self.lambda_short;
        l * (-l * z).exp() / -(-l * d).exp_m1()
    }

    /// L_l(z) for an on-ray cause at distance `d` (linear space).
    #[inline]
    pub fn on_ray(&self, z: f64, d: f64) -> f64 {
        if self.is_no_return(z) {
            return self.w_max;
        }
        match self.kind {
            SensorModelKind::Ijrr => self.hit_density(z, d),
            SensorModelKind::Mixture => {
                self.w_hit * self.hit_density(z, d)
                    + self.w_short * self.short_density(z, d)
                    + self.w_rand / self.z_max
            }
            SensorModelKind::AuthorsCode => self.authors_bsm(d, z),
        }
    }

    /// log L_l(z) for an on-ray cause at distance `d`.
    #[inline]
    pub fn log_on_ray(&self, z: f64, d: f64) -> f64 {
        match (self.kind, self.is_no_return(z)) {
            (SensorModelKind::Ijrr, false) => self.log_hit_density(z, d),
            (SensorModelKind::Ijrr, true) => f64::NEG_INFINITY,
            _ => self.on_ray(z, d).ln(),
        }
    }

    /// Hit density of a cause spread uniformly over the chord [a, b] ([`CauseKernel::Chord`]).
    #[inline]
    pub(crate) fn chord_hit_density(&self, z: f64, a: f64, b: f64) -> f64 {
        let s = self.sigma_hit;
        let (ua, ub) = ((z - a) / s, (z - b) / s);
        if ua < -GAUSS_CUTOFF_SIGMAS || ub > GAUSS_CUTOFF_SIGMAS {
            return 0.0;
        }
        // Φ(ua) − Φ(ub), from the tail that keeps precision.
        let mass = if ub > 0.0 {
            normal_cdf(-ub) - normal_cdf(-ua)
        } else {
            normal_cdf(ua) - normal_cdf(ub)
        };
        mass.max(0.0) / (b - a) * (-self.log_trunc_norm(0.5 * (a + b))).exp()
    }

    /// log of [`Self::chord_hit_density`], with the Mills-ratio tail where it underflows.
    #[inline]
    fn log_chord_hit_density(&self, z: f64, a: f64, b: f64) -> f64 {
        let lin = self.chord_hit_density(z, a, b);
        if lin > 1e-280 {
            return lin.ln();
        }
        let s = self.sigma_hit;
        // Distance (in σ) to the nearest chord end; Φ-difference ≈ φ(u)/u for large u.
        let u = if z > b { (z - b) / s } else { (a - z) / s };
        -0.5 * u * u
            - (u * (2.0 * std::f64::consts::PI).sqrt()).ln()
            - (b - a).ln()
            - self.log_trunc_norm(0.5 * (a + b))
    }

    /// L_l(z) for an on-ray cause occupying the chord [t_in, t_out] of its cell.
    #[inline]
    pub fn on_ray_cell(&self, z: f64, t_in: f64, t_out: f64) -> f64 {
        let d = 0.5 * (t_in + t_out);
        if self.kernel == CauseKernel::Midpoint
            || self.is_no_return(z)
            || self.kind == SensorModelKind::AuthorsCode
        {
            return self.on_ray(z, d);
        }
        let hit = self.chord_hit_density(z, t_in, t_out);
        match self.kind {
            SensorModelKind::Ijrr => hit,
            _ => {
                self.w_hit * hit
                    + self.w_short * self.short_density(z, d)
                    + self.w_rand / self.z_max
            }
        }
    }

    /// [`Self::on_ray_cell`] of every cell of a ray into `out`, bit for bit, with the terms that
    /// depend only on the reading (the short-reading numerator λe^{−λz} and w_rand/z_max)
    /// computed once per ray instead of once per cell.
    pub fn on_ray_cells(&self, z: f64, cells: &[RayCell], out: &mut Vec<f64>) {
        out.clear();
        match MixtureReading::new(self, z) {
            Some(r) if !r.is_no_return() => {
                out.extend(cells.iter().map(|c| r.cell(c.t_in, c.t_out)))
            }
            _ => out.extend(cells.iter().map(|c| self.on_ray_cell(z, c.t_in, c.t_out))),
        }
    }

    /// log L_l(z) for an on-ray cause occupying the chord [t_in, t_out].
    #[inline]
    pub fn log_on_ray_cell(&self, z: f64, t_in: f64, t_out: f64) -> f64 {
        let d = 0.5 * (t_in + t_out);
        match (self.kernel, self.kind, self.is_no_return(z)) {
            (CauseKernel::Chord, SensorModelKind::Ijrr, false) => {
                self.log_chord_hit_density(z, t_in, t_out)
            }
            (CauseKernel::Chord, SensorModelKind::Mixture, false) => {
                self.on_ray_cell(z, t_in, t_out).ln()
            }
            _ => self.log_on_ray(z, d),
        }
    }

    /// L_∞(z): likelihood of the reading if nothing lies within range.
    #[inline]
    pub fn infinity(&self, z: f64) -> f64 {
        if self.is_no_return(z) {
            return self.w_hit + self.w_max;
        }
        self.w_short * self.short_density(z, self.z_max) + self.w_rand / self.z_max
    }

    /// R1's `beamSensorModel(dist, z)` (crm-spec 2.3, 3.4): untruncated Gaussian, the short term
    /// on the side d ≤ z and unnormalised, p_max only when d equals z_max.
    #[inline]
    pub fn authors_bsm(&self, d: f64, z: f64) -> f64 {
        let s = self.sigma_hit;
        let u = (z - d) / s;
        let hit = if u.abs() > GAUSS_CUTOFF_SIGMAS {
            0.0
        } else {
            (-0.5 * u * u).exp() / (s * LN_SQRT_2PI.exp())
        };
        let short = if d <= z {
            self.lambda_short * (-self.lambda_short * d).exp()
        } else {
            0.0
        };
        let pmax = if d == self.z_max { 1.0 } else { 0.0 };
        self.w_hit * hit + self.w_short * short + self.w_max * pmax + self.w_rand / self.z_max
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn truncation_normaliser_skips_only_exact_tails() {
        // The plain formula, both Φ computed.
        let plain = |m: &SensorModel, d: f64| {
            let s = m.sigma_hit;
            (normal_cdf((m.z_max - d) / s) - normal_cdf(-d / s))
                .max(1e-300)
                .ln()
        };
        for sigma in [0.01, 0.03, 0.1, 0.2, 0.5] {
            let mut m = SensorModel::with_defaults(SensorModelKind::Mixture, 8.0, 0.1);
            m.sigma_hit = sigma;
            let s = sigma;
            for i in 0..=20_000 {
                let d = -1.0 + 10.0 * i as f64 / 20_000.0;
                assert_eq!(
                    m.log_trunc_norm(d).to_bits(),
                    plain(&m, d).to_bits(),
                    "sigma {sigma}, d {d}"
                );
            }
            // Around both thresholds, ulp by ulp.
            for base in [EXACT_TAIL_SIGMAS * s, 8.0 - EXACT_TAIL_SIGMAS * s] {
                let mut d = base;
                for _ in 0..64 {
                    d = d.next_down();
                }
                for _ in 0..128 {
                    assert_eq!(m.log_trunc_norm(d).to_bits(), plain(&m, d).to_bits());
                    d = d.next_up();
                }
            }
        }
        assert_eq!(normal_cdf(EXACT_TAIL_SIGMAS), 1.0);
        assert_eq!(normal_cdf(-EXACT_TAIL_SIGMAS), 0.0);
    }

    fn quad(f: impl Fn(f64) -> f64, a: f64, b: f64, n: usize) -> f64 {
        let h = (b - a) / n as f64;
        (0..n).map(|i| f(a + (i as f64 + 0.5) * h)).sum::<f64>() * h
    }

    #[test]
    fn ray_likelihoods_equal_the_per_cell_ones_bit_for_bit() {
        // Cells of 0.2 m along an 8 m ray, with a grazing chord and one cut short.
        let mut cells: Vec<RayCell> = (0..40)
            .map(|i| RayCell {
                ix: i,
                iy: 0,
                t_in: 0.2 * i as f64,
                t_out: 0.2 * (i + 1) as f64,
            })
            .collect();
        cells[7].t_out = cells[7].t_in + 0.013;
        cells[39].t_out = 7.95;
        let mut out = Vec::new();
        for kind in [
            SensorModelKind::Ijrr,
            SensorModelKind::Mixture,
            SensorModelKind::AuthorsCode,
        ] {
            for kernel in [CauseKernel::Midpoint, CauseKernel::Chord] {
                let mut m = SensorModel::with_defaults(kind, 8.0, 0.2);
                m.kernel = kernel;
                for z in [0.0, 0.05, 1.37, 4.0, 7.99, 8.0, f64::INFINITY] {
                    m.on_ray_cells(z, &cells, &mut out);
                    assert_eq!(out.len(), cells.len());
                    for (c, got) in cells.iter().zip(&out) {
                        let want = m.on_ray_cell(z, c.t_in, c.t_out);
                        assert_eq!(got.to_bits(), want.to_bits(), "{kind:?} {kernel:?} z={z}");
                    }
                }
            }
        }
    }

    #[test]
    fn models_are_proper_distributions() {
        for kind in [SensorModelKind::Ijrr, SensorModelKind::Mixture] {
            let m = SensorModel::with_defaults(kind, 8.0, 0.2);
            m.validate().unwrap();
            for d in [0.1, 0.05, 2.3, 7.95] {
                let mass = quad(|z| m.on_ray(z, d), 0.0, 8.0, 400_000) + m.on_ray(8.0, d);
                assert!((mass - 1.0).abs() < 1e-4, "{kind:?} d={d} mass={mass}");
            }
            let mass = quad(|z| m.infinity(z), 0.0, 8.0, 100_000) + m.infinity(8.0);
            assert!((mass - 1.0).abs() < 1e-6);
        }
    }

    #[test]
    fn chord_kernel_is_proper_and_spreads_over_the_chord() {
        let mut m = SensorModel::with_defaults(SensorModelKind::Ijrr, 8.0, 0.2);
        m.kernel = CauseKernel::Chord;
        m.sigma_hit = 0.01;
        for (a, b) in [(2.0, 2.2), (3.0, 3.28), (5.0, 5.001)] {
            let mass = quad(|z| m.on_ray_cell(z, a, b), 0.0, 8.0, 800_000);
            assert!((mass - 1.0).abs() < 1e-4, "chord [{a}, {b}] mass {mass}");
            // Flat inside the chord, unlike the midpoint Gaussian.
            if b - a > 0.1 {
                let (p1, p2) = (m.on_ray_cell(a + 0.04, a, b), m.on_ray_cell(b - 0.04, a, b));
                assert!((p1 - p2).abs() < 1e-3 * p1);
            }
        }
        // The log form agrees with the linear one, and keeps going where it underflows.
        assert!(
            (m.log_on_ray_cell(2.25, 2.0, 2.2) - m.on_ray_cell(2.25, 2.0, 2.2).ln()).abs() < 1e-9
        );
        let far = m.log_on_ray_cell(4.0, 2.0, 2.2);
        assert!(far.is_finite() && far < -1e4);
        assert!(CauseKernel::parse("edge").is_err());
    }

    #[test]
    fn log_and_linear_agree() {
        let m = SensorModel::with_defaults(SensorModelKind::Ijrr, 8.0, 0.2);
        for (z, d) in [(2.0, 2.1), (0.03, 0.1), (7.99, 7.9)] {
            let a = m.log_on_ray(z, d);
            let b = m.on_ray(z, d).ln();
            assert!((a - b).abs() < 1e-12);
        }
        assert_eq!(m.on_ray(8.0, 3.0), 0.0);
        assert_eq!(m.infinity(8.0), 1.0);
        assert_eq!(m.infinity(3.0), 0.0);
    }

    #[test]
    fn validation_rejects_bad_values() {
        let mut m = SensorModel::with_defaults(SensorModelKind::Mixture, 8.0, 0.2);
        m.w_rand = 0.5;
        assert!(m.validate().is_err());
        let mut m = SensorModel::with_defaults(SensorModelKind::Mixture, 8.0, 0.2);
        m.sigma_hit = f64::NAN;
        assert!(m.validate().is_err());
        assert!(SensorModelKind::parse("beam").is_err());
    }

    #[test]
    fn default_sigma_matches_spec() {
        assert!((default_sigma_hit(0.01, 0.2) - 0.0586).abs() < 1e-3);
    }
}
