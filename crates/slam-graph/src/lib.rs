//! # slam-graph: graph-based SLAM's back end
//!
//! A 2-D pose graph and its sparse nonlinear least-squares optimiser, after Grisetti,
//! Kümmerle, Stachniss and Burgard, "A tutorial on graph-based SLAM" (IEEE Intelligent
//! Transportation Systems Magazine, 2010) and Kümmerle, Grisetti, Strasdat, Konolige and
//! Burgard, "g2o: A general framework for graph optimization" (ICRA 2011):
//!
//! * [`PoseGraph`]: SE(2) pose nodes and R² point nodes; relative-pose edges (g2o
//!   `EDGE_SE2`), Cartesian point edges (`EDGE_SE2_XY`) and range-bearing point edges, each
//!   with its information matrix Ω.
//! * [`factor`]: each edge's error and exact analytic Jacobians (tested by finite
//!   differences).
//! * [`Optimizer`]: Gauss-Newton or Levenberg-Marquardt on the manifold, the normal equations
//!   solved by faer's sparse Cholesky with an AMD ordering ([`linear`]), robust kernels
//!   ([`RobustKernel`]: Huber, Cauchy, DCS) by IRLS, the gauge fixed at the first pose, an
//!   [`IterationInfo`] per iteration and a documented stopping rule ending in a
//!   [`Termination`]; by default started from LAGO's global estimate ([`lago`]) when that is
//!   better, and with loop closures under a two-stage robust treatment that survives false
//!   closures (see [`optimizer`]).
//!
//! * [`landmark`]: the landmark front end, [`landmark::GraphLandmarkSlam`], full SLAM with
//!   range-bearing landmark edges and the EKF's data association behind `LandmarkSlam`.
//! * [`laser`]: the laser front end ([`laser::LaserGraphSlam`], `ScanSlam` name `"graph"`):
//!   keyframes, scan-to-submap odometry edges, branch-and-bound loop closures, a smoothed
//!   trajectory with one node per record.
//!
//! The χ² reported everywhere is g2o's: Σ eᵀΩe over the edges (GTSAM reports half of it).
//! File input and output (g2o format) live in `slam-io`.

#![warn(missing_docs)]

pub mod error;
pub mod factor;
pub mod graph;
pub mod kernel;
pub mod lago;
pub mod landmark;
pub mod laser;
pub mod linear;
pub mod optimizer;

pub use error::GraphError;
pub use graph::{BetweenEdge, Edge, Node, NodeValue, PointXyEdge, PoseGraph, RangeBearingEdge};
pub use kernel::RobustKernel;
pub use linear::{Factorization, Ordering};
pub use optimizer::{
    is_odometry, Damping, InitReport, Initialisation, IterationInfo, Method, OptimizeReport,
    Optimizer, OptimizerConfig, Start, StopReason, Termination,
};

/// The `slam-models` vocabulary this crate's API speaks (poses and matrices of the graph,
/// the filter traits its front ends implement), re-exported so that a user of the pose
/// graph or its front ends compiles with this crate alone (sophus-rs style).
pub use slam_models::association::{AssociationMode, AssociationOptions};
pub use slam_models::{
    ConfigError, Control, FilterError, FromConfig, GridMap, LandmarkDataset, LandmarkEstimate,
    LandmarkId, LandmarkSlam, LaserScan, Matrix2, Matrix3, OdometryControl, Point2, Pose2,
    RangeBearing, ScanDataset, ScanRecord, ScanSlam, ScanUpdateInfo, TimedPose, UpdateInfo,
    VelocityControl,
};

/// Traits only, for glob import: `use slam_graph::prelude::*;` (re-exports
/// [`slam_models::prelude`]).
pub mod prelude {
    pub use slam_models::prelude::*;
}
