#![doc = include_str!("../README.md")]
//!
//! ## The umbrella crate
//!
//! Re-exports every layer of slam-rs under one name, plus the numeric crates they use, so
//! that applications depend on one crate and never fight version skew:
//!
//! | module | crate | what |
//! |---|---|---|
//! | [`models`] | `slam-models` | SE(2), motion/measurement models, resampling, filter traits |
//! | [`ekf`] | `slam-ekf` | EKF-SLAM |
//! | [`fastslam`] | `slam-fastslam` | FastSLAM 1.0 / 2.0 |
//! | [`grid`] | `slam-grid` | occupancy grids, likelihood fields, scan matching |
//! | [`gridfast`] | `slam-gridfast` | grid-based FastSLAM |
//! | [`graph`] | `slam-graph` | pose graphs and their sparse least-squares optimiser |
//! | [`sim`] | `slam-sim` | simulators and scenarios |
//! | [`io`] | `slam-io` | dataset readers and writers |
//! | `viz` | `slam-viz` | PNG pictures of runs and pose graphs (feature `png`, on by default) |
//! | [`eval`] | `slam-eval` | running a filter over a dataset, metrics, filters from a config |
//!
//! Dependencies point one way: `models` at the bottom; `ekf`, `fastslam`, `grid`, `sim`, `io`
//! on it; `gridfast` on `grid`; `graph` on `models` (and `io` on `graph` for g2o files); `viz`
//! on `models` and `graph`; the `slam` command-line program (`slam-cli`) on top.

pub use faer;
pub use nalgebra;
pub use rand;
pub use rand_pcg;
pub use slam_ekf as ekf;
pub use slam_eval as eval;
pub use slam_fastslam as fastslam;
pub use slam_graph as graph;
pub use slam_grid as grid;
pub use slam_gridfast as gridfast;
pub use slam_io as io;
pub use slam_mcl as mcl;
pub use slam_models as models;
pub use slam_sim as sim;
#[cfg(feature = "png")]
pub use slam_viz as viz;

/// The filter and model traits, for glob import: `use slam::prelude::*;`.
pub mod prelude {
    pub use slam_models::prelude::*;
}

#[cfg(test)]
mod tests {
    /// The README's two programs are `examples/landmarks.rs` and `examples/laser.rs`, verbatim:
    /// the doc tests compile the README's copies and `cargo test` builds the examples, so
    /// neither can rot while the other is checked.
    #[test]
    fn readme_programs_are_the_examples() {
        let readme = include_str!("../README.md");
        for (fence, example) in [
            ("```rust\n", include_str!("../examples/landmarks.rs")),
            ("```rust,no_run\n", include_str!("../examples/laser.rs")),
        ] {
            let start = readme.find(fence).expect("the README has the code block") + fence.len();
            let len = readme[start..]
                .find("\n```")
                .expect("the code block is closed");
            assert_eq!(&readme[start..start + len], example.trim_end());
        }
    }
}
