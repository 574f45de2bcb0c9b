//! Errors of the FastSLAM filters.

use slam_models::{ConfigError, FilterError, ModelError};
use thiserror::Error;

/// What went wrong in FastSLAM.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum FastSlamError {
    /// A field of [`crate::FastSlamConfig`] was outside its documented range.
    #[error(transparent)]
    InvalidConfig(#[from] ConfigError),
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
         observations: more than max-landmarks = {max} could be mapped"
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

/// Sorts the error into a [`FilterError`] category and keeps it, typed, as the source
/// (`FilterError::downcast_ref::<FastSlamError>()` gives it back).
impl From<FastSlamError> for FilterError {
    fn from(e: FastSlamError) -> Self {
        match e {
            FastSlamError::NonFiniteInput { .. } | FastSlamError::Model(_) => {
                FilterError::invalid_input(e)
            }
            FastSlamError::Degenerate(_) => FilterError::numerical(e),
            _ => FilterError::other(e),
        }
    }
}
