//! # slam-mcl: Monte Carlo localization on a known map
//!
//! The second half of the mapping-then-localization workflow: a map built once (by `slam
//! run`, or any ROS map_server map) and a robot localized on it, from a known start or from
//! nowhere (global localization), recovering when it is lost or kidnapped.
//!
//! * [`Mcl`]: the particle filter (Probabilistic Robotics table 8.2), moved by the
//!   odometry motion model of slam-models (PR table 5.6), weighed by the likelihood-field
//!   or beam model ([`sensor`], PR §6.3/§6.4, both on slam-grid's field and ray casting),
//!   with weights in log space, updates only after the robot moved (`update_min_d`,
//!   `update_min_a`), resampling (low variance) on N_eff, KLD-sampling for the particle
//!   count ([`kld`], Fox 2003, PR table 8.4) and augmented MCL's random particles for
//!   recovery (PR table 8.3, α_slow/α_fast).
//! * [`MclMap`]: a saved [`GridMap`](slam_models::GridMap) prepared for localization.
//! * [`MclConfig`]: every parameter with its documented default (`configs/mcl.toml`).
//!
//! Deterministic: one seeded `rand_pcg` stream, no threads; the same seed and records
//! give the same bytes. No I/O: the program (`slam localize`) reads maps and logs.
//!
//! Units: metres, radians; world (map) frame right-handed, θ counter-clockwise.

pub mod config;
pub mod error;
pub mod filter;
pub mod kld;
pub mod map;
pub mod sensor;

pub use config::{KldConfig, MclConfig, RecoveryConfig, SensorConfig, SensorKind};
pub use error::MclError;
pub use filter::{InitialBelief, Mcl, StepInfo};
pub use map::MclMap;
