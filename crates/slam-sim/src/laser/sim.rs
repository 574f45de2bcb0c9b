//! The laser simulation loop.

use super::{LaserScanner, World};
use crate::error::{check_range, check_steps, SimError};
use crate::path::{Follower, FollowerConfig, Path};
use crate::rng::{stream, tag};
use crate::LaserSimRun;
use serde::{Deserialize, Serialize};
use slam_models::motion::{MotionModel, OdometryModel, VelocityModel};
use slam_models::{ScanDataset, ScanRecord, TimedPose};

/// Everything a laser simulation needs besides the world, the path and the seed.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields, default)]
pub struct LaserSimConfig {
    /// Dataset name.
    pub name: String,
    /// Number of scans.
    pub scans: usize,
    /// Odometry records per scan (≥ 1): the scan is attached to every `odometry_per_scan`-th
    /// record, the others are odometry only, as in CARMEN logs.
    pub odometry_per_scan: usize,
    /// The controller that steers the true robot (its Δt is the odometry period).
    pub follower: FollowerConfig,
    /// Odometry noise (PR table 5.6) drawn between consecutive records.
    pub odometry: OdometryModel,
    /// The scanner.
    pub scanner: LaserScanner,
}

impl Default for LaserSimConfig {
    /// 600 scans, 3 odometry records per scan, follower at 0.8 m/s with Δt = 0.1 s (a scan
    /// every 0.24 m / 0.3 s), odometry α = (0.02, 0.002, 0.02, 0.001), the default
    /// [`LaserScanner`].
    fn default() -> Self {
        Self {
            name: "laser-sim".into(),
            scans: 600,
            odometry_per_scan: 3,
            follower: FollowerConfig {
                speed: 0.8,
                dt: 0.1,
                lookahead: 1.0,
                max_turn_rate: 1.0,
            },
            odometry: OdometryModel::new([0.02, 0.002, 0.02, 0.001]),
            scanner: LaserScanner::default(),
        }
    }
}

/// Drives the robot along `path` and records a CARMEN-like dataset, all randomness from
/// `seed`.
///
/// Each odometry period the follower commands (v, ω) from the true pose; the intended
/// motion is turned into an odometry increment ū (PR table 5.5), the true pose is drawn
/// x_k ~ p(x_k | ū, x_{k−1}) (PR table 5.6), and the odometry pose is advanced by the
/// noise-free ū: odometry_k = g(ū, odometry_{k−1}), starting at the true initial pose. So the
/// increments between odometry readings are the reported controls, and the odometry pose
/// drifts from the truth as real odometry does. Every `odometry_per_scan`-th record carries
/// a scan from the true pose. `ground_truth` has the true pose of every record, same time.
/// Stops early if an open path ends.
pub fn simulate_laser(
    world: &World,
    path: &Path,
    cfg: &LaserSimConfig,
    seed: u64,
) -> Result<LaserSimRun, SimError> {
    cfg.scanner.validate()?;
    for a in cfg.odometry.alpha {
        check_range("odometry alpha", a, 0.0, 1e3, "0 <= alpha <= 1000")?;
    }
    if cfg.odometry_per_scan == 0 {
        return Err(SimError::InvalidParameter {
            name: "odometry_per_scan",
            value: "0".into(),
            expected: "at least 1 odometry record per scan",
        });
    }
    let mut follower = Follower::new(path, cfg.follower.clone())?;
    let mut motion_rng = stream(seed, tag::MOTION);
    let mut sensor_rng = stream(seed, tag::SENSOR);
    let vel = VelocityModel::default();
    let start = path.start_pose();
    let (mut pose, mut odom) = (start, start);
    let n = check_steps(
        "scans x odometry_per_scan",
        cfg.scans.saturating_mul(cfg.odometry_per_scan),
    )?;
    let mut records = Vec::with_capacity(n);
    let mut gt = Vec::with_capacity(n);
    // Record 0: the start, with a scan.
    records.push(ScanRecord {
        t: 0.0,
        odometry: odom,
        scan: Some(cfg.scanner.scan(world, &pose, &mut sensor_rng)),
    });
    gt.push(TimedPose { t: 0.0, pose });
    for k in 1..n {
        if follower.finished() {
            break;
        }
        let cmd = follower.command(&pose);
        let intended = vel.predict(&pose, &cmd);
        let u = cfg.odometry.control_from_poses(&pose, &intended);
        pose = cfg.odometry.sample(&pose, &u, &mut motion_rng);
        odom = cfg.odometry.predict(&odom, &u);
        let t = k as f64 * cfg.follower.dt;
        let scan = (k % cfg.odometry_per_scan == 0)
            .then(|| cfg.scanner.scan(world, &pose, &mut sensor_rng));
        records.push(ScanRecord {
            t,
            odometry: odom,
            scan,
        });
        gt.push(TimedPose { t, pose });
    }
    Ok(LaserSimRun {
        dataset: ScanDataset {
            name: cfg.name.clone(),
            records,
            ground_truth: Some(gt),
        },
        world: world.clone(),
        odometry: cfg.odometry,
        scanner: cfg.scanner.clone(),
    })
}
