//! Looking an estimate up at a time (the rule of the dataset README, section 6), and
//! [`associate`], the one rule that pairs an estimate with its ground truth for ATE and RPE.

use slam_models::{normalize_angle, Pose2, TimedPose};

/// The default largest time difference between a requested time and the estimate used
/// for it, seconds (6 ms, as in the benchmark figures of the dataset README).
pub const DEFAULT_MAX_DT: f64 = 0.006;

/// The poses sorted by time, keeping the given order among equal times (a stable sort).
/// Non-finite times sort last.
pub fn sorted_by_time(traj: &[TimedPose]) -> Vec<TimedPose> {
    let mut v = traj.to_vec();
    v.sort_by(|a, b| a.t.total_cmp(&b.t));
    v
}

/// Index in `sorted` (sorted by time) of the pose used for time `t`: of the last pose with
/// time < t and the first with time ≥ t, the nearer one (the earlier on a tie), or `None`
/// when that is more than `max_dt` away (or `sorted` is empty).
pub fn lookup(sorted: &[TimedPose], t: f64, max_dt: f64) -> Option<usize> {
    let i = sorted.partition_point(|p| p.t < t);
    let before = i.checked_sub(1);
    let after = (i < sorted.len()).then_some(i);
    let pick = match (before, after) {
        (Some(b), Some(a)) => {
            if t - sorted[b].t <= sorted[a].t - t {
                b
            } else {
                a
            }
        }
        (Some(b), None) => b,
        (None, Some(a)) => a,
        (None, None) => return None,
    };
    ((sorted[pick].t - t).abs() <= max_dt).then_some(pick)
}

/// True when `a` and `b` come from the same log: the same number of poses with the same
/// time stamps, record by record (bit for bit).
pub fn same_stamps(a: &[TimedPose], b: &[TimedPose]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(p, q)| p.t.to_bits() == q.t.to_bits())
}

/// The association of an estimate with its ground truth: pairs (estimate index, ground-truth
/// index), both in file (record) order, in ground-truth file order. This is the one rule ATE,
/// RPE and the "as is" anchor use (documented in `docs/evaluation.md`):
///
/// * When both files come from the same log ([`same_stamps`]: same length, same stamps in
///   the same order), record i of the estimate goes with record i of the ground truth. Only
///   this keeps repeated or backward stamps apart, so a trajectory scored against itself is
///   exactly 0.
/// * Otherwise every ground-truth pose takes the estimate pose nearest in time ([`lookup`]
///   on the estimate sorted by time, file order kept among equal stamps, the earlier on a
///   tie), if it is at most `max_dt` seconds away; ground-truth poses without one are left
///   out.
pub fn associate(est: &[TimedPose], gt: &[TimedPose], max_dt: f64) -> Vec<(usize, usize)> {
    if same_stamps(est, gt) {
        return (0..est.len()).map(|i| (i, i)).collect();
    }
    let mut order: Vec<usize> = (0..est.len()).collect();
    order.sort_by(|&a, &b| est[a].t.total_cmp(&est[b].t));
    let sorted: Vec<TimedPose> = order.iter().map(|&i| est[i]).collect();
    gt.iter()
        .enumerate()
        .filter_map(|(j, g)| lookup(&sorted, g.t, max_dt).map(|k| (order[k], j)))
        .collect()
}

/// Stamps that repeat (equal to the one before) and stamps that step back (earlier than the
/// one before), counted in file order.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct StampOrder {
    /// Poses whose stamp equals the previous pose's.
    pub repeated: usize,
    /// Poses whose stamp is earlier than the previous pose's.
    pub backwards: usize,
}

/// Counts repeated and backward stamps in `traj` (file order).
pub fn stamp_order(traj: &[TimedPose]) -> StampOrder {
    let mut s = StampOrder::default();
    for w in traj.windows(2) {
        if w[1].t == w[0].t {
            s.repeated += 1;
        } else if w[1].t < w[0].t {
            s.backwards += 1;
        }
    }
    s
}

/// One warning line (without a `warning:` prefix) when `traj`, named `what`, has stamps that
/// repeat or step back, saying how such poses are associated; `None` when its stamps
/// strictly increase.
pub fn stamp_order_warning(traj: &[TimedPose], what: &str) -> Option<String> {
    let s = stamp_order(traj);
    (s.repeated + s.backwards > 0).then(|| {
        format!(
            "{what}: {} of {} time stamps repeat and {} step back; poses are associated by \
             nearest stamp, record by record when both files have the same stamps (see \
             docs/evaluation.md)",
            s.repeated,
            traj.len(),
            s.backwards
        )
    })
}

/// The [`stamp_order_warning`] lines for an estimate scored against a ground truth: one
/// for both when they come from the same log ([`same_stamps`]), else one per trajectory
/// whose stamps repeat or step back.
pub fn stamp_order_warnings(est: &[TimedPose], gt: &[TimedPose]) -> Vec<String> {
    let lines = if same_stamps(est, gt) {
        vec![stamp_order_warning(
            gt,
            "estimate and ground truth (same stamps)",
        )]
    } else {
        vec![
            stamp_order_warning(est, "estimate"),
            stamp_order_warning(gt, "ground truth"),
        ]
    };
    lines.into_iter().flatten().collect()
}

/// How an estimate is read at a time t.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PoseLookup {
    /// The nearest pose by [`lookup`] within `max_dt` seconds (the dataset README's rule,
    /// used for every published figure we compare with).
    Nearest {
        /// Largest accepted time difference, s.
        max_dt: f64,
    },
    /// A pose whose time equals t exactly (the first such) if there is one; otherwise the
    /// linear interpolation between the last pose before t and the first after it —
    /// x and y linearly, θ along the shorter arc — provided the two are at most `max_gap`
    /// seconds apart. No extrapolation beyond the ends.
    Interpolate {
        /// Largest time gap bridged by interpolation, s.
        max_gap: f64,
    },
}

impl Default for PoseLookup {
    /// `Nearest` with [`DEFAULT_MAX_DT`].
    fn default() -> Self {
        PoseLookup::Nearest {
            max_dt: DEFAULT_MAX_DT,
        }
    }
}

/// The estimated pose at time `t` from `sorted` (sorted by time, see [`sorted_by_time`]),
/// read as `how` says; `None` when the rule finds none.
pub fn pose_at(sorted: &[TimedPose], t: f64, how: PoseLookup) -> Option<Pose2> {
    match how {
        PoseLookup::Nearest { max_dt } => lookup(sorted, t, max_dt).map(|i| sorted[i].pose),
        PoseLookup::Interpolate { max_gap } => {
            let i = sorted.partition_point(|p| p.t < t);
            if i < sorted.len() && sorted[i].t == t {
                return Some(sorted[i].pose);
            }
            let (a, b) = (sorted.get(i.checked_sub(1)?)?, sorted.get(i)?);
            if b.t - a.t > max_gap {
                return None;
            }
            let f = (t - a.t) / (b.t - a.t);
            let dth = normalize_angle(b.pose.theta - a.pose.theta);
            Some(Pose2::new(
                a.pose.x + f * (b.pose.x - a.pose.x),
                a.pose.y + f * (b.pose.y - a.pose.y),
                a.pose.theta + f * dth,
            ))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use slam_models::Pose2;

    fn at(t: f64, x: f64) -> TimedPose {
        TimedPose {
            t,
            pose: Pose2::new(x, 0.0, 0.0),
        }
    }

    #[test]
    fn nearest_earlier_on_tie_within_limit() {
        // Two poses share t = 1.0 (file order x = 1 then x = 2).
        let s = sorted_by_time(&[at(1.0, 1.0), at(0.5, 0.0), at(1.0, 2.0), at(1.004, 3.0)]);
        assert_eq!(s[1].pose.x, 1.0);
        assert_eq!(s[2].pose.x, 2.0);
        // Exactly at 1.0: the first with time ≥ t is index 1 (x = 1), distance 0.
        assert_eq!(lookup(&s, 1.0, 0.006), Some(1));
        // 1.002: last < t is x = 2 (index 2, 2 ms), first ≥ t is index 3 (2 ms): tie → earlier.
        assert_eq!(lookup(&s, 1.002, 0.006), Some(2));
        assert_eq!(lookup(&s, 1.0031, 0.006), Some(3));
        // Too far from anything.
        assert_eq!(lookup(&s, 0.75, 0.006), None);
        assert_eq!(lookup(&s, 1.011, 0.006), None);
        assert_eq!(lookup(&s, 1.0099, 0.006), Some(3));
        assert_eq!(lookup(&[], 1.0, 1.0), None);
    }

    #[test]
    fn association_rule() {
        // Same log, with a repeated and a backward stamp: record by record.
        let a = [at(1.0, 0.0), at(1.0, 1.0), at(0.9, 2.0), at(2.0, 3.0)];
        let b = [at(1.0, 5.0), at(1.0, 6.0), at(0.9, 7.0), at(2.0, 8.0)];
        assert!(same_stamps(&a, &b));
        assert_eq!(
            associate(&a, &b, 0.006),
            vec![(0, 0), (1, 1), (2, 2), (3, 3)]
        );
        assert_eq!(
            stamp_order(&a),
            StampOrder {
                repeated: 1,
                backwards: 1
            }
        );
        assert!(stamp_order_warning(&a, "x").unwrap().contains("1 of 4"));
        assert!(stamp_order_warning(&a[2..], "x").is_none());
        // Different logs: nearest stamp, indices in the estimate's file order, the first of
        // equal stamps; the ground truth at 5.0 finds nothing.
        let gt = [at(2.001, 0.0), at(1.0, 0.0), at(0.902, 0.0), at(5.0, 0.0)];
        assert!(!same_stamps(&a, &gt));
        assert_eq!(associate(&a, &gt, 0.006), vec![(3, 0), (0, 1), (2, 2)]);
    }

    #[test]
    fn interpolation_hand_computed() {
        use std::f64::consts::PI;
        let s = sorted_by_time(&[
            TimedPose {
                t: 0.0,
                pose: Pose2::new(0.0, 0.0, PI - 0.1),
            },
            TimedPose {
                t: 1.0,
                pose: Pose2::new(2.0, -4.0, -PI + 0.1),
            },
            TimedPose {
                t: 3.0,
                pose: Pose2::new(0.0, 0.0, 0.0),
            },
        ]);
        let how = PoseLookup::Interpolate { max_gap: 1.5 };
        // A quarter of the way from t = 0 to t = 1: (0.5, −1), heading across ±π by the
        // short arc: π − 0.1 + 0.25·0.2 = π − 0.05.
        let p = pose_at(&s, 0.25, how).unwrap();
        assert!((p.x - 0.5).abs() < 1e-12 && (p.y + 1.0).abs() < 1e-12);
        assert!((normalize_angle(p.theta - (PI - 0.05))).abs() < 1e-12);
        // Exact time: that pose.
        assert_eq!(pose_at(&s, 1.0, how).unwrap().x, 2.0);
        // The gap 1 → 3 is 2 s > 1.5 s; outside the ends: none.
        assert!(pose_at(&s, 2.0, how).is_none());
        assert!(pose_at(&s, -0.1, how).is_none() && pose_at(&s, 3.1, how).is_none());
        assert!(pose_at(&s, 2.0, PoseLookup::Interpolate { max_gap: 2.0 }).is_some());
        // Nearest: the README rule.
        assert_eq!(pose_at(&s, 0.004, PoseLookup::default()).unwrap().x, 0.0);
        assert!(pose_at(&s, 0.5, PoseLookup::default()).is_none());
    }
}
