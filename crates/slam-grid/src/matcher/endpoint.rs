//! The truncated endpoint model on the incremental distance field: the scorer, hill
//! climber and exhaustive grid search of grid FastSLAM's scan matching.
//!
//! A prepared scan's end points are in the robot frame ([`PreparedScan`]); every pose
//! evaluation is then one rotation and translation per beam and a bilinear look-up in a
//! grid's incrementally repaired distance field ([`DistanceField`]), with no trigonometry
//! per beam (GMapping recomputes sin/cos and rounding for every beam of every evaluation).
//!
//! Endpoint model (PR §6.4, "likelihood field"): a beam ending at distance d from the
//! nearest occupied cell contributes ln p = −min(d, r)²/(2σ²) (the truncation r is the
//! outlier floor). The scan's log-likelihood is Σ ln p divided by the gain g (GMapping's
//! `ogain`). Unlike the lazy field's mean value s̄ the other matchers score, this is a
//! log-likelihood, which a particle filter needs for its weights and for the Gaussian fit
//! of the improved proposal (Grisetti et al. 2007, eqs. 14–16).
//!
//! Two truncations, coarse to fine, are the caller's choice: the coarse search and the hill
//! climber's coarse phase score with a wide r (`capture`, e.g. the field's full reach) so
//! that a pose several centimetres off still feels the walls; the fine phase with the
//! model's own r, so that beams ending on clutter pull the mode less.

use super::hill_climb::{climb, Climb};
use crate::cell::CellIndex;
use crate::grid::distance::DistanceField;
use crate::scan::PreparedScan;
use slam_models::{Matrix3, Point2, Pose2, Vector3};

/// The parameters of the truncated endpoint model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EndpointModel {
    /// 1/(2σ²·g), per m².
    pub k: f64,
    /// Truncation r, metres: distances beyond it count as r (at most the field's reach).
    pub radius: f64,
    /// The gain g itself: `g ·` an [`EndpointScore::log_likelihood`] is the untempered
    /// Σ ln p.
    pub gain: f64,
}

impl EndpointModel {
    /// The model with standard deviation `sigma` (metres), truncation `radius` (metres) and
    /// gain `gain` (≥ 1 tempers the scan's likelihood): k = 1/(2σ²·g).
    pub fn new(sigma: f64, radius: f64, gain: f64) -> Self {
        Self {
            k: 1.0 / (2.0 * sigma * sigma * gain),
            radius,
            gain,
        }
    }
}

/// The score of one pose: Σ ln p / g, and how many end points ended within the
/// truncation r (the beams that "find the map").
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EndpointScore {
    /// Σ −min(d, r)²·k over the end points.
    pub log_likelihood: f64,
    /// End points closer than r to an obstacle.
    pub inliers: usize,
}

/// Scores the robot-frame end points `points` at `pose` (bilinear interpolation of the
/// distance field between the four cell centres around each end point).
#[inline]
pub fn score(
    field: &DistanceField<'_>,
    points: &[Point2],
    pose: &Pose2,
    model: &EndpointModel,
) -> EndpointScore {
    let frame = field.frame();
    let inv = 1.0 / frame.resolution;
    let unit = field.metres_per_unit();
    let (s, c) = pose.theta.sin_cos();
    let (tx, ty) = (
        (pose.x - frame.origin.x) * inv - 0.5,
        (pose.y - frame.origin.y) * inv - 0.5,
    );
    let (s, c) = (s * inv, c * inv);
    let mut sum = 0.0;
    let mut inliers = 0;
    let r_in = model.radius * 0.999;
    let mut field = field.cursor();
    for p in points {
        // Cell-centre coordinates: cell (i, j) has its centre at (i, j).
        let u = c * p.x - s * p.y + tx;
        let v = s * p.x + c * p.y + ty;
        let (iu, iv) = (fast_floor(u), fast_floor(v));
        let (au, av) = (u - iu as f64, v - iv as f64);
        let d = field.dist4(CellIndex::new(iu, iv));
        let d0 = d[0] as f64 + au * (d[1] as f64 - d[0] as f64);
        let d1 = d[2] as f64 + au * (d[3] as f64 - d[2] as f64);
        let dm = ((d0 + av * (d1 - d0)) * unit).min(model.radius);
        if dm < r_in {
            inliers += 1;
        }
        sum += dm * dm;
    }
    EndpointScore {
        log_likelihood: -model.k * sum,
        inliers,
    }
}

/// ⌊x⌋ as an integer without a libm call (x well inside the i32 range; NaN maps to 0).
#[inline(always)]
fn fast_floor(x: f64) -> i32 {
    let i = x as i32;
    i - ((i as f64) > x) as i32
}

/// The score of every matching point of `scan` at `pose`.
#[inline]
pub fn score_scan(
    field: &DistanceField<'_>,
    scan: &PreparedScan,
    pose: &Pose2,
    model: &EndpointModel,
) -> EndpointScore {
    score(field, &scan.points, pose, model)
}

/// The log-likelihood of the coarse subset ([`PreparedScan::coarse_points`]) at `pose`, for
/// choosing between starting points.
pub fn coarse_score(
    field: &DistanceField<'_>,
    scan: &PreparedScan,
    pose: &Pose2,
    model: &EndpointModel,
) -> f64 {
    score(field, scan.coarse_points(), pose, model).log_likelihood
}

/// A matched pose and its score.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EndpointMatch {
    /// The pose (world frame).
    pub pose: Pose2,
    /// Its score under the fine model.
    pub score: EndpointScore,
}

/// Hill-climbing parameters (GMapping's `lstep`, `astep`, `iterations`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HillClimbSteps {
    /// Initial translation step, metres.
    pub linear_step: f64,
    /// Initial rotation step, radians.
    pub angular_step: f64,
    /// Step halvings before stopping.
    pub refinements: usize,
}

/// Most iterations (tries of the six moves) of one [`hill_climb`]: a hard cap that keeps
/// pathological inputs bounded (≈ GMapping's ~121 evaluations).
const CLIMB_BUDGET: u32 = 64;

/// GMapping-style hill climbing from `initial` (the crate's climber, Grisetti et al. 2007
/// §VI) in two phases: while the steps are at least a quarter of the initial ones, the
/// coarse subset scores under `capture` (4× cheaper evaluations, the wide truncation's
/// capture range); then every point under `model`, which also scores the result.
pub fn hill_climb(
    field: &DistanceField<'_>,
    scan: &PreparedScan,
    initial: &Pose2,
    capture: &EndpointModel,
    model: &EndpointModel,
    steps: &HillClimbSteps,
) -> EndpointMatch {
    let mut c = Climb {
        pose: *initial,
        linear_step: steps.linear_step,
        angular_step: steps.angular_step,
        halvings: 0,
        budget: CLIMB_BUDGET,
    };
    let refinements = u32::try_from(steps.refinements).unwrap_or(u32::MAX);
    if scan.has_coarse_subset() {
        let points = &scan.coarse[..];
        let start = score(field, points, &c.pose, capture);
        climb(
            &mut c,
            2.min(refinements),
            start,
            |s| s.log_likelihood,
            |p| score(field, points, p, capture),
        );
    }
    let start = score(field, &scan.points, &c.pose, model);
    let best = climb(
        &mut c,
        refinements.saturating_add(1),
        start,
        |s| s.log_likelihood,
        |p| score(field, &scan.points, p, model),
    );
    EndpointMatch {
        pose: c.pose,
        score: best,
    }
}

/// The window of [`grid_search`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SearchWindow {
    /// ± this in x and y around the initial pose, metres.
    pub range_xy: f64,
    /// Translation step, metres (> 0).
    pub step_xy: f64,
    /// ± this in θ, radians.
    pub range_theta: f64,
    /// Rotation step, radians (> 0).
    pub step_theta: f64,
    /// R⁻¹, the inverse of the motion model's covariance at the initial pose (the prior).
    pub information: Matrix3,
}

impl SearchWindow {
    /// The log motion prior −½ eᵀR⁻¹e of `candidate` = `initial` ⊕ δ, with
    /// e = (x − x₀, y − y₀, δθ): it keeps ambiguous directions (corridors) at the
    /// prediction.
    #[inline]
    pub fn log_prior(&self, initial: &Pose2, candidate: &Pose2, dtheta: f64) -> f64 {
        let e = Vector3::new(candidate.x - initial.x, candidate.y - initial.y, dtheta);
        -0.5 * e.dot(&(self.information * e))
    }
}

/// Exhaustive coarse search (Olson's correlative matching, ICRA 2009, at one coarse
/// resolution) over the poses `initial` ⊕ (dx, dy, dθ) with |dx|, |dy| ≤ `range_xy` in
/// steps of `step_xy` and |dθ| ≤ `range_theta` in steps of `step_theta`, scored with the
/// coarse subset (times the subsampling factor) plus the log motion prior
/// −½ eᵀR⁻¹e: the mode of likelihood × motion model on the lattice. Returns the best pose
/// (the initial pose wins ties).
pub fn grid_search(
    field: &DistanceField<'_>,
    scan: &PreparedScan,
    initial: &Pose2,
    model: &EndpointModel,
    window: &SearchWindow,
) -> Pose2 {
    let points = scan.coarse_points();
    let mut best = *initial;
    let scale = scan.points.len() as f64 / points.len().max(1) as f64;
    let mut top = scale * score(field, points, initial, model).log_likelihood;
    let nxy = (window.range_xy / window.step_xy).floor() as i32;
    let nth = (window.range_theta / window.step_theta).floor() as i32;
    for it in -nth..=nth {
        for iy in -nxy..=nxy {
            for ix in -nxy..=nxy {
                if ix == 0 && iy == 0 && it == 0 {
                    continue;
                }
                let delta = Pose2::new(
                    ix as f64 * window.step_xy,
                    iy as f64 * window.step_xy,
                    it as f64 * window.step_theta,
                );
                let cand = initial.compose(&delta);
                let prior = window.log_prior(initial, &cand, delta.theta);
                let s = scale * score(field, points, &cand, model).log_likelihood + prior;
                if s > top {
                    top = s;
                    best = cand;
                }
            }
        }
    }
    best
}
