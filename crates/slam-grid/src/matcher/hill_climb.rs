//! GMapping-style hill climbing.

use super::{check_input, covariance_by_sampling, default_steps, mean_interpolated};
use super::{MatchResult, ScanMatcher};
use crate::error::{ensure_config, GridError};
use crate::grid::OccupancyGrid;
use crate::scan::PreparedScan;
use serde::{Deserialize, Serialize};
use slam_models::Pose2;

/// Greedy hill climbing over (x, y, θ) with step halving, as GMapping's
/// `ScanMatcher::optimize` (Grisetti et al. 2007): from the current pose try the six moves
/// ±Δx, ±Δy (world axes), ±Δθ; take the best one if it improves the score; otherwise halve
/// both steps, up to `refinements` times. The score is the mean bilinearly interpolated
/// field value, so the search keeps improving below one cell.
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
    /// Safety bound on the number of accepted moves. Default 200.
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
        scan: &PreparedScan,
        initial: &Pose2,
    ) -> Result<MatchResult, GridError> {
        self.validate()?;
        let reach = self.linear_step * self.max_moves as f64;
        check_input(grid, scan, initial, self.min_points, reach)?;
        let mut pose = *initial;
        let mut best = mean_interpolated(grid, scan, &pose);
        let (mut ls, mut las) = (self.linear_step, self.angular_step);
        let mut refinements = 0;
        let mut moves = 0;
        while refinements <= self.refinements && moves < self.max_moves {
            let candidates = [
                Pose2::new(pose.x + ls, pose.y, pose.theta),
                Pose2::new(pose.x - ls, pose.y, pose.theta),
                Pose2::new(pose.x, pose.y + ls, pose.theta),
                Pose2::new(pose.x, pose.y - ls, pose.theta),
                Pose2::new(pose.x, pose.y, pose.theta + las),
                Pose2::new(pose.x, pose.y, pose.theta - las),
            ];
            let mut improved = None;
            let mut local_best = best;
            for c in candidates {
                let s = mean_interpolated(grid, scan, &c);
                if s > local_best {
                    local_best = s;
                    improved = Some(c);
                }
            }
            match improved {
                Some(c) => {
                    pose = c;
                    best = local_best;
                    moves += 1;
                }
                None => {
                    ls *= 0.5;
                    las *= 0.5;
                    refinements += 1;
                }
            }
        }
        let covariance = covariance_by_sampling(grid, scan, &pose, default_steps(grid, scan));
        Ok(MatchResult {
            pose,
            score: best,
            covariance,
        })
    }
}

impl ScanMatcher for HillClimbMatcher {
    fn match_prepared(
        &self,
        grid: &OccupancyGrid,
        scan: &PreparedScan,
        initial: &Pose2,
    ) -> Result<MatchResult, GridError> {
        HillClimbMatcher::match_prepared(self, grid, scan, initial)
    }
}
