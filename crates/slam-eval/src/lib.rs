//! # slam-eval: run a filter over a dataset and score it
//!
//! The layer between the filter crates and a front end (the `slam` program, a benchmark, a
//! test), so that none of them writes its own run loop or re-implements a metric:
//!
//! * [`metrics`]: ATE, RPE, the Kümmerle et al. relations metric, landmark map error,
//!   NEES/NIS with chi-square bands, each checked against hand-computed cases.
//! * [`Metrics`]: the figures of one run, as `metrics.json` holds them.
//! * [`run_landmarks`] / [`run_scans`]: drive a `&mut dyn LandmarkSlam` / `&mut dyn
//!   ScanSlam` over a dataset and score it ([`run`]), with an observer for progress,
//!   pictures and Ctrl-C.
//! * [`input`]: a run's input, loaded: a simulated scenario, or whatever a dataset path
//!   holds (CARMEN, Freiburg, MRCLAM, ROS bags, through slam-io's readers).
//! * [`factory`]: a [`FilterConfig`] tagged by the filter's name (`filter = "ekf"`, …)
//!   builds a `Box<dyn LandmarkSlam>` / `Box<dyn ScanSlam>`, so swapping the filter is a
//!   config change; [`filters`](factory::filters) lists them.
//! * [`pose_graph`]: g2o and TORO pose-graph files (slam-io's records) to a slam-graph
//!   [`slam_graph::PoseGraph`] and back.
//!
//! Readers and writers stay in `slam-io` (formats only); filters never do I/O.

#![warn(missing_docs)]

pub mod config_text;
pub mod error;
pub mod factory;
pub mod input;
pub mod metrics;
pub mod metrics_json;
pub mod pose_graph;
pub mod run;

pub use error::EvalError;
pub use factory::{FactoryError, FilterConfig};
pub use input::{Input, InputData, InputError};
pub use metrics_json::{peak_rss_mb, Metrics};
pub use run::{
    run_landmarks, run_landmarks_observed, run_scans, run_scans_observed, Flow, LandmarkObserver,
    LandmarkProgress, LandmarkRun, ObserverError, RunError, RunOptions, ScanObserver, ScanProgress,
    ScanRun,
};

/// The `slam-models` vocabulary this crate's API speaks, re-exported so that a user
/// compiles with this crate alone.
pub use slam_models::{LandmarkDataset, LandmarkSlam, Pose2, ScanDataset, ScanSlam, TimedPose};
