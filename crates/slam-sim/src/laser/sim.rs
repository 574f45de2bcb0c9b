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
    /// Kidnappings: the simulator carries the robot elsewhere without the odometry
    /// noticing (none by default).
    pub teleports: Vec<Teleport>,
}

/// A kidnapping (PR §8.3.5): just before record `record` is taken, the true robot is put
/// at the path's pose at arc length `to` (heading along the path; closed paths wrap) and
/// the follower's carrot moves there too. The odometry is not told: record `record`'s
/// odometry increment is only the commanded motion, so the odometry pose goes on from where
/// it was, while the ground truth of that record and every later one shows the jump.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
pub struct Teleport {
    /// Index of the first record taken at the new place (≥ 1; record 0 is the start).
    pub record: usize,
    /// Arc length along the path (metres) where the robot is put.
    pub to: f64,
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
            teleports: Vec::new(),
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
/// Stops early if an open path ends. `cfg.teleports` kidnap the robot (see [`Teleport`]).
///
/// Errors: invalid scanner or odometry settings, no odometry record per scan, too many
/// steps, a teleport at record 0 or to a non-finite arc length (or beyond an open path).
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
    for tp in &cfg.teleports {
        let hi = if path.is_closed() {
            f64::MAX
        } else {
            path.length()
        };
        check_range(
            "teleport to",
            tp.to,
            0.0,
            hi,
            "an arc length >= 0 m (at most the length of an open path)",
        )?;
        if tp.record == 0 {
            return Err(SimError::InvalidParameter {
                name: "teleport record",
                value: "0".into(),
                expected: "a record index >= 1 (record 0 is the start)",
            });
        }
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
        if let Some(tp) = cfg.teleports.iter().find(|tp| tp.record == k) {
            // Kidnapped: the truth jumps, the odometry does not know.
            pose = path.pose_at(tp.to);
            follower.jump_to(tp.to);
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::laser::{office_path, office_world};

    /// A kidnapping: the truth jumps to the path's pose at the given arc length, the
    /// odometry increment of that record stays a normal step, and the follower goes on
    /// from the new place.
    #[test]
    fn a_teleport_moves_the_truth_and_not_the_odometry() {
        let (world, path) = (office_world(), office_path());
        let cfg = LaserSimConfig {
            scans: 200,
            teleports: vec![Teleport {
                record: 100,
                to: 40.0,
            }],
            ..LaserSimConfig::default()
        };
        let run = simulate_laser(&world, &path, &cfg, 3).unwrap();
        let gt = run.dataset.ground_truth.as_ref().unwrap();
        let rec = &run.dataset.records;
        let step = |k: usize| gt[k - 1].pose.distance(&gt[k].pose);
        let odo = |k: usize| rec[k - 1].odometry.distance(&rec[k].odometry);
        // Before: steps of about speed·dt = 0.08 m in both.
        assert!(step(99) < 0.2 && odo(99) < 0.2);
        // At the teleport: the truth is next to the path's pose at 40 m, far from before.
        let target = path.pose_at(40.0);
        assert!(gt[100].pose.distance(&target) < 0.2, "{:?}", gt[100].pose);
        assert!(step(100) > 5.0, "the truth did not jump");
        assert!(odo(100) < 0.2, "the odometry saw the jump");
        // After: the robot follows the path from there, close to it.
        assert!(step(150) < 0.2);
        assert!(gt[199].pose.distance(&path.pose_at(40.0 + 99.0 * 0.08)) < 1.0);
        // A teleport at record 0 or to a non-finite place is refused.
        let bad = LaserSimConfig {
            teleports: vec![Teleport { record: 0, to: 1.0 }],
            ..LaserSimConfig::default()
        };
        assert!(simulate_laser(&world, &path, &bad, 3).is_err());
        let bad = LaserSimConfig {
            teleports: vec![Teleport {
                record: 5,
                to: f64::NAN,
            }],
            ..LaserSimConfig::default()
        };
        assert!(simulate_laser(&world, &path, &bad, 3).is_err());
    }
}
