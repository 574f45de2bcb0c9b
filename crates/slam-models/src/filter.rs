//! The traits downstream code swaps filters behind.
//!
//! * [`LandmarkSlam`]: EKF-SLAM, FastSLAM 1.0 and FastSLAM 2.0: a pose and a map of point
//!   landmarks, driven by [`Control`]s and range-bearing observations.
//! * [`ScanSlam`]: grid-based FastSLAM and scan-matching odometry: driven by odometry and
//!   laser scans, producing a trajectory and an occupancy map.
//!
//! Both are object safe, so a program can pick a filter at run time and hold it as
//! `Box<dyn LandmarkSlam>` or `Box<dyn ScanSlam>`:
//!
//! ```
//! use slam_models::{LandmarkSlam, ScanSlam};
//! fn _takes(_: Box<dyn LandmarkSlam>, _: Box<dyn ScanSlam>) {}
//! ```

use crate::data::{Control, LandmarkId, RangeBearing, ScanRecord, TimedPose};
use crate::error::ModelError;
use crate::grid_map::GridMap;
use crate::particle::ParticlePaths;
use crate::{Matrix2, Matrix3, Point2, Pose2};
use serde::{Deserialize, Serialize};
use thiserror::Error;

/// A filter's own error, boxed so that it crosses the object-safe trait boundary with its
/// type intact (`std::io::Error::other` style): recover it with
/// [`FilterError::downcast_ref`] or `source()?.downcast_ref::<E>()`.
pub type BoxedError = Box<dyn std::error::Error + Send + Sync + 'static>;

/// Why a filter step failed.
///
/// Filters keep their own detailed error enums (`EkfError`, `FastSlamError`, `GridError`,
/// `GridFastError`) and convert into this one at the trait boundary. The conversion sorts
/// the error into a category a generic caller can act on (bad input, numerical failure,
/// anything else) and keeps the filter's typed error as the [`source`](std::error::Error::source),
/// so a caller that knows the filter can still match on its variants:
///
/// ```
/// use slam_models::{FilterError, ModelError};
/// let typed = ModelError::EmptyWeights;
/// let e = FilterError::numerical(typed.clone());
/// assert_eq!(e.downcast_ref::<ModelError>(), Some(&typed));
/// let source = std::error::Error::source(&e).unwrap();
/// assert_eq!(source.downcast_ref::<ModelError>(), Some(&typed));
/// ```
#[derive(Debug, Error)]
pub enum FilterError {
    /// A model computation of this crate failed (bad input, degenerate geometry, …).
    #[error(transparent)]
    Model(#[from] ModelError),
    /// The input was rejected (non-finite value, wrong kind of control, missing landmark
    /// id, …); the source is the filter's own error.
    #[error("invalid input: {source}")]
    InvalidInput {
        /// The filter's typed error.
        #[source]
        source: BoxedError,
    },
    /// The filter's state became numerically invalid (a covariance lost positive
    /// definiteness, every particle weight vanished, …); the source is the filter's own
    /// error.
    #[error("numerical failure: {source}")]
    Numerical {
        /// The filter's typed error.
        #[source]
        source: BoxedError,
    },
    /// Any other error of one filter implementation (a bound such as `max_landmarks`, a map
    /// grown past its extent, …); the source is the filter's own error.
    #[error("{source}")]
    Other {
        /// The filter's typed error.
        #[source]
        source: BoxedError,
    },
}

impl FilterError {
    /// [`FilterError::InvalidInput`] holding `source`.
    pub fn invalid_input(source: impl std::error::Error + Send + Sync + 'static) -> Self {
        Self::InvalidInput {
            source: Box::new(source),
        }
    }

    /// [`FilterError::Numerical`] holding `source`.
    pub fn numerical(source: impl std::error::Error + Send + Sync + 'static) -> Self {
        Self::Numerical {
            source: Box::new(source),
        }
    }

    /// [`FilterError::Other`] holding `source`.
    pub fn other(source: impl std::error::Error + Send + Sync + 'static) -> Self {
        Self::Other {
            source: Box::new(source),
        }
    }

    /// The typed error this one was made from, if it is an `E`: the filter's own error for
    /// the boxed variants, the [`ModelError`] itself for [`FilterError::Model`].
    pub fn downcast_ref<E: std::error::Error + 'static>(&self) -> Option<&E> {
        match self {
            Self::Model(m) => (m as &dyn std::error::Error).downcast_ref::<E>(),
            Self::InvalidInput { source } | Self::Numerical { source } | Self::Other { source } => {
                source.downcast_ref::<E>()
            }
        }
    }
}

/// What one landmark update did: non-fatal diagnostics (faer style "info" struct).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct UpdateInfo {
    /// Observations received.
    pub observations: usize,
    /// Observations associated with landmarks already in the map and used for the update.
    pub associated: usize,
    /// Landmarks added to the map by this update.
    pub new_landmarks: usize,
    /// Observations rejected (outside every gate and not accepted as new; clutter).
    pub rejected: usize,
    /// Landmarks removed (negative evidence, provisional landmarks that expired).
    pub removed: usize,
    /// Sum of the normalised innovation squared over associated observations (NIS), and
    /// its degrees of freedom (2 per associated observation).
    pub nis: f64,
    /// Effective sample size after the update (particle filters; `None` for the EKF).
    pub n_eff: Option<f64>,
    /// True when the particles were resampled in this step.
    pub resampled: bool,
}

/// A landmark estimate: identity, mean (world frame, metres) and 2×2 covariance (m²).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LandmarkEstimate {
    /// The landmark's id (the data's own when known, otherwise assigned by the filter).
    pub id: LandmarkId,
    /// Mean position.
    pub mean: Point2,
    /// Position covariance.
    pub covariance: Matrix2,
}

/// A particle's pose with its normalised weight (for particle-cloud pictures).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct WeightedPose {
    /// The particle's current pose.
    pub pose: Pose2,
    /// Normalised weight in [0, 1].
    pub weight: f64,
}

/// The one constructor shape of every filter: a configuration, the initial pose and a seed.
///
/// Every filter crate's filter (`EkfSlam`, `FastSlam`, `ScanMatchOdometry`,
/// `GridFastSlam`, slam-graph's `GraphLandmarkSlam` and `LaserGraphSlam`) has an inherent
/// `new(config, initial_pose, seed)` with exactly these arguments and implements this trait
/// by calling it, so generic code (a filter factory, a benchmark over several filters) can
/// build any of them the same way. Deterministic filters (the EKF, scan-matching odometry,
/// the pose-graph front ends) take the seed for uniformity and ignore it;
/// for the particle filters it fixes every random draw (same seed, same bytes).
///
/// `initial_pose` places the filter's own starting frame in the world frame:
///
/// * landmark filters and scan-matching odometry: the robot's pose before the first step
///   (the first record);
/// * grid FastSLAM: the pose of the odometry frame, so a record's uncorrected pose is
///   `initial_pose ⊕ odometry` (GMapping's convention: the map is drawn in the odometry
///   frame, and `Pose2::IDENTITY` keeps it there);
/// * slam-graph's laser front end: the pose of the odometry frame too, of which it accepts
///   only `Pose2::IDENTITY` (it maps in the odometry frame; another pose is a config error).
///
/// `Pose2::IDENTITY` gives every filter its behaviour from before this argument existed.
pub trait FromConfig: Sized {
    /// The filter's configuration struct.
    type Config;
    /// The filter's own error type (convertible into [`FilterError`] with the typed
    /// source kept).
    type Error: std::error::Error + Send + Sync + 'static + Into<FilterError>;

    /// Builds the filter; errors on an invalid configuration or a non-finite pose.
    fn from_config(
        config: Self::Config,
        initial_pose: Pose2,
        seed: u64,
    ) -> Result<Self, Self::Error>;
}

/// `impl FromConfig for $filter` by the filter's own constructor
/// `$filter::new(config, initial_pose, seed) -> Result<$filter, $error>`, the shape every
/// filter of the workspace has: `from_config_by_new!(EkfSlam, EkfConfig, EkfError);`.
#[macro_export]
macro_rules! from_config_by_new {
    ($filter:ty, $config:ty, $error:ty) => {
        impl $crate::FromConfig for $filter {
            type Config = $config;
            type Error = $error;

            fn from_config(
                config: $config,
                initial_pose: $crate::Pose2,
                seed: u64,
            ) -> Result<Self, $error> {
                Self::new(config, initial_pose, seed)
            }
        }
    };
}

/// A landmark-based SLAM filter: EKF-SLAM, FastSLAM 1.0/2.0.
///
/// Call order per time step: [`predict`](LandmarkSlam::predict) with the control that moved
/// the robot, then [`update`](LandmarkSlam::update) with the observations taken after the
/// motion (an empty slice is allowed). Bearings and headings are radians, CCW positive.
///
/// Two trajectories can be read from a filter:
///
/// * the *online* estimate: [`pose`](LandmarkSlam::pose) read after each step, x̂_t given
///   z_{1:t}. This is all a filter such as the EKF has: it marginalises past poses out.
/// * the *full-SLAM* estimate of the path x_{0:t} given everything seen so far,
///   [`full_path`](LandmarkSlam::full_path), from filters that estimate the path posterior
///   (FastSLAM: each particle is a path hypothesis, Probabilistic Robotics §13.3). At the
///   end of a run it is the better answer: later observations have re-weighted the past.
///
/// Times: the trait knows none. Path entry 0 is the pose the filter was built with (before
/// any step); entry k ≥ 1 is the pose after the k-th call of `update`. A run loop that
/// makes one `predict` + `update` per data step (as `slam run` does) pairs entry k with the
/// time of its k-th step (counting from 1), so a path of a run of n steps has n + 1 poses
/// and entries 1..=n line up with the n online poses.
pub trait LandmarkSlam: Send {
    /// Short name, e.g. `"ekf"`, `"fastslam2"`.
    fn name(&self) -> &str;

    /// Moves the belief by one control.
    fn predict(&mut self, control: &Control) -> Result<(), FilterError>;

    /// Incorporates a batch of observations taken at the current pose.
    fn update(&mut self, observations: &[RangeBearing]) -> Result<UpdateInfo, FilterError>;

    /// Called once after the last step. A smoother runs its final optimisation here, so
    /// [`full_path`](LandmarkSlam::full_path) and [`landmarks`](LandmarkSlam::landmarks)
    /// read afterwards use every observation; filters have nothing to do (the default).
    fn finish(&mut self) -> Result<(), FilterError> {
        Ok(())
    }

    /// Current pose estimate (the mean, or the best particle's pose for particle filters).
    fn pose(&self) -> Pose2;

    /// 3×3 pose covariance (m², rad²): the EKF's marginal; for particle filters the weighted
    /// covariance of the particle poses about their weighted mean (see
    /// [`pose_gaussian`](LandmarkSlam::pose_gaussian)).
    fn pose_covariance(&self) -> Matrix3;

    /// The Gaussian summary N(μ, Σ) of the pose posterior, the pair a consistency test
    /// (NEES = eᵀΣ⁻¹e with e = x_true ⊖ μ) must use. Default: (`pose()`, `pose_covariance()`),
    /// right for the EKF. Particle filters return the weighted mean of the particle poses
    /// (circular mean for θ) with the covariance about it, which differs from the best
    /// particle's `pose()`.
    fn pose_gaussian(&self) -> (Pose2, Matrix3) {
        (self.pose(), self.pose_covariance())
    }

    /// The current map: every landmark with its id, mean and covariance.
    fn landmarks(&self) -> Vec<LandmarkEstimate>;

    /// The particle cloud, for particle filters; `None` otherwise.
    fn particles(&self) -> Option<Vec<WeightedPose>> {
        None
    }

    /// The full-SLAM estimate of the path: the path of the particle with the highest weight
    /// now, one pose per `update` call after the initial pose (see the trait docs for how
    /// entries pair with times). Its last pose is [`pose`](LandmarkSlam::pose); its
    /// map is [`landmarks`](LandmarkSlam::landmarks). `None` (the default) for a filter
    /// that keeps no path: the EKF marginalises past poses out, so its trajectory is the
    /// online one, `pose()` after each step.
    fn full_path(&self) -> Option<Vec<Pose2>> {
        None
    }

    /// Every particle's path, as one tree of distinct poses with each particle's leaf, its
    /// weight, and which particle [`full_path`](LandmarkSlam::full_path) follows (for
    /// pictures of the path posterior). Step numbering as in `full_path`. `None` (the
    /// default) for filters without particles.
    fn particle_paths(&self) -> Option<ParticlePaths> {
        None
    }

    /// Every particle's map, in particle order (the order of
    /// [`particle_paths`](LandmarkSlam::particle_paths)' leaves), each as
    /// [`landmarks`](LandmarkSlam::landmarks) would give it for that particle: for
    /// pictures of the map posterior. O(particles × landmarks) memory, so meant for the
    /// end of a run, not every step. `None` (the default) for filters without particles.
    fn particle_landmarks(&self) -> Option<Vec<Vec<LandmarkEstimate>>> {
        None
    }
}

/// What one scan-SLAM step did.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct ScanUpdateInfo {
    /// True when the record carried a scan and the filter ran a full update with it
    /// (grid FastSLAM skips scans until the robot moved far enough).
    pub processed_scan: bool,
    /// Effective sample size after the step (particle filters).
    pub n_eff: Option<f64>,
    /// True when the particles were resampled in this step.
    pub resampled: bool,
    /// Particles whose scan matching failed and fell back to the motion model.
    pub match_failures: usize,
    /// Particles whose match was poor (too few beams found the map) and that a wider
    /// search recovered (grid FastSLAM's improved proposal); not counted in
    /// `match_failures`.
    #[serde(default)]
    pub match_recoveries: usize,
    /// Odometry jumps skipped at this record (0 or 1; only with
    /// [`crate::OnOdometryJump::Skip`]): the caller should warn.
    #[serde(default)]
    pub odometry_jumps_skipped: usize,
}

/// A scan-based SLAM filter: grid FastSLAM, scan-matching odometry.
///
/// Every record, with or without a scan, must be passed in file order; the filter keeps a
/// pose for each (the last corrected pose composed with the odometry since), so that
/// [`trajectory`](ScanSlam::trajectory) has one entry per input record.
pub trait ScanSlam: Send {
    /// Short name, e.g. `"gridfast"`, `"scanmatch"`.
    fn name(&self) -> &str;

    /// Processes one record.
    fn process(&mut self, record: &ScanRecord) -> Result<ScanUpdateInfo, FilterError>;

    /// Current best pose estimate.
    fn pose(&self) -> Pose2;

    /// The best estimate of the whole trajectory, one pose per record processed so far.
    fn trajectory(&self) -> Vec<TimedPose>;

    /// The current best map.
    fn map(&self) -> GridMap;

    /// The current best map re-rendered at `resolution` metres per cell (e.g. 0.01 m for a
    /// filter that matches on 0.05 m cells) from the best trajectory and every scan the
    /// filter kept, or `None` when the filter keeps no scans to re-render from, or when
    /// `resolution` is not positive and finite; an error when a kept scan cannot be written
    /// at this cell size (the map would be too large), rather than a map without it.
    /// Default: `None`.
    fn render_map(&self, resolution: f64) -> Option<Result<GridMap, FilterError>> {
        let _ = resolution;
        None
    }

    /// The particle cloud, for particle filters; `None` otherwise.
    fn particles(&self) -> Option<Vec<WeightedPose>> {
        None
    }

    /// Called once after the last record: a filter that holds work back (the graph front
    /// end's group of loop closures not yet checked) finishes it here, so that
    /// [`trajectory`](ScanSlam::trajectory) and [`map`](ScanSlam::map) read afterwards use
    /// every record. Filters with nothing held back have nothing to do (the default).
    fn finish(&mut self) -> Result<(), FilterError> {
        Ok(())
    }

    /// The configuration the filter runs with, for a front end that writes it: the
    /// filter's own configuration type (a front end downcasts it), with every value the
    /// given configuration left to the data taken from the data (grid FastSLAM: the range
    /// limit and the preset, from its first processed scan). The filter is the only place
    /// that resolves them. Default: `None` (the configuration as given).
    fn effective_config(&self) -> Option<&dyn std::any::Any> {
        None
    }
}
