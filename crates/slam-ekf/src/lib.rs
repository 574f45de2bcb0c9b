//! # slam-ekf: EKF-SLAM
//!
//! EKF-SLAM (Probabilistic Robotics, ch. 10): the robot pose and all landmarks in one
//! Gaussian. Implements `slam_models::LandmarkSlam` under the name `"ekf"`.
//!
//! * **Covariance core** ([`EkfSlam::covariance`]): a dense `faer::Mat`, grown with
//!   amortised doubling of its capacity. Prediction touches only the pose rows and columns
//!   (O(N), N = 3 + 2n); an update with m observations forms Σ·Hᵀ in O(N·m) from the
//!   sparsity of H and applies Σ ← Σ − W·Wᵀ (W = Σ·Hᵀ·L⁻ᵀ, S = L·Lᵀ) as one rank-2m
//!   product in place, which is the Joseph form for the optimal gain in a form that keeps Σ
//!   exactly symmetric.
//! * **Landmark initialisation** with the inverse range-bearing model and both of its
//!   Jacobians: the new landmark's covariance *and* its cross-covariances with the pose and
//!   every landmark.
//! * **Data association** ([`AssociationMode`]): known ids; or, for id-less observations,
//!   Mahalanobis gating with a χ² threshold and maximum-likelihood nearest neighbour, or
//!   JCBB (Neira & Tardós 2001). Id-less observations that match nothing become provisional
//!   landmarks that join the map after k consistent sightings.
//!
//! Order of one update: (1) observations with known ids are paired with their landmarks
//! (outliers beyond `known_id_gate_probability` rejected); (2) id-less observations are
//! gated against every landmark and associated (NN or JCBB); (3) one batched EKF update
//! with every pairing; (4) new known ids join the map from the updated pose; (5) unpaired
//! id-less observations inside some landmark's (wider) new-landmark gate are dropped as
//! ambiguous, the others are provisional
//! sightings (or join at once when k = 1).
#![warn(missing_docs)]

mod config;
mod error;
mod filter;
mod state;

pub use config::{AssociationMode, AssociationOptions, EkfConfig, MAX_LANDMARKS};
pub use error::EkfError;
pub use filter::{EkfSlam, EkfUpdateInfo};
pub use slam_models::association::{Association, AUTO_ID_BASE};

/// The `slam-models` vocabulary this crate's API speaks, re-exported so that a user of
/// EKF-SLAM compiles with this crate alone (sophus-rs style).
pub use slam_models::{
    ConfigError, Control, FilterError, FromConfig, LandmarkEstimate, LandmarkId, LandmarkSlam,
    OdometryControl, Pose2, RangeBearing, UpdateInfo, VelocityControl,
};

/// Traits only, for glob import: `use slam_ekf::prelude::*;` (re-exports
/// [`slam_models::prelude`]).
pub mod prelude {
    pub use slam_models::prelude::*;
}
