//! Configuration of EKF-SLAM.

use crate::error::EkfError;
use serde::{Deserialize, Serialize};
use slam_models::measurement::RangeBearingModel;
use slam_models::motion::MotionModels;

pub use slam_models::association::AssociationMode;
use slam_models::association::AssociationOptions;

/// Parameters of [`crate::EkfSlam`].
///
/// ```
/// let c: slam_ekf::EkfConfig = toml::from_str("min-sightings = 2").unwrap();
/// assert_eq!(c.min_sightings, 2);
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
    /// Data association mode.
    pub association: AssociationMode,
    /// Individual-compatibility gate: an observation may match a landmark when its
    /// Mahalanobis distance d² = νᵀS⁻¹ν is below the chi-square quantile with 2 dof at this
    /// probability.
    pub gate_probability: f64,
    /// An id-less observation left unpaired is discarded as ambiguous, rather than
    /// starting a new landmark, when some landmark lies inside this wider χ²₂ gate (at least
    /// `gate_probability`): a duplicate of a mapped landmark costs more than a lost
    /// observation.
    pub new_landmark_gate_probability: f64,
    /// Joint-compatibility gate of JCBB: a hypothesis with k pairings is accepted when its
    /// joint d² is below χ²_{2k} at this probability.
    pub joint_probability: f64,
    /// Outlier gate for observations with known ids (χ²₂ quantile at this probability);
    /// `None` accepts every observation of a known landmark.
    pub known_id_gate_probability: Option<f64>,
    /// k: an id-less observation that matches no landmark starts a provisional landmark,
    /// which joins the state after this many consistent sightings (1 = at once).
    /// Landmarks with known ids always join at their first sighting.
    pub min_sightings: usize,
    /// A provisional landmark not seen for more than this many updates is dropped, so its
    /// k sightings must come with gaps of at most this many updates: a real landmark in
    /// view is seen nearly every scan, clutter at one place only by chance.
    pub provisional_max_age: usize,
    /// Gate (χ²₂ probability) for matching a sighting to a provisional landmark.
    pub provisional_gate_probability: f64,
    /// Search budget of JCBB (nodes of the interpretation tree per update); when it is
    /// exhausted the best hypothesis found so far is used.
    pub jcbb_max_nodes: usize,
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
    /// initial pose covariance, `Auto` association, gates at 99.9 % (individual), 99 %
    /// (joint), 99.999 % (no new landmark inside) and 99.99 % (known-id outliers), k = 4 sightings with gaps of at most 2 updates
    /// (provisional gate 99 %), 100 000 JCBB nodes.
    fn default() -> Self {
        Self {
            motion: MotionModels::default(),
            extra_motion_noise: [0.0; 3],
            sensor: RangeBearingModel::default(),
            initial_pose_variance: [0.0; 3],
            association: AssociationMode::Auto,
            gate_probability: 0.999,
            new_landmark_gate_probability: 0.99999,
            joint_probability: 0.99,
            known_id_gate_probability: Some(0.9999),
            min_sightings: 4,
            provisional_max_age: 2,
            provisional_gate_probability: 0.99,
            jcbb_max_nodes: 100_000,
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
        self.association_options().validate().map_err(named)
    }

    /// The association keys, for `slam_models::association::Associator` (observations
    /// with a negative range are rejected, all others kept: `min_range` = 0).
    pub fn association_options(&self) -> AssociationOptions {
        AssociationOptions {
            mode: self.association,
            gate_probability: self.gate_probability,
            new_landmark_gate_probability: self.new_landmark_gate_probability,
            joint_probability: self.joint_probability,
            known_id_gate_probability: self.known_id_gate_probability,
            min_sightings: self.min_sightings,
            provisional_max_age: self.provisional_max_age,
            provisional_gate_probability: self.provisional_gate_probability,
            jcbb_max_nodes: self.jcbb_max_nodes,
            min_range: 0.0,
        }
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
        assert_eq!(back.min_sightings, c.min_sightings);
        assert!(toml::from_str::<EkfConfig>("no_such_field = 1").is_err());
    }

    #[test]
    fn rejects_bad_values() {
        let c = EkfConfig {
            gate_probability: 1.0,
            ..EkfConfig::default()
        };
        assert!(matches!(
            c.validate(),
            Err(EkfError::InvalidConfig(ConfigError {
                field: "gate_probability",
                ..
            }))
        ));
        let mut c = EkfConfig::default();
        c.sensor.sigma_range = f64::NAN;
        assert!(c.validate().is_err());
        let c = EkfConfig {
            min_sightings: 0,
            ..EkfConfig::default()
        };
        assert!(c.validate().is_err());
    }
}
