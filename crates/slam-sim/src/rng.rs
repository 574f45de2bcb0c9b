//! Seeded random streams.
//!
//! Every random quantity of a simulation comes from one user seed. Independent parts of a
//! simulation (world generation, motion noise, sensor noise, clutter, …) draw from their own
//! stream, derived from the seed and a fixed tag, so that switching clutter on does not change
//! the motion noise of the same seed, and the output never depends on evaluation order across
//! parts.

use rand::Rng;
use rand_pcg::Pcg64Mcg;
use slam_models::detmath;

/// Stream tags (fixed forever: changing one changes every simulated dataset).
pub(crate) mod tag {
    /// World generation (landmark placement, room layout, random walk of the route).
    pub const WORLD: u64 = 1;
    /// Motion noise.
    pub const MOTION: u64 = 2;
    /// Sensor noise and detection draws.
    pub const SENSOR: u64 = 3;
    /// Clutter (false alarms).
    pub const CLUTTER: u64 = 4;
    /// Path generation through free space (replay).
    pub const PATH: u64 = 5;
}

/// The stream `tag` of `seed` ([`slam_models::rng::tagged_stream`]).
pub(crate) fn stream(seed: u64, tag: u64) -> Pcg64Mcg {
    slam_models::rng::tagged_stream(seed, tag)
}

/// A Poisson(λ) draw by Knuth's product-of-uniforms method (exact; uses only uniforms,
/// multiplications and [`detmath::exp`], so it is bit-reproducible everywhere). Meant for the
/// small rates of clutter (λ ≲ 30); larger λ is split into halves recursively to avoid
/// underflow of e^(−λ).
pub(crate) fn poisson<R: Rng + ?Sized>(lambda: f64, rng: &mut R) -> usize {
    if lambda <= 0.0 || !lambda.is_finite() {
        return 0;
    }
    if lambda > 30.0 {
        return poisson(lambda * 0.5, rng) + poisson(lambda * 0.5, rng);
    }
    let limit = detmath::exp(-lambda);
    let mut k = 0usize;
    let mut p: f64 = rng.random();
    while p > limit {
        k += 1;
        p *= rng.random::<f64>();
    }
    k
}

/// A standard normal draw ([`slam_models::sampling::standard_normal`], bit-reproducible).
#[inline]
pub(crate) fn normal<R: Rng + ?Sized>(rng: &mut R) -> f64 {
    slam_models::sampling::standard_normal(rng)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn streams_differ_by_tag_and_seed() {
        let a: u64 = stream(1, tag::MOTION).random();
        let b: u64 = stream(1, tag::SENSOR).random();
        let c: u64 = stream(2, tag::MOTION).random();
        let a2: u64 = stream(1, tag::MOTION).random();
        assert_eq!(a, a2);
        assert_ne!(a, b);
        assert_ne!(a, c);
    }

    #[test]
    fn poisson_mean_and_variance() {
        // Mean and variance of Poisson(λ) are both λ; standard error of the sample mean is
        // √(λ/n), of the sample variance ≈ √((λ + 2λ²)/n) (fourth cumulant λ).
        let mut rng = stream(9, 99);
        for lambda in [0.3, 2.5, 45.0] {
            let n = 40_000;
            let xs: Vec<f64> = (0..n).map(|_| poisson(lambda, &mut rng) as f64).collect();
            let mean = xs.iter().sum::<f64>() / n as f64;
            let var = xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
            let se_mean = (lambda / n as f64).sqrt();
            let se_var = ((lambda + 2.0 * lambda * lambda) / n as f64).sqrt();
            assert!(
                (mean - lambda).abs() < 5.0 * se_mean,
                "λ={lambda} mean={mean}"
            );
            assert!((var - lambda).abs() < 5.0 * se_var, "λ={lambda} var={var}");
        }
    }
}
