//! Importance weights and resampling.

/// Normalised weights exp(log w − LSE) of log-weights; uniform if every log-weight is −∞ or NaN.
pub fn normalize_log_weights(log_w: &[f64]) -> Vec<f64> {
    let m = log_w
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .fold(f64::NEG_INFINITY, f64::max);
    if !m.is_finite() {
        return vec![1.0 / log_w.len() as f64; log_w.len()];
    }
    let w: Vec<f64> = log_w
        .iter()
        .map(|&l| if l.is_finite() { (l - m).exp() } else { 0.0 })
        .collect();
    let s: f64 = w.iter().sum();
    w.into_iter().map(|x| x / s).collect()
}

/// Effective sample size 1 / Σ w̄², in [1, n] for normalised weights.
pub fn effective_sample_size(w: &[f64]) -> f64 {
    1.0 / w.iter().map(|x| x * x).sum::<f64>()
}

/// Systematic (low-variance) resampling: indices of the parents of `n` children, using one
/// uniform `u0 ∈ [0, 1)`. With equal weights every particle is kept exactly once.
pub fn systematic_resample(w: &[f64], u0: f64) -> Vec<usize> {
    let n = w.len();
    let mut out = Vec::with_capacity(n);
    let step = 1.0 / n as f64;
    let mut c = w[0];
    let mut i = 0;
    for k in 0..n {
        let target = (u0 + k as f64) * step;
        while target >= c && i + 1 < n {
            i += 1;
            c += w[i];
        }
        out.push(i);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weights_and_neff() {
        let w = normalize_log_weights(&[-1000.0, -1000.0 + 2f64.ln(), f64::NEG_INFINITY]);
        assert!(
            (w[0] - 1.0 / 3.0).abs() < 1e-12 && (w[1] - 2.0 / 3.0).abs() < 1e-12 && w[2] == 0.0
        );
        assert!((effective_sample_size(&[0.25; 4]) - 4.0).abs() < 1e-12);
        assert!((effective_sample_size(&[1.0, 0.0]) - 1.0).abs() < 1e-12);
        assert_eq!(
            normalize_log_weights(&[f64::NAN, f64::NEG_INFINITY]),
            vec![0.5, 0.5]
        );
    }

    #[test]
    fn systematic_resampling_invariants() {
        for u0 in [0.0, 0.3, 0.999] {
            assert_eq!(systematic_resample(&[0.25; 4], u0), vec![0, 1, 2, 3]);
        }
        let idx = systematic_resample(&[0.0, 1.0, 0.0], 0.5);
        assert_eq!(idx, vec![1, 1, 1]);
        // Each particle i is copied floor(n w_i) or ceil(n w_i) times.
        let w = [0.1, 0.45, 0.05, 0.4];
        let idx = systematic_resample(&w, 0.77);
        for (i, wi) in w.iter().enumerate() {
            let c = idx.iter().filter(|&&j| j == i).count() as f64;
            assert!(c >= (4.0 * wi).floor() && c <= (4.0 * wi).ceil());
        }
    }
}
