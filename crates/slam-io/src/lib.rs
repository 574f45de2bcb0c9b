//! # slam-io: datasets in, trajectories and maps out
//!
//! * Readers, each tested on the real files of `../shared/datasets`: [`freiburg`] (course
//!   landmark data), [`mrclam`] (UTIAS MRCLAM), [`carmen`] (CARMEN laser logs, plain or
//!   gzip), [`relations`] (Kümmerle et al. 2009 benchmark relations), [`tum`] (TUM
//!   trajectories), [`g2o`] (2-D pose graphs in g2o and TORO format, as plain records, read and
//!   written), `rosbag` (ROS bags:
//!   ROS 2 MCAP and sqlite3 files and rosbag2 folders, ROS 1 bags; features `rosbag`,
//!   `rosbag-sqlite`, `rosbag1`, on by default); [`open_dataset`]
//!   picks the reader for a path.
//! * Writers: [`tum`], [`ros_map`] (map_server PGM + YAML), [`landmarks_csv`],
//!   [`estimates_csv`] (per-step pose, covariance and NEES), [`freiburg::write_freiburg`],
//!   [`carmen::write_carmen`], [`g2o::write_graph_file`], `mcap_out` (a run as an MCAP file of
//!   ROS 2 messages for Foxglove and `ros2 bag play`, feature `rosbag`).
//!
//! Metrics computed from these (ATE, RPE, the relations metric, NEES) live in `slam-eval`,
//! and the PNG pictures of results in `slam-viz`: this crate reads and writes formats only
//! (its one image dependency, behind the `png` feature, off by default, decodes the PNG
//! images of map_server maps).
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
pub mod estimates_csv;
pub mod freiburg;
pub mod g2o;
pub mod landmarks_csv;
#[cfg(feature = "rosbag")]
pub mod mcap_out;
pub mod mrclam;
pub mod relations;
pub mod report;
pub mod ros_map;
#[cfg(feature = "rosbag")]
pub mod ros_msg;
#[cfg(feature = "rosbag")]
pub mod rosbag;
pub(crate) mod text;
pub mod tum;

pub use dataset::{
    dataset_info, dataset_kind, dead_reckoning, odometry_trajectory, open_dataset,
    open_dataset_report, open_dataset_with, Dataset, DatasetOptions, OpenedDataset,
};
pub use error::{DatasetOption, IoError};
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
