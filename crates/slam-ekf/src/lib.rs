//! # slam-ekf: EKF-SLAM
//!
//! Will hold EKF-SLAM (PR ch. 10): the robot pose and all landmarks in one Gaussian, a dense
//! `faer` covariance with O(n) prediction and O(n²) low-rank updates, landmark
//! initialisation with full cross-covariances, and known/unknown data association
//! (gated nearest neighbour, JCBB). Implements `slam_models::LandmarkSlam`.
