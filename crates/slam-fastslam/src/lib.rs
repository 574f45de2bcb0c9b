//! # slam-fastslam: FastSLAM 1.0 and 2.0
//!
//! FastSLAM (Montemerlo, Thrun, Koller & Wegbreit, AAAI 2002; Montemerlo et al., IJCAI 2003;
//! Probabilistic Robotics ch. 13, tables 13.1–13.3): a particle filter over the robot path
//! in which each particle carries its own map of point landmarks, each landmark a 2-D
//! Gaussian with its own 2×2 EKF.
//!
//! * [`FastSlam`]: the filter, implementing [`slam_models::LandmarkSlam`] under the names
//!   `"fastslam1"` and `"fastslam2"` ([`Variant`]), configured by [`FastSlamConfig`].
//! * [`tree::PersistentMap`]: the landmark store — a balanced 16-ary tree with
//!   `Arc`-shared nodes, so resampling copies a pointer and an update copies only the path to
//!   the changed landmark: time and memory per step grow with log N, not N.
//! * [`map::LandmarkMap`]: a particle's map, the landmark tree plus a persistent spatial
//!   index for nearest-landmark queries (maximum-likelihood association, negative
//!   evidence).
//! * [`landmark::Landmark`]: mean, covariance and existence counter of one landmark.
//! * [`particle::Particle`]: pose, path (a leaf of one tree of poses shared by all
//!   particles, [`slam_models::particle::PathNode`]), log weight and map. The best
//!   particle's path is the full-SLAM estimate ([`slam_models::LandmarkSlam::full_path`]).
//!
//! Units: metres and radians; bearings counter-clockwise from the heading; angles normalised
//! to (−π, π].

#![warn(missing_docs)]

pub mod config;
pub mod error;
pub mod filter;
pub mod landmark;
pub mod map;
mod par;
pub mod particle;
pub mod tree;

pub use config::{Association, FastSlamConfig, Variant, MAX_LANDMARKS, MAX_PARTICLES};
pub use error::FastSlamError;
pub use filter::FastSlam;
pub use particle::Particle;

/// The `slam-models` vocabulary this crate's API speaks, re-exported so that a user of
/// FastSLAM compiles with this crate alone (sophus-rs style).
pub use slam_models::{
    ConfigError, Control, FilterError, FromConfig, LandmarkEstimate, LandmarkId, LandmarkSlam,
    OdometryControl, Pose2, RangeBearing, UpdateInfo, VelocityControl, WeightedPose,
};

/// Traits only, for glob import: `use slam_fastslam::prelude::*;` (re-exports
/// [`slam_models::prelude`]).
pub mod prelude {
    pub use slam_models::prelude::*;
}
