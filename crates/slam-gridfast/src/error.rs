//! Errors of grid-based FastSLAM.

use thiserror::Error;

/// What went wrong in [`crate::GridFastSlam`]. Each variant says what was expected.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum GridFastError {
    /// A configuration value was outside its documented range.
    #[error("invalid configuration: {field} = {value}, expected {expected}")]
    InvalidConfig {
        /// The field of [`crate::GridFastConfig`].
        field: &'static str,
        /// The value given.
        value: f64,
        /// What was expected, in words.
        expected: &'static str,
    },
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
