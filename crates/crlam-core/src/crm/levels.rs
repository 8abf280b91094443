//! Occupancy levels μ_k and priors of a cell belief (crm-spec 1.3).

use crate::error::{config_err, Result};

/// Where the K occupancy levels sit in [0, 1].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LevelPlacement {
    /// μ_k = (k − ½)/K, k = 1..K: the uniform prior has mean exactly 0.5 (default).
    Midpoints,
    /// K + 1 levels at 0, 1/K, …, 1 (Agha's convention; needs the belief floor).
    Endpoints,
    /// μ_k = k/K, k = 1..K: the right endpoints used by the authors' MATLAB (parity only).
    R1Right,
}

impl LevelPlacement {
    /// Parses `"midpoints" | "endpoints" | "r1_right"`.
    pub fn parse(name: &str) -> Result<Self> {
        match name {
            "midpoints" => Ok(Self::Midpoints),
            "endpoints" => Ok(Self::Endpoints),
            "r1_right" => Ok(Self::R1Right),
            other => Err(config_err(
                "levels",
                format!(
                    "unknown level placement {other:?}; expected midpoints, endpoints or r1_right"
                ),
            )),
        }
    }

    /// Canonical name.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Midpoints => "midpoints",
            Self::Endpoints => "endpoints",
            Self::R1Right => "r1_right",
        }
    }
}

/// Level values for `n_levels` bins (the stored pmf has `values(..).len()` entries).
pub fn level_values(n_levels: usize, placement: LevelPlacement) -> Result<Vec<f64>> {
    if !(2..=64).contains(&n_levels) {
        return Err(config_err(
            "n_levels",
            format!("must be in 2..=64, got {n_levels}"),
        ));
    }
    let k = n_levels as f64;
    Ok(match placement {
        LevelPlacement::Midpoints => (0..n_levels).map(|i| (i as f64 + 0.5) / k).collect(),
        LevelPlacement::Endpoints => (0..=n_levels).map(|i| i as f64 / k).collect(),
        LevelPlacement::R1Right => (1..=n_levels).map(|i| i as f64 / k).collect(),
    })
}

/// The uniform pmf over `n` levels.
pub fn uniform_prior(n: usize) -> Vec<f64> {
    vec![1.0 / n as f64; n]
}

fn tilted(mu: &[f64], theta: f64) -> Vec<f64> {
    // Shift by the max exponent so exp never overflows for |θ| up to 500.
    let m = mu
        .iter()
        .map(|&x| theta * x)
        .fold(f64::NEG_INFINITY, f64::max);
    let w: Vec<f64> = mu.iter().map(|&x| (theta * x - m).exp()).collect();
    let s: f64 = w.iter().sum();
    w.into_iter().map(|x| x / s).collect()
}

fn pmf_mean(mu: &[f64], p: &[f64]) -> f64 {
    mu.iter().zip(p).map(|(a, b)| a * b).sum()
}

/// The tilted pmf p_k ∝ exp(θ μ_k) whose mean is `mean` (bisection on θ ∈ [−500, 500]).
/// The mean must lie strictly between the smallest and largest level.
pub fn tilted_prior(mu: &[f64], mean: f64) -> Result<Vec<f64>> {
    let (lo_mu, hi_mu) = (mu[0], mu[mu.len() - 1]);
    if !(mean.is_finite() && mean > lo_mu && mean < hi_mu) {
        return Err(config_err(
            "prior_mean",
            format!("must lie strictly inside ({lo_mu}, {hi_mu}) for these levels, got {mean}"),
        ));
    }
    let (mut lo, mut hi) = (-500.0f64, 500.0f64);
    if pmf_mean(mu, &tilted(mu, lo)) > mean || pmf_mean(mu, &tilted(mu, hi)) < mean {
        return Err(config_err(
            "prior_mean",
            format!("{mean} is not reachable with a tilt in [-500, 500]"),
        ));
    }
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if pmf_mean(mu, &tilted(mu, mid)) < mean {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Ok(tilted(mu, 0.5 * (lo + hi)))
}

/// Mean, variance and entropy (bits) of a pmf whose entries may not sum exactly to 1 (f32
/// storage); the pmf is normalised on the fly.
#[inline]
pub fn moments(mu: &[f64], p: &[f32]) -> (f64, f64, f64) {
    let (mut s, mut m1, mut m2) = (0.0f64, 0.0f64, 0.0f64);
    for (&x, &q) in mu.iter().zip(p) {
        let q = q as f64;
        s += q;
        m1 += x * q;
        m2 += x * x * q;
    }
    let mean = m1 / s;
    let var = (m2 / s - mean * mean).max(0.0);
    let mut h = 0.0;
    for &q in p {
        let q = q as f64 / s;
        if q > 0.0 {
            h -= q * q.log2();
        }
    }
    (mean, var, h)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn placements() {
        let m = level_values(10, LevelPlacement::Midpoints).unwrap();
        assert_eq!(m.len(), 10);
        assert!((m[0] - 0.05).abs() < 1e-15 && (m[9] - 0.95).abs() < 1e-15);
        assert_eq!(
            level_values(10, LevelPlacement::Endpoints).unwrap().len(),
            11
        );
        let r = level_values(10, LevelPlacement::R1Right).unwrap();
        assert!((r[0] - 0.1).abs() < 1e-15 && (r[9] - 1.0).abs() < 1e-15);
        assert!(level_values(1, LevelPlacement::Midpoints).is_err());
    }

    #[test]
    fn uniform_prior_has_mean_half_and_log2k_entropy() {
        let mu = level_values(10, LevelPlacement::Midpoints).unwrap();
        let p: Vec<f32> = uniform_prior(10).iter().map(|&x| x as f32).collect();
        let (m, _, h) = moments(&mu, &p);
        assert!((m - 0.5).abs() < 1e-7);
        assert!((h - 10f64.log2()).abs() < 1e-6);
    }

    #[test]
    fn tilted_prior_reaches_means_a_linear_pmf_cannot() {
        let mu = level_values(10, LevelPlacement::Midpoints).unwrap();
        for target in [0.3, 0.85, 0.5, 0.06] {
            let p = tilted_prior(&mu, target).unwrap();
            assert!((p.iter().sum::<f64>() - 1.0).abs() < 1e-12);
            assert!((pmf_mean(&mu, &p) - target).abs() < 1e-9, "{target}");
        }
        assert!(tilted_prior(&mu, 0.97).is_err());
    }
}
