//! Laser worlds: line segments with a grid-indexed ray caster, the scanner, and the
//! simulation loop.
//!
//! * [`world`]: walls, polygons, occupancy-map loading, ray casting.
//! * [`scanner`]: the laser range finder (beams, range, noise, short readings).
//! * [`sim`]: drives a robot along a path and records odometry and scans.

pub mod scanner;
pub mod sim;
pub mod world;

pub use scanner::LaserScanner;
pub use sim::{simulate_laser, LaserSimConfig, Teleport};
pub use world::{Segment, World};
