//! The three proposal distributions: how one particle draws its pose at a processed scan
//! and by how much its weight changes.

use nalgebra::Cholesky;
use rand::Rng;
use slam_grid::matcher::endpoint::{
    coarse_score, grid_search, hill_climb, score, score_scan, wide_search, EndpointModel,
    HillClimbSteps, SearchWindow,
};
use slam_grid::DistanceField;
use slam_grid::PreparedScan;
use slam_models::motion::{MotionModel, OdometryModel};
use slam_models::{normalize_angle, Matrix3, OdometryControl, Pose2, Vector3};

/// What is the same for every particle in one step.
pub(crate) struct StepContext<'a> {
    pub scan: &'a PreparedScan,
    /// The endpoint model truncated at `likelihood_radius`: fine matching, samples, weights.
    pub lk: EndpointModel,
    /// The same model truncated at the field's reach: the choice of starting point and the
    /// hill climber's coarse phase.
    pub capture: EndpointModel,
    pub hc: HillClimbSteps,
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
    /// The answer to a poor match, if any.
    pub recovery: Option<Recovery>,
}

/// The wide search a poor match triggers ([`crate::RecoveryConfig`]).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Recovery {
    /// A match with fewer inliers than this is poor.
    pub trigger_inliers: usize,
    /// ± window and steps (x/y in metres, θ in radians).
    pub range_xy: f64,
    pub step_xy: f64,
    pub range_theta: f64,
    pub step_theta: f64,
}

/// A particle's new pose, its log-weight increment, whether matching failed (the pose is
/// the motion model's) and whether a poor match was replaced by the wide search's.
pub(crate) struct Drawn {
    pub pose: Pose2,
    pub log_weight: f64,
    pub match_failed: bool,
    pub match_recovered: bool,
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
        log_weight: score_scan(field, ctx.scan, &x, &ctx.lk).log_likelihood,
        match_failed: false,
        match_recovered: false,
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
///    p(z | m, xⱼ) is evaluated on every 2nd end point and scaled to the whole scan
///    (`sample_points`);
/// 3. η = Σ τⱼ, μ = Σ xⱼτⱼ/η, Σ = Σ (xⱼ − μ)(xⱼ − μ)ᵀτⱼ/η (eqs. 14–16);
/// 4. xₜ ~ N(μ, Σ) (sampled, as published), and ln wₜ = ln wₜ₋₁ + ln η (eq. 18).
///
/// The likelihood gain g (`likelihood_gain`) tempers the weights only, as GMapping's
/// `obsSigmaGain` does (it enters `GridSlamProcessor::normalize` and nothing else): η is
/// summed over τⱼ with p(z | m, xⱼ)^(1/g), while μ and Σ are fitted to τⱼ with the
/// untempered p(z | m, xⱼ): fitting them to the tempered likelihood widens the proposal by
/// √g, which made Intel worse and the office no better (docs/results/defaults.md).
///
/// A poor match (fewer inliers than [`Recovery::trigger_inliers`]: the prediction was too
/// far off for the hill climber's capture range, e.g. after an odometry jump) is answered
/// by a branch-and-bound search of a wide window around the prediction over a max-pyramid
/// of the capture field, built for this particle's map when the recovery triggers
/// ([`wide_search`]; the same optimum as brute force over its lattice), under the motion
/// model widened by the window, N(x', R + W) with
/// W = diag((w_xy/2)², (w_xy/2)², (w_θ/2)²): the broad component of a mixture that admits
/// odometry errors of the window's size. Hill climbing from its best pose replaces the
/// local match when more beams find the map there; the samples τⱼ then use that widened
/// motion density, so that the recovered particle is neither favoured nor punished for the
/// distance from its prediction beyond what the window allows. The wide search's match is
/// taken only when it is not poor itself.
///
/// When the match still has too few inliers (empty or unrelated map) the particle falls
/// back to [`motion_and_likelihood`] and the failure is reported.
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
        && coarse_score(field, ctx.scan, &shifted, &ctx.capture)
            > coarse_score(field, ctx.scan, &predicted, &ctx.capture)
    {
        shifted
    } else {
        predicted
    };
    let mut m = hill_climb(field, ctx.scan, &start, &ctx.capture, &ctx.lk, &ctx.hc);
    let mut covariance =
        ctx.motion.noise_covariance(pose, &ctx.u) + Matrix3::from_diagonal(&ctx.min_var);
    let mut recovered = false;
    if let Some(rc) = ctx
        .recovery
        .filter(|rc| m.score.inliers < rc.trigger_inliers)
    {
        let wide = covariance
            + Matrix3::from_diagonal(&Vector3::new(
                (0.5 * rc.range_xy).powi(2),
                (0.5 * rc.range_xy).powi(2),
                (0.5 * rc.range_theta).powi(2),
            ));
        let window = SearchWindow {
            range_xy: rc.range_xy,
            step_xy: rc.step_xy,
            range_theta: rc.range_theta,
            step_theta: rc.step_theta,
            information: wide.try_inverse().unwrap_or_else(Matrix3::zeros),
        };
        // Branch and bound over a pyramid built for this particle's map now (its map
        // changes every step); brute force only if the window is too large for a pyramid.
        let found = match wide_search(field, ctx.scan, &predicted, &ctx.capture, &window) {
            Ok(w) => w.pose,
            Err(_) => grid_search(field, ctx.scan, &predicted, &ctx.capture, &window),
        };
        let m2 = hill_climb(field, ctx.scan, &found, &ctx.capture, &ctx.lk, &ctx.hc);
        // Taken when it is no longer poor itself (and better than the local match).
        if m2.score.inliers > m.score.inliers
            && m2.score.inliers >= rc.trigger_inliers.max(ctx.min_inliers)
        {
            m = m2;
            covariance = wide;
            recovered = true;
        }
    }
    let chol = Cholesky::new((covariance + covariance.transpose()) * 0.5);
    let (Some(chol), true) = (chol, m.score.inliers >= ctx.min_inliers) else {
        let mut d = motion_and_likelihood(pose, field, ctx, &ctx.motion, &ctx.u, rng);
        d.match_failed = true;
        return d;
    };
    let log_det = 2.0 * (0..3).map(|i| chol.l_dirty()[(i, i)].ln()).sum::<f64>();
    // ln τⱼ with the tempered likelihood (for η) and with the untempered one (for μ, Σ).
    let mut log_tau = [0.0f64; 729];
    let mut log_fit = [0.0f64; 729];
    let k = ctx.offsets.len();
    let (sample_points, sample_scale) = sample_points(ctx.scan);
    for (j, o) in ctx.offsets.iter().enumerate() {
        let xj = Pose2::new(m.pose.x + o[0], m.pose.y + o[1], m.pose.theta + o[2]);
        // Every sample on the same end points, the mode's too (its match score has all).
        let l = sample_scale * score(field, sample_points, &xj, &ctx.lk).log_likelihood;
        let e = Vector3::new(
            xj.x - predicted.x,
            xj.y - predicted.y,
            normalize_angle(xj.theta - predicted.theta),
        );
        let log_motion = -0.5 * (e.dot(&chol.solve(&e)) + log_det);
        log_tau[j] = l + log_motion;
        log_fit[j] = ctx.lk.gain * l + log_motion;
    }
    let log_tau = &log_tau[..k];
    let top = log_tau.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let eta: f64 = log_tau.iter().map(|t| (t - top).exp()).sum();
    // The fit's normalised weights, in place of their logarithms.
    let fit = &mut log_fit[..k];
    let top_fit = fit.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    fit.iter_mut().for_each(|t| *t = (*t - top_fit).exp());
    let total: f64 = fit.iter().sum();
    fit.iter_mut().for_each(|w| *w /= total);
    let mut mean = Vector3::zeros();
    for (w, o) in fit.iter().zip(ctx.offsets) {
        mean += Vector3::new(o[0], o[1], o[2]) * *w;
    }
    let mut sigma = Matrix3::zeros();
    for (w, o) in fit.iter().zip(ctx.offsets) {
        let d = Vector3::new(o[0], o[1], o[2]) - mean;
        sigma += d * d.transpose() * *w;
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
        match_recovered: recovered,
    }
}

/// The end points the K samples of the improved proposal score: every 2nd
/// ([`PreparedScan::half_points`]), and the factor n / n_half that scales their
/// log-likelihood to the whole scan's. The samples are close to one another (±1 cm, ±0.3°
/// by default), so half the beams still tell them apart, at half the cost (they were about
/// a third of a particle's evaluations). Measured on Intel (5 seeds, relations) and
/// Freiburg-101 (3 seeds, ATE): docs/results/gridfast-speed.md.
fn sample_points(scan: &PreparedScan) -> (&[slam_models::Point2], f64) {
    let points = scan.half_points();
    (
        points,
        scan.points().len() as f64 / points.len().max(1) as f64,
    )
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
    use crate::matcher::field;
    use crate::matcher::tests::{empty_map, room_scan};
    use rand::SeedableRng;

    /// The gain tempers the weight and nothing else: for the same σ and random stream,
    /// gains 1 and 3 draw the same pose, and the weights are η over p(z | m, xⱼ)^(1/g),
    /// recomputed here from the K samples independently of the function.
    #[test]
    fn the_gain_tempers_the_weight_not_the_proposal() {
        let mut map = empty_map();
        for p in [Pose2::new(0.0, 0.0, 0.0), Pose2::new(-1.0, -0.5, 1.0)] {
            map.integrate_scan(&p, &room_scan(&p));
        }
        let truth = Pose2::new(0.3, 0.4, 0.3);
        let scan = PreparedScan::with_limits(&room_scan(&truth), 0.0, 50.0).unwrap();
        let offsets = sample_offsets(3, 0.01, 0.005);
        let motion = OdometryModel::new([0.05, 0.002, 0.02, 0.002]);
        let previous = Pose2::new(0.0, 0.0, 0.0);
        // Odometry that overshoots the true pose by a few centimetres.
        let u = motion.control_from_poses(&previous, &Pose2::new(0.33, 0.37, 0.31));
        let sigma = 0.05;
        let draw = |gain: f64| {
            let ctx = StepContext {
                scan: &scan,
                lk: EndpointModel {
                    k: 1.0 / (2.0 * sigma * sigma * gain),
                    radius: 0.15,
                    gain,
                },
                capture: EndpointModel {
                    k: 1.0 / (2.0 * sigma * sigma * gain),
                    radius: 0.2,
                    gain,
                },
                hc: HillClimbSteps {
                    linear_step: 0.05,
                    angular_step: 0.05,
                    refinements: 6,
                },
                u,
                motion,
                min_var: Vector3::new(1e-4, 1e-4, 2.5e-5),
                min_inliers: 10,
                offsets: &offsets,
                correction: Pose2::IDENTITY,
                recovery: None,
            };
            let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(5);
            (improved(&previous, &field(&map), &ctx, &mut rng), ctx)
        };
        let (d1, _) = draw(1.0);
        let (d3, ctx3) = draw(3.0);
        assert!(!d1.match_failed && !d3.match_failed);
        assert!(
            d1.pose.distance(&d3.pose) < 1e-9,
            "{:?} vs {:?}",
            d1.pose,
            d3.pose
        );
        assert!((d1.pose.theta - d3.pose.theta).abs() < 1e-9);
        assert!(d1.pose.distance(&truth) < 0.03, "{:?}", d1.pose);
        // η with the tempered likelihood, from the mode the matcher finds.
        let predicted = motion.predict(&previous, &u);
        let m = hill_climb(
            &field(&map),
            &scan,
            &predicted,
            &ctx3.capture,
            &ctx3.lk,
            &ctx3.hc,
        );
        // The samples' end points: every 2nd, scaled to the whole scan.
        let half = scan.half_points();
        let scale = scan.points().len() as f64 / half.len() as f64;
        let cov = motion.noise_covariance(&previous, &u) + Matrix3::from_diagonal(&ctx3.min_var);
        let (inv, det) = (cov.try_inverse().unwrap(), cov.determinant());
        let log_tau: Vec<f64> = offsets
            .iter()
            .map(|o| {
                let xj = Pose2::new(m.pose.x + o[0], m.pose.y + o[1], m.pose.theta + o[2]);
                let l = scale * score(&field(&map), half, &xj, &ctx3.lk).log_likelihood;
                let e = Vector3::new(
                    xj.x - predicted.x,
                    xj.y - predicted.y,
                    xj.theta - predicted.theta,
                );
                l - 0.5 * (e.dot(&(inv * e)) + det.ln())
            })
            .collect();
        let top = log_tau.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let log_eta = top + log_tau.iter().map(|t| (t - top).exp()).sum::<f64>().ln();
        assert!(
            (d3.log_weight - log_eta).abs() < 1e-6,
            "{} vs {log_eta}",
            d3.log_weight
        );
        assert!(d1.log_weight < d3.log_weight);
    }

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
