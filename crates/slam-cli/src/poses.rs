//! `slam run --filter known-poses --poses FILE.tum`: the poses of a TUM file given to the
//! scans of a log, matched by timestamp.

use crate::error::CliError;
use slam_models::{ScanRecord, TimedPose};
use std::path::Path;

/// Largest time difference (seconds) between a scan and the TUM pose given to it.
///
/// 5 ms: below half the period of any laser in our data (≥ 10 ms between scans), above
/// the 1 µs rounding of TUM's printed times and the 6-digit printing of CARMEN logs.
pub const POSE_TOLERANCE: f64 = 0.005;

/// Replaces the records of a laser log by its scan records, each with the pose of `poses`
/// nearest in time as its odometry (so known-poses mapping writes the scan there);
/// odometry-only records are dropped (they write nothing into the map).
///
/// Matching goes through both lists in file order: for each scan, the candidates are the
/// poses after the one the previous scan took whose time is within
/// [`POSE_TOLERANCE`] of the scan's; the nearest wins (the first on a tie). So scans that
/// share one printed time take consecutive poses of that time, in order.
///
/// Errors ([`CliError::InvalidArgument`], naming `path`, the scan's record index and
/// time, and the nearest pose time): a scan without a pose within the tolerance; a file
/// without poses.
pub fn apply_poses(
    records: &[ScanRecord],
    poses: &[TimedPose],
    path: &Path,
) -> Result<Vec<ScanRecord>, CliError> {
    if poses.is_empty() {
        return Err(CliError::InvalidArgument(format!(
            "--poses {}: no pose in the file",
            path.display()
        )));
    }
    let mut out = Vec::new();
    let mut next = 0usize;
    for (k, r) in records.iter().enumerate() {
        if r.scan.is_none() {
            continue;
        }
        let mut best: Option<(usize, f64)> = None;
        for (j, p) in poses.iter().enumerate().skip(next) {
            let dt = (p.t - r.t).abs();
            if dt <= POSE_TOLERANCE && best.is_none_or(|(_, b)| dt < b) {
                best = Some((j, dt));
            }
            // Poses are in time order up to small steps back: stop well past the scan.
            if p.t > r.t + 100.0 * POSE_TOLERANCE && best.is_some() {
                break;
            }
        }
        let Some((j, _)) = best else {
            let nearest = poses
                .iter()
                .map(|p| p.t)
                .min_by(|a, b| (a - r.t).abs().total_cmp(&(b - r.t).abs()))
                .unwrap_or(f64::NAN);
            return Err(CliError::InvalidArgument(format!(
                "--poses {}: no pose within {POSE_TOLERANCE} s of the scan of record {k} \
                 (t = {} s; the nearest pose of the file is at t = {nearest} s{})",
                path.display(),
                r.t,
                if next > 0 {
                    ", or it was already given to an earlier scan"
                } else {
                    ""
                }
            )));
        };
        next = j + 1;
        out.push(ScanRecord {
            t: r.t,
            odometry: poses[j].pose,
            scan: r.scan.clone(),
        });
    }
    if out.is_empty() {
        return Err(CliError::InvalidArgument(format!(
            "--poses {}: the log has no scan to give a pose to",
            path.display()
        )));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use slam_models::{LaserScan, Pose2};

    fn rec(t: f64, scan: bool) -> ScanRecord {
        ScanRecord {
            t,
            odometry: Pose2::new(-1.0, -1.0, 0.0),
            scan: scan.then(|| LaserScan {
                angle_min: -0.5,
                angle_increment: 0.5,
                ranges: vec![1.0; 3],
                max_range: 10.0,
                sensor_pose: Pose2::IDENTITY,
            }),
        }
    }

    fn pose(t: f64, x: f64) -> TimedPose {
        TimedPose {
            t,
            pose: Pose2::new(x, 0.0, 0.0),
        }
    }

    #[test]
    fn scans_take_the_nearest_pose_in_order_and_odometry_records_go() {
        let records = [
            rec(0.0, false),
            rec(1.0, true),
            rec(1.0, true), // same printed time: the next pose of that time
            rec(2.0, false),
            rec(3.001, true),
        ];
        let poses = [
            pose(0.5, 9.0),
            pose(1.0, 1.0),
            pose(1.0, 2.0),
            pose(3.0, 3.0),
            pose(3.004, 4.0),
        ];
        let out = apply_poses(&records, &poses, Path::new("p.tum")).unwrap();
        let xs: Vec<f64> = out.iter().map(|r| r.odometry.x).collect();
        assert_eq!(xs, [1.0, 2.0, 3.0]);
        assert_eq!(out[2].t, 3.001);
    }

    #[test]
    fn a_scan_without_a_pose_is_a_clear_error() {
        let records = [rec(1.0, true), rec(2.0, true)];
        let poses = [pose(1.0, 1.0), pose(2.01, 2.0)];
        let e = apply_poses(&records, &poses, Path::new("p.tum"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("p.tum") && e.contains("record 1"), "{e}");
        assert!(e.contains("t = 2 s") && e.contains("2.01"), "{e}");
        assert!(apply_poses(&records, &[], Path::new("p.tum")).is_err());
    }
}
