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

/// A single run's pose NEES over its steps, summarised so that a few steps where the
/// filter collapsed cannot dominate (as they dominate the mean).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NeesSummary {
    /// Steps summarised (including those whose NEES is not finite).
    pub steps: usize,
    /// The two-sided 95 % band of one χ²(3) draw, [χ²⁻¹(0.025), χ²⁻¹(0.975)] =
    /// [0.216, 9.348].
    pub band: (f64, f64),
    /// Fraction of steps whose NEES lies inside `band`: ≈ 0.95 for a consistent filter;
    /// a non-finite NEES (covariance not positive definite) counts as outside.
    pub in_band_fraction: f64,
    /// Median NEES over all steps, a non-finite one ranked above every finite value
    /// (≈ χ²⁻¹(0.5; 3) = 2.366 for a consistent filter); NaN when that rank is the median.
    pub median: f64,
    /// Mean over the finite values (≈ 3 for a consistent filter); NaN when none is finite.
    pub mean: f64,
}

/// Summarises a run's per-step pose NEES values (3 dof): the fraction of steps inside the
/// 95 % χ² band, the median and the mean. `None` for an empty slice.
pub fn nees_summary(nees: &[f64]) -> Option<NeesSummary> {
    if nees.is_empty() {
        return None;
    }
    let band = chi2_band(3, 1, 0.95);
    let inside = nees.iter().filter(|&&e| e >= band.0 && e <= band.1).count();
    let mut ranked: Vec<f64> = nees
        .iter()
        .map(|&e| if e.is_finite() { e } else { f64::INFINITY })
        .collect();
    ranked.sort_by(f64::total_cmp);
    let n = ranked.len();
    let median = if n % 2 == 1 {
        ranked[n / 2]
    } else {
        0.5 * (ranked[n / 2 - 1] + ranked[n / 2])
    };
    let finite: Vec<f64> = nees.iter().copied().filter(|e| e.is_finite()).collect();
    let mean = if finite.is_empty() {
        f64::NAN
    } else {
        finite.iter().sum::<f64>() / finite.len() as f64
    };
    Some(NeesSummary {
        steps: n,
        band,
        in_band_fraction: inside as f64 / n as f64,
        median: if median.is_finite() { median } else { f64::NAN },
        mean,
    })
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

    /// Against hand-made values, and against χ²(3) draws (the sum of three squared
    /// standard normals from a seeded generator): about 95 % inside the band, median near
    /// χ²⁻¹(0.5; 3) = 2.366, mean near 3.
    #[test]
    fn nees_summary_by_hand_and_on_chi2_draws() {
        assert!(nees_summary(&[]).is_none());
        let s = nees_summary(&[0.1, 1.0, 2.0, 50.0, f64::NAN]).unwrap();
        assert_eq!(s.steps, 5);
        assert!((s.band.0 - 0.2158).abs() < 1e-4 && (s.band.1 - 9.3484).abs() < 1e-4);
        assert_eq!(s.in_band_fraction, 0.4);
        assert_eq!(s.median, 2.0);
        assert!((s.mean - 53.1 / 4.0).abs() < 1e-12);
        let s = nees_summary(&[1.0, f64::INFINITY, f64::NAN]).unwrap();
        assert!(s.median.is_nan());
        assert_eq!(s.mean, 1.0);
        use rand::SeedableRng;
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(5);
        let draws: Vec<f64> = (0..20_000)
            .map(|_| {
                (0..3)
                    .map(|_| slam_models::sampling::standard_normal(&mut rng).powi(2))
                    .sum()
            })
            .collect();
        let s = nees_summary(&draws).unwrap();
        assert!((s.in_band_fraction - 0.95).abs() < 0.006, "{s:?}");
        assert!((s.median - 2.366).abs() < 0.06, "{s:?}");
        assert!((s.mean - 3.0).abs() < 0.06, "{s:?}");
    }

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
