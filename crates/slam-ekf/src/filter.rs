//! [`EkfSlam`]: the filter, its per-update diagnostics and the `LandmarkSlam` impl.

use crate::config::{AssociationMode, EkfConfig};
use crate::error::EkfError;
use crate::state::State;
use slam_models::association::{Association, Associator, Linearised, AUTO_ID_BASE};
use slam_models::{
    Control, FilterError, LandmarkEstimate, LandmarkId, LandmarkSlam, Matrix3, Pose2, RangeBearing,
    UpdateInfo, Vector3,
};
use std::collections::HashMap;

/// EKF-specific diagnostics of one update (faer-style info struct), in addition to the
/// common [`UpdateInfo`].
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct EkfUpdateInfo {
    /// The common counts. `rejected` includes sightings held as provisional landmarks.
    pub common: UpdateInfo,
    /// Observations recorded as provisional sightings.
    pub provisional: usize,
    /// Id-less observations discarded because they fell inside some landmark's
    /// new-landmark gate without being paired (neither safe to use nor to map).
    pub ambiguous: usize,
    /// Nodes visited by JCBB (0 when it did not run).
    pub jcbb_nodes: usize,
    /// True when JCBB hit its node budget and returned the best hypothesis found so far.
    pub jcbb_exhausted: bool,
}

/// EKF-SLAM (Probabilistic Robotics table 10.1 with known correspondences, §10.3 with
/// unknown ones): one Gaussian over the pose and every landmark.
///
/// ```
/// use slam_ekf::{EkfConfig, EkfSlam};
/// use slam_models::{Control, LandmarkId, LandmarkSlam, OdometryControl, Pose2, RangeBearing};
/// let mut ekf = EkfSlam::new(EkfConfig::default(), Pose2::IDENTITY, 0).unwrap();
/// ekf.predict(&Control::Odometry(OdometryControl { rot1: 0.0, trans: 1.0, rot2: 0.0 })).unwrap();
/// let z = RangeBearing::new(2.0, 0.5, Some(LandmarkId(7))).unwrap();
/// let info = ekf.update(&[z]).unwrap();
/// assert_eq!(info.new_landmarks, 1);
/// assert_eq!(ekf.landmarks()[0].id, LandmarkId(7));
/// ```
#[derive(Debug, Clone)]
pub struct EkfSlam {
    config: EkfConfig,
    state: State,
    ids: Vec<LandmarkId>,
    index: HashMap<LandmarkId, usize>,
    next_id: u32,
    assoc: Associator,
    step: u64,
    associations: Vec<Association>,
    info: EkfUpdateInfo,
}

impl EkfSlam {
    /// A filter at `initial_pose` with covariance `config.initial_pose_variance` and an
    /// empty map. Rejects invalid configurations and non-finite poses. The EKF draws
    /// nothing at random: `seed` is taken for the one constructor shape of every filter
    /// ([`slam_models::FromConfig`]) and ignored.
    pub fn new(config: EkfConfig, initial_pose: Pose2, seed: u64) -> Result<Self, EkfError> {
        let _ = seed;
        config.validate()?;
        if !initial_pose.is_finite() {
            return Err(EkfError::InvalidInput(format!(
                "initial pose {initial_pose:?} is not finite"
            )));
        }
        let v = config.initial_pose_variance;
        let state = State::new(
            Pose2::new(initial_pose.x, initial_pose.y, initial_pose.theta),
            Matrix3::from_diagonal(&Vector3::new(v[0], v[1], v[2])),
        );
        Ok(Self {
            // Negative ranges are rejected, all others kept (the EKF's linearisation copes
            // with a near landmark; the sensor's `min_range` is the graph's bound).
            assoc: Associator::new(config.association, 0.0),
            next_id: if config.association.mode == AssociationMode::Auto {
                AUTO_ID_BASE
            } else {
                0
            },
            config,
            state,
            ids: Vec::new(),
            index: HashMap::new(),
            step: 0,
            associations: Vec::new(),
            info: EkfUpdateInfo::default(),
        })
    }

    /// The configuration in use.
    pub fn config(&self) -> &EkfConfig {
        &self.config
    }

    /// Number of landmarks in the map (provisional ones excluded).
    pub fn landmark_count(&self) -> usize {
        self.state.landmark_count()
    }

    /// Number of provisional landmarks waiting for more sightings.
    pub fn provisional_count(&self) -> usize {
        self.assoc.provisional_count()
    }

    /// The state mean μ = (x, y, θ, m₁ₓ, m₁ᵧ, …), metres and radians; landmark `k` of
    /// [`EkfSlam::landmarks`] sits at indices 3 + 2k and 4 + 2k.
    pub fn mean(&self) -> &[f64] {
        self.state.mean()
    }

    /// The full (3 + 2n)² state covariance Σ, ordered as [`EkfSlam::mean`].
    pub fn covariance(&self) -> faer::MatRef<'_, f64> {
        self.state.covariance()
    }

    /// What became of each observation of the last update, in input order.
    pub fn last_associations(&self) -> &[Association] {
        &self.associations
    }

    /// Diagnostics of the last update.
    pub fn last_update_info(&self) -> EkfUpdateInfo {
        self.info
    }

    fn fresh_id(&mut self) -> LandmarkId {
        while self.index.contains_key(&LandmarkId(self.next_id)) {
            self.next_id = self.next_id.wrapping_add(1);
        }
        let id = LandmarkId(self.next_id);
        self.next_id = self.next_id.wrapping_add(1);
        id
    }

    fn insert_landmark(&mut self, z: &RangeBearing, id: LandmarkId) -> Result<(), EkfError> {
        let inv = self.config.sensor.inverse(&self.state.pose(), z);
        if !(inv.landmark.x.is_finite() && inv.landmark.y.is_finite()) {
            return Err(EkfError::InvalidInput(format!(
                "observation {z:?} places a landmark at a non-finite position"
            )));
        }
        let max = self.config.max_landmarks;
        if self.ids.len() >= max {
            return Err(EkfError::TooManyLandmarks { max });
        }
        let slot =
            self.state
                .add_landmark(&inv, &self.config.sensor.noise_covariance(), 3 + 2 * max)?;
        debug_assert_eq!(slot, self.ids.len());
        self.ids.push(id);
        self.index.insert(id, slot);
        Ok(())
    }

    /// Moves the belief by one control: O(N), only the pose rows and columns change.
    pub fn predict_control(&mut self, control: &Control) -> Result<(), EkfError> {
        control.validate()?;
        let pose = self.state.pose();
        let m = &self.config.motion;
        let new_pose = m.predict(&pose, control);
        let g = m.jacobian_state(&pose, control);
        let e = self.config.extra_motion_noise;
        let r = m.noise_covariance(&pose, control)
            + Matrix3::from_diagonal(&Vector3::new(e[0], e[1], e[2]));
        if !new_pose.is_finite() || g.iter().chain(r.iter()).any(|v| !v.is_finite()) {
            return Err(EkfError::InvalidInput(format!(
                "control {control:?} gives a non-finite prediction"
            )));
        }
        self.state.predict(&new_pose, &g, &r);
        Ok(())
    }

    /// Incorporates a batch of observations (see the crate docs for the order of
    /// operations) and returns the detailed diagnostics.
    pub fn update_observations(
        &mut self,
        observations: &[RangeBearing],
    ) -> Result<EkfUpdateInfo, EkfError> {
        for z in observations {
            if !(z.range.is_finite() && z.bearing.is_finite()) {
                return Err(EkfError::InvalidInput(format!(
                    "observation {z:?} is not finite"
                )));
            }
        }
        self.step += 1;
        let sensor = self.config.sensor;
        let mut info = EkfUpdateInfo {
            common: UpdateInfo {
                observations: observations.len(),
                ..UpdateInfo::default()
            },
            ..EkfUpdateInfo::default()
        };
        // Known ids and id-less observations paired (slam_models::association::batch).
        let mut pairing = self
            .assoc
            .pair(&self.state, &sensor, &self.ids, &self.index, observations)
            .map_err(|index| EkfError::MissingId { index })?;
        info.jcbb_nodes = pairing.jcbb_nodes;
        info.jcbb_exhausted = pairing.jcbb_exhausted;
        // One batched update with every associated observation.
        let lins: Vec<Linearised> = pairing.paired.iter().map(|&(_, lin)| lin).collect();
        if !lins.is_empty() {
            info.common.nis = self.state.update(&lins)?;
            info.common.associated = lins.len();
        }
        // New landmarks with known ids join at once, from the updated pose.
        for i in std::mem::take(&mut pairing.new_known) {
            let z = &observations[i];
            let Some(id) = z.id else { continue };
            if self.index.contains_key(&id) {
                // A second sighting of an id first seen in this batch: left out rather
                // than double counted (its first sighting initialised the landmark).
                continue;
            }
            self.insert_landmark(z, id)?;
            pairing.associations[i] = Association::New(id);
            info.common.new_landmarks += 1;
        }
        // Unpaired id-less observations: ambiguous, provisional or new.
        let (pose, pxx) = (self.state.pose(), self.state.pose_cov());
        let ready =
            self.assoc
                .unpaired(&mut pairing, &pose, &pxx, &sensor, observations, self.step);
        info.ambiguous = pairing.ambiguous;
        info.provisional = pairing.provisional;
        for i in ready {
            let id = self.fresh_id();
            self.insert_landmark(&observations[i], id)?;
            pairing.associations[i] = Association::New(id);
            info.common.new_landmarks += 1;
        }
        info.common.removed = self.assoc.expire(self.step);
        info.common.rejected =
            observations.len() - info.common.associated - info.common.new_landmarks;
        self.associations = pairing.associations;
        self.info = info;
        Ok(info)
    }
}

slam_models::from_config_by_new!(EkfSlam, EkfConfig, EkfError);

impl LandmarkSlam for EkfSlam {
    fn name(&self) -> &str {
        "ekf"
    }

    fn predict(&mut self, control: &Control) -> Result<(), FilterError> {
        self.predict_control(control).map_err(FilterError::from)
    }

    fn update(&mut self, observations: &[RangeBearing]) -> Result<UpdateInfo, FilterError> {
        self.update_observations(observations)
            .map(|i| i.common)
            .map_err(FilterError::from)
    }

    fn pose(&self) -> Pose2 {
        self.state.pose()
    }

    fn pose_covariance(&self) -> Matrix3 {
        self.state.pose_cov()
    }

    fn landmarks(&self) -> Vec<LandmarkEstimate> {
        self.ids
            .iter()
            .enumerate()
            .map(|(j, &id)| LandmarkEstimate {
                id,
                mean: self.state.landmark(j),
                covariance: self.state.landmark_cov(j),
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::AssociationOptions;
    use slam_models::OdometryControl;

    fn z(range: f64, bearing: f64, id: Option<u32>) -> RangeBearing {
        RangeBearing {
            range,
            bearing,
            id: id.map(LandmarkId),
        }
    }

    /// The landmark cap is a config bound and a runtime error, never an allocation abort
    /// (20 000 landmarks used to panic in the covariance's `reserve`).
    #[test]
    fn landmark_cap_is_a_config_bound_and_an_error_when_reached() {
        let e = EkfSlam::new(
            EkfConfig {
                max_landmarks: 20_001,
                ..EkfConfig::default()
            },
            Pose2::IDENTITY,
            0,
        )
        .unwrap_err();
        assert!(
            matches!(
                e,
                EkfError::InvalidConfig(slam_models::ConfigError {
                    field: "max_landmarks",
                    ..
                })
            ),
            "{e}"
        );
        assert!(e.to_string().contains("20001") && e.to_string().contains("20000"));
        let cfg = EkfConfig {
            association: AssociationMode::KnownIds.into(),
            max_landmarks: 3,
            ..EkfConfig::default()
        };
        let mut ekf = EkfSlam::new(cfg, Pose2::IDENTITY, 0).unwrap();
        let obs: Vec<_> = (0..3)
            .map(|k| z(2.0 + k as f64, 0.3 * k as f64, Some(k)))
            .collect();
        ekf.update_observations(&obs).unwrap();
        let e = ekf
            .update_observations(&[z(4.0, -0.5, Some(7))])
            .unwrap_err();
        assert_eq!(e, EkfError::TooManyLandmarks { max: 3 });
        assert!(e.to_string().contains("max-landmarks = 3"), "{e}");
        // Known landmarks are still updated.
        ekf.update_observations(&obs).unwrap();
    }

    /// Through the object-safe trait the EKF's error keeps its type: a missing id is
    /// `InvalidInput` and downcasts back to `EkfError::MissingId`, as the source too.
    #[test]
    fn trait_errors_keep_the_typed_source() {
        let cfg = EkfConfig {
            association: AssociationMode::KnownIds.into(),
            ..EkfConfig::default()
        };
        let mut ekf: Box<dyn LandmarkSlam> = Box::new(
            <EkfSlam as slam_models::FromConfig>::from_config(cfg, Pose2::IDENTITY, 0).unwrap(),
        );
        let e = ekf.update(&[z(1.0, 0.0, None)]).unwrap_err();
        assert!(matches!(e, FilterError::InvalidInput { .. }), "{e:?}");
        assert_eq!(
            e.downcast_ref::<EkfError>(),
            Some(&EkfError::MissingId { index: 0 })
        );
        let source = std::error::Error::source(&e).expect("a source");
        assert_eq!(
            source.downcast_ref::<EkfError>(),
            Some(&EkfError::MissingId { index: 0 })
        );
        assert!(
            e.to_string().contains("observation 0 has no landmark id"),
            "{e}"
        );
    }

    #[test]
    fn input_errors_and_rejections() {
        let cfg = EkfConfig {
            association: AssociationMode::KnownIds.into(),
            ..EkfConfig::default()
        };
        let mut ekf = EkfSlam::new(cfg, Pose2::IDENTITY, 0).unwrap();
        assert!(matches!(
            ekf.update_observations(&[z(1.0, 0.0, None)]),
            Err(EkfError::MissingId { index: 0 })
        ));
        assert!(ekf
            .update_observations(&[z(f64::NAN, 0.0, Some(1))])
            .is_err());
        let bad = Control::Odometry(OdometryControl {
            rot1: f64::INFINITY,
            trans: 0.0,
            rot2: 0.0,
        });
        assert!(ekf.predict_control(&bad).is_err());
        let info = ekf
            .update_observations(&[z(-0.5, 0.3, Some(1)), z(2.0, 0.3, Some(2))])
            .unwrap();
        assert_eq!(info.common.new_landmarks, 1);
        assert_eq!(info.common.rejected, 1);
        assert_eq!(
            ekf.last_associations(),
            &[Association::Rejected, Association::New(LandmarkId(2))]
        );
        assert!(EkfSlam::new(EkfConfig::default(), Pose2::new(f64::NAN, 0.0, 0.0), 0).is_err());
    }

    /// Id-less observations of one landmark: provisional for k − 1 sightings, then mapped,
    /// then associated; a lone far-away observation stays provisional and expires.
    #[test]
    fn provisional_landmarks_join_after_k_sightings() {
        let cfg = EkfConfig {
            association: AssociationOptions {
                mode: AssociationMode::Jcbb,
                min_sightings: 3,
                ..AssociationOptions::default()
            },
            ..EkfConfig::default()
        };
        let mut ekf = EkfSlam::new(cfg, Pose2::IDENTITY, 0).unwrap();
        let still = Control::Odometry(OdometryControl {
            rot1: 0.0,
            trans: 0.0,
            rot2: 0.0,
        });
        let mut seen = Vec::new();
        for k in 0..5 {
            ekf.predict_control(&still).unwrap();
            let mut obs = vec![z(3.0 + 0.01 * k as f64, 0.5, None)];
            if k == 0 {
                obs.push(z(4.0, -1.0, None));
            }
            ekf.update_observations(&obs).unwrap();
            seen.push(ekf.last_associations()[0]);
        }
        assert_eq!(&seen[..2], &[Association::Provisional; 2]);
        assert_eq!(seen[2], Association::New(LandmarkId(0)));
        assert_eq!(&seen[3..], &[Association::Landmark(LandmarkId(0)); 2]);
        assert_eq!(ekf.landmark_count(), 1);
        assert_eq!(ekf.provisional_count(), 0);
    }
}
