//! # slam-gridfast: grid-based FastSLAM (the GMapping family)
//!
//! A Rao-Blackwellized particle filter on occupancy grids (Murphy 2000; Hähnel, Burgard,
//! Fox & Thrun, IROS 2003; Grisetti, Stachniss & Burgard, ICRA 2005 / T-RO 2007). Each
//! particle holds a pose, a trajectory (a leaf of one shared tree of poses,
//! [`slam_models::particle::PathNode`]), a log-odds occupancy grid
//! ([`slam_grid::OccupancyGrid`]: copy-on-write tiles shared between particles) and a log
//! weight.
//!
//! * [`GridFastSlam`]: the filter; implements [`slam_models::ScanSlam`] (name
//!   `"gridfast"`), and [`GridFastSlam::render_map`] re-renders the best particle's map at
//!   any resolution from its trajectory and every processed scan.
//! * [`GridFastConfig`]: every parameter with a documented default, in tables (sensor,
//!   map, matching, proposal, resampling, motion); [`Proposal`] selects the proposal
//!   distribution (`odometry`, `scan-matched-odometry`, `improved`), [`Preset`] the
//!   environment (`auto`, `indoor`, `outdoor`) the scale-dependent defaults are for. The
//!   sensor's range limit and the preset come from the data unless the configuration sets
//!   them ([`GridFastConfig::resolve`]).
//!
//! The maps are slam-grid's: scan integration (exact traversal, inverse sensor model with
//! `protect_scan_hits`) and the likelihood field, a truncated distance field that slam-grid
//! repairs incrementally after each integration from the cells whose occupancy flipped
//! ([`slam_grid::OccupancyGrid::with_incremental_distance`]), stored in copy-on-write tiles
//! like the occupancy. This crate adds the filter and the proposals; they match with
//! slam-grid's endpoint matching on that field ([`slam_grid::matcher::endpoint`]: the scan's
//! log-likelihood, which the weights need, GMapping's hill climber and an exhaustive coarse
//! search). The scorer truncates the field twice, coarse to fine: at its full reach
//! (`matching.field-radius`) for the capture range of the coarse search and of the
//! hill climber's first steps, and tighter (`matching.likelihood-radius`) where
//! the pose is decided and weighed, so that beams ending on clutter pull less.
//!
//! Speed comes from work done once instead of per particle or per beam: beam end points
//! are computed once per scan; the field is never recomputed, so matching costs one
//! bilinear look-up per beam; after resampling, copies of a particle integrate the scan
//! once and share the result.
//!
//! Units: metres, radians, seconds; θ counter-clockwise, normalised to (−π, π].

#![warn(missing_docs)]

mod config;
mod error;
mod filter;
mod matcher;
mod proposal;
mod setup;

pub use config::{
    median_return_range, GridFastConfig, MapConfig, MatchingConfig, MotionConfig, OdometrySource,
    Preset, Proposal, ProposalConfig, RecoveryConfig, ResamplingConfig, SensorConfig, StartChoice,
    AUTO_OUTDOOR_MEDIAN_RANGE, LASER_ODOMETRY_SEARCH_RANGE_XY, MAX_PARTICLES,
};
pub use error::GridFastError;
pub use filter::GridFastSlam;

/// The `slam-models` vocabulary this crate's API speaks, re-exported so that a user of
/// grid FastSLAM compiles with this crate alone (sophus-rs style).
pub use slam_models::{
    ConfigError, FilterError, FromConfig, GridMap, LaserScan, Pose2, ScanDataset, ScanRecord,
    ScanSlam, ScanUpdateInfo, TimedPose, WeightedPose,
};

/// Traits only, for glob import: `use slam_gridfast::prelude::*;` (re-exports
/// [`slam_models::prelude`]).
pub mod prelude {
    pub use slam_models::prelude::*;
}
