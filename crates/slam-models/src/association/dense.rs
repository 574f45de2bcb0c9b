//! A plain dense joint Gaussian over the pose and the landmarks (nalgebra, no in-place
//! growth tricks), with the prediction and augmentation steps of PR table 10.1. Back ends
//! that need an association belief but not the EKF update (the pose graph between two
//! optimisations) use it; EKF-SLAM keeps its own faer core, which grows in place and owns
//! the batched update.

use super::JointGaussian;
use crate::measurement::InverseRangeBearing;
use crate::{normalize_angle, Matrix2, Matrix3, Matrix3x2, Point2, Pose2};
use nalgebra::{DMatrix, DVector};

/// Mean μ = (x, y, θ, m₁ₓ, m₁ᵧ, …, mₙₓ, mₙᵧ) and covariance Σ ((3 + 2n)², symmetric).
#[derive(Debug, Clone, PartialEq)]
pub struct DenseGaussian {
    /// μ, metres and radians.
    pub mean: DVector<f64>,
    /// Σ.
    pub cov: DMatrix<f64>,
}

impl DenseGaussian {
    /// A pose with covariance `pose_cov` and no landmarks.
    pub fn new(pose: Pose2, pose_cov: Matrix3) -> Self {
        Self {
            mean: DVector::from_column_slice(&[pose.x, pose.y, pose.theta]),
            cov: DMatrix::from_fn(3, 3, |r, c| pose_cov[(r, c)]),
        }
    }

    /// Prediction (PR table 10.1 lines 3–5) given the predicted pose g(u, μ), its Jacobian
    /// G and the process noise R: Σxx ← G·Σxx·Gᵀ + R, Σxm ← G·Σxm. O(N).
    pub fn predict(&mut self, new_pose: &Pose2, g: &Matrix3, r: &Matrix3) {
        let n = self.mean.len();
        self.mean[0] = new_pose.x;
        self.mean[1] = new_pose.y;
        self.mean[2] = normalize_angle(new_pose.theta);
        let pxx = g * self.pose_cov() * g.transpose() + r;
        let pxx = (pxx + pxx.transpose()) * 0.5;
        for c in 3..n {
            let v = g * crate::Vector3::new(self.cov[(0, c)], self.cov[(1, c)], self.cov[(2, c)]);
            for k in 0..3 {
                self.cov[(k, c)] = v[k];
                self.cov[(c, k)] = v[k];
            }
        }
        for r in 0..3 {
            for c in 0..3 {
                self.cov[(r, c)] = pxx[(r, c)];
            }
        }
    }

    /// Appends a landmark initialised by the inverse measurement model m = h⁻¹(x, z) with
    /// Gx = ∂m/∂x, Gz = ∂m/∂z: Σmm = Gx·Σxx·Gxᵀ + Gz·Q·Gzᵀ, Σm· = Gx·Σx· (PR §10.2.3 with
    /// the full Jacobians). Returns its number. O(N²) (the matrix is copied).
    pub fn add_landmark(&mut self, inv: &InverseRangeBearing, q: &Matrix2) -> usize {
        let n = self.mean.len();
        let gx = &inv.g_pose;
        let pmm = gx * self.pose_cov() * gx.transpose() + inv.g_z * q * inv.g_z.transpose();
        let pmm = (pmm + pmm.transpose()) * 0.5;
        let cov = std::mem::replace(&mut self.cov, DMatrix::zeros(0, 0));
        let mut cov = cov.resize(n + 2, n + 2, 0.0);
        for c in 0..n {
            let v = gx * crate::Vector3::new(cov[(0, c)], cov[(1, c)], cov[(2, c)]);
            for k in 0..2 {
                cov[(n + k, c)] = v[k];
                cov[(c, n + k)] = v[k];
            }
        }
        for r in 0..2 {
            for c in 0..2 {
                cov[(n + r, n + c)] = pmm[(r, c)];
            }
        }
        self.cov = cov;
        let mean = std::mem::replace(&mut self.mean, DVector::zeros(0));
        self.mean = mean.push(inv.landmark.x).push(inv.landmark.y);
        self.landmark_count() - 1
    }
}

impl JointGaussian for DenseGaussian {
    fn pose(&self) -> Pose2 {
        Pose2::new(self.mean[0], self.mean[1], self.mean[2])
    }
    fn landmark_count(&self) -> usize {
        (self.mean.len() - 3) / 2
    }
    fn landmark(&self, j: usize) -> Point2 {
        Point2::new(self.mean[3 + 2 * j], self.mean[4 + 2 * j])
    }
    fn pose_cov(&self) -> Matrix3 {
        Matrix3::from_fn(|r, c| self.cov[(r, c)])
    }
    fn pose_landmark_cov(&self, j: usize) -> Matrix3x2 {
        Matrix3x2::from_fn(|r, c| self.cov[(r, 3 + 2 * j + c)])
    }
    fn landmark_cov(&self, j: usize) -> Matrix2 {
        self.landmark_landmark_cov(j, j)
    }
    fn landmark_landmark_cov(&self, i: usize, j: usize) -> Matrix2 {
        Matrix2::from_fn(|r, c| self.cov[(3 + 2 * i + r, 3 + 2 * j + c)])
    }
}
