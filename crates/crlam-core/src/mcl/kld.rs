//! KLD sampling (Fox 2003): how many particles a resampled set needs so that, with probability
//! 1 − δ, the Kullback-Leibler divergence between its histogram and the true posterior's stays
//! below ε, given k occupied histogram bins.
//!
//!   n(k) = (k − 1) / (2ε) · (1 − 2/(9(k − 1)) + sqrt(2/(9(k − 1))) · z_{1−δ})³
//!
//! (the Wilson-Hilferty approximation of the χ² quantile with k − 1 degrees of freedom). The
//! bins are boxes of the pose space: `bin_xy` metres by `bin_theta` radians, as AMCL's.

use std::collections::HashSet;

use crate::error::{config_err, Result};
use crate::pose::Pose;

/// Settings of the adaptive particle count.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KldSettings {
    /// Fewest particles after resampling (and the count of a converged filter).
    pub n_min: usize,
    /// Most particles (and the count of a global initialisation).
    pub n_max: usize,
    /// ε: the bound on the KL divergence (AMCL's `kld_err`, default 0.01).
    pub epsilon: f64,
    /// z_{1−δ}: the upper standard normal quantile for the confidence 1 − δ (2.326 for δ = 0.01).
    pub z: f64,
    /// Histogram bin size in position (m).
    pub bin_xy: f64,
    /// Histogram bin size in heading (rad).
    pub bin_theta: f64,
}

impl Default for KldSettings {
    /// AMCL's defaults (100..5000 particles, ε = 0.01, 0.5 m × 10° bins) with Fox's z for δ = 0.01.
    fn default() -> Self {
        Self {
            n_min: 100,
            n_max: 5000,
            epsilon: 0.01,
            z: 2.326_347_874_040_840_8,
            bin_xy: 0.5,
            bin_theta: 10f64.to_radians(),
        }
    }
}

impl KldSettings {
    pub fn validate(&self) -> Result<()> {
        if !(1 <= self.n_min && self.n_min <= self.n_max) {
            return Err(config_err(
                "particles",
                format!("need 1 <= min ({}) <= max ({})", self.n_min, self.n_max),
            ));
        }
        // The particle limit in force (`crate::limits`), before any set is allocated.
        crate::limits::check_particles("the localizer's max_particles", self.n_max)?;
        if !(self.epsilon.is_finite() && self.epsilon > 0.0) {
            return Err(config_err(
                "kld_err",
                format!("must be > 0, got {}", self.epsilon),
            ));
        }
        if !(self.z.is_finite() && self.z >= 0.0) {
            return Err(config_err("kld_z", format!("must be >= 0, got {}", self.z)));
        }
        let pos = |v: f64| v.is_finite() && v > 0.0;
        if !(pos(self.bin_xy) && pos(self.bin_theta)) {
            return Err(config_err("kld_bins", "bin sizes must be finite and > 0"));
        }
        Ok(())
    }

    /// The sample count for `k` occupied bins, within [n_min, n_max].
    pub fn limit(&self, k: usize) -> usize {
        let n = kld_sample_count(k, self.epsilon, self.z);
        if n.is_finite() {
            (n.ceil() as usize).clamp(self.n_min, self.n_max)
        } else {
            self.n_max
        }
    }

    /// The histogram bin of a pose.
    #[inline]
    pub fn bin_of(&self, p: &Pose) -> (i64, i64, i64) {
        (
            (p[0] / self.bin_xy).floor() as i64,
            (p[1] / self.bin_xy).floor() as i64,
            (p[2] / self.bin_theta).floor() as i64,
        )
    }
}

/// Fox's bound n(k) (unclamped; 0 for k ≤ 1).
pub fn kld_sample_count(k: usize, epsilon: f64, z: f64) -> f64 {
    if k <= 1 {
        return 0.0;
    }
    let km1 = (k - 1) as f64;
    let a = 2.0 / (9.0 * km1);
    let x = 1.0 - a + a.sqrt() * z;
    km1 / (2.0 * epsilon) * x * x * x
}

/// The occupied bins of a growing sample set.
#[derive(Clone, Debug, Default)]
pub struct BinCounter {
    bins: HashSet<(i64, i64, i64)>,
}

impl BinCounter {
    /// Adds a pose; returns the number of occupied bins.
    pub fn add(&mut self, kld: &KldSettings, p: &Pose) -> usize {
        self.bins.insert(kld.bin_of(p));
        self.bins.len()
    }

    pub fn len(&self) -> usize {
        self.bins.len()
    }

    pub fn is_empty(&self) -> bool {
        self.bins.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bound_matches_fox_2003() {
        // Fox 2003, Eq. 13, computed by hand: k = 2, ε = 0.05, z = 2.326 (δ = 0.01).
        let n = kld_sample_count(2, 0.05, 2.326);
        let x: f64 = 1.0 - 2.0 / 9.0 + (2.0f64 / 9.0).sqrt() * 2.326;
        assert!((n - 10.0 * x.powi(3)).abs() < 1e-12);
        // Grows about linearly with k, and with 1/ε.
        let a = kld_sample_count(100, 0.01, 2.326);
        let b = kld_sample_count(200, 0.01, 2.326);
        assert!(b > 1.7 * a && b < 2.0 * a, "{a} {b}");
        assert!(
            (kld_sample_count(50, 0.005, 2.0) / kld_sample_count(50, 0.01, 2.0) - 2.0).abs()
                < 1e-12
        );
        assert_eq!(kld_sample_count(1, 0.01, 2.326), 0.0);
    }

    #[test]
    fn limit_is_clamped_to_the_bounds() {
        let s = KldSettings {
            n_min: 300,
            n_max: 2000,
            ..KldSettings::default()
        };
        assert_eq!(s.limit(1), 300);
        assert_eq!(
            s.limit(2),
            kld_sample_count(2, s.epsilon, s.z).ceil() as usize
        );
        assert_eq!(s.limit(2), 330);
        assert_eq!(s.limit(10_000), 2000);
        for k in 1..500 {
            let n = s.limit(k);
            assert!((300..=2000).contains(&n));
            assert!(n >= s.limit(k.saturating_sub(1).max(1)));
        }
    }

    #[test]
    fn settings_are_checked() {
        let ok = KldSettings::default();
        assert!(ok.validate().is_ok());
        assert!(KldSettings { n_min: 0, ..ok }.validate().is_err());
        assert!(KldSettings {
            n_min: 10,
            n_max: 5,
            ..ok
        }
        .validate()
        .is_err());
        assert!(KldSettings { epsilon: 0.0, ..ok }.validate().is_err());
        assert!(KldSettings {
            bin_theta: f64::NAN,
            ..ok
        }
        .validate()
        .is_err());
    }

    #[test]
    fn bins_count_distinct_boxes() {
        let s = KldSettings::default();
        let mut c = BinCounter::default();
        assert_eq!(c.add(&s, &[0.1, 0.1, 0.0]), 1);
        assert_eq!(c.add(&s, &[0.2, 0.4, 0.1]), 1);
        assert_eq!(c.add(&s, &[0.6, 0.4, 0.1]), 2);
        assert_eq!(c.add(&s, &[0.6, 0.4, -0.1]), 3);
    }
}
