//! # slam-models: the bottom layer of slam-rs
//!
//! Everything the filters share and nothing filter-specific:
//!
//! * [`Pose2`]: rigid motions of the plane, SE(2), with composition (⊕), inverse and
//!   relative pose (⊖); angles in radians, normalised to (−π, π] by [`normalize_angle`].
//! * [`motion`]: the velocity motion model (Probabilistic Robotics, table 5.3 / 10.1) and the
//!   odometry motion model (table 5.6), each with exact Jacobians, noise mapped to state
//!   space, and a sampler.
//! * [`measurement`]: the range-bearing landmark model (PR eq. 6.40, table 10.1) with its
//!   inverse (landmark initialisation) and all Jacobians.
//! * [`gaussian`]: numerically safe Gaussian log-likelihoods of innovations; [`chi2`]:
//!   chi-square quantiles for gates and consistency bands.
//! * [`particle`]: log-space weights, N_eff and four O(N) resamplers.
//! * [`data`]: the data types every reader, simulator and filter exchanges (controls,
//!   observations, laser scans, time steps, whole datasets).
//! * [`detmath`] and [`sampling`]: transcendental functions and normal/exponential samplers
//!   that give the same bits on every machine (pure-Rust `libm`, no platform math library);
//!   everything in this crate uses them, so the simulator built on it is reproducible.
//! * [`rng`]: the one derivation of seeded random streams (splitmix64 over the seed and
//!   the particle, step or part), so that a draw never depends on the thread count.
//! * [`keyframes`]: a keyframe filter's pose at every record of a log (last corrected
//!   pose ⊕ odometry since, GMapping's convention).
//! * [`odometry_jump`]: the laser filters' guard against glitched odometry (a jump between
//!   two records beyond a limit is an error, or skipped).
//! * [`association`]: data association of range-bearing observations against a joint
//!   Gaussian (individual gating, nearest neighbour, JCBB, provisional landmarks), shared
//!   by EKF-SLAM and the pose graph.
//! * [`filter`]: the traits [`LandmarkSlam`] and [`ScanSlam`] that downstream code swaps
//!   filters behind.
//!
//! Frames: the world frame is right-handed, x forward/east, y left/north, θ counter-clockwise
//! from the x axis. Robot-frame quantities (bearings, scan beams) are measured
//! counter-clockwise from the robot's heading.
//!
//! Small matrices are nalgebra fixed-size types; this crate is re-exported as
//! `slam::models` by the umbrella crate, together with `nalgebra` itself.

#![warn(missing_docs)]

pub mod angle;
pub mod association;
pub mod chi2;
pub mod data;
pub mod detmath;
pub mod error;
pub mod filter;
pub mod gaussian;
pub mod grid_map;
pub mod keyframes;
pub mod measurement;
pub mod motion;
pub mod odometry_jump;
pub mod particle;
pub mod pose;
pub mod rng;
pub mod sampling;

pub use angle::normalize_angle;
pub use data::{
    Control, DataKind, LandmarkDataset, LandmarkId, LandmarkStep, LaserScan, OdometryControl,
    RangeBearing, ScanDataset, ScanRecord, TimedPose, VelocityControl, YawRate,
};
pub use error::{ConfigError, ModelError};
pub use filter::{
    BoxedError, FilterError, FromConfig, LandmarkEstimate, LandmarkSlam, ScanSlam, ScanUpdateInfo,
    UpdateInfo, WeightedPose,
};
pub use grid_map::GridMap;
pub use odometry_jump::{OdometryJumpGuard, OdometryJumpLimit, OnOdometryJump};
pub use particle::{ParticlePaths, PathTreeNode};
pub use pose::Pose2;

/// A 2-D point in the world frame, metres.
pub type Point2 = nalgebra::Point2<f64>;
/// 2-vector (innovations, measurements, landmark offsets).
pub type Vector2 = nalgebra::Vector2<f64>;
/// 3-vector (pose-sized quantities: (x, y, θ)).
pub type Vector3 = nalgebra::Vector3<f64>;
/// 2×2 matrix (landmark and measurement covariances).
pub type Matrix2 = nalgebra::Matrix2<f64>;
/// 3×3 matrix (pose covariances, motion Jacobians).
pub type Matrix3 = nalgebra::Matrix3<f64>;
/// 2×3 matrix (measurement Jacobian w.r.t. the pose).
pub type Matrix2x3 = nalgebra::Matrix2x3<f64>;
/// 3×2 matrix (velocity-model Jacobian w.r.t. the control (v, ω)).
pub type Matrix3x2 = nalgebra::Matrix3x2<f64>;

/// Traits only, for glob import: `use slam_models::prelude::*;`.
pub mod prelude {
    pub use crate::filter::{FromConfig, LandmarkSlam, ScanSlam};
    pub use crate::motion::MotionModel;
}
