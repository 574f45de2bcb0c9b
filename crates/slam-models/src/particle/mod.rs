//! Particle-filter tools: weights in log space, effective sample size, resampling, and
//! particle paths shared in one tree.

pub mod path;
pub mod resample;
pub mod weights;

pub use path::{ParticlePaths, PathNode, PathTreeNode};
pub use resample::Resampler;
pub use weights::{
    effective_sample_size, effective_sample_size_log, log_sum_exp, normalize_log_weights,
};
