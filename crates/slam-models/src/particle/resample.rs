//! O(N) resamplers (Douc, Cappé & Moulines 2005; PR table 4.4 for the low-variance one).
//!
//! Each draws N ancestor indices from normalised weights w and returns them in ascending
//! order, so that particle i is copied cᵢ times with E(cᵢ) = N·wᵢ for all four schemes.
//! All of them walk the cumulative weights once against N sorted points u₁ ≤ … ≤ u_N in
//! [0, 1): O(N) time, no sorting, no binary search.
//!
//! | scheme | sorted points | copy count cᵢ |
//! |---|---|---|
//! | multinomial | order statistics of N uniforms (by normalised exponential spacings) | Binomial(N, wᵢ) |
//! | stratified | uₖ = (k + Uₖ)/N, one uniform per stratum | within ⌊Nwᵢ⌋−1 … ⌈Nwᵢ⌉+1 |
//! | systematic | uₖ = (k + U)/N, one uniform for all (PR table 4.4) | within ⌊Nwᵢ⌋ … ⌈Nwᵢ⌉ |
//! | residual | ⌊Nwᵢ⌋ copies, then systematic on the residuals frac(Nwᵢ) | within ⌊Nwᵢ⌋ … ⌊Nwᵢ⌋+1 |
//!
//! The residual stage uses systematic rather than multinomial sampling (Liu & Chen 1998
//! allow either), which keeps its variance lower and its copy counts bounded.

use crate::error::ModelError;
use rand::Rng;
use serde::{Deserialize, Serialize};

/// Which resampling scheme to use. Systematic is the default: lowest variance of the four
/// and the one GMapping and PR table 4.4 use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Resampler {
    /// Independent draws (the textbook baseline; highest variance).
    Multinomial,
    /// One uniform draw per stratum [k/N, (k+1)/N).
    Stratified,
    /// One uniform draw shifted through all strata ("low-variance sampler").
    #[default]
    Systematic,
    /// Deterministic integer parts, then systematic on the remainders.
    Residual,
}

impl Resampler {
    /// Draws `weights.len()` ancestor indices (ascending). Weights need not be normalised
    /// but must be finite, non-negative and not all zero.
    pub fn resample<R: Rng + ?Sized>(
        &self,
        weights: &[f64],
        rng: &mut R,
    ) -> Result<Vec<usize>, ModelError> {
        let mut out = Vec::with_capacity(weights.len());
        self.resample_into(weights, weights.len(), rng, &mut out)?;
        Ok(out)
    }

    /// Draws `n` ancestor indices (ascending) into `out` (cleared first).
    pub fn resample_into<R: Rng + ?Sized>(
        &self,
        weights: &[f64],
        n: usize,
        rng: &mut R,
        out: &mut Vec<usize>,
    ) -> Result<(), ModelError> {
        out.clear();
        if weights.is_empty() {
            return Err(ModelError::EmptyWeights);
        }
        if weights.iter().any(|w| !w.is_finite() || *w < 0.0) {
            return Err(ModelError::InvalidWeights {
                reason: "a weight is negative or not finite",
            });
        }
        let total: f64 = weights.iter().sum();
        if total <= 0.0 || !total.is_finite() {
            return Err(ModelError::InvalidWeights {
                reason: "weights sum to zero",
            });
        }
        if n == 0 {
            return Ok(());
        }
        let nf = n as f64;
        match self {
            Resampler::Multinomial => {
                // Sorted uniforms: uₖ = Sₖ / S_{n+1}, Sₖ partial sums of Exp(1) draws.
                let mut spacings = Vec::with_capacity(n + 1);
                let mut s = 0.0;
                for _ in 0..=n {
                    let e = crate::sampling::exponential1(rng);
                    s += e;
                    spacings.push(s);
                }
                let total_s = spacings[n];
                walk(weights, total, n, |k| spacings[k] / total_s, out);
            }
            Resampler::Stratified => {
                let us: Vec<f64> = (0..n)
                    .map(|k| (k as f64 + rng.random::<f64>()) / nf)
                    .collect();
                walk(weights, total, n, |k| us[k], out);
            }
            Resampler::Systematic => {
                let u0: f64 = rng.random::<f64>();
                walk(weights, total, n, |k| (k as f64 + u0) / nf, out);
            }
            Resampler::Residual => {
                let mut residual = Vec::with_capacity(weights.len());
                let mut deterministic = 0usize;
                for (i, &w) in weights.iter().enumerate() {
                    let expected = nf * w / total;
                    let copies = (expected.floor() as usize).min(n - deterministic);
                    out.extend(std::iter::repeat_n(i, copies));
                    deterministic += copies;
                    residual.push((expected - expected.floor()).max(0.0));
                }
                let rest = n - deterministic;
                let rtotal: f64 = residual.iter().sum();
                if rest > 0 && rtotal > 0.0 {
                    let u0: f64 = rng.random::<f64>();
                    let mut extra = Vec::with_capacity(rest);
                    walk(
                        &residual,
                        rtotal,
                        rest,
                        |k| (k as f64 + u0) / rest as f64,
                        &mut extra,
                    );
                    merge_sorted(out, &extra);
                } else if rest > 0 {
                    // Rounding left no residual mass: give the remaining copies to the heaviest.
                    let best = argmax(weights);
                    out.extend(std::iter::repeat_n(best, rest));
                    out.sort_unstable();
                }
            }
        }
        Ok(())
    }
}

/// Walks the cumulative weights against the sorted points `u(0..n)` in [0, 1).
fn walk(weights: &[f64], total: f64, n: usize, u: impl Fn(usize) -> f64, out: &mut Vec<usize>) {
    let last = weights.len() - 1;
    let mut i = 0;
    let mut cum = weights[0] / total;
    for k in 0..n {
        let uk = u(k);
        while uk >= cum && i < last {
            i += 1;
            cum += weights[i] / total;
        }
        out.push(i);
    }
}

fn argmax(w: &[f64]) -> usize {
    let mut best = 0;
    for (i, &x) in w.iter().enumerate() {
        if x > w[best] {
            best = i;
        }
    }
    best
}

/// Merges sorted `extra` into sorted `out`.
fn merge_sorted(out: &mut Vec<usize>, extra: &[usize]) {
    let a = std::mem::take(out);
    out.reserve(a.len() + extra.len());
    let (mut i, mut j) = (0, 0);
    while i < a.len() || j < extra.len() {
        if j >= extra.len() || (i < a.len() && a[i] <= extra[j]) {
            out.push(a[i]);
            i += 1;
        } else {
            out.push(extra[j]);
            j += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_pcg::Pcg64Mcg;

    const ALL: [Resampler; 4] = [
        Resampler::Multinomial,
        Resampler::Stratified,
        Resampler::Systematic,
        Resampler::Residual,
    ];

    fn counts(idx: &[usize], m: usize) -> Vec<usize> {
        let mut c = vec![0; m];
        for &i in idx {
            c[i] += 1;
        }
        c
    }

    fn test_weights() -> Vec<f64> {
        // Uneven weights with some zeros, not summing to one.
        vec![0.5, 0.0, 3.0, 0.25, 1.7, 0.0, 0.05, 2.2, 0.9, 1.4]
    }

    #[test]
    fn expected_counts_are_n_w() {
        let w = test_weights();
        let total: f64 = w.iter().sum();
        let n = w.len();
        let trials = 20_000;
        for r in ALL {
            let mut rng = Pcg64Mcg::seed_from_u64(7);
            let mut sum = vec![0.0; n];
            for _ in 0..trials {
                let idx = r.resample(&w, &mut rng).unwrap();
                assert_eq!(idx.len(), n);
                assert!(idx.windows(2).all(|p| p[0] <= p[1]), "{r:?} not sorted");
                for (s, c) in sum.iter_mut().zip(counts(&idx, n)) {
                    *s += c as f64;
                }
            }
            for i in 0..n {
                let p = w[i] / total;
                let expect = n as f64 * p;
                // Multinomial variance N·p(1−p) bounds all four schemes; 5 standard errors.
                let se = (n as f64 * p * (1.0 - p) / trials as f64).sqrt();
                let mean = sum[i] / trials as f64;
                assert!(
                    (mean - expect).abs() <= 5.0 * se + 1e-12,
                    "{r:?} particle {i}: {mean} vs {expect}"
                );
            }
        }
    }

    #[test]
    fn systematic_and_residual_counts_are_bounded() {
        let w = test_weights();
        let total: f64 = w.iter().sum();
        let n = w.len();
        let mut rng = Pcg64Mcg::seed_from_u64(11);
        for _ in 0..5_000 {
            for r in [Resampler::Systematic, Resampler::Residual] {
                let c = counts(&r.resample(&w, &mut rng).unwrap(), n);
                for i in 0..n {
                    let e = n as f64 * w[i] / total;
                    let lo = e.floor() as usize;
                    let hi = if r == Resampler::Residual {
                        e.floor() as usize + 1
                    } else {
                        e.ceil() as usize
                    };
                    assert!(
                        c[i] >= lo && c[i] <= hi,
                        "{r:?}: particle {i} copied {} times, N·w = {e}",
                        c[i]
                    );
                }
            }
        }
    }

    #[test]
    fn zero_weight_never_survives_and_bad_input_errors() {
        let w = test_weights();
        let mut rng = Pcg64Mcg::seed_from_u64(3);
        for r in ALL {
            for _ in 0..1000 {
                let idx = r.resample(&w, &mut rng).unwrap();
                assert!(!idx.contains(&1) && !idx.contains(&5));
            }
            assert!(r.resample(&[], &mut rng).is_err());
            assert!(r.resample(&[0.0, 0.0], &mut rng).is_err());
            assert!(r.resample(&[1.0, f64::NAN], &mut rng).is_err());
            assert!(r.resample(&[1.0, -0.1], &mut rng).is_err());
        }
    }
}
