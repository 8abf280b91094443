//! The mixture's hit density for the localizer's likelihood with its truncation normaliser
//! Z(d) = Φ((z_max − d)/σ) − Φ(−d/σ) read from a table of Φ instead of two erfc calls.
//!
//! Z differs from 1 only for causes within 8.3 σ of the sensor or of z_max, but while a set is
//! spread the localizer anneals σ up to decimetres (`sigma_max`), and then most causes of an
//! indoor scan lie there: two erfc calls, a logarithm and an exponential per cause were about
//! half of a global localization's time. Φ on [0, 8.3] (σ-free: Z = Φ(a) + Φ(b) − 1 with
//! a = (z_max − d)/σ, b = d/σ) is tabulated once at spacing 2^-11 and interpolated linearly:
//! |Φ''| = |x φ(x)| ≤ φ(1) < 0.25, so the error is at most h²/8 · 0.25 < 7.5e-9, and Z ≥ 1/2
//! wherever z_max ≥ 16.6 σ (one of a and b is then at least 8.3), so the hit term is within a
//! relative [`HIT_TABLE_ERROR`] of the computed one, and so is η (the hit term is a part of it):
//! each beam's log η moves by less than that. The localizer uses the table when its tail
//! tolerance is at least that (the default 1e-6; `crm-exact`'s 2^-60 computes Z).

use std::sync::OnceLock;

use crate::numeric::normal_cdf;
use crate::sensor::{SensorModel, GAUSS_CUTOFF_SIGMAS, SQRT_2PI, TRUNC_SIGMAS};

/// Spacing of the table (in σ).
const STEP: f64 = 1.0 / 2048.0;

/// Bound of the relative error of a hit term, and so of each beam's log η, from the table
/// (3e-8 from the interpolation where Z ≥ 1/2, with margin).
pub const HIT_TABLE_ERROR: f64 = 1e-7;

/// Φ(k · STEP) for k = 0 ..= TRUNC_SIGMAS / STEP (+1).
fn table() -> &'static [f64] {
    static TABLE: OnceLock<Vec<f64>> = OnceLock::new();
    TABLE.get_or_init(|| {
        let n = (TRUNC_SIGMAS / STEP).ceil() as usize + 2;
        (0..n).map(|k| normal_cdf(k as f64 * STEP)).collect()
    })
}

/// Φ(x) from the table (1 beyond it: 1 − Φ(8.3) < 1e-16), by symmetry below 0.
#[inline]
fn phi(x: f64) -> f64 {
    let (ax, neg) = if x < 0.0 { (-x, true) } else { (x, false) };
    let t = table();
    let u = ax / STEP;
    let v = if u < (t.len() - 1) as f64 {
        let k = u as usize;
        let f = u - k as f64;
        t[k] + f * (t[k + 1] - t[k])
    } else {
        1.0
    };
    if neg {
        1.0 - v
    } else {
        v
    }
}

/// The hit density φ̃(z; d) of `model` ([`SensorModel::hit_density_fast`]) with the truncation
/// normaliser from the table of Φ: within a relative [`HIT_TABLE_ERROR`] of it where
/// z_max ≥ 16.6 σ.
#[inline]
pub fn hit_density_table(model: &SensorModel, z: f64, d: f64) -> f64 {
    let s = model.sigma_hit;
    let u = (z - d) / s;
    if u.abs() > GAUSS_CUTOFF_SIGMAS {
        return 0.0;
    }
    let peak = crate::numeric::fastmath::exp_table(-0.5 * u * u) / (s * SQRT_2PI);
    if d > TRUNC_SIGMAS * s && model.z_max - d > TRUNC_SIGMAS * s {
        peak
    } else {
        let z_norm = phi((model.z_max - d) / s) + phi(d / s) - 1.0;
        peak / z_norm.max(1e-300)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sensor::SensorModelKind;

    /// Φ from the table against the computed one on a fine grid over [−9, 9] (every table
    /// interval, midpoints included): within 7.5e-9.
    #[test]
    fn the_table_of_phi_is_within_its_bound() {
        let mut worst = 0.0f64;
        for i in -9 * 8192..=9 * 8192 {
            let x = i as f64 / 8192.0 + 1.3e-5;
            worst = worst.max((phi(x) - normal_cdf(x)).abs());
        }
        assert!(worst < 7.5e-9, "{worst}");
    }

    /// The hit density against the computed one where the normaliser matters (causes near the
    /// sensor and near z_max, σ from millimetres to decimetres): within HIT_TABLE_ERROR.
    #[test]
    fn hit_density_within_the_stated_error() {
        for sigma in [0.003, 0.0176, 0.05, 0.2, 0.5] {
            let mut m = SensorModel::with_defaults(SensorModelKind::Mixture, 12.0, 0.03);
            m.sigma_hit = sigma;
            for i in 0..4000 {
                let d = 12.0 * (i as f64 + 0.37) / 4000.0;
                for dz in [-3.0, -1.0, -0.2, 0.0, 0.5, 2.0] {
                    let z = (d + dz * sigma).clamp(0.0, 11.999);
                    let want = m.hit_density_fast(z, d);
                    let got = hit_density_table(&m, z, d);
                    assert!(
                        (got - want).abs() <= HIT_TABLE_ERROR * want + 1e-300,
                        "σ {sigma} d {d} z {z}: {got} vs {want}"
                    );
                }
            }
        }
    }
}
