//! The error type of slam-ekf.

use slam_models::{ConfigError, FilterError, ModelError};
use thiserror::Error;

/// What went wrong in EKF-SLAM. Each variant says what was expected.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum EkfError {
    /// A field of [`crate::EkfConfig`] was outside its documented range.
    #[error(transparent)]
    InvalidConfig(#[from] ConfigError),
    /// An input (control, observation, initial pose) was non-finite or otherwise invalid.
    #[error("invalid input: {0}")]
    InvalidInput(String),
    /// An observation carried no landmark id although the association mode is
    /// [`crate::AssociationMode::KnownIds`].
    #[error("observation {index} has no landmark id, but the association mode is \"known-ids\"")]
    MissingId {
        /// Index of the observation in the batch.
        index: usize,
    },
    /// The innovation covariance S of an update was not positive definite (the covariance
    /// of the state has lost positive definiteness).
    #[error("innovation covariance of a {dim}-dimensional update is not positive definite")]
    InnovationNotPositiveDefinite {
        /// Dimension of the stacked innovation.
        dim: usize,
    },
    /// A diagonal entry of the state covariance became non-positive or non-finite.
    #[error("state covariance entry ({index}, {index}) = {value} is not positive and finite")]
    CovarianceNotPositive {
        /// Index into the state vector.
        index: usize,
        /// The diagonal value found.
        value: f64,
    },
    /// A new landmark would exceed [`crate::EkfConfig::max_landmarks`].
    #[error(
        "the map already holds max-landmarks = {max} landmarks; raise max-landmarks (at most 20000; \
         the covariance takes (3 + 2n)² × 8 bytes)"
    )]
    TooManyLandmarks {
        /// The configured cap.
        max: usize,
    },
    /// Memory for the state covariance could not be reserved.
    #[error("cannot allocate the {dim} × {dim} state covariance ({bytes} bytes)")]
    OutOfMemory {
        /// Rows = columns reserved.
        dim: usize,
        /// Bytes asked for.
        bytes: u128,
    },
    /// A model computation failed.
    #[error(transparent)]
    Model(#[from] ModelError),
}

/// Sorts the error into a [`FilterError`] category and keeps it, typed, as the source
/// (`FilterError::downcast_ref::<EkfError>()` gives it back).
impl From<EkfError> for FilterError {
    fn from(e: EkfError) -> Self {
        match e {
            EkfError::InvalidInput(_) | EkfError::MissingId { .. } | EkfError::Model(_) => {
                FilterError::invalid_input(e)
            }
            EkfError::InnovationNotPositiveDefinite { .. }
            | EkfError::CovarianceNotPositive { .. } => FilterError::numerical(e),
            _ => FilterError::other(e),
        }
    }
}
