//! GMapping-style hill climbing: the one climber of the crate ([`climb`]), used by
//! [`HillClimbMatcher`] on the lazy likelihood field and by
//! [`super::endpoint::hill_climb`] on the incremental distance field.

use super::MatchResult;
use super::{check_input, covariance_by_sampling, default_steps, mean_interpolated};
use crate::error::{ensure_config, GridError};
use crate::grid::OccupancyGrid;
use crate::scan::RangeData;
use serde::{Deserialize, Serialize};
use slam_models::Pose2;

/// Where a climb stands: the pose, its current steps, how often they were halved and how
/// many iterations (tries of the six moves) are left.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Climb {
    pub pose: Pose2,
    pub linear_step: f64,
    pub angular_step: f64,
    pub halvings: u32,
    pub budget: u32,
}

/// GMapping's `ScanMatcher::optimize` (Grisetti et al. 2007 §VI): from `c.pose` try the six
/// moves ±Δx, ±Δy (world axes) and ±Δθ; take the best if it improves on `start` (the
/// score of `c.pose`), otherwise halve both steps; until the steps were halved `last`
/// times or the budget of iterations is spent. After a step the move that would undo it is
/// not tried again (it leads back to a pose that scored lower). `value` orders scores
/// (higher is better). Returns the score of the final `c.pose`.
///
/// A climb may run in phases with different scorers (coarse then fine): `c` carries the
/// steps, halvings and budget from one phase to the next.
pub(crate) fn climb<S: Copy>(
    c: &mut Climb,
    last: u32,
    start: S,
    value: impl Fn(&S) -> f64,
    mut score: impl FnMut(&Pose2) -> S,
) -> S {
    let mut best_score = start;
    let mut back: Option<usize> = None;
    while c.halvings < last && c.budget > 0 {
        c.budget -= 1;
        let (best, ls, as_) = (c.pose, c.linear_step, c.angular_step);
        let moves = [
            Pose2::new(best.x + ls, best.y, best.theta),
            Pose2::new(best.x - ls, best.y, best.theta),
            Pose2::new(best.x, best.y + ls, best.theta),
            Pose2::new(best.x, best.y - ls, best.theta),
            Pose2::new(best.x, best.y, best.theta + as_),
            Pose2::new(best.x, best.y, best.theta - as_),
        ];
        let mut improved = None;
        let mut top = value(&best_score);
        for (i, m) in moves.into_iter().enumerate() {
            // Moves come in ± pairs: i ^ 1 undoes i.
            if back == Some(i) {
                continue;
            }
            let s = score(&m);
            if value(&s) > top {
                top = value(&s);
                improved = Some((i, m, s));
            }
        }
        match improved {
            Some((i, m, s)) => {
                c.pose = m;
                best_score = s;
                back = Some(i ^ 1);
            }
            None => {
                c.linear_step *= 0.5;
                c.angular_step *= 0.5;
                c.halvings += 1;
                back = None;
            }
        }
    }
    best_score
}

/// Greedy hill climbing over (x, y, θ) with step halving, as GMapping's
/// `ScanMatcher::optimize` (Grisetti et al. 2007; the crate's one climber, shared with
/// [`super::endpoint::hill_climb`]):
/// from the current pose try the six moves ±Δx, ±Δy (world axes), ±Δθ; take the best one
/// if it improves the score; otherwise halve both steps, up to `refinements` times. The
/// score is the mean bilinearly interpolated field value, so the search keeps improving
/// below one cell.
///
/// Converges to the local optimum nearest to the initial pose: use it when the initial
/// error is below a few cells (odometry between close scans); otherwise
/// [`super::CorrelativeMatcher`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields, default)]
pub struct HillClimbMatcher {
    /// Initial translation step, metres. Default 0.05 m (GMapping `lstep`).
    pub linear_step: f64,
    /// Initial rotation step, radians. Default 0.05 rad (GMapping `astep`).
    pub angular_step: f64,
    /// Number of step halvings before stopping. Default 5 (GMapping `iterations`).
    pub refinements: u32,
    /// Safety bound on the number of accepted moves (the climber's budget is this plus one
    /// iteration per refinement). Default 200.
    pub max_moves: u32,
    /// Fewer end points than this is an error. Default 10.
    pub min_points: usize,
}

impl Default for HillClimbMatcher {
    fn default() -> Self {
        Self {
            linear_step: 0.05,
            angular_step: 0.05,
            refinements: 5,
            max_moves: 200,
            min_points: 10,
        }
    }
}

impl HillClimbMatcher {
    /// Checks the steps are positive.
    pub fn validate(&self) -> Result<(), GridError> {
        ensure_config(
            self.linear_step > 0.0,
            "linear_step",
            self.linear_step,
            "> 0 m",
        )?;
        ensure_config(
            self.angular_step > 0.0,
            "angular_step",
            self.angular_step,
            "> 0 rad",
        )
    }

    /// Matches `scan` starting at `initial`; see the type documentation.
    pub fn match_prepared(
        &self,
        grid: &OccupancyGrid,
        scan: &RangeData,
        initial: &Pose2,
    ) -> Result<MatchResult, GridError> {
        self.validate()?;
        let reach = self.linear_step * self.max_moves as f64;
        check_input(grid, scan, initial, self.min_points, reach)?;
        let mut c = Climb {
            pose: *initial,
            linear_step: self.linear_step,
            angular_step: self.angular_step,
            halvings: 0,
            budget: self
                .max_moves
                .saturating_add(self.refinements.saturating_add(1)),
        };
        let start = mean_interpolated(grid, scan, initial);
        let best = climb(
            &mut c,
            self.refinements.saturating_add(1),
            start,
            |s| *s,
            |p| mean_interpolated(grid, scan, p),
        );
        let pose = c.pose;
        let covariance = covariance_by_sampling(grid, scan, &pose, default_steps(grid, scan));
        Ok(MatchResult {
            pose,
            score: best,
            covariance,
        })
    }
}

super::scan_matcher_by_inherent_method!(HillClimbMatcher);
