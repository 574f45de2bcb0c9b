//! The three proposal distributions: how one particle draws its pose at a processed scan
//! and by how much its weight changes.

use crate::config::StartChoice;
use nalgebra::Cholesky;
use rand::Rng;
use slam_grid::matcher::endpoint::{
    coarse_score, grid_search, hill_climb, score, score_scan, wide_search, EndpointMatch,
    EndpointModel, HillClimbSteps, SearchWindow,
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
    /// How the match's start is chosen ([`crate::MatchingConfig::start_choice`]).
    pub start_choice: StartChoice,
}

/// The wide search a poor match triggers ([`crate::RecoveryConfig`]).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Recovery {
    /// A match with fewer inliers than this is poor.
    pub trigger_inliers: usize,
    /// The trigger as a fraction ([`crate::RecoveryConfig::trigger_fraction`]).
    pub trigger_fraction: f64,
    /// Count the fraction among the beams whose end point the map can judge
    /// ([`crate::RecoveryConfig::observed_only`]).
    pub observed_only: bool,
    /// The wide search's match replaces the local one only with at least this many inliers.
    pub accept_inliers: usize,
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
/// 1. x̂ = argmax p(z | m, x) by hill climbing from x' = xₜ₋₁ ⊕ uₜ and, when c — the
///    correction a coarse exhaustive search found for the best particle — reaches beyond
///    the climber's first steps, also from x' ⊕ c, keeping the climb with the larger
///    p(z | m, x̂)·N(x̂; x', R) ([`StartChoice::Posterior`]: the mode of the target
///    distribution, eq. 9, rather than whichever start fits the map better, which let a
///    few dozen more beams on the map outweigh a heading 0.6 rad off good odometry);
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
/// A poor match (fewer inliers than [`Recovery::trigger_fraction`] of the beams whose end
/// points the map can judge, [`observed_beams`], or of all the beams without
/// [`Recovery::observed_only`]: the prediction was too far off for the hill climber's
/// capture range, e.g. after an odometry jump; a scan that looks into space not yet
/// mapped is not poor for that alone) is answered
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
///
/// Everything but the final draw depends only on the particle's pose and map, so
/// [`improved_fit`] computes it once for a group of identical particles (the copies of
/// one parent since a resampling) and [`Fitted::draw`] draws for each.
#[cfg(test)]
pub(crate) fn improved<R: Rng + ?Sized>(
    pose: &Pose2,
    map: &slam_grid::OccupancyGrid,
    field: &DistanceField<'_>,
    ctx: &StepContext<'_>,
    rng: &mut R,
) -> Drawn {
    improved_fit(pose, map, field, ctx).draw(pose, field, ctx, rng)
}

/// The improved proposal's Gaussian N(μ, Σ) around the match, or its failure, for a
/// particle at `pose` with `map` ([`improved`], steps 1–3): deterministic, the same for
/// every particle with the same pose and map.
pub(crate) enum Fitted {
    /// xₜ = x̂ ⊕ (μ + L·z), z ~ N(0, I) (L the Cholesky factor of Σ, `None` when Σ is not
    /// positive definite: xₜ = x̂ ⊕ μ, no draw); ln η the weight increment.
    Gaussian {
        mode: Pose2,
        mean: Vector3,
        factor: Option<Matrix3>,
        log_eta: f64,
        recovered: bool,
    },
    /// Too few inliers (or a singular motion covariance): the particle samples the motion
    /// model ([`motion_and_likelihood`]).
    Failed,
}

impl Fitted {
    /// One particle's draw from the fit (its own random stream `rng`).
    pub(crate) fn draw<R: Rng + ?Sized>(
        &self,
        pose: &Pose2,
        field: &DistanceField<'_>,
        ctx: &StepContext<'_>,
        rng: &mut R,
    ) -> Drawn {
        match self {
            Fitted::Gaussian {
                mode,
                mean,
                factor,
                log_eta,
                recovered,
            } => {
                let offset = match factor {
                    Some(l) => {
                        let z = Vector3::new(
                            rng.sample(rand_distr::StandardNormal),
                            rng.sample(rand_distr::StandardNormal),
                            rng.sample(rand_distr::StandardNormal),
                        );
                        mean + l * z
                    }
                    None => *mean,
                };
                Drawn {
                    pose: Pose2::new(
                        mode.x + offset[0],
                        mode.y + offset[1],
                        mode.theta + offset[2],
                    ),
                    log_weight: *log_eta,
                    match_failed: false,
                    match_recovered: *recovered,
                }
            }
            Fitted::Failed => {
                let mut d = motion_and_likelihood(pose, field, ctx, &ctx.motion, &ctx.u, rng);
                d.match_failed = true;
                d
            }
        }
    }
}

/// Steps 1–3 of [`improved`] for a particle at `pose` with `map`.
pub(crate) fn improved_fit(
    pose: &Pose2,
    map: &slam_grid::OccupancyGrid,
    field: &DistanceField<'_>,
    ctx: &StepContext<'_>,
) -> Fitted {
    let predicted = ctx.motion.predict(pose, &ctx.u);
    let shifted = predicted.compose(&ctx.correction);
    let mut covariance =
        ctx.motion.noise_covariance(pose, &ctx.u) + Matrix3::from_diagonal(&ctx.min_var);
    let mut m = match ctx.start_choice {
        // Both starts, when the correction reaches beyond the climber's first steps (two
        // climbs from closer starts end in the same mode): the mode of likelihood × motion
        // prior, which the weights below score too.
        StartChoice::Posterior
            if ctx.correction.x.hypot(ctx.correction.y) > ctx.hc.linear_step
                || ctx.correction.theta.abs() > ctx.hc.angular_step =>
        {
            let information = covariance.try_inverse().unwrap_or_else(Matrix3::zeros);
            let posterior = |m: &EndpointMatch| {
                let e = Vector3::new(
                    m.pose.x - predicted.x,
                    m.pose.y - predicted.y,
                    normalize_angle(m.pose.theta - predicted.theta),
                );
                m.score.log_likelihood - 0.5 * e.dot(&(information * e))
            };
            let local = hill_climb(field, ctx.scan, &predicted, &ctx.capture, &ctx.lk, &ctx.hc);
            let moved = hill_climb(field, ctx.scan, &shifted, &ctx.capture, &ctx.lk, &ctx.hc);
            if posterior(&moved) > posterior(&local) {
                moved
            } else {
                local
            }
        }
        // One climb, from the start whose coarse score is larger.
        _ => {
            let start = if ctx.correction != Pose2::IDENTITY
                && coarse_score(field, ctx.scan, &shifted, &ctx.capture)
                    > coarse_score(field, ctx.scan, &predicted, &ctx.capture)
            {
                shifted
            } else {
                predicted
            };
            hill_climb(field, ctx.scan, &start, &ctx.capture, &ctx.lk, &ctx.hc)
        }
    };
    let mut recovered = false;
    // Poor: too few beams find the map, counted among all the used beams or among those
    // whose end point lies where the map can say anything ([`observed_beams`]); a match
    // that would fail is always poor.
    let poor = |rc: &Recovery, m: &EndpointMatch| {
        if rc.observed_only {
            // (The judged beams are a subset of all: counted only below the plain trigger.)
            m.score.inliers < ctx.min_inliers
                || (m.score.inliers < rc.trigger_inliers
                    && (m.score.inliers as f64)
                        < rc.trigger_fraction
                            * observed_beams(map, field, ctx.scan, &m.pose, &ctx.lk) as f64)
        } else {
            m.score.inliers < rc.trigger_inliers
        }
    };
    if let Some(rc) = ctx.recovery.filter(|rc| poor(rc, &m)) {
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
        // Taken when it is better than the local match, no longer poor itself and fits
        // most of the scan (`accept_inliers`): a pose far from the prediction needs more
        // than not being poor.
        if m2.score.inliers > m.score.inliers
            && !poor(&rc, &m2)
            && m2.score.inliers >= rc.accept_inliers
        {
            m = m2;
            covariance = wide;
            recovered = true;
        }
    }
    let chol = Cholesky::new((covariance + covariance.transpose()) * 0.5);
    let (Some(chol), true) = (chol, m.score.inliers >= ctx.min_inliers) else {
        return Fitted::Failed;
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
    Fitted::Gaussian {
        mode: m.pose,
        mean,
        factor: Cholesky::new((sigma + sigma.transpose()) * 0.5).map(|c| c.l()),
        log_eta: top + eta.ln(),
        recovered,
    }
}

/// The beams of `scan` at `pose` that the map can judge: the end point lies in an observed
/// cell (log-odds ≠ 0) or within the model's truncation r of an obstacle, or the beam
/// passes through an occupied cell (log-odds > 0) more than r before its end — a beam that
/// ends beyond a mapped wall contradicts the map as much as one that ends in mapped free
/// space. Only the beams ending in unknown space are walked, in steps of a cell.
pub(crate) fn observed_beams(
    map: &slam_grid::OccupancyGrid,
    field: &DistanceField<'_>,
    scan: &PreparedScan,
    pose: &Pose2,
    model: &EndpointModel,
) -> usize {
    let unit = field.metres_per_unit();
    let step = map.resolution();
    let origin = pose.compose(&scan.sensor_pose()).translation();
    scan.points()
        .iter()
        .filter(|p| {
            let end = pose.transform_point(p);
            let c = map.world_to_cell(&end);
            if map.log_odds(c) != 0.0 || (field.dist(c) as f64 * unit) < model.radius {
                return true;
            }
            let (dx, dy) = (end.x - origin.x, end.y - origin.y);
            let length = dx.hypot(dy);
            let n = ((length - model.radius) / step).floor().max(0.0) as usize;
            (1..=n).any(|i| {
                let t = i as f64 * step / length;
                let q = slam_models::Point2::new(origin.x + t * dx, origin.y + t * dy);
                map.log_odds(map.world_to_cell(&q)) > 0.0
            })
        })
        .count()
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
                start_choice: StartChoice::Posterior,
            };
            let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(5);
            (improved(&previous, &map, &field(&map), &ctx, &mut rng), ctx)
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

    /// A wall segment, from one end point (x, y) to the other, metres.
    type Segment = ((f64, f64), (f64, f64));

    /// A 361-beam, 360° scan from `pose` of the walls `segments`: each reading the range to
    /// the nearest wall along the beam, readings from `max_range` on (and beams that meet
    /// no wall) no returns at `max_range`.
    fn scan_of(segments: &[Segment], pose: &Pose2, max_range: f64) -> slam_models::LaserScan {
        let n = 361;
        let inc = std::f64::consts::TAU / n as f64;
        let ranges = (0..n)
            .map(|k| {
                let a = pose.theta - std::f64::consts::PI + k as f64 * inc;
                let d = (a.cos(), a.sin());
                let mut best = f64::INFINITY;
                for &((px, py), (qx, qy)) in segments {
                    // The ray pose + t·d against the segment p + u·(q − p), u in [0, 1].
                    let e = (qx - px, qy - py);
                    let den = d.0 * e.1 - d.1 * e.0;
                    if den.abs() < 1e-12 {
                        continue;
                    }
                    let w = (px - pose.x, py - pose.y);
                    let t = (w.0 * e.1 - w.1 * e.0) / den;
                    let u = (w.0 * d.1 - w.1 * d.0) / den;
                    if t > 0.0 && (0.0..=1.0).contains(&u) {
                        best = best.min(t);
                    }
                }
                best.min(max_range)
            })
            .collect();
        slam_models::LaserScan {
            angle_min: -std::f64::consts::PI,
            angle_increment: inc,
            ranges,
            max_range,
            sensor_pose: Pose2::IDENTITY,
        }
    }

    /// A corridor from x = −20 to 20 m whose walls are saw-toothed with a period of one
    /// metre (y = ±1 at whole metres, ±1.3 half-way): shifted by one metre along x it looks
    /// the same, and every wall beam says where along the period the robot is.
    fn corridor_scan(pose: &Pose2, max_range: f64) -> slam_models::LaserScan {
        let mut segments = vec![((-20.0, -1.0), (-20.0, 1.0)), ((20.0, -1.0), (20.0, 1.0))];
        for k in -20..20 {
            let x0 = k as f64;
            for s in [-1.0, 1.0] {
                segments.push(((x0, s * 1.0), (x0 + 0.5, s * 1.3)));
                segments.push(((x0 + 0.5, s * 1.3), (x0 + 1.0, s * 1.0)));
            }
        }
        scan_of(&segments, pose, max_range)
    }

    /// One particle's draw with the indoor preset's matching (σ 0.05 m, r 0.15 m, capture
    /// 0.2 m, gain 3, steps 0.1 m / 0.1 rad halved 6 times, 3³ samples over ±1 cm / ±0.3°)
    /// and Intel's motion model, moving from `previous` to where the odometry says, `to`.
    #[allow(clippy::too_many_arguments)]
    fn indoor_draw(
        map: &slam_grid::OccupancyGrid,
        scan: &PreparedScan,
        previous: Pose2,
        to: Pose2,
        min_inliers: usize,
        correction: Pose2,
        recovery: Option<Recovery>,
        start_choice: StartChoice,
    ) -> Drawn {
        let offsets = sample_offsets(3, 0.01, 0.005);
        let motion = OdometryModel::new([0.05, 0.002, 0.02, 0.002]);
        let lk = EndpointModel::new(0.05, 0.15, 3.0);
        let ctx = StepContext {
            scan,
            lk,
            capture: EndpointModel { radius: 0.2, ..lk },
            hc: HillClimbSteps {
                linear_step: 0.1,
                angular_step: 0.1,
                refinements: 6,
            },
            u: motion.control_from_poses(&previous, &to),
            motion,
            min_var: Vector3::new(1e-4, 1e-4, 2.5e-5),
            min_inliers,
            offsets: &offsets,
            correction,
            recovery,
            start_choice,
        };
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(3);
        improved(&previous, map, &field(map), &ctx, &mut rng)
    }

    /// The indoor preset's recovery (trigger 40 %, ±1.5 m, ±0.9 rad) for a scan of `n`
    /// beams, counted among all the beams or among the observed ones, taking a wide match
    /// with at least `accept_inliers`.
    fn indoor_recovery(n: f64, observed_only: bool, accept_inliers: usize) -> Option<Recovery> {
        Some(Recovery {
            trigger_inliers: (0.4 * n).ceil() as usize,
            trigger_fraction: 0.4,
            observed_only,
            accept_inliers,
            range_xy: 1.5,
            step_xy: 0.1,
            range_theta: 0.9,
            step_theta: 0.02,
        })
    }

    /// The csail failure in miniature (docs/gridfast.md): the map holds the corridor only up
    /// to about `last` + 1.3 m (24 scans with a 1.6 m range from x ≤ `last`), the robot
    /// moved from x = 1.1 to 1.9 m with exact odometry, and its 361-beam scan looks mostly
    /// into the part not yet mapped. The beams the map can judge fit the true pose, but the
    /// alias one metre back (every tooth on a tooth) puts more beams on mapped walls.
    /// Returns the true pose and the particle's draw for the given start rule, coarse
    /// correction and recovery (min-inlier fraction 5 %).
    fn corridor_draw(
        last: f64,
        start_choice: StartChoice,
        correction: Pose2,
        recovery: Option<Recovery>,
    ) -> (Pose2, Drawn) {
        let mut map = empty_map();
        for k in 0..24 {
            let x = last - 0.5 * k as f64;
            let p = Pose2::new(x, 0.05, 0.02 * k as f64);
            map.integrate_scan(&p, &corridor_scan(&p, 1.6));
        }
        let truth = Pose2::new(1.9, 0.1, 0.05);
        let previous = Pose2::new(1.1, 0.05, 0.0);
        let scan = PreparedScan::with_limits(&corridor_scan(&truth, 30.0), 0.0, 29.9).unwrap();
        let min_inliers = scan.points().len() / 20;
        let drawn = indoor_draw(
            &map,
            &scan,
            previous,
            truth,
            min_inliers,
            correction,
            recovery,
            start_choice,
        );
        (truth, drawn)
    }

    /// The indoor preset's recovery (±1.5 m, ±0.9 rad), counted among all the beams or
    /// among the observed ones; any wide match with more inliers is accepted
    /// (`accept-fraction` 0), so that only the trigger is tested.
    fn corridor_recovery(observed_only: bool) -> Option<Recovery> {
        indoor_recovery(361.0, observed_only, 0)
    }

    /// A scan looking into space not yet mapped is no poor match when the beams the map can
    /// judge fit: counted among those (`observed-only`), the particle keeps the true pose;
    /// counted among all the beams, the wide search replaces it by the alias a metre away.
    #[test]
    fn a_scan_into_new_space_does_not_trigger_the_wide_search() {
        // Mapped up to x ≈ 1 m: 26 % of the beams find the map at the true pose, all of
        // those the map can judge; 51 % at the alias.
        let (truth, kept) = corridor_draw(
            -0.3,
            StartChoice::Posterior,
            Pose2::IDENTITY,
            corridor_recovery(true),
        );
        assert!(!kept.match_recovered && !kept.match_failed);
        // Within the climber's reach of the truth (the map's edge pulls it a few cm).
        assert!(
            kept.pose.distance(&truth) < 0.1
                && normalize_angle(kept.pose.theta - truth.theta).abs() < 0.02,
            "{:?} against the truth {truth:?}",
            kept.pose
        );
        let (_, lost) = corridor_draw(
            -0.3,
            StartChoice::Posterior,
            Pose2::IDENTITY,
            corridor_recovery(false),
        );
        assert!(lost.match_recovered);
        assert!(lost.pose.distance(&truth) > 0.5, "{:?}", lost.pose);
    }

    /// When the best particle's coarse correction points at the alias (it fits more beams),
    /// the posterior rule keeps the match the motion prior supports, the true pose; the
    /// coarse-score rule climbs from the alias and stays there.
    #[test]
    fn the_start_is_chosen_by_likelihood_times_motion_prior() {
        // Mapped up to x ≈ −1 m: the alias's likelihood is 25 nats larger (51 against 34
        // beams on the map), its motion prior far smaller (1 m off a 0.8 m step whose
        // translation deviation is 0.11 m).
        let alias = Pose2::new(-1.0, 0.0, 0.0);
        let (truth, kept) = corridor_draw(-2.3, StartChoice::Posterior, alias, None);
        assert!(
            kept.pose.distance(&truth) < 0.1
                && normalize_angle(kept.pose.theta - truth.theta).abs() < 0.02,
            "{:?} against the truth {truth:?}",
            kept.pose
        );
        let (_, lost) = corridor_draw(-2.3, StartChoice::CoarseScore, alias, None);
        assert!(lost.pose.distance(&truth) > 0.5, "{:?}", lost.pose);
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

    /// A corridor (walls at y = ±1 m) with a rib 0.4 m deep on each wall every
    /// `RIB_PERIOD` metres, scanned with 361 beams over 360° up to 3 m: a repetitive
    /// structure in which a scan shifted by whole periods fits the walls again.
    const RIB_PERIOD: f64 = 0.7;

    fn ribbed_corridor_scan(pose: &Pose2) -> slam_grid::LaserScan {
        let mut walls = vec![((-20.0, 1.0), (20.0, 1.0)), ((-20.0, -1.0), (20.0, -1.0))];
        for i in -30..=30 {
            let x = RIB_PERIOD * i as f64;
            walls.push(((x, 1.0), (x, 0.6)));
            walls.push(((x, -1.0), (x, -0.6)));
        }
        scan_of(&walls, pose, 3.0)
    }

    /// Issue 21, fhw: where the robot faces space not yet mapped, its true pose fits few
    /// beams (here 29 %: the match is poor and the wide search runs), while in a repetitive
    /// structure a pose two rib periods (1.4 m) back fits more (56 %). The odometry is
    /// exact. The wide search's match used to replace the local one whenever more beams
    /// found the map there, and the particle jumped to the alias; with
    /// `recovery.accept-fraction` (0.6 by default) it keeps its local match at the truth.
    #[test]
    fn a_wide_match_in_unmapped_space_needs_most_beams_on_the_map() {
        let mut map = empty_map();
        // The corridor mapped up to x ≈ 0 (scans from x = −6 … −3 reaching 3 m).
        for i in 0..5 {
            let p = Pose2::new(-6.0 + i as f64 * 0.75, 0.0, 0.0);
            map.integrate_scan(&p, &ribbed_corridor_scan(&p));
        }
        let truth = Pose2::new(0.0, 0.0, 0.0);
        let previous = Pose2::new(-1.0, 0.0, 0.0);
        let scan = PreparedScan::with_limits(&ribbed_corridor_scan(&truth), 0.0, 2.999).unwrap();
        let n = scan.points().len() as f64;
        // The trigger counted among all the beams (`observed-only` off), so that the wide
        // search runs and only the acceptance rule is tested.
        let draw = |accept_fraction: f64| {
            indoor_draw(
                &map,
                &scan,
                previous,
                truth,
                (0.25 * n).ceil() as usize,
                Pose2::IDENTITY,
                indoor_recovery(n, false, (accept_fraction * n).ceil() as usize),
                StartChoice::Posterior,
            )
        };
        let kept = draw(crate::RecoveryConfig::default().accept_fraction);
        assert!(!kept.match_recovered && !kept.match_failed);
        assert!(
            kept.pose.distance(&truth) < 0.05 && kept.pose.theta.abs() < 0.02,
            "{:?}",
            kept.pose
        );
        // Taking the wide match whenever more beams fit (the rule before) jumps to the alias.
        let jumped = draw(0.0);
        assert!(jumped.match_recovered);
        assert!(jumped.pose.distance(&truth) > 1.0, "{:?}", jumped.pose);
    }
}
