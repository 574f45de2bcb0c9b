//! # slam-io: datasets in, maps and metrics out
//!
//! * Readers, each tested on the real files of `../shared/datasets`: [`freiburg`] (course
//!   landmark data), [`mrclam`] (UTIAS MRCLAM), [`carmen`] (CARMEN laser logs, plain or
//!   gzip), [`relations`] (Kümmerle et al. 2009 benchmark relations), [`tum`] (TUM
//!   trajectories); [`open_dataset`] picks the reader for a path.
//! * Writers: [`tum`], [`ros_map`] (map_server PGM + YAML), [`landmarks_csv`],
//!   [`freiburg::write_freiburg`], [`carmen::write_carmen`], [`picture`] (PNG).
//! * Metrics: [`eval`] (ATE, RPE, relations metric, landmark map error, NEES/NIS with
//!   chi-square bands).
//!
//! Bad input is an [`IoError`] naming the file, the 1-based line and what was expected;
//! NaN/∞ values and empty files are errors; nothing panics on user data. Data a reader
//! reads but keeps out of a dataset (an invalid observation, another robot's barcode, an
//! unknown CARMEN record type) is listed or counted in that reader's report, never dropped
//! silently.

#![warn(missing_docs)]

pub mod bounds;
pub mod carmen;
mod dataset;
pub mod error;
pub mod eval;
pub mod freiburg;
mod glyphs;
pub mod landmarks_csv;
pub mod mrclam;
pub mod picture;
pub mod relations;
pub mod report;
pub mod ros_map;
pub(crate) mod text;
pub mod tum;

pub use dataset::{dead_reckoning, odometry_trajectory, open_dataset, Dataset};
pub use error::IoError;
pub use report::Skipped;

/// The `slam-models` vocabulary this crate's API speaks, re-exported so that a user of
/// the readers and writers compiles with this crate alone (sophus-rs style).
pub use slam_models::{
    GridMap, LandmarkDataset, LaserScan, Pose2, ScanDataset, ScanRecord, TimedPose,
};

/// Traits only, for glob import: `use slam_io::prelude::*;` (re-exports
/// [`slam_models::prelude`]).
pub mod prelude {
    pub use slam_models::prelude::*;
}
