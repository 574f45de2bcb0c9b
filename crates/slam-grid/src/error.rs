//! Errors of slam-grid.

use slam_models::{ConfigError, FilterError, ModelError};
use thiserror::Error;

/// What went wrong in a grid, field or matcher operation.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum GridError {
    /// A value that must be finite was NaN or infinite (poses, ranges, configuration).
    #[error("{what} is not finite ({value})")]
    NonFinite {
        /// Which quantity.
        what: &'static str,
        /// The offending value.
        value: f64,
    },
    /// A configuration parameter was outside its documented range.
    #[error(transparent)]
    InvalidConfig(#[from] ConfigError),
    /// A [`crate::RangeData`] was integrated into a grid whose sensor model classifies
    /// beams by other range rules (`min_range`, `max_range`, `far_hits_clear`,
    /// `no_return_range`) than the model it was built with: build it with the grid's
    /// model ([`crate::OccupancyGrid::sensor_model`]).
    #[error(
        "the scan was classified into returns and misses under other range rules than the map's sensor model (min_range, max_range, far_hits_clear, no_return_range)"
    )]
    OtherRangeRules,
    /// A scan had too few usable end points to be matched.
    #[error("scan has {found} usable end points; at least {needed} are needed for matching")]
    TooFewPoints {
        /// End points usable for matching (hits within the matcher's range limits).
        found: usize,
        /// The configured minimum.
        needed: usize,
    },
    /// The matcher's normal equations were singular (degenerate geometry, e.g. a single
    /// straight wall, or no end point near an obstacle).
    #[error("degenerate scan matching problem: {0}")]
    Degenerate(&'static str),
    /// A scan would stretch the map beyond its documented maximum extent
    /// ([`crate::grid::MAX_MAP_EXTENT_CELLS`] per side, [`crate::grid::MAX_MAP_CELLS`] in
    /// all), usually because of a glitched pose or range far from the rest of the map.
    #[error(
        "the map would span {width} × {height} cells ({:.0} m × {:.0} m at {resolution} m per cell), \
         beyond the maximum extent of {} cells per side and {} cells in all; \
         a glitched pose or range far from the rest of the map (an odometry jump) usually causes this",
        *.width as f64 * .resolution,
        *.height as f64 * .resolution,
        crate::grid::MAX_MAP_EXTENT_CELLS,
        crate::grid::MAX_MAP_CELLS
    )]
    MapTooLarge {
        /// Width of the bounding box of everything covered, cells.
        width: u64,
        /// Height of that box, cells.
        height: u64,
        /// Cell edge, metres.
        resolution: f64,
    },
    /// A pose, end point or search window lies farther from the grid origin than cell
    /// arithmetic allows ([`crate::matcher::MAX_MATCH_CELLS`]).
    #[error(
        "{what} reaches {cells:.3e} cells from the grid origin, beyond the ±2^30 cells \
         (MAX_MATCH_CELLS) within which cell indices are exact: a glitched pose"
    )]
    OutOfGrid {
        /// What was out of reach.
        what: &'static str,
        /// Its distance from the origin, cells (largest coordinate).
        cells: f64,
    },
    /// A thresholded search (branch and bound) found no pose scoring at least its
    /// threshold.
    #[error("no pose in the search window scores at least min_score = {min_score} (mean field value per end point)")]
    NoMatch {
        /// The threshold, mean field value per end point in [0, 1].
        min_score: f64,
    },
    /// A model-layer check failed (invalid scan readings, pose).
    #[error(transparent)]
    Model(#[from] ModelError),
}

/// Sorts the error into a [`FilterError`] category (non-finite input and model-layer
/// checks as `InvalidInput`, everything else as `Other`) and keeps it, typed, as the source
/// (`FilterError::downcast_ref::<GridError>()` gives it back).
impl From<GridError> for FilterError {
    fn from(e: GridError) -> Self {
        match e {
            GridError::NonFinite { .. } | GridError::Model(_) => FilterError::invalid_input(e),
            _ => FilterError::other(e),
        }
    }
}

/// `Err(GridError::NonFinite)` unless `value` is finite.
#[inline]
pub(crate) fn ensure_finite(what: &'static str, value: f64) -> Result<f64, GridError> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(GridError::NonFinite { what, value })
    }
}

/// `Err(GridError::InvalidConfig)` unless `ok`.
#[inline]
pub(crate) fn ensure_config(
    ok: bool,
    name: &'static str,
    value: f64,
    expected: &'static str,
) -> Result<(), GridError> {
    Ok(slam_models::error::ensure_config(
        ok, "grid", name, value, expected,
    )?)
}
