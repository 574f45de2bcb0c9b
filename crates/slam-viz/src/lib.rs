//! # slam-viz: PNG pictures of SLAM runs and pose graphs
//!
//! * [`picture`]: the plotter. A map picture ([`picture::Picture`]: occupancy map,
//!   trajectories, ground truth, landmark 95 % ellipses, true landmarks, the particle cloud,
//!   every particle's path and landmark estimates; axes in metres, y up, a legend, a scale
//!   bar) and series plots ([`picture::plot_series`], e.g. an average NEES with its
//!   chi-square band).
//! * [`run_picture`]: which layers a landmark or laser filter's run shows, their legend
//!   labels and the title (what `slam run` writes as `map.png` and its `--frames`).
//! * [`graph_picture`]: a pose graph before and after optimisation.
//!
//! Text is set in DejaVu Sans compiled into the crate (`fonts/`, with its licence), so no
//! system font library is needed. Every picture is a pure function of its inputs: the same
//! layers give the same bytes.
//!
//! Layering: this crate draws what the crates below it compute (`slam-models`' types and
//! `slam-graph`'s pose graphs); it reads no dataset (that is `slam-io`, which has no image
//! dependency) and runs no filter. Bad input (nothing finite, coordinates beyond
//! [`picture::MAX_COORDINATE_M`], series of unequal length) is a [`VizError`], never a panic.

#![warn(missing_docs)]

pub mod error;
mod font;
pub mod graph_picture;
pub mod picture;
pub mod run_picture;

pub use error::VizError;
