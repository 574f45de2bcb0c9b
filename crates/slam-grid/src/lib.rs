//! # slam-grid: occupancy grids and scan matching
//!
//! The mapping and matching core of slam-rs, usable on its own:
//!
//! * [`OccupancyGrid`]: log-odds occupancy grid (Probabilistic Robotics §9.2) that grows on
//!   demand, stored as copy-on-write 32×32 tiles behind `Arc` so that clones (one per
//!   particle in grid FastSLAM) share every tile they have not written; beams are traced
//!   exactly (Amanatides–Woo) with an [`InverseSensorModel`].
//! * [`CellIndex`] and [`GridFrame`]: integer cells versus world points, never mixed.
//! * [`likelihood`]: Thrun's endpoint model (PR §6.4) from an exact linear-time Euclidean
//!   distance transform (Felzenszwalb & Huttenlocher 2012), computed per tile on demand.
//! * [`DistanceField`] ([`grid::distance`]): optionally, a truncated distance field repaired
//!   incrementally after every scan integration from the cells whose obstacle status
//!   flipped, in copy-on-write tiles like the occupancy (grid FastSLAM's likelihood field).
//! * [`matcher`]: scan matchers returning pose, score and covariance: GMapping-style hill
//!   climbing, correlative multi-resolution search (Olson 2009) and Gauss-Newton on the
//!   bilinearly interpolated field (Hector SLAM), and a branch-and-bound search over a
//!   reusable max-pyramid (Cartographer's fast correlative matcher) for loop closures;
//!   [`matcher::endpoint`]: the truncated endpoint model as a log-likelihood on the
//!   incremental distance field, with the same hill climber and an exhaustive search under a
//!   motion prior (the matching of grid FastSLAM and of scan-matching odometry). Every
//!   matcher takes the one [`RangeData`].
//! * [`KnownPoseMapping`]: mapping with known poses, each scan written at the log's own
//!   pose (`ScanSlam`, name `"known-poses"`); [`OccupancyGrid::from_grid_map`] and
//!   [`OccupancyGrid::cast_ray`] load a saved map back and cast beams on it (localization).
//! * [`ScanMatchOdometry`]: each scan matched against the map built so far with
//!   [`matcher::endpoint`] (`ScanSlam`, name `"scanmatch"`).
//! * [`LaserOdometry`]: the odometry of a recording that has none, each scan matched
//!   against a local map of the scans before it (two active submaps) around several
//!   predictions (zero motion, constant velocity) by a wide branch-and-bound search over
//!   max-pooled grids (Hector SLAM's and Cartographer's front end), optionally with an
//!   IMU's yaw rate as one more prediction; the front stage of laser-only mapping.
//!
//! Units: metres, radians; world frame right-handed, θ counter-clockwise.

#![warn(missing_docs)]

pub mod cell;
pub mod error;
pub mod grid;
pub mod likelihood;
pub mod scan;

pub use cell::{CellIndex, GridFrame};
pub use error::GridError;
pub use grid::distance::{
    DistanceCursor, DistanceField, DISTANCE_UNITS_PER_CELL, MAX_DISTANCE_RADIUS,
};
pub use grid::sensor_model::InverseSensorModel;
pub use grid::tiles::{TILE_CELLS, TILE_SIZE};
pub use grid::{CopyStats, OccupancyGrid, MAX_MAP_CELLS, MAX_MAP_EXTENT_CELLS};
pub use likelihood::{LikelihoodField, LikelihoodParams};
pub use scan::RangeData;
pub mod matcher;

#[cfg(test)]
pub(crate) mod testutil;

pub use matcher::{
    BranchBoundMatcher, CorrelativeMatcher, GaussNewtonMatcher, HillClimbMatcher, MatchResult,
    MaxPyramid, RefinedCorrelativeMatcher, ScanMatcher,
};
pub mod known_poses;
pub use known_poses::{KnownPoseConfig, KnownPoseMapping};
pub mod scanmatch;
pub use scanmatch::{EndpointMatchingConfig, ScanMatchConfig, ScanMatchOdometry};
pub mod laser_odometry;
pub use laser_odometry::{
    laser_odometry, LaserOdometry, LaserOdometryConfig, LaserOdometryRun, LaserOdometryStream,
    MotionPrediction,
};

/// The `slam-models` vocabulary this crate's API speaks, re-exported so that a user of
/// the occupancy grid and scan matchers compiles with this crate alone (sophus-rs style).
pub use slam_models::{
    ConfigError, FilterError, FromConfig, GridMap, LaserScan, Point2, Pose2, ScanDataset,
    ScanRecord, ScanSlam, ScanUpdateInfo, TimedPose, YawRate,
};

/// Traits only, for glob import: `use slam_grid::prelude::*;` (re-exports
/// [`slam_models::prelude`]).
pub mod prelude {
    pub use slam_models::prelude::*;
}
