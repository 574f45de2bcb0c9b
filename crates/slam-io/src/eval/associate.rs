//! Looking an estimate up at a time (the rule of the dataset README, section 6).

use slam_models::TimedPose;

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
}
