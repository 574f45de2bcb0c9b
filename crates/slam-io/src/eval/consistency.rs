//! Filter consistency: NEES, NIS and chi-square bands (Bar-Shalom, Li & Kirubarajan,
//! *Estimation with Applications to Tracking and Navigation*, 2001, §5.4). The chi-square
//! quantiles and bands live in `slam_models::chi2` and are re-exported here.

pub use slam_models::chi2::{chi2_band, chi2_quantile, regularized_gamma_p};
use slam_models::gaussian::mahalanobis_squared;
use slam_models::{normalize_angle, Matrix2, Matrix3, Pose2, Vector2, Vector3};

/// Normalised estimation error squared of a pose: ε = eᵀP⁻¹e with
/// e = (x − x*, y − y*, normalize(θ − θ*)). For a consistent filter ε ~ χ²(3).
/// Returns NaN when `cov` is not symmetric positive definite or a value is not finite.
pub fn nees_pose(est: &Pose2, cov: &Matrix3, truth: &Pose2) -> f64 {
    let e = Vector3::new(
        est.x - truth.x,
        est.y - truth.y,
        normalize_angle(est.theta - truth.theta),
    );
    mahalanobis_squared(&e, cov).unwrap_or(f64::NAN)
}

/// Normalised innovation squared of a range-bearing innovation ν (bearing already
/// normalised) with covariance S: νᵀS⁻¹ν ~ χ²(2) when consistent. NaN when S is not
/// positive definite.
pub fn nis(innovation: &Vector2, s: &Matrix2) -> f64 {
    mahalanobis_squared(innovation, s).unwrap_or(f64::NAN)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nees_hand_computed() {
        // e = (1, −2, 0.1 via wrap-around), P = diag(1, 4, 0.01): ε = 1 + 1 + 1 = 3.
        let est = Pose2::new(1.0, -2.0, std::f64::consts::PI - 0.05);
        let truth = Pose2::new(0.0, 0.0, -std::f64::consts::PI + 0.05);
        let p = Matrix3::from_diagonal(&Vector3::new(1.0, 4.0, 0.01));
        assert!((nees_pose(&est, &p, &truth) - 3.0).abs() < 1e-9);
        assert!(nees_pose(&est, &Matrix3::zeros(), &truth).is_nan());
        let s = Matrix2::new(2.0, 0.0, 0.0, 0.5);
        assert!((nis(&Vector2::new(2.0, 1.0), &s) - 4.0).abs() < 1e-12);
    }
}
