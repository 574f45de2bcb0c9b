//! # slam-fastslam: FastSLAM 1.0 and 2.0
//!
//! Will hold FastSLAM (Montemerlo et al. 2002/2003, PR ch. 13): particles over the robot
//! path with a small EKF per landmark, persistent landmark trees shared between particles,
//! per-particle data association and adaptive resampling. Implements
//! `slam_models::LandmarkSlam`.
