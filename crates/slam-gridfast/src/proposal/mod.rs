//! The three proposal distributions: how one particle draws its pose at a processed scan
//! and by how much its weight changes.

use crate::config::StartChoice;
use crate::setup::{beams, Recovery, Setup, Window};
use nalgebra::Cholesky;
use rand::Rng;
use slam_grid::matcher::endpoint::{
    coarse_score, grid_search, hill_climb, score, score_scan, wide_search, EndpointMatch,
    EndpointModel,
};
use slam_grid::DistanceField;
use slam_grid::RangeData;
use slam_models::motion::{MotionModel, OdometryModel};
use slam_models::{normalize_angle, Matrix3, OdometryControl, Pose2, Vector3};

/// One update's inputs to every particle's proposal: the filter's setup, the scan, the
/// odometry increment and the best particle's coarse correction.
pub(crate) struct Step<'a> {
    pub setup: &'a Setup,
    pub scan: &'a RangeData,
    /// The odometry increment since the last processed scan.
    pub u: OdometryControl,
    /// The correction x̂_best ⊖ x'_best that the shared coarse search found for the best
    /// particle (identity when the search is off).
    pub correction: Pose2,
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
    step: &Step<'_>,
    motion: &OdometryModel,
    u: &OdometryControl,
    rng: &mut R,
) -> Drawn {
    let x = motion.sample(pose, u, rng);
    Drawn {
        pose: x,
        log_weight: score_scan(field, step.scan, &x, &step.setup.likelihood).log_likelihood,
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
/// local match when more beams find the map there; the samples τⱼ then use the mixture
/// (1 − ε)·N(x′, R) + ε·N(x′, R + W) ([`MotionDensity`]), so that the recovered particle
/// pays the prior odds ε of an odometry outlier and nothing more for the distance from its
/// prediction within the window. The wide search's match is taken only when it is not
/// poor itself and fits `accept-fraction` of the beams. On a step whose odometry turned
/// (`turn-trigger`), a poor match the wide window did not recover is searched again over
/// every heading at the predicted position ([`recover`]).
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
    step: &Step<'_>,
    rng: &mut R,
) -> Drawn {
    improved_fit(pose, map, field, step).draw(pose, field, step, rng)
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
        step: &Step<'_>,
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
                let mut d =
                    motion_and_likelihood(pose, field, step, &step.setup.odometry, &step.u, rng);
                d.match_failed = true;
                d
            }
        }
    }
}

/// Steps 1–3 of [`improved`] for a particle at `pose` with `map`: the match
/// ([`climb`]), the answer to a poor one ([`recover`]), the Gaussian fitted around it
/// ([`fit_gaussian`]).
pub(crate) fn improved_fit(
    pose: &Pose2,
    map: &slam_grid::OccupancyGrid,
    field: &DistanceField<'_>,
    step: &Step<'_>,
) -> Fitted {
    let setup = step.setup;
    let predicted = setup.odometry.predict(pose, &step.u);
    let covariance =
        setup.odometry.noise_covariance(pose, &step.u) + Matrix3::from_diagonal(&setup.min_var);
    let m = climb(field, step, &predicted, &covariance);
    let (m, broad) = match setup.recovery {
        Some(rc) => match recover(map, field, step, &rc, &predicted, &covariance, &m) {
            Some((m2, wide)) => (m2, Some((wide, rc.log_outlier_odds))),
            None => (m, None),
        },
        None => (m, None),
    };
    let motion = MotionDensity {
        predicted,
        covariance,
        broad,
    };
    fit_gaussian(field, step, &m, &motion)
}

/// The motion density p(x | xₜ₋₁, uₜ) the samples τⱼ are weighed with, up to the factor
/// (1 − ε) common to every particle: N(x; x′, R) + ε/(1 − ε)·N(x; x′, R + W).
///
/// The filter's motion model is the mixture (1 − ε)·N(x′, R) + ε·N(x′, R + W) (ε =
/// `outlier-weight`, W the recovery window's, [`recover`]): the odometry model plus a
/// small-weight broad component for the steps whose odometry is an outlier (a turn in
/// place measured 1.24 rad off). The improved proposal's weight is the normaliser of the
/// proposal, η = Σⱼ p(z | m, xⱼ)·p(xⱼ | xₜ₋₁, uₜ) (Grisetti et al. 2007, eqs. 12, 18), with
/// that mixture as p(xⱼ | …). A particle whose match was not recovered weighs its samples
/// (within 1 cm / 0.3° of a mode the hill climber reached from x′) by the first component
/// alone: the broad one adds at most ε/(1 − ε)·√(det R / det(R + W)) relative to it (for
/// a 0.1 m / 0.1 rad odometry σ, 4·10⁻⁵ with the indoor wide window, 2·10⁻⁴ with the
/// turn search's), so ln η moves by less than 2·10⁻⁴ nats; leaving it out keeps every
/// step without a recovery as it was. W is the window of the search that recovered (the
/// wide window, or the turn search's on a step that turned). A recovered particle's
/// samples lie where the broad component can dominate, so it weighs them by both,
/// exactly.
pub(crate) struct MotionDensity {
    /// x′ = xₜ₋₁ ⊕ uₜ.
    pub predicted: Pose2,
    /// R (linearised odometry model plus the floor `motion.min-std`²).
    pub covariance: Matrix3,
    /// The broad component for a recovered particle: R + W and ln(ε / (1 − ε)).
    pub broad: Option<(Matrix3, f64)>,
}

/// Step 1: x̂ by hill climbing from the prediction `predicted` (motion covariance
/// `covariance`) and, per [`StartChoice`], from the prediction moved by the shared
/// correction.
fn climb(
    field: &DistanceField<'_>,
    step: &Step<'_>,
    predicted: &Pose2,
    covariance: &Matrix3,
) -> EndpointMatch {
    let (setup, c) = (step.setup, &step.correction);
    let (capture, lk, hc) = (&setup.capture, &setup.likelihood, &setup.climb);
    let shifted = predicted.compose(c);
    match setup.start_choice {
        // Both starts, when the correction reaches beyond the climber's first steps (two
        // climbs from closer starts end in the same mode): the mode of likelihood × motion
        // prior, which the weights below score too.
        StartChoice::Posterior
            if c.x.hypot(c.y) > hc.linear_step || c.theta.abs() > hc.angular_step =>
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
            let local = hill_climb(field, step.scan, predicted, capture, lk, hc);
            let moved = hill_climb(field, step.scan, &shifted, capture, lk, hc);
            if posterior(&moved) > posterior(&local) {
                moved
            } else {
                local
            }
        }
        // One climb, from the start whose coarse score is larger.
        _ => {
            let start = if *c != Pose2::IDENTITY
                && coarse_score(field, step.scan, &shifted, capture)
                    > coarse_score(field, step.scan, predicted, capture)
            {
                shifted
            } else {
                *predicted
            };
            hill_climb(field, step.scan, &start, capture, lk, hc)
        }
    }
}

/// The answer to a poor match `m`: the wide search's match, or on a step that turned the
/// turn search's, and the widened covariance R + W of the window searched, when they
/// replace `m` (see [`improved`]); `None` when `m` is not poor or neither match is taken.
fn recover(
    map: &slam_grid::OccupancyGrid,
    field: &DistanceField<'_>,
    step: &Step<'_>,
    rc: &Recovery,
    predicted: &Pose2,
    covariance: &Matrix3,
    m: &EndpointMatch,
) -> Option<(EndpointMatch, Matrix3)> {
    let (setup, n) = (step.setup, step.scan.points().len());
    // A scan without a usable end point (every beam beyond `sensor.max-range`) has nothing
    // a wider search could fit: the match stands.
    if n == 0 {
        return None;
    }
    let (min_inliers, trigger_inliers) = (setup.min_inliers(n), beams(rc.trigger_fraction, n));
    // Poor: too few beams find the map, counted among all the used beams or among those
    // whose end point lies where the map can say anything ([`observed_beams`]); a match
    // that would fail is always poor.
    let poor = |m: &EndpointMatch| {
        if rc.observed_only {
            // (The judged beams are a subset of all: counted only below the plain trigger.)
            m.score.inliers < min_inliers
                || (m.score.inliers < trigger_inliers
                    && (m.score.inliers as f64)
                        < rc.trigger_fraction
                            * observed_beams(map, field, step.scan, &m.pose, &setup.likelihood)
                                as f64)
        } else {
            m.score.inliers < trigger_inliers
        }
    };
    if !poor(m) {
        return None;
    }
    let capture = &setup.capture;
    // The window W's search under N(x′, R + W), then hill climbing from its best pose.
    let search = |w: &Window| {
        let wide = covariance
            + Matrix3::from_diagonal(&Vector3::new(
                (0.5 * w.range_xy).powi(2),
                (0.5 * w.range_xy).powi(2),
                (0.5 * w.range_theta).powi(2),
            ));
        let window = w.with_prior(&wide);
        // Branch and bound over a pyramid built for this particle's map now (its map
        // changes every step); brute force only if the window is too large for a pyramid.
        let found = match wide_search(field, step.scan, predicted, capture, &window) {
            Ok(w) => w.pose,
            Err(_) => grid_search(field, step.scan, predicted, capture, &window),
        };
        let m2 = hill_climb(
            field,
            step.scan,
            &found,
            capture,
            &setup.likelihood,
            &setup.climb,
        );
        (m2, wide)
    };
    // Taken when it is better than the local match, no longer poor itself and fits
    // `fraction` of the scan: a pose far from the prediction needs more than not being
    // poor.
    let taken = |m2: &EndpointMatch, fraction: f64| {
        m2.score.inliers > m.score.inliers && !poor(m2) && m2.score.inliers >= beams(fraction, n)
    };
    let (m2, wide) = search(&rc.window);
    if taken(&m2, rc.accept_fraction) {
        return Some((m2, wide));
    }
    // A step that turned: every heading (`turn-range-theta`) at the predicted position
    // (± `turn-range-xy`), since odometry that turned in place can be off by more than the
    // turn itself; near the predicted position a scan that looks partly into space not
    // yet mapped can fit only half its beams at the right pose (`turn-accept-fraction`).
    let turn = step.u.rot1.abs() + step.u.rot2.abs();
    if turn < rc.turn_trigger {
        return None;
    }
    let w = Window {
        range_xy: rc.turn_range_xy,
        range_theta: rc.turn_range_theta,
        ..rc.window
    };
    let (m3, wide) = search(&w);
    taken(&m3, rc.turn_accept_fraction).then_some((m3, wide))
}

/// Steps 2–3: the K samples around the match `m`, weighed by likelihood × the motion
/// density ([`MotionDensity`]), and the Gaussian fitted to them; a failed match (too few
/// inliers) or a singular covariance gives [`Fitted::Failed`].
fn fit_gaussian(
    field: &DistanceField<'_>,
    step: &Step<'_>,
    m: &EndpointMatch,
    motion: &MotionDensity,
) -> Fitted {
    let (setup, offsets) = (step.setup, &step.setup.offsets);
    let predicted = &motion.predicted;
    let min_inliers = setup.min_inliers(step.scan.points().len());
    let Some(narrow) = LogGaussian::new(&motion.covariance) else {
        return Fitted::Failed;
    };
    let broad = match &motion.broad {
        Some((c, log_odds)) => match LogGaussian::new(c) {
            Some(g) => Some((g, *log_odds)),
            None => return Fitted::Failed,
        },
        None => None,
    };
    if m.score.inliers < min_inliers {
        return Fitted::Failed;
    }
    let recovered = broad.is_some();
    // ln τⱼ with the tempered likelihood (for η) and with the untempered one (for μ, Σ).
    let mut log_tau = [0.0f64; 729];
    let mut log_fit = [0.0f64; 729];
    let k = offsets.len();
    let (sample_points, sample_scale) = sample_points(step.scan);
    for (j, o) in offsets.iter().enumerate() {
        let xj = Pose2::new(m.pose.x + o[0], m.pose.y + o[1], m.pose.theta + o[2]);
        // Every sample on the same end points, the mode's too (its match score has all).
        let l = sample_scale * score(field, sample_points, &xj, &setup.likelihood).log_likelihood;
        let e = Vector3::new(
            xj.x - predicted.x,
            xj.y - predicted.y,
            normalize_angle(xj.theta - predicted.theta),
        );
        let log_motion = match &broad {
            None => narrow.at(&e),
            Some((b, log_odds)) => log_add(narrow.at(&e), log_odds + b.at(&e)),
        };
        log_tau[j] = l + log_motion;
        log_fit[j] = setup.likelihood.gain * l + log_motion;
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
    for (w, o) in fit.iter().zip(offsets) {
        mean += Vector3::new(o[0], o[1], o[2]) * *w;
    }
    let mut sigma = Matrix3::zeros();
    for (w, o) in fit.iter().zip(offsets) {
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

/// ln N(e; 0, C) + (3/2)·ln 2π for a 3×3 covariance C, from its Cholesky factor.
struct LogGaussian {
    chol: Cholesky<f64, nalgebra::U3>,
    log_det: f64,
}

impl LogGaussian {
    /// `None` when C is not positive definite.
    fn new(c: &Matrix3) -> Option<Self> {
        let chol = Cholesky::new((c + c.transpose()) * 0.5)?;
        let log_det = 2.0 * (0..3).map(|i| chol.l_dirty()[(i, i)].ln()).sum::<f64>();
        Some(Self { chol, log_det })
    }

    /// −½·(eᵀC⁻¹e + ln det C).
    fn at(&self, e: &Vector3) -> f64 {
        -0.5 * (e.dot(&self.chol.solve(e)) + self.log_det)
    }
}

/// ln(eᵃ + eᵇ), without overflow or underflow.
fn log_add(a: f64, b: f64) -> f64 {
    let (hi, lo) = if a >= b { (a, b) } else { (b, a) };
    if lo == f64::NEG_INFINITY {
        hi
    } else {
        hi + (lo - hi).exp().ln_1p()
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
    scan: &RangeData,
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
/// ([`RangeData::half_points`]), and the factor n / n_half that scales their
/// log-likelihood to the whole scan's. The samples are close to one another (±1 cm, ±0.3°
/// by default), so half the beams still tell them apart, at half the cost (they were about
/// a third of a particle's evaluations). Measured on Intel (5 seeds, relations) and
/// Freiburg-101 (3 seeds, ATE): docs/results/gridfast-speed.md.
fn sample_points(scan: &RangeData) -> (&[slam_models::Point2], f64) {
    let points = scan.half_points();
    (
        points,
        scan.points().len() as f64 / points.len().max(1) as f64,
    )
}

#[cfg(test)]
mod tests;
