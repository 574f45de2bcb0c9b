//! # slam-sim: deterministic simulators with ground truth
//!
//! Worlds where the truth is known exactly, for tests, consistency (NEES) checks, scaling
//! benchmarks and demos:
//!
//! * [`landmark`]: point-landmark worlds seen by a range-bearing sensor (noise, field of
//!   view, detection probability, Poisson clutter, optional hidden ids);
//! * [`laser`]: worlds of line segments seen by a planar laser scanner, with a grid-indexed
//!   ray caster, and a loader from occupancy maps ([`laser::World::from_grid_map`]);
//! * [`path`]: reference paths and the pure-pursuit follower that drives the robot;
//! * [`scenario`]: the named scenarios `loop`, `figure8`, `city`, `clutter`, `office` and
//!   `replay`, each with documented defaults.
//!
//! Both simulators produce the same data types as the dataset readers
//! ([`slam_models::LandmarkDataset`], [`slam_models::ScanDataset`]), so simulated and real
//! data take the same code paths.
//!
//! **Determinism.** Everything flows from one `u64` seed through `rand_pcg` streams, one per
//! independent part (world, motion, sensor, clutter, path), single-threaded, and no output
//! depends on hash-map iteration order. The same seed gives bit-identical data on any
//! machine, OS, CPU or thread count. That rests on:
//!
//! * IEEE-754 arithmetic and `sqrt`, which are exactly rounded everywhere (Rust never fuses a
//!   multiply-add on its own);
//! * [`slam_models::detmath`] for every transcendental function (`sin`, `cos`, `atan2`,
//!   `exp`, `ln`, `hypot`, …): the pure-Rust `libm` crate at a pinned version, instead of the
//!   platform's math library, which may differ in the last bit between systems (glibc even
//!   chooses FMA or non-FMA code per CPU at run time);
//! * samplers built from uniform draws only ([`slam_models::sampling`]: Marsaglia's polar
//!   method for normals; Knuth's product of uniforms for Poisson counts) instead of
//!   `rand_distr`'s, which call the platform's `exp`/`ln`;
//! * the tidy step of `cargo xtask test-all`, which rejects std transcendental calls,
//!   `powi` and `rand_distr` in the non-test code of slam-models and slam-sim.
//!
//! `tests/reproducibility.rs` holds digests of short runs of each kind of scenario: a
//! machine that disagrees with them has found a reproducibility bug.
//!
//! ```
//! use slam_sim::{scenario::{generate, ScenarioOptions}, SimOutput};
//! let out = generate("loop", &ScenarioOptions { seed: 7, steps: Some(20), ..Default::default() }).unwrap();
//! let SimOutput::Landmark(run) = out else { panic!("loop is a landmark scenario") };
//! assert_eq!(run.true_poses.len(), 20);
//! assert_eq!(run.dataset.steps.len(), 20);
//! ```

#![warn(missing_docs)]

pub mod error;
pub mod landmark;
pub mod laser;
pub mod path;
pub(crate) mod rng;
pub mod scenario;

pub use error::SimError;
pub use laser::World;

use serde::{Deserialize, Serialize};
use slam_models::measurement::RangeBearingModel;
use slam_models::motion::MotionModels;

/// The output of a scenario: landmark or laser data with its ground truth.
// Built once per run and matched immediately: boxing the larger variant would only
// complicate the contract's `SimOutput::Landmark(run)` pattern.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone)]
pub enum SimOutput {
    /// A landmark run.
    Landmark(LandmarkSimRun),
    /// A laser run.
    Laser(LaserSimRun),
}

/// A simulated landmark run with everything a test needs to judge a filter.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct LandmarkSimRun {
    /// The data: initial pose, steps (control + observations), the true landmark map, and
    /// the ground-truth trajectory (one pose per step, at the step's time).
    pub dataset: LandmarkDataset,
    /// True pose after each step (index = step).
    pub true_poses: Vec<Pose2>,
    /// Per step, per observation (same order as `dataset.steps[k].observations`): true for
    /// a false alarm.
    pub is_clutter: Vec<Vec<bool>>,
    /// The motion noise model the data was generated with (what a filter should use; with a
    /// deliberate mismatch, the nominal model and `true_motion` the one actually drawn from).
    pub motion: MotionModels,
    /// The sensor noise model the data was generated with (nominal; see `true_sensor`).
    pub sensor: RangeBearingModel,
    /// The motion model the noise was actually drawn from (= `motion` unless mismatched).
    pub true_motion: MotionModels,
    /// The sensor noise actually drawn (= `sensor` unless mismatched).
    pub true_sensor: RangeBearingModel,
    /// The full sensor configuration (range limits, field of view, detection probability,
    /// clutter rate) for filters that use negative information or clutter densities.
    pub sensor_config: landmark::RangeBearingSensor,
}

/// A simulated laser run.
#[derive(Debug, Clone)]
pub struct LaserSimRun {
    /// The data: odometry records with scans, and the ground-truth trajectory (one pose per
    /// record, same time).
    pub dataset: ScanDataset,
    /// The world the scans were cast in.
    pub world: World,
    /// The odometry noise model the motion was drawn from (PR table 5.6; the data's
    /// odometry increments are the reported controls).
    pub odometry: slam_models::motion::OdometryModel,
    /// The scanner that produced the scans (beams, range, noise, short-reading rate).
    pub scanner: laser::LaserScanner,
}

/// The `slam-models` vocabulary this crate's API speaks, re-exported so that a user of
/// the simulators compiles with this crate alone (sophus-rs style).
pub use slam_models::{LandmarkDataset, LaserScan, Pose2, RangeBearing, ScanDataset, TimedPose};

/// Traits only, for glob import: `use slam_sim::prelude::*;` (re-exports
/// [`slam_models::prelude`]).
pub mod prelude {
    pub use slam_models::prelude::*;
}

/// The noise models simulated landmark data was generated with: the "true" models a filter
/// run on that data should assume, unless its configuration says otherwise. A filter left at
/// its own defaults on simulated data assumes noise the data does not have and is less
/// accurate with no warning, so the rule is an explicit call a front end can report.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoiseModels {
    /// The motion model ([`LandmarkSimRun::motion`]).
    pub motion: MotionModels,
    /// The range-bearing sensor model ([`LandmarkSimRun::sensor`]).
    pub sensor: RangeBearingModel,
}

/// Which models [`NoiseModels::apply_to`] replaced.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct NoiseApplied {
    /// The motion model was replaced by the simulator's.
    pub motion: bool,
    /// The sensor model was replaced by the simulator's.
    pub sensor: bool,
}

impl NoiseApplied {
    /// True when either model was replaced.
    pub fn any(&self) -> bool {
        self.motion || self.sensor
    }
}

impl NoiseModels {
    /// The simulator's noise rule: a filter's motion and sensor models become these, except
    /// a model its configuration sets explicitly (`config_sets_motion`,
    /// `config_sets_sensor`), which is kept. Returns what was replaced, so that a front end
    /// can say so.
    pub fn apply_to(
        &self,
        motion: &mut MotionModels,
        sensor: &mut RangeBearingModel,
        config_sets_motion: bool,
        config_sets_sensor: bool,
    ) -> NoiseApplied {
        if !config_sets_motion {
            *motion = self.motion;
        }
        if !config_sets_sensor {
            *sensor = self.sensor;
        }
        NoiseApplied {
            motion: !config_sets_motion,
            sensor: !config_sets_sensor,
        }
    }
}

impl LandmarkSimRun {
    /// The nominal noise models this data was generated with ([`NoiseModels::apply_to`]
    /// copies them into a filter's configuration).
    pub fn noise_models(&self) -> NoiseModels {
        NoiseModels {
            motion: self.motion,
            sensor: self.sensor,
        }
    }
}
