//! The single-beam CRM update on one ray (crm-spec 3.1, 4.2), independent of map storage.
//!
//! Inputs are the expected occupancies m̂_l of the traversed cells (ordered by distance) and the
//! cause likelihoods L_l, L_∞ of the reading. The backward sweep gives S_l, the likelihood of the
//! reading given that the beam reaches cell l; η = S_1 is the predictive likelihood (the RBPF
//! per-beam weight) and α_l = R_l (L_l − S_{l+1}) / η the per-cell update coefficient: every
//! traversed cell's pmf is multiplied by the self-normalising factor 1 + α_l (μ_k − m̂_l).

/// η below this is treated as underflowed in the linear sweep and recomputed in log space.
pub const LINEAR_ETA_MIN: f64 = 1e-250;

/// log(e^a + e^b), exact for infinite arguments.
#[inline]
pub fn log_add_exp(a: f64, b: f64) -> f64 {
    let (hi, lo) = if a > b { (a, b) } else { (b, a) };
    if hi == f64::NEG_INFINITY {
        return f64::NEG_INFINITY;
    }
    if hi == f64::INFINITY {
        return f64::INFINITY;
    }
    hi + (lo - hi).exp().ln_1p()
}

/// (sign, log|e^a − e^b|): a stable "logdiffexp".
#[inline]
pub fn log_diff_exp(a: f64, b: f64) -> (f64, f64) {
    if a == b {
        return (0.0, f64::NEG_INFINITY);
    }
    let (sign, hi, lo) = if a > b { (1.0, a, b) } else { (-1.0, b, a) };
    if lo == f64::NEG_INFINITY {
        return (sign, hi);
    }
    (sign, hi + (-(-(hi - lo)).exp_m1()).ln())
}

/// Linear-space sweep. Fills `alpha` (length N) when given and returns η. `s_next` is scratch.
/// If η < [`LINEAR_ETA_MIN`] the α are not reliable; use [`cause_sweep_log`].
pub fn cause_sweep(
    mhat: &[f64],
    like: &[f64],
    like_inf: f64,
    s_next: &mut Vec<f64>,
    alpha: Option<&mut [f64]>,
) -> f64 {
    let n = mhat.len();
    s_next.clear();
    s_next.resize(n, 0.0);
    let mut s = like_inf;
    for l in (0..n).rev() {
        s_next[l] = s;
        s = mhat[l] * like[l] + (1.0 - mhat[l]) * s;
    }
    let eta = s;
    if let Some(alpha) = alpha {
        if eta > 0.0 && eta.is_finite() {
            let inv = 1.0 / eta;
            let mut reach = 1.0;
            for l in 0..n {
                alpha[l] = reach * (like[l] - s_next[l]) * inv;
                reach *= 1.0 - mhat[l];
            }
        } else {
            alpha[..n].fill(0.0);
        }
    }
    eta
}

/// Log-space sweep for the case where far Gaussians underflow (crm-spec 4.2). Inputs are
/// log L_l and log L_∞; fills `alpha` when given and returns log η (−∞ when no cause explains the
/// reading, in which case α = 0).
pub fn cause_sweep_log(
    mhat: &[f64],
    log_like: &[f64],
    log_like_inf: f64,
    log_s_next: &mut Vec<f64>,
    alpha: Option<&mut [f64]>,
) -> f64 {
    let n = mhat.len();
    log_s_next.clear();
    log_s_next.resize(n, 0.0);
    let mut ls = log_like_inf;
    for l in (0..n).rev() {
        log_s_next[l] = ls;
        ls = log_add_exp(mhat[l].ln() + log_like[l], (-mhat[l]).ln_1p() + ls);
    }
    let log_eta = ls;
    if let Some(alpha) = alpha {
        if log_eta.is_finite() {
            let mut log_reach = 0.0;
            for l in 0..n {
                let (sign, ld) = log_diff_exp(log_like[l], log_s_next[l]);
                alpha[l] = sign * (log_reach + ld - log_eta).exp();
                log_reach += (-mhat[l]).ln_1p();
            }
        } else {
            alpha[..n].fill(0.0);
        }
    }
    log_eta
}

/// Multiplies `p` (f64, length K) by 1 + α(μ_k − m̂), clipping factors at 0, renormalises and
/// applies the floor. Returns false (leaving `p` unchanged) if the result has no mass.
#[inline]
pub fn apply_factor(p: &mut [f64], mu: &[f64], alpha: f64, mhat: f64, floor: f64) -> bool {
    let mut sum = 0.0;
    let mut tmp = [0.0f64; 65];
    let k = p.len();
    for i in 0..k {
        let f = (1.0 + alpha * (mu[i] - mhat)).max(0.0);
        tmp[i] = p[i] * f;
        sum += tmp[i];
    }
    if !(sum > 0.0 && sum.is_finite()) {
        return false;
    }
    p.copy_from_slice(&tmp[..k]);
    normalize_with_floor(p, sum, floor);
    true
}

/// p ← max(p/sum, floor), then renormalised. `sum` is Σp.
#[inline]
pub fn normalize_with_floor(p: &mut [f64], sum: f64, floor: f64) {
    let inv = 1.0 / sum;
    if floor > 0.0 {
        let mut s2 = 0.0;
        for x in p.iter_mut() {
            *x = (*x * inv).max(floor);
            s2 += *x;
        }
        let inv2 = 1.0 / s2;
        for x in p.iter_mut() {
            *x *= inv2;
        }
    } else {
        for x in p.iter_mut() {
            *x *= inv;
        }
    }
}

/// Mean of a normalised pmf.
#[inline]
pub fn mean(mu: &[f64], p: &[f64]) -> f64 {
    mu.iter().zip(p).map(|(a, b)| a * b).sum()
}

/// Updates the beliefs of one ray in place from given cause likelihoods: `beliefs` is N×K
/// row-major (normalised pmfs), `like` the N on-ray likelihoods, `like_inf` the ∞ cause.
/// Returns η. Used by tests and by callers with their own likelihoods; the map update goes
/// through the same functions.
pub fn update_ray(beliefs: &mut [f64], mu: &[f64], like: &[f64], like_inf: f64, floor: f64) -> f64 {
    let k = mu.len();
    let n = like.len();
    let mhat: Vec<f64> = (0..n)
        .map(|l| mean(mu, &beliefs[l * k..(l + 1) * k]))
        .collect();
    let mut alpha = vec![0.0; n];
    let mut s = Vec::new();
    let mut eta = cause_sweep(&mhat, like, like_inf, &mut s, Some(&mut alpha));
    if eta.is_nan() || eta < LINEAR_ETA_MIN {
        let ll: Vec<f64> = like.iter().map(|x| x.ln()).collect();
        let le = cause_sweep_log(&mhat, &ll, like_inf.ln(), &mut s, Some(&mut alpha));
        eta = le.exp();
        if !le.is_finite() {
            return eta;
        }
    }
    for l in 0..n {
        apply_factor(
            &mut beliefs[l * k..(l + 1) * k],
            mu,
            alpha[l],
            mhat[l],
            floor,
        );
    }
    eta
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn log_helpers() {
        assert!((log_add_exp(0.0, 0.0) - 2f64.ln()).abs() < 1e-15);
        assert_eq!(log_add_exp(f64::NEG_INFINITY, 1.5), 1.5);
        let (s, v) = log_diff_exp(1.0, 0.0);
        assert_eq!(s, 1.0);
        assert!((v - (1f64.exp() - 1.0).ln()).abs() < 1e-14);
        let (s, v) = log_diff_exp(0.0, 1.0);
        assert_eq!(s, -1.0);
        assert!((v - (1f64.exp() - 1.0).ln()).abs() < 1e-14);
    }

    #[test]
    fn log_and_linear_sweeps_agree() {
        let mhat = [0.5, 0.3, 0.8, 0.1, 0.6];
        let like = [0.01, 0.3, 2.0, 0.4, 1e-3];
        let (mut a1, mut a2) = ([0.0; 5], [0.0; 5]);
        let mut s = Vec::new();
        let eta = cause_sweep(&mhat, &like, 0.05, &mut s, Some(&mut a1));
        let ll: Vec<f64> = like.iter().map(|x| x.ln()).collect();
        let le = cause_sweep_log(&mhat, &ll, 0.05f64.ln(), &mut s, Some(&mut a2));
        assert!((le.exp() - eta).abs() < 1e-12 * eta);
        for i in 0..5 {
            assert!((a1[i] - a2[i]).abs() < 1e-12 * (1.0 + a1[i].abs()));
        }
    }
}
