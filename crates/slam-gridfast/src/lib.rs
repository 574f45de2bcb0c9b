//! # slam-gridfast: grid-based FastSLAM (the GMapping family)
//!
//! A Rao-Blackwellized particle filter on occupancy grids (Murphy 2000; Hähnel, Burgard,
//! Fox & Thrun, IROS 2003; Grisetti, Stachniss & Burgard, ICRA 2005 / T-RO 2007). Each
//! particle holds a pose, a trajectory (a leaf of one shared tree of poses), a log-odds
//! occupancy grid made of copy-on-write tiles, and a log weight.
//!
//! * [`GridFastSlam`]: the filter; implements [`slam_models::ScanSlam`] (name
//!   `"gridfast"`), and [`GridFastSlam::render_map`] re-renders the best particle's map at
//!   any resolution from its trajectory and every processed scan.
//! * [`GridFastConfig`]: every parameter with a documented default; [`Proposal`] selects
//!   the proposal distribution (`odometry`, `scan-matched-odometry`, `improved`).
//!
//! Speed comes from work done once instead of per particle or per beam: beam end points
//! are computed once per scan; each map carries its likelihood field (a truncated distance
//! field) maintained incrementally in the same copy-on-write tiles, so matching costs one
//! bilinear look-up per beam and never recomputes a field; after resampling, copies of a
//! particle integrate the scan once and share the result.
//!
//! Units: metres, radians, seconds; θ counter-clockwise, normalised to (−π, π].

#![warn(missing_docs)]

mod config;
mod error;
mod filter;
mod matcher;
mod proposal;
mod trajectory;

pub use config::{GridFastConfig, Proposal};
pub use error::GridFastError;
pub use filter::GridFastSlam;
