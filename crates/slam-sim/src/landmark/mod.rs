//! Landmark worlds: point landmarks, a range-bearing sensor, and the simulation loop.
//!
//! * [`world`]: the landmark map with a uniform-grid spatial hash for visibility queries.
//! * [`sensor`]: the range-bearing sensor (noise, field of view, detection probability,
//!   clutter, hidden ids).
//! * [`sim`]: drives a robot along a path and records controls, observations and truth.

pub mod sensor;
pub mod sim;
pub mod world;

pub use sensor::RangeBearingSensor;
pub use sim::{simulate_landmarks, ControlKind, LandmarkSimConfig};
pub use world::LandmarkWorld;
