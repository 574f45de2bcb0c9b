//! Errors of the model layer.

use thiserror::Error;

/// What went wrong in a model computation. Each variant says exactly which input was bad.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ModelError {
    /// A value that must be finite was NaN or infinite.
    #[error("{what} is not finite ({value})")]
    NonFinite {
        /// Which quantity.
        what: &'static str,
        /// The offending value.
        value: f64,
    },
    /// The landmark coincides (to within `min_range`) with the sensor, so bearing and the
    /// measurement Jacobians are undefined.
    #[error(
        "degenerate geometry: landmark at range {range} m from the sensor (minimum {min_range} m)"
    )]
    DegenerateGeometry {
        /// Distance between sensor and landmark, metres.
        range: f64,
        /// The smallest range the model accepts, metres.
        min_range: f64,
    },
    /// A measured range was negative.
    #[error("negative range {range} m")]
    NegativeRange {
        /// The measured range, metres.
        range: f64,
    },
    /// A covariance matrix was not symmetric positive definite (its Cholesky factorisation
    /// failed).
    #[error("{what} is not positive definite")]
    NotPositiveDefinite {
        /// Which matrix.
        what: &'static str,
    },
    /// A particle weight set was empty.
    #[error("no particles / weights given")]
    EmptyWeights,
    /// Particle weights were negative, non-finite or summed to zero.
    #[error("invalid particle weights: {reason}")]
    InvalidWeights {
        /// Why the weights were rejected.
        reason: &'static str,
    },
    /// A parameter was outside its documented range.
    #[error("parameter {name} = {value} is out of range: {expected}")]
    OutOfRange {
        /// The parameter's name.
        name: &'static str,
        /// The value given.
        value: f64,
        /// What was expected, in words.
        expected: &'static str,
    },
    /// The odometry of two consecutive records differs by more than the configured limit
    /// (see [`crate::odometry_jump`]).
    #[error(
        "odometry jumped {jump} m between two consecutive records, beyond odometry_jump.max_jump = {max_jump} m \
         (a glitched record; set odometry_jump.on_jump = \"skip\" in the filter config to skip such jumps)"
    )]
    OdometryJump {
        /// Distance between the two odometry positions, metres.
        jump: f64,
        /// The limit, metres.
        max_jump: f64,
    },
    /// Inputs that belong together do not fit each other (lengths, order, indices).
    #[error("{what}: {reason}")]
    Mismatch {
        /// Which input.
        what: &'static str,
        /// What does not fit, with the offending values.
        reason: String,
    },
}

/// Returns `Err(ModelError::NonFinite)` unless `value` is finite.
#[inline]
pub fn ensure_finite(what: &'static str, value: f64) -> Result<f64, ModelError> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(ModelError::NonFinite { what, value })
    }
}
