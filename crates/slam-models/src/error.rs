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
        "odometry jumped {jump} m between two consecutive records, beyond odometry-jump.max-jump = {max_jump} m \
         (a glitched record; set odometry-jump.on-jump = \"skip\" in the filter config to skip such jumps)"
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

/// A configuration value outside its documented range: the one config-error type of every
/// filter crate (each crate's error enum wraps it as `InvalidConfig`), so a caller handles
/// a bad EKF, FastSLAM, grid, grid FastSLAM or optimiser setting the same way.
///
/// The message names the component, the field as it is written in a TOML config file
/// (kebab-case, dotted for nested tables), the value given and the bound it broke:
///
/// ```
/// use slam_models::ConfigError;
/// let e = ConfigError::new("EKF", "gate_probability", 1.0, "a probability in (0, 1)");
/// assert_eq!(
///     e.to_string(),
///     "invalid EKF configuration: gate-probability = 1, expected a probability in (0, 1)"
/// );
/// assert_eq!(e.key(), "gate-probability");
/// ```
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error("invalid {component} configuration: {} = {value}, expected {expected}", self.key())]
pub struct ConfigError {
    /// Which configuration: `"EKF"`, `"FastSLAM"`, `"grid"`, `"grid FastSLAM"`, ….
    pub component: &'static str,
    /// The field's Rust path, e.g. `"sensor.sigma_range"`; [`ConfigError::key`] gives
    /// the config-file spelling.
    pub field: &'static str,
    /// The value given, as text (numbers, lists and names alike).
    pub value: String,
    /// The bound it broke: what was expected, in words (`"> 0 m"`, `"in (0, 1]"`).
    pub expected: &'static str,
}

impl ConfigError {
    /// A config error for `field` of `component` holding `value`, which should have been
    /// `expected`.
    pub fn new(
        component: &'static str,
        field: &'static str,
        value: impl std::fmt::Display,
        expected: &'static str,
    ) -> Self {
        Self {
            component,
            field,
            value: value.to_string(),
            expected,
        }
    }

    /// The field as written in a config file: the Rust path with `_` spelled `-`
    /// (every config is `#[serde(rename_all = "kebab-case")]`).
    pub fn key(&self) -> String {
        self.field.replace('_', "-")
    }
}

/// `Err(ConfigError)` unless `ok` holds and `value` is finite: the shared range check of
/// the config validators.
pub fn ensure_config(
    ok: bool,
    component: &'static str,
    field: &'static str,
    value: f64,
    expected: &'static str,
) -> Result<(), ConfigError> {
    if ok && value.is_finite() {
        Ok(())
    } else {
        Err(ConfigError::new(component, field, value, expected))
    }
}
