//! Errors of the FastSLAM filters.

use slam_models::{FilterError, ModelError};
use thiserror::Error;

/// What went wrong in FastSLAM.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum FastSlamError {
    /// A configuration value was outside its documented range.
    #[error("invalid FastSLAM configuration: {field} = {value}, expected {expected}")]
    InvalidConfig {
        /// The field of [`crate::FastSlamConfig`].
        field: &'static str,
        /// The value given (as text).
        value: String,
        /// What was expected, in words.
        expected: &'static str,
    },
    /// An input (initial pose, control, observation) was not finite.
    #[error("invalid input: {what} is not finite ({value})")]
    NonFiniteInput {
        /// Which input.
        what: &'static str,
        /// The offending value.
        value: f64,
    },
    /// A model computation failed.
    #[error(transparent)]
    Model(#[from] ModelError),
    /// An update could take a particle's map past [`crate::FastSlamConfig::max_landmarks`].
    #[error(
        "a particle's map holds {landmarks} landmarks and this update brings {observations} \
         observations: more than max_landmarks = {max} could be mapped"
    )]
    TooManyLandmarks {
        /// The largest map among the particles.
        landmarks: usize,
        /// Observations in the refused update.
        observations: usize,
        /// The configured bound.
        max: usize,
    },
    /// Every particle's weight vanished or became NaN (no particle explains the data).
    #[error("particle weights degenerated: {0}")]
    Degenerate(String),
}

impl From<FastSlamError> for FilterError {
    fn from(e: FastSlamError) -> Self {
        match e {
            FastSlamError::Model(m) => FilterError::Model(m),
            FastSlamError::NonFiniteInput { .. } => FilterError::InvalidInput(e.to_string()),
            FastSlamError::Degenerate(_) => FilterError::Numerical(e.to_string()),
            other => FilterError::Other(Box::new(other)),
        }
    }
}
