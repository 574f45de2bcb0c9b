//! Data association for range-bearing observations of point landmarks, shared by every
//! landmark SLAM back end that keeps a joint Gaussian of the pose and the map (EKF-SLAM's
//! state, the graph's marginal covariance).
//!
//! * [`JointGaussian`]: what association reads from a belief: the pose and landmark means
//!   and the covariance blocks between them.
//! * [`compatibility`]: individual compatibility of an observation with a landmark (the
//!   Mahalanobis gate) and the cross-covariance of two predicted measurements.
//! * [`nearest`]: maximum-likelihood nearest neighbour with greedy conflict resolution.
//! * [`jcbb`]: joint compatibility branch and bound (Neira & Tardós 2001).
//! * [`DenseGaussian`]: a plain dense joint Gaussian with prediction and augmentation.
//! * [`provisional`]: id-less sightings held back until k consistent sightings.
//! * [`Associator`]: one batch of observations through all of the above, in EKF-SLAM's
//!   order, for every back end.
//! * [`GateTable`]: cached χ²_{2k} thresholds of the joint gate.

pub mod batch;
pub mod compatibility;
pub mod dense;
pub mod jcbb;
pub mod nearest;
pub mod provisional;

pub use batch::{
    moved_key_hint, options_or_mode, AssociationOptions, Associator, Pairing, ASSOCIATION_KEYS,
};
pub use compatibility::{candidates, cross_cov, linearise, projected_cov, Candidate};
pub use dense::DenseGaussian;
pub use provisional::ProvisionalList;

use crate::chi2::chi2_quantile;
use crate::{LandmarkId, Matrix2, Matrix2x3, Matrix3x2, Point2, Pose2, Vector2};
use serde::{Deserialize, Serialize};

/// How observations are matched to landmarks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum AssociationMode {
    /// Use an observation's id when it has one; match id-less observations with JCBB.
    #[default]
    Auto,
    /// Every observation must carry its landmark's id; a missing id is an error.
    KnownIds,
    /// Ignore ids. Individual compatibility (Mahalanobis gate) and maximum-likelihood
    /// nearest neighbour, conflicts resolved greedily by likelihood.
    NearestNeighbour,
    /// Ignore ids. Joint compatibility branch and bound (Neira & Tardós 2001).
    Jcbb,
}

/// What became of one observation in the last update.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Association {
    /// Matched to this mapped landmark and used in the update.
    Landmark(LandmarkId),
    /// Started (or completed the k sightings of) a landmark, which joined the map with this id.
    New(LandmarkId),
    /// Recorded as a sighting of a provisional landmark (not yet in the map).
    Provisional,
    /// Not used: outside the known-id outlier gate, ambiguous (unpaired but inside some
    /// landmark's new-landmark gate), a negative range, or degenerate geometry.
    Rejected,
}

/// Ids the filter assigns to landmarks found without ids start here in
/// [`AssociationMode::Auto`] (so they cannot clash with the data's own ids); in
/// `NearestNeighbour` and `Jcbb` mode they start at 0.
pub const AUTO_ID_BASE: u32 = 1 << 30;

/// A joint Gaussian over the robot pose (x, y, θ) and n point landmarks, as association reads
/// it: means and covariance blocks (metres, radians; world frame). Landmarks are numbered
/// 0..n in the belief's own order.
pub trait JointGaussian {
    /// The pose mean.
    fn pose(&self) -> Pose2;
    /// n, the number of landmarks.
    fn landmark_count(&self) -> usize;
    /// The mean of landmark `j`.
    fn landmark(&self, j: usize) -> Point2;
    /// Σ_xx (3×3).
    fn pose_cov(&self) -> crate::Matrix3;
    /// Σ_{x, mⱼ} (3×2).
    fn pose_landmark_cov(&self, j: usize) -> Matrix3x2;
    /// Σ_{mⱼ, mⱼ} (2×2).
    fn landmark_cov(&self, j: usize) -> Matrix2;
    /// Σ_{mᵢ, mⱼ} (2×2).
    fn landmark_landmark_cov(&self, i: usize, j: usize) -> Matrix2;
}

/// One observation linearised at the current mean: innovation ν = z − h(μ) (bearing
/// normalised), H's two non-zero blocks and the measurement noise Q.
#[derive(Debug, Clone, Copy)]
pub struct Linearised {
    /// Landmark number in the belief.
    pub landmark: usize,
    /// ν = z − ẑ.
    pub nu: Vector2,
    /// ∂h/∂(x, y, θ).
    pub h_pose: Matrix2x3,
    /// ∂h/∂(mx, my).
    pub h_landmark: Matrix2,
    /// Q.
    pub q: Matrix2,
}

/// Caches gate thresholds χ²_{dof}(p) for one probability, dof = 2, 4, 6, … (range-bearing
/// innovations contribute two degrees of freedom each, so every joint gate has an even
/// dimension 2·pairs).
#[derive(Debug, Clone)]
pub struct GateTable {
    p: f64,
    by_pairs: Vec<f64>,
}

impl GateTable {
    /// A table for probability `p` ∈ (0, 1).
    pub fn new(p: f64) -> Self {
        Self {
            p,
            by_pairs: Vec::new(),
        }
    }

    /// χ²_{2·pairs}(p) (pairs = 0 is read as 1).
    pub fn threshold(&mut self, pairs: usize) -> f64 {
        let pairs = pairs.max(1);
        while self.by_pairs.len() < pairs {
            let k = self.by_pairs.len() + 1;
            self.by_pairs.push(chi2_quantile(2 * k, self.p));
        }
        self.by_pairs[pairs - 1]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gaussian::CHI2_95;

    #[test]
    fn table_caches_in_order() {
        let mut t = GateTable::new(0.95);
        assert!((t.threshold(3) - CHI2_95[5]).abs() < 1e-5);
        assert!((t.threshold(1) - CHI2_95[1]).abs() < 1e-5);
    }
}
