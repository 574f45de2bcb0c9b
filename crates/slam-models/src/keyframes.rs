//! Poses at every record of a log from the corrected poses of its keyframes.
//!
//! A keyframe-based scan SLAM filter (GMapping, slam-rs's `slam-gridfast`) corrects the
//! robot's pose only at the scans it processes. Its estimate at any other record i is the
//! last corrected pose composed with the odometry since, x(i) = x(k) ⊕ (o(k)⁻¹ ⊕ o(i)) with
//! k the last keyframe at or before i and o the odometry readings (`Pose2::between`), the
//! `map → odom → base_link` chain of a ROS node; before the first keyframe it is the
//! odometry itself (the world frame is the odometry frame). A record that carries both
//! the time stamp and the odometry of the *next* keyframe is that keyframe's own instant
//! (CARMEN and GMapping logs write a scan's ODOM line just before its FLASER line) and
//! takes the keyframe's corrected pose.
//!
//! Records that merely share a printed time stamp with the next keyframe but carry other
//! odometry are earlier readings and follow the general rule: logs printed with few
//! digits put several readings on one time stamp. This is GMapping's own convention; it
//! reproduces its trajectory file of the Intel benchmark input at every record (tested in
//! the workspace's `tests/gridfast.rs`).

use crate::error::ModelError;
use crate::pose::Pose2;

/// A keyframe: the index of its record in the log and its corrected pose (world frame,
/// metres and radians).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Keyframe {
    /// Index of the keyframe's record in the log.
    pub record: usize,
    /// The corrected pose at that record.
    pub pose: Pose2,
}

/// The pose of record `i` given the keyframes around it: `previous`, the last keyframe at
/// or before `i`, and `next`, the first one after `i` (see the module doc for the rule).
///
/// `times` and `odometry` hold one entry per record of the log. Returns `None` when `i`
/// or a keyframe's record index lies outside them ([`poses_at_records`], the entry point
/// for whole logs, checks its inputs and says what is wrong).
pub fn pose_at_record(
    times: &[f64],
    odometry: &[Pose2],
    i: usize,
    previous: Option<Keyframe>,
    next: Option<Keyframe>,
) -> Option<Pose2> {
    let (t, o) = (*times.get(i)?, *odometry.get(i)?);
    if let Some(n) = next {
        if *times.get(n.record)? == t && *odometry.get(n.record)? == o {
            return Some(n.pose);
        }
    }
    Some(match previous {
        Some(k) => k.pose.compose(&odometry.get(k.record)?.between(&o)),
        None => o,
    })
}

/// The pose at every record of a log (see the module doc for the rule), in one pass.
///
/// Errors when `times` and `odometry` differ in length, or when the keyframes' record
/// indices are not strictly increasing and inside the log.
pub fn poses_at_records(
    times: &[f64],
    odometry: &[Pose2],
    keyframes: &[Keyframe],
) -> Result<Vec<Pose2>, ModelError> {
    if times.len() != odometry.len() {
        return Err(ModelError::Mismatch {
            what: "log records",
            reason: format!(
                "{} time stamps but {} odometry readings",
                times.len(),
                odometry.len()
            ),
        });
    }
    for (j, k) in keyframes.iter().enumerate() {
        let after_previous = j == 0 || keyframes[j - 1].record < k.record;
        if k.record >= times.len() || !after_previous {
            return Err(ModelError::Mismatch {
                what: "keyframes",
                reason: format!(
                    "keyframe {j} refers to record {}; records must be strictly increasing \
                     and below {}",
                    k.record,
                    times.len()
                ),
            });
        }
    }
    let mut out = Vec::with_capacity(times.len());
    let mut j = 0; // keyframes[..j] are at or before the current record
    for i in 0..times.len() {
        while j < keyframes.len() && keyframes[j].record <= i {
            j += 1;
        }
        let previous = j.checked_sub(1).map(|p| keyframes[p]);
        let next = keyframes.get(j).copied();
        // Every index was checked above, so this is always `Some`.
        let pose = pose_at_record(times, odometry, i, previous, next).ok_or_else(|| {
            ModelError::Mismatch {
                what: "keyframes",
                reason: format!("record {i} or its keyframes lie outside the log"),
            }
        })?;
        out.push(pose);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_general_rule_and_the_same_instant_exception() {
        let times = [0.0, 1.0, 2.0, 2.0, 2.0, 3.0];
        let odometry = [
            Pose2::new(0.0, 0.0, 0.0),
            Pose2::new(0.5, 0.0, 0.2),
            Pose2::new(0.9, 0.1, 0.3), // an earlier reading printed at t = 2
            Pose2::new(1.0, 0.2, 0.4), // the keyframe's own ODOM line
            Pose2::new(1.0, 0.2, 0.4), // the keyframe
            Pose2::new(1.5, 0.3, 0.6),
        ];
        let k0 = Keyframe {
            record: 1,
            pose: Pose2::new(10.0, 5.0, 1.0),
        };
        let k1 = Keyframe {
            record: 4,
            pose: Pose2::new(10.3, 5.4, 1.25),
        };
        let p = poses_at_records(&times, &odometry, &[k0, k1]).unwrap();
        // Before the first keyframe: the odometry.
        assert_eq!(p[0], odometry[0]);
        assert_eq!(p[1], k0.pose);
        // x(k) ⊕ (o(k) ⊖ o(i)), written out: rotate the odometry step into the keyframe.
        let (dx, dy) = (odometry[2].x - odometry[1].x, odometry[2].y - odometry[1].y);
        let (c, s) = (
            (k0.pose.theta - odometry[1].theta).cos(),
            (k0.pose.theta - odometry[1].theta).sin(),
        );
        let want = Pose2::new(
            k0.pose.x + c * dx - s * dy,
            k0.pose.y + s * dx + c * dy,
            k0.pose.theta + odometry[2].theta - odometry[1].theta,
        );
        assert!(p[2].approx_eq(&want, 1e-12), "{:?} vs {want:?}", p[2]);
        // The keyframe's own ODOM line and the keyframe.
        assert_eq!(p[3], k1.pose);
        assert_eq!(p[4], k1.pose);
        let want = k1.pose.compose(&odometry[4].between(&odometry[5]));
        assert!(p[5].approx_eq(&want, 1e-12));
    }

    #[test]
    fn inconsistent_inputs_are_errors() {
        let t = [0.0, 1.0];
        let o = [Pose2::IDENTITY; 2];
        let k = |r| Keyframe {
            record: r,
            pose: Pose2::IDENTITY,
        };
        assert!(poses_at_records(&t, &o[..1], &[]).is_err());
        assert!(poses_at_records(&t, &o, &[k(2)]).is_err());
        assert!(poses_at_records(&t, &o, &[k(1), k(1)]).is_err());
        assert!(poses_at_records(&t, &o, &[k(1), k(0)]).is_err());
        assert_eq!(poses_at_records(&t, &o, &[k(0), k(1)]).unwrap().len(), 2);
        // The single-record form answers None instead of indexing out of bounds.
        assert_eq!(pose_at_record(&t, &o, 2, None, None), None);
        assert_eq!(pose_at_record(&t, &o, 0, Some(k(5)), None), None);
        assert_eq!(pose_at_record(&t, &o, 0, None, Some(k(5))), None);
        assert_eq!(
            pose_at_record(&t, &o, 1, Some(k(0)), None),
            Some(Pose2::IDENTITY)
        );
    }
}
