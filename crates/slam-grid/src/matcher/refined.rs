//! Correlative search followed by Gauss-Newton refinement.

use super::{CorrelativeMatcher, GaussNewtonMatcher, MatchResult};
use crate::error::GridError;
use crate::grid::OccupancyGrid;
use crate::scan::RangeData;
use serde::{Deserialize, Serialize};
use slam_models::Pose2;

/// [`CorrelativeMatcher`] (global within its window, cell accuracy), then
/// [`GaussNewtonMatcher`] from its result (sub-cell accuracy). If the refinement fails or
/// strays beyond its `max_displacement`, the correlative result is returned.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields, default)]
pub struct RefinedCorrelativeMatcher {
    /// The coarse global stage.
    pub correlative: CorrelativeMatcher,
    /// The refinement stage.
    pub refine: GaussNewtonMatcher,
}

impl RefinedCorrelativeMatcher {
    /// Matches `scan` around `initial`; see the type documentation.
    pub fn match_prepared(
        &self,
        grid: &OccupancyGrid,
        scan: &RangeData,
        initial: &Pose2,
    ) -> Result<MatchResult, GridError> {
        let coarse = self.correlative.match_prepared(grid, scan, initial)?;
        // Gauss-Newton only accepts steps that lower its cost, so its result is never worse
        // than its start under its own interpolant; it fails on degenerate geometry.
        match self.refine.match_prepared(grid, scan, &coarse.pose) {
            Ok(fine) => Ok(fine),
            Err(_) => Ok(coarse),
        }
    }
}

super::scan_matcher_by_inherent_method!(RefinedCorrelativeMatcher);
