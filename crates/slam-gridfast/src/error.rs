//! Errors of grid-based FastSLAM.

use slam_models::{ConfigError, FilterError};
use thiserror::Error;

/// What went wrong in [`crate::GridFastSlam`]. Each variant says what was expected.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum GridFastError {
    /// A field of [`crate::GridFastConfig`] was outside its documented range.
    #[error(transparent)]
    InvalidConfig(#[from] ConfigError),
    /// An input record was rejected (non-finite odometry or an invalid scan).
    #[error("record {index} (t = {t}) rejected: {reason}")]
    InvalidRecord {
        /// 0-based index of the record in the order it was passed.
        index: usize,
        /// The record's time, seconds.
        t: f64,
        /// Why it was rejected.
        reason: String,
    },
    /// slam-grid refused the map configuration (resolution, log-odds, field radius);
    /// [`crate::GridFastConfig::validate`] checks the same ranges first.
    #[error("particle map: {0}")]
    Map(#[from] slam_grid::GridError),
    /// The particle weights became invalid (every particle has zero weight, or a NaN).
    #[error("numerical failure at processed scan {scan}: {reason}")]
    Numerical {
        /// 0-based index of the processed scan.
        scan: usize,
        /// What failed.
        reason: String,
    },
}

/// Sorts the error into a [`FilterError`] category (a rejected record as `InvalidInput`,
/// invalid weights as `Numerical`, everything else as `Other`) and keeps it, typed, as the
/// source (`FilterError::downcast_ref::<GridFastError>()` gives it back).
impl From<GridFastError> for FilterError {
    fn from(e: GridFastError) -> Self {
        match e {
            GridFastError::InvalidRecord { .. } => FilterError::invalid_input(e),
            GridFastError::Numerical { .. } => FilterError::numerical(e),
            _ => FilterError::other(e),
        }
    }
}
