//! The one error type of slam-eval.

use thiserror::Error;

/// Why a metric could not be computed.
#[derive(Debug, Error)]
pub enum EvalError {
    /// A metric could not be computed from the trajectories given (no pose matched in
    /// time, a non-finite pose, a bad parameter), in words.
    #[error("evaluation: {0}")]
    Metric(String),
}
