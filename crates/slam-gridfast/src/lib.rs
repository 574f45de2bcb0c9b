//! # slam-gridfast: grid-based FastSLAM
//!
//! Will hold the Rao-Blackwellized particle filter on occupancy grids (Hähnel et al. 2003;
//! Grisetti et al. 2007) with the improved proposal and selective resampling. Implements
//! `slam_models::ScanSlam`.
