//! KLD-sampling's particle bound (Fox 2003, eq. 12; PR table 8.4 line 14) and its histogram
//! bins.

use crate::config::KldConfig;
use slam_models::Pose2;

/// The number of particles KLD-sampling requires when they occupy `k` bins:
/// n = (k − 1)/(2ε) · (1 − 2/(9(k − 1)) + √(2/(9(k − 1))) · z)³ (the Wilson–Hilferty
/// approximation of the χ² quantile with k − 1 degrees of freedom, halved over ε);
/// 1 for k ≤ 1.
pub fn kld_bound(k: usize, epsilon: f64, z: f64) -> f64 {
    if k <= 1 {
        return 1.0;
    }
    let km1 = (k - 1) as f64;
    let a = 2.0 / (9.0 * km1);
    let t = 1.0 - a + a.sqrt() * z;
    km1 / (2.0 * epsilon) * t * t * t
}

/// The histogram bin of a pose: (⌊x / bin_xy⌋, ⌊y / bin_xy⌋, ⌊(θ + π) / bin_θ⌋ mod n_θ),
/// n_θ = ⌈2π / bin_θ⌉ (headings wrap: the last bin neighbours the first).
#[inline]
pub fn bin_of(p: &Pose2, config: &KldConfig) -> (i32, i32, i32) {
    (
        (p.x / config.bin_xy).floor() as i32,
        (p.y / config.bin_xy).floor() as i32,
        ((p.theta + std::f64::consts::PI) / config.bin_theta).floor() as i32 % theta_bins(config),
    )
}

/// n_θ = ⌈2π / bin_θ⌉, the number of heading bins.
#[inline]
pub fn theta_bins(config: &KldConfig) -> i32 {
    (std::f64::consts::TAU / config.bin_theta)
        .ceil()
        .clamp(1.0, 1e6) as i32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bound_matches_fox_2003_figures() {
        // Independent check: the exact χ² quantile χ²_{k−1, 1−δ}/(2ε). For k − 1 = 99,
        // δ = 0.01 the 0.99 quantile is 134.642 (tables; scipy.stats.chi2.ppf(0.99, 99)),
        // so n ≈ 134.642 / (2·0.05) = 1346.4; Wilson–Hilferty is within 0.1 %.
        let n = kld_bound(100, 0.05, 2.326_347_874);
        assert!((n - 1346.42).abs() / 1346.42 < 1e-3, "{n}");
        // k − 1 = 9: χ²_{9, 0.99} = 21.666 → 216.66 (Wilson–Hilferty within 0.5 %).
        let n = kld_bound(10, 0.05, 2.326_347_874);
        assert!((n - 216.66).abs() / 216.66 < 5e-3, "{n}");
        assert_eq!(kld_bound(1, 0.05, 2.33), 1.0);
        // More bins, more particles.
        assert!(kld_bound(1000, 0.05, 2.33) > kld_bound(100, 0.05, 2.33));
    }
}
