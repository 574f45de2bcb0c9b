//! Errors of slam-mcl.

use slam_grid::GridError;
use slam_models::{ConfigError, FilterError, ModelError};
use thiserror::Error;

/// What went wrong while building or running Monte Carlo localization.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum MclError {
    /// A configuration field was outside its documented range (names the field and bound).
    #[error(transparent)]
    InvalidConfig(#[from] ConfigError),
    /// The map could not be turned into a grid and likelihood field.
    #[error("map: {0}")]
    Map(#[from] GridError),
    /// The map has no free cell to draw particles from (global localization and the
    /// random particles of augmented MCL need one).
    #[error("the map has no free cell (value 0 … {free_max}) to draw particles from")]
    NoFreeSpace {
        /// Largest occupancy value (percent) counted as free.
        free_max: i8,
    },
    /// A record or initial pose held a non-finite value.
    #[error("{what} is not finite")]
    NonFinite {
        /// Which quantity.
        what: &'static str,
    },
    /// A model computation failed (weights all zero, …).
    #[error(transparent)]
    Model(#[from] ModelError),
}

/// Bad input as [`FilterError::InvalidInput`], the rest as numerical or other failures,
/// the typed error kept as the source.
impl From<MclError> for FilterError {
    fn from(e: MclError) -> Self {
        match e {
            MclError::NonFinite { .. } | MclError::InvalidConfig(_) => {
                FilterError::invalid_input(e)
            }
            MclError::Model(_) => FilterError::numerical(e),
            _ => FilterError::other(e),
        }
    }
}
