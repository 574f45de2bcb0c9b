//! Gaussian densities of innovations, evaluated safely through a Cholesky factor.
//!
//! For an innovation ν ∈ ℝᴰ with covariance S (the measurement likelihood of PR table 10.2,
//! and the importance factor of FastSLAM, PR eq. 13.19):
//!
//! ```text
//! ln N(ν; 0, S) = −½·(νᵀS⁻¹ν + ln det S + D·ln 2π)
//! ```
//!
//! With S = LLᵀ: νᵀS⁻¹ν = ‖L⁻¹ν‖² and ln det S = 2·Σ ln Lᵢᵢ, so nothing is inverted
//! explicitly and nothing under- or overflows for tiny or huge S.

use crate::detmath;
use crate::error::ModelError;
use nalgebra::{SMatrix, SVector};

/// ln(2π).
const LN_2PI: f64 = 1.837_877_066_409_345_5;

/// Squared Mahalanobis distance νᵀS⁻¹ν and ln det S. S is symmetrised first; it must be
/// positive definite.
pub fn mahalanobis_and_log_det<const D: usize>(
    nu: &SVector<f64, D>,
    s: &SMatrix<f64, D, D>,
) -> Result<(f64, f64), ModelError> {
    if nu.iter().chain(s.iter()).any(|v| !v.is_finite()) {
        return Err(ModelError::NonFinite {
            what: "innovation or its covariance",
            value: f64::NAN,
        });
    }
    let sym = (s + s.transpose()) * 0.5;
    let chol = nalgebra::Cholesky::new(sym).ok_or(ModelError::NotPositiveDefinite {
        what: "innovation covariance S",
    })?;
    let l = chol.l_dirty();
    let y = l
        .solve_lower_triangular(nu)
        .ok_or(ModelError::NotPositiveDefinite {
            what: "innovation covariance S",
        })?;
    let log_det = 2.0 * (0..D).map(|i| detmath::ln(l[(i, i)])).sum::<f64>();
    Ok((y.norm_squared(), log_det))
}

/// Squared Mahalanobis distance νᵀS⁻¹ν (compare with a chi-square quantile with D degrees
/// of freedom for gating).
pub fn mahalanobis_squared<const D: usize>(
    nu: &SVector<f64, D>,
    s: &SMatrix<f64, D, D>,
) -> Result<f64, ModelError> {
    mahalanobis_and_log_det(nu, s).map(|(d2, _)| d2)
}

/// ln N(ν; 0, S) = −½(νᵀS⁻¹ν + ln det S + D ln 2π).
pub fn log_likelihood<const D: usize>(
    nu: &SVector<f64, D>,
    s: &SMatrix<f64, D, D>,
) -> Result<f64, ModelError> {
    let (d2, log_det) = mahalanobis_and_log_det(nu, s)?;
    Ok(-0.5 * (d2 + log_det + D as f64 * LN_2PI))
}

/// Upper 95 % quantiles of the chi-square distribution for 1..=10 degrees of freedom, for
/// gating and consistency bands.
pub const CHI2_95: [f64; 10] = [
    3.841459, 5.991465, 7.814728, 9.487729, 11.070498, 12.591587, 14.067140, 15.507313, 16.918978,
    18.307038,
];

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix2, Vector2};

    #[test]
    fn matches_closed_form() {
        // Diagonal S: ln N = −½(ν₁²/a + ν₂²/b + ln(ab) + 2 ln 2π).
        let (a, b) = (0.04f64, 2.5f64);
        let nu = Vector2::new(0.3, -1.1);
        let s = Matrix2::new(a, 0.0, 0.0, b);
        let expect =
            -0.5 * (0.09 / a + 1.21 / b + (a * b).ln() + 2.0 * (2.0 * std::f64::consts::PI).ln());
        assert!((log_likelihood(&nu, &s).unwrap() - expect).abs() < 1e-12);
    }

    #[test]
    fn tiny_covariance_does_not_underflow() {
        let s = Matrix2::identity() * 1e-300;
        let l = log_likelihood(&Vector2::new(1e-150, 0.0), &s).unwrap();
        assert!(l.is_finite());
    }

    #[test]
    fn rejects_indefinite_and_nan() {
        let s = Matrix2::new(1.0, 2.0, 2.0, 1.0);
        assert!(matches!(
            log_likelihood(&Vector2::new(0.0, 0.0), &s),
            Err(ModelError::NotPositiveDefinite { .. })
        ));
        assert!(log_likelihood(&Vector2::new(f64::NAN, 0.0), &Matrix2::identity()).is_err());
    }
}
