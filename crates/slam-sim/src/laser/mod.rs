//! Laser worlds: line segments, a grid-indexed ray caster, and the scanner.

pub mod world;

pub use world::{Segment, World};
