//! Configuration of EKF-SLAM.

use crate::error::EkfError;
use serde::{Deserialize, Serialize};
use slam_models::measurement::RangeBearingModel;
use slam_models::motion::MotionModels;

pub use slam_models::association::{AssociationMode, AssociationOptions};

/// Parameters of [`crate::EkfSlam`].
///
/// ```
/// let c: slam_ekf::EkfConfig = toml::from_str("[association]\nmin-sightings = 2").unwrap();
/// assert_eq!(c.association.min_sightings, 2);
/// ```
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields, default)]
pub struct EkfConfig {
    /// Motion models (velocity and odometry, PR tables 5.3/5.6) with their noise
    /// parameters; the one used is chosen by the kind of each control.
    pub motion: MotionModels,
    /// Extra process noise added to the pose each prediction, variances
    /// (m², m², rad²) on the diagonal of R (the Freiburg course's additive pose noise).
    pub extra_motion_noise: [f64; 3],
    /// Range-bearing sensor noise Q = diag(σr², σφ²).
    pub sensor: RangeBearingModel,
    /// Initial pose covariance, diagonal variances (m², m², rad²). Zero fixes the world
    /// frame at the initial pose (the usual SLAM convention).
    pub initial_pose_variance: [f64; 3],
    /// Data association: the mode, its gates and provisional landmarks (the `[association]`
    /// table; a bare mode string `association = "auto"` is still read).
    #[serde(deserialize_with = "slam_models::association::options_or_mode")]
    pub association: AssociationOptions,
    /// Most landmarks the map may hold (1 ..= [`MAX_LANDMARKS`]); one more is
    /// [`EkfError::TooManyLandmarks`]. The dense covariance takes (3 + 2n)² × 8 bytes:
    /// 800 MB at the default 5000 (the `city` scenario's default world has 2000).
    pub max_landmarks: usize,
}

/// Upper bound of [`EkfConfig::max_landmarks`]: 20 000 landmarks make a 12.8 GB
/// covariance, beyond which the O(N²) update is no longer a practical EKF.
pub const MAX_LANDMARKS: usize = 20_000;

impl Default for EkfConfig {
    /// slam-models' default motion and sensor models, no extra motion noise, a zero
    /// initial pose covariance, [`AssociationOptions`]' defaults, at most 5000 landmarks.
    fn default() -> Self {
        Self {
            motion: MotionModels::default(),
            extra_motion_noise: [0.0; 3],
            sensor: RangeBearingModel::default(),
            initial_pose_variance: [0.0; 3],
            association: AssociationOptions::default(),
            max_landmarks: 5000,
        }
    }
}

fn check(
    field: &'static str,
    value: f64,
    ok: bool,
    expected: &'static str,
) -> Result<(), EkfError> {
    Ok(slam_models::error::ensure_config(
        ok, "EKF", field, value, expected,
    )?)
}

impl EkfConfig {
    /// Checks every field against its documented range.
    pub fn validate(&self) -> Result<(), EkfError> {
        check(
            "max_landmarks",
            self.max_landmarks as f64,
            (1..=MAX_LANDMARKS).contains(&self.max_landmarks),
            "1 ..= 20000 (MAX_LANDMARKS)",
        )?;
        for v in self.extra_motion_noise {
            check("extra_motion_noise", v, v >= 0.0, "finite and >= 0")?;
        }
        for v in self.initial_pose_variance {
            check("initial_pose_variance", v, v >= 0.0, "finite and >= 0")?;
        }
        let named = |e: slam_models::ModelError| match e {
            slam_models::ModelError::OutOfRange {
                name,
                value,
                expected,
            } => {
                EkfError::InvalidConfig(slam_models::ConfigError::new("EKF", name, value, expected))
            }
            other => EkfError::Model(other),
        };
        self.motion.validate().map_err(named)?;
        self.sensor.validate().map_err(named)?;
        self.association.validate().map_err(named)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use slam_models::ConfigError;

    #[test]
    fn default_is_valid_and_round_trips() {
        let c = EkfConfig::default();
        c.validate().unwrap();
        let s = toml::to_string(&c).unwrap();
        let back: EkfConfig = toml::from_str(&s).unwrap();
        assert_eq!(back.association, c.association);
        assert!(toml::from_str::<EkfConfig>("no_such_field = 1").is_err());
    }

    #[test]
    fn rejects_bad_values() {
        let mut c = EkfConfig::default();
        c.association.gate_probability = 1.0;
        assert!(matches!(
            c.validate(),
            Err(EkfError::InvalidConfig(ConfigError {
                field: "association.gate_probability",
                ..
            }))
        ));
        let mut c = EkfConfig::default();
        c.sensor.sigma_range = f64::NAN;
        assert!(c.validate().is_err());
        let mut c = EkfConfig::default();
        c.association.min_sightings = 0;
        assert!(c.validate().is_err());
    }
}
