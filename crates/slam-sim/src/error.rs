//! The error type of the simulators.

use thiserror::Error;

/// What went wrong while building a world or running a simulation.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum SimError {
    /// The scenario name is not one of [`crate::scenario::list`].
    #[error("unknown scenario {name:?}; expected one of: {expected}")]
    UnknownScenario {
        /// The name given.
        name: String,
        /// The known names, comma separated.
        expected: String,
    },
    /// A parameter was NaN/∞ or outside its documented range.
    #[error("parameter {name} = {value} is invalid: expected {expected}")]
    InvalidParameter {
        /// The parameter's name.
        name: &'static str,
        /// The value given (as text, so integers and floats both fit).
        value: String,
        /// What was expected, in words.
        expected: &'static str,
    },
    /// A scenario needs an input that was not given (e.g. `replay` without a map).
    #[error("scenario {scenario:?} needs {what}")]
    MissingInput {
        /// The scenario.
        scenario: &'static str,
        /// What is missing, in words.
        what: &'static str,
    },
    /// A world could not be built from the given input (empty map, no free space, …).
    #[error("invalid world: {0}")]
    InvalidWorld(String),
    /// A path could not be planned or followed.
    #[error("invalid path: {0}")]
    InvalidPath(String),
    /// A model computation failed.
    #[error(transparent)]
    Model(#[from] slam_models::ModelError),
}

/// Checks that `value` is finite and within `[lo, hi]`.
pub(crate) fn check_range(
    name: &'static str,
    value: f64,
    lo: f64,
    hi: f64,
    expected: &'static str,
) -> Result<f64, SimError> {
    if value.is_finite() && value >= lo && value <= hi {
        Ok(value)
    } else {
        Err(SimError::InvalidParameter {
            name,
            value: value.to_string(),
            expected,
        })
    }
}

/// The largest number of steps (or odometry records) a simulation accepts: far beyond any
/// useful run, small enough that the output vectors can always be allocated.
pub(crate) const MAX_STEPS: usize = 50_000_000;

/// Checks a step count against [`MAX_STEPS`].
pub(crate) fn check_steps(name: &'static str, n: usize) -> Result<usize, SimError> {
    if n <= MAX_STEPS {
        Ok(n)
    } else {
        Err(SimError::InvalidParameter {
            name,
            value: n.to_string(),
            expected: "at most 50 000 000",
        })
    }
}
