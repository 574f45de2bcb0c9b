//! Particle weights kept in log space.
//!
//! Importance weights are products of many likelihoods and leave the range of `f64` after a
//! few dozen updates, so filters store ln wᵢ and normalise with log-sum-exp:
//! ln Σ exp(ℓᵢ) = m + ln Σ exp(ℓᵢ − m), m = max ℓᵢ.

use crate::detmath;
use crate::error::ModelError;

/// ln Σᵢ exp(ℓᵢ), computed stably. Returns −∞ for an empty slice or all −∞ inputs.
pub fn log_sum_exp(log_w: &[f64]) -> f64 {
    let m = log_w.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if m == f64::NEG_INFINITY {
        return m;
    }
    if m == f64::INFINITY {
        return m;
    }
    m + detmath::ln(log_w.iter().map(|&l| detmath::exp(l - m)).sum::<f64>())
}

/// Normalises log weights in place so that Σ exp(ℓᵢ) = 1, and returns the log normaliser
/// ln Σ exp(ℓᵢ) that was subtracted (the log marginal likelihood increment).
///
/// Errors on an empty slice, a NaN or +∞ weight, or when every weight is −∞ (no particle
/// explains the data).
pub fn normalize_log_weights(log_w: &mut [f64]) -> Result<f64, ModelError> {
    if log_w.is_empty() {
        return Err(ModelError::EmptyWeights);
    }
    if log_w.iter().any(|l| l.is_nan() || *l == f64::INFINITY) {
        return Err(ModelError::InvalidWeights {
            reason: "a log weight is NaN or +inf",
        });
    }
    let z = log_sum_exp(log_w);
    if z == f64::NEG_INFINITY {
        return Err(ModelError::InvalidWeights {
            reason: "every weight is zero",
        });
    }
    for l in log_w.iter_mut() {
        *l -= z;
    }
    Ok(z)
}

/// Effective sample size N_eff = 1 / Σ w̃ᵢ² of weights w (normalised here, so any positive
/// scale is accepted). Uniform weights give N; a single non-zero weight gives 1.
/// (Liu 1996; Grisetti et al. 2007 eq. 20.)
pub fn effective_sample_size(w: &[f64]) -> f64 {
    let s: f64 = w.iter().sum();
    if s <= 0.0 || !s.is_finite() {
        return 0.0;
    }
    1.0 / w.iter().map(|x| (x / s) * (x / s)).sum::<f64>()
}

/// N_eff from log weights (need not be normalised).
pub fn effective_sample_size_log(log_w: &[f64]) -> f64 {
    let z = log_sum_exp(log_w);
    if !z.is_finite() {
        return 0.0;
    }
    1.0 / log_w
        .iter()
        .map(|l| detmath::exp(2.0 * (l - z)))
        .sum::<f64>()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uniform_neff_is_n() {
        for n in [1usize, 7, 1000] {
            assert!((effective_sample_size(&vec![0.3; n]) - n as f64).abs() < 1e-9 * n as f64);
            assert!(
                (effective_sample_size_log(&vec![-1234.5; n]) - n as f64).abs() < 1e-9 * n as f64
            );
        }
        assert!((effective_sample_size(&[0.0, 5.0, 0.0]) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn log_sum_exp_is_stable() {
        // exp(−1000) underflows, the log-sum-exp does not: ln(2·e^−1000) = −1000 + ln 2.
        assert!((log_sum_exp(&[-1000.0, -1000.0]) - (-1000.0 + 2.0f64.ln())).abs() < 1e-12);
        assert!((log_sum_exp(&[1000.0, 0.0]) - 1000.0).abs() < 1e-12);
        let mut l = vec![-2000.0, -2001.0, -2002.0];
        normalize_log_weights(&mut l).unwrap();
        let s: f64 = l.iter().map(|x| x.exp()).sum();
        assert!((s - 1.0).abs() < 1e-12);
    }

    #[test]
    fn bad_weights_are_errors() {
        assert!(normalize_log_weights(&mut []).is_err());
        assert!(normalize_log_weights(&mut [f64::NEG_INFINITY; 3]).is_err());
        assert!(normalize_log_weights(&mut [0.0, f64::NAN]).is_err());
    }
}
