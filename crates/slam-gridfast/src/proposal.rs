//! The three proposal distributions: how one particle draws its pose at a processed scan
//! and by how much its weight changes.

use crate::matcher::{coarse_score, hill_climb, score, HillClimb, Likelihood, PreparedScan};
use nalgebra::Cholesky;
use rand::Rng;
use slam_grid::DistanceField;
use slam_models::motion::{MotionModel, OdometryModel};
use slam_models::{normalize_angle, Matrix3, OdometryControl, Pose2, Vector3};

/// What is the same for every particle in one step.
pub(crate) struct StepContext<'a> {
    pub scan: &'a PreparedScan,
    pub lk: Likelihood,
    pub hc: HillClimb,
    /// The odometry increment since the last processed scan.
    pub u: OdometryControl,
    pub motion: OdometryModel,
    /// Variances (m², m², rad²) added to the motion covariance.
    pub min_var: Vector3,
    /// Minimum number of inliers for a match to count as successful.
    pub min_inliers: usize,
    /// Offsets (dx, dy, dθ) of the K samples around the mode (improved proposal).
    pub offsets: &'a [[f64; 3]],
    /// The correction x̂_best ⊖ x'_best that the shared coarse search found for the best
    /// particle (identity when the search is off).
    pub correction: Pose2,
}

/// A particle's new pose, its log-weight increment, and whether matching failed.
pub(crate) struct Drawn {
    pub pose: Pose2,
    pub log_weight: f64,
    pub match_failed: bool,
}

/// Sample the motion model and weight by the scan likelihood (FastSLAM 1.0 on grids).
pub(crate) fn motion_and_likelihood<R: Rng + ?Sized>(
    pose: &Pose2,
    field: &DistanceField<'_>,
    ctx: &StepContext<'_>,
    motion: &OdometryModel,
    u: &OdometryControl,
    rng: &mut R,
) -> Drawn {
    let x = motion.sample(pose, u, rng);
    Drawn {
        pose: x,
        log_weight: score(field, ctx.scan, &x, &ctx.lk).log_likelihood,
        match_failed: false,
    }
}

/// The improved proposal (Grisetti, Stachniss & Burgard, T-RO 2007, Table I):
///
/// 1. x̂ = argmax p(z | m, x) by hill climbing from x' = xₜ₋₁ ⊕ uₜ (or from x' ⊕ c, with
///    c the correction a coarse exhaustive search found for the best particle, when that
///    fits this particle's map better);
/// 2. K samples xⱼ on a grid around x̂; τⱼ = p(z | m, xⱼ)·p(xⱼ | xₜ₋₁, uₜ) with the motion
///    density the Gaussian N(x', R) of the linearised odometry model (R = V·M·Vᵀ, PR
///    table 5.6, plus a floor);
/// 3. η = Σ τⱼ, μ = Σ xⱼτⱼ/η, Σ = Σ (xⱼ − μ)(xⱼ − μ)ᵀτⱼ/η (eqs. 14–16);
/// 4. xₜ ~ N(μ, Σ) (sampled, as published), and ln wₜ = ln wₜ₋₁ + ln η (eq. 18).
///
/// When the match has too few inliers (empty or unrelated map) the particle falls back to
/// [`motion_and_likelihood`] and the failure is reported.
pub(crate) fn improved<R: Rng + ?Sized>(
    pose: &Pose2,
    field: &DistanceField<'_>,
    ctx: &StepContext<'_>,
    rng: &mut R,
) -> Drawn {
    let predicted = ctx.motion.predict(pose, &ctx.u);
    // Start from the prediction or from the prediction moved by the best particle's coarse
    // correction, whichever fits this particle's map better.
    let shifted = predicted.compose(&ctx.correction);
    let start = if ctx.correction != Pose2::IDENTITY
        && coarse_score(field, ctx.scan, &shifted, &ctx.lk)
            > coarse_score(field, ctx.scan, &predicted, &ctx.lk)
    {
        shifted
    } else {
        predicted
    };
    let m = hill_climb(field, ctx.scan, &start, &ctx.lk, &ctx.hc);
    let covariance =
        ctx.motion.noise_covariance(pose, &ctx.u) + Matrix3::from_diagonal(&ctx.min_var);
    let chol = Cholesky::new((covariance + covariance.transpose()) * 0.5);
    let (Some(chol), true) = (chol, m.score.inliers >= ctx.min_inliers) else {
        let mut d = motion_and_likelihood(pose, field, ctx, &ctx.motion, &ctx.u, rng);
        d.match_failed = true;
        return d;
    };
    let log_det = 2.0 * (0..3).map(|i| chol.l_dirty()[(i, i)].ln()).sum::<f64>();
    let mut log_tau = [0.0f64; 729];
    let k = ctx.offsets.len();
    for (j, o) in ctx.offsets.iter().enumerate() {
        let xj = Pose2::new(m.pose.x + o[0], m.pose.y + o[1], m.pose.theta + o[2]);
        let l = score(field, ctx.scan, &xj, &ctx.lk).log_likelihood;
        let e = Vector3::new(
            xj.x - predicted.x,
            xj.y - predicted.y,
            normalize_angle(xj.theta - predicted.theta),
        );
        let mahal = e.dot(&chol.solve(&e));
        log_tau[j] = l - 0.5 * (mahal + log_det);
    }
    let log_tau = &log_tau[..k];
    let top = log_tau.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let mut eta = 0.0;
    let mut mean = Vector3::zeros();
    for (t, o) in log_tau.iter().zip(ctx.offsets) {
        let w = (t - top).exp();
        eta += w;
        mean += Vector3::new(o[0], o[1], o[2]) * w;
    }
    mean /= eta;
    let mut sigma = Matrix3::zeros();
    for (t, o) in log_tau.iter().zip(ctx.offsets) {
        let w = (t - top).exp() / eta;
        let d = Vector3::new(o[0], o[1], o[2]) - mean;
        sigma += d * d.transpose() * w;
    }
    // A tiny floor keeps Σ positive definite when one sample carries all the mass.
    sigma += Matrix3::from_diagonal(&Vector3::new(1e-8, 1e-8, 1e-9));
    let offset = match Cholesky::new((sigma + sigma.transpose()) * 0.5) {
        Some(c) => {
            let z = Vector3::new(
                rng.sample(rand_distr::StandardNormal),
                rng.sample(rand_distr::StandardNormal),
                rng.sample(rand_distr::StandardNormal),
            );
            mean + c.l() * z
        }
        None => mean,
    };
    Drawn {
        pose: Pose2::new(
            m.pose.x + offset[0],
            m.pose.y + offset[1],
            m.pose.theta + offset[2],
        ),
        log_weight: top + eta.ln(),
        match_failed: false,
    }
}

/// The K = n³ sample offsets of the improved proposal: a regular grid spanning
/// ±`range_xy` in x and y and ±`range_theta` in θ (GMapping's `llsamplerange` /
/// `lasamplerange`).
pub(crate) fn sample_offsets(n: usize, range_xy: f64, range_theta: f64) -> Vec<[f64; 3]> {
    let axis = |r: f64| -> Vec<f64> {
        if n == 1 {
            vec![0.0]
        } else {
            (0..n)
                .map(|i| -r + 2.0 * r * i as f64 / (n - 1) as f64)
                .collect()
        }
    };
    let (xy, th) = (axis(range_xy), axis(range_theta));
    let mut out = Vec::with_capacity(n * n * n);
    for &dx in &xy {
        for &dy in &xy {
            for &dt in &th {
                out.push([dx, dy, dt]);
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn offsets_are_a_symmetric_grid() {
        let o = sample_offsets(3, 0.01, 0.005);
        assert_eq!(o.len(), 27);
        let s: [f64; 3] = o
            .iter()
            .fold([0.0; 3], |a, b| [a[0] + b[0], a[1] + b[1], a[2] + b[2]]);
        assert!(s.iter().all(|v| v.abs() < 1e-12));
        assert!(o.contains(&[-0.01, 0.01, 0.005]));
        assert_eq!(sample_offsets(1, 0.01, 0.005), vec![[0.0, 0.0, 0.0]]);
    }
}
