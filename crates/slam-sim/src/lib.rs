//! # slam-sim: simulators with ground truth
//!
//! Will hold deterministic landmark and laser-world simulators and the named scenarios
//! (`loop`, `figure8`, `city`, `clutter`, `office`, `replay:`).
