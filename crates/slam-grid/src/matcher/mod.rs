//! Scan matchers: find the robot pose at which a scan best fits a grid's likelihood field.
//!
//! Every matcher takes a [`RangeData`] (end points precomputed in the robot frame, so a
//! candidate pose costs one `sin_cos`, never one per beam) and returns a [`MatchResult`]:
//!
//! * [`HillClimbMatcher`]: GMapping-style greedy search over (x, y, θ) with step halving;
//! * [`CorrelativeMatcher`]: exhaustive two-level (coarse max-pooled / fine) correlative
//!   search with branch and bound (Olson, ICRA 2009), for large initial errors;
//! * [`GaussNewtonMatcher`]: Gauss-Newton on the bilinearly interpolated field (Hector SLAM,
//!   Kohlbrecher et al. 2011), for sub-cell accuracy;
//! * [`RefinedCorrelativeMatcher`]: correlative search, then Gauss-Newton refinement;
//! * [`BranchBoundMatcher`]: depth-first branch and bound over a [`MaxPyramid`] of many
//!   levels (Olson 2009, §IV-C; Cartographer's fast correlative matcher, Hess et al. 2016,
//!   §V), with a reusable pyramid and a score threshold, for loop closures.
//!
//! Scores are the mean field value s̄ = (1/n)·Σ s(pᵢ) ∈ (0, 1] over the n end points
//! (1: every end point on an obstacle).
//!
//! [`endpoint`] scores the same endpoint model as a truncated log-likelihood on a grid's
//! incrementally repaired distance field, with the same hill climber and an exhaustive
//! search under a motion prior: the matching of grid FastSLAM (slam-gridfast), which needs
//! log-likelihoods for its weights, and of scan-matching odometry
//! ([`crate::ScanMatchOdometry`]). The mean-field matchers above serve the pose-graph front
//! end (slam-graph: local matching, loop closures, the response covariance).

mod branch_bound;
mod correlative;
pub mod endpoint;
mod gauss_newton;
mod hill_climb;
mod levels;
mod pyramids;
mod refined;

pub use branch_bound::{BranchBoundMatcher, MaxPyramid, MAX_PYRAMID_CELLS, MAX_PYRAMID_DEPTH};
pub use correlative::CorrelativeMatcher;
pub use gauss_newton::{GaussNewtonMatcher, Interpolation};
pub use hill_climb::HillClimbMatcher;
pub use refined::RefinedCorrelativeMatcher;

use crate::error::GridError;
use crate::grid::OccupancyGrid;
use crate::scan::RangeData;
use slam_models::{LaserScan, Matrix3, Point2, Pose2};

/// The outcome of a scan match.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MatchResult {
    /// The matched robot pose (world frame).
    pub pose: Pose2,
    /// Mean field value of the end points at `pose`, in (0, 1].
    pub score: f64,
    /// Estimated 3×3 covariance of `pose` (m², rad²), symmetric positive definite.
    pub covariance: Matrix3,
}

/// Common interface of the matchers (object safe).
pub trait ScanMatcher {
    /// Matches a prepared scan against `grid`, starting from (or searching around) `initial`.
    fn match_prepared(
        &self,
        grid: &OccupancyGrid,
        scan: &RangeData,
        initial: &Pose2,
    ) -> Result<MatchResult, GridError>;

    /// Prepares `scan` and matches it.
    fn match_scan(
        &self,
        grid: &OccupancyGrid,
        scan: &LaserScan,
        initial: &Pose2,
    ) -> Result<MatchResult, GridError> {
        // Under the grid's own model (only the matching points are used here).
        let prepared = RangeData::new(scan, grid.sensor_model())?;
        self.match_prepared(grid, &prepared, initial)
    }
}

/// `impl ScanMatcher for T` by `T`'s inherent `match_prepared` (the matchers whose search
/// is a method of their own, callable without the trait in scope).
macro_rules! scan_matcher_by_inherent_method {
    ($t:ty) => {
        impl $crate::matcher::ScanMatcher for $t {
            fn match_prepared(
                &self,
                grid: &$crate::OccupancyGrid,
                scan: &$crate::RangeData,
                initial: &$crate::Pose2,
            ) -> Result<$crate::MatchResult, $crate::GridError> {
                <$t>::match_prepared(self, grid, scan, initial)
            }
        }
    };
}
pub(crate) use scan_matcher_by_inherent_method;

/// The rotation step of a correlative search: `configured` when positive, else the angle
/// that moves the farthest end point (`max_point_range`, at least one cell) by one cell
/// of `resolution`: acos(1 − res² / (2 r²)) (Olson 2009 §IV), at least 10⁻⁴ rad.
pub(crate) fn rotation_step(configured: f64, resolution: f64, max_point_range: f64) -> f64 {
    if configured > 0.0 {
        return configured;
    }
    let r_max = max_point_range.max(resolution);
    (1.0 - resolution * resolution / (2.0 * r_max * r_max))
        .clamp(-1.0, 1.0)
        .acos()
        .max(1e-4)
}

/// Largest distance from the grid origin, in cells, that a matched pose may reach with its
/// end points and its search window: 2³⁰ cells (53 687 km at 5 cm, the bound scan
/// integration keeps too), far beyond any map ([`crate::MAX_MAP_EXTENT_CELLS`]) and far
/// enough from `i32::MAX` that the matchers' cell arithmetic (window corners, widths,
/// offsets) cannot overflow.
pub const MAX_MATCH_CELLS: f64 = (1u32 << 30) as f64;

/// Rejects a non-finite initial pose, scans with fewer than `min_points` end points, and
/// an initial pose whose end points, moved by up to `reach` metres (the search window),
/// would leave ±[`MAX_MATCH_CELLS`] cells of the grid origin.
pub(crate) fn check_input(
    grid: &OccupancyGrid,
    scan: &RangeData,
    initial: &Pose2,
    min_points: usize,
    reach: f64,
) -> Result<(), GridError> {
    if !initial.is_finite() {
        return Err(GridError::NonFinite {
            what: "initial pose",
            value: f64::NAN,
        });
    }
    let (u, v) = grid.frame().world_to_continuous(&initial.translation());
    let far = u.abs().max(v.abs()) + (scan.max_point_range + reach) / grid.resolution() + 2.0;
    if far.is_nan() || far > MAX_MATCH_CELLS {
        return Err(GridError::OutOfGrid {
            what: "scan matching around the initial pose",
            cells: far,
        });
    }
    if scan.points.len() < min_points.max(1) {
        return Err(GridError::TooFewPoints {
            found: scan.points.len(),
            needed: min_points.max(1),
        });
    }
    Ok(())
}

/// World positions of the scan's end points under `pose`: R(θ)·p + t.
#[inline]
pub(crate) fn transform_points<'a>(
    points: &'a [Point2],
    pose: &Pose2,
) -> impl Iterator<Item = Point2> + 'a {
    let (s, c) = pose.theta.sin_cos();
    let (x, y) = (pose.x, pose.y);
    points
        .iter()
        .map(move |p| Point2::new(x + c * p.x - s * p.y, y + s * p.x + c * p.y))
}

/// The end points of a scan whose cells under many poses ([`PointCells::cells_at`]) the
/// search lattices take.
pub(crate) struct PointCells<'a> {
    points: &'a [Point2],
    /// max |x| + |y| over the points (≥ each one's norm); NaN when one is not finite.
    reach: f64,
}

impl<'a> PointCells<'a> {
    pub(crate) fn new(points: &'a [Point2]) -> Self {
        let finite = points.iter().all(|p| p.x.is_finite() && p.y.is_finite());
        let reach = if finite {
            points
                .iter()
                .map(|p| p.x.abs() + p.y.abs())
                .fold(0.0, f64::max)
        } else {
            f64::NAN
        };
        Self { points, reach }
    }

    /// The cell of every end point under `pose` into `out` (one per point): the same
    /// arithmetic as [`transform_points`] and [`crate::cell::GridFrame::world_to_cell`], so
    /// the same cells, in a loop the compiler vectorises. When every cell coordinate is
    /// bounded well inside the `i32` range (|u| ≤ (|t − origin| + |p|)/resolution, a
    /// rotation keeping |p|; room left for rounding) the floor is
    /// [`crate::cell::floor_i32_bounded`], without a float-to-integer conversion.
    #[inline]
    pub(crate) fn cells_at(
        &self,
        frame: &crate::cell::GridFrame,
        pose: &Pose2,
        out: &mut [crate::cell::CellIndex],
    ) {
        use crate::cell::{floor_i32, floor_i32_bounded, FLOOR_BOUNDED_LIMIT};
        let (s, c) = pose.theta.sin_cos();
        let (x, y) = (pose.x, pose.y);
        let inv = 1.0 / frame.resolution;
        let (ox, oy) = (frame.origin.x, frame.origin.y);
        let extent = (x - ox).abs().max((y - oy).abs()) + self.reach + 1.0;
        let affine = [x, y, c, s, ox, oy, inv];
        if extent * inv * 2.0 < FLOOR_BOUNDED_LIMIT {
            self.fill(affine, out, floor_i32_bounded);
        } else {
            self.fill(affine, out, floor_i32);
        }
    }

    /// The loop of [`PointCells::cells_at`], instantiated for each floor (so inlined and
    /// vectorised): `[x, y, cos θ, sin θ, origin x, origin y, 1 / resolution]`.
    #[inline(always)]
    fn fill(
        &self,
        [x, y, c, s, ox, oy, inv]: [f64; 7],
        out: &mut [crate::cell::CellIndex],
        floor: impl Fn(f64) -> i32,
    ) {
        for (cell, p) in out.iter_mut().zip(self.points) {
            let u = (x + c * p.x - s * p.y - ox) * inv;
            let v = (y + s * p.x + c * p.y - oy) * inv;
            *cell = crate::cell::CellIndex::new(floor(u), floor(v));
        }
    }
}

/// Mean field value of the end points at `pose`, looking up the cell of each end point.
pub fn mean_field_value(grid: &OccupancyGrid, scan: &RangeData, pose: &Pose2) -> f64 {
    if scan.points.is_empty() {
        return 0.0;
    }
    let sum: f64 = transform_points(&scan.points, pose)
        .map(|p| grid.likelihood(grid.world_to_cell(&p)) as f64)
        .sum();
    sum / scan.points.len() as f64
}

/// Mean of the bilinearly interpolated field over the end points at `pose`.
pub(crate) fn mean_interpolated(grid: &OccupancyGrid, scan: &RangeData, pose: &Pose2) -> f64 {
    if scan.points.is_empty() {
        return 0.0;
    }
    let sum: f64 = transform_points(&scan.points, pose)
        .map(|p| grid.likelihood_interpolated(&p).0)
        .sum();
    sum / scan.points.len() as f64
}

/// ln p(z | x, m) of the whole scan under the likelihood-field model (PR table 6.3): the sum
/// over end points of ln(z_hit·N(d; 0, σ²) + z_rand/z_max), with d read from the cell of each
/// end point. Beams are treated as independent, as in the book.
pub fn scan_log_likelihood(grid: &OccupancyGrid, scan: &RangeData, pose: &Pose2) -> f64 {
    let params = grid.likelihood_params();
    transform_points(&scan.points, pose)
        .map(|p| params.log_likelihood(grid.likelihood(grid.world_to_cell(&p))))
        .sum()
}

/// Covariance of the pose by sampling the scan likelihood on a 3×3×3 lattice of poses
/// around `mode` with spacings `steps` (x, y, θ): weights wₖ ∝ p(z | xₖ, m) (the Gaussian
/// fit GMapping's improved proposal uses, Grisetti et al. 2007 eq. 16–18), plus the
/// lattice's own quantisation variance step²/12 on the diagonal so the result stays PD
/// when the likelihood is sharper than the lattice.
pub(crate) fn covariance_by_sampling(
    grid: &OccupancyGrid,
    scan: &RangeData,
    mode: &Pose2,
    steps: [f64; 3],
) -> Matrix3 {
    covariance_from_log_likelihood(mode, steps, |p| scan_log_likelihood(grid, scan, p))
}

/// [`covariance_by_sampling`] with the scan log-likelihood given as a function of the pose
/// (for matchers that score on their own copy of the field).
pub(crate) fn covariance_from_log_likelihood(
    mode: &Pose2,
    steps: [f64; 3],
    log_likelihood: impl Fn(&Pose2) -> f64,
) -> Matrix3 {
    let mut samples = Vec::with_capacity(27);
    for i in -1..=1 {
        for j in -1..=1 {
            for k in -1..=1 {
                let d = [
                    i as f64 * steps[0],
                    j as f64 * steps[1],
                    k as f64 * steps[2],
                ];
                let pose = Pose2::new(mode.x + d[0], mode.y + d[1], mode.theta + d[2]);
                samples.push((d, log_likelihood(&pose)));
            }
        }
    }
    let max = samples
        .iter()
        .map(|s| s.1)
        .fold(f64::NEG_INFINITY, f64::max);
    let mut wsum = 0.0;
    let mut mean = [0.0; 3];
    for (d, ll) in &samples {
        let w = (ll - max).exp();
        wsum += w;
        for a in 0..3 {
            mean[a] += w * d[a];
        }
    }
    let mut cov = Matrix3::zeros();
    if wsum > 0.0 && wsum.is_finite() {
        mean.iter_mut().for_each(|m| *m /= wsum);
        for (d, ll) in &samples {
            let w = (ll - max).exp() / wsum;
            for a in 0..3 {
                for b in 0..3 {
                    cov[(a, b)] += w * (d[a] - mean[a]) * (d[b] - mean[b]);
                }
            }
        }
    }
    for a in 0..3 {
        cov[(a, a)] += steps[a] * steps[a] / 12.0;
    }
    (cov + cov.transpose()) * 0.5
}

/// Lattice spacings for [`covariance_by_sampling`]: one cell in x and y, and the rotation
/// that moves the mean end point by one cell.
pub(crate) fn default_steps(grid: &OccupancyGrid, scan: &RangeData) -> [f64; 3] {
    let res = grid.resolution();
    let n = scan.points.len().max(1) as f64;
    let mean_r = (scan.points.iter().map(|p| p.coords.norm()).sum::<f64>() / n).max(res);
    [res, res, res / mean_r]
}

#[cfg(test)]
mod tests;

/// The search-window checks shared by the correlative and branch-and-bound matchers: a
/// linear window ≥ 0 m, an angular window in [0, π] rad, an angular step ≥ 0 rad (0:
/// automatic).
pub(crate) fn validate_window(
    linear_window: f64,
    angular_window: f64,
    angular_step: f64,
) -> Result<(), crate::error::GridError> {
    use crate::error::ensure_config;
    ensure_config(
        linear_window >= 0.0,
        "linear_window",
        linear_window,
        ">= 0 m",
    )?;
    ensure_config(
        (0.0..=std::f64::consts::PI).contains(&angular_window),
        "angular_window",
        angular_window,
        "in [0, π] rad",
    )?;
    ensure_config(
        angular_step >= 0.0,
        "angular_step",
        angular_step,
        ">= 0 rad (0: automatic)",
    )
}
