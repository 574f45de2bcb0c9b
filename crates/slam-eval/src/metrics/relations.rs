//! The relations metric of Kümmerle et al., *On measuring the accuracy of SLAM algorithms*
//! (Autonomous Robots 27, 2009), eq. 1: ε(δ) = 1/N Σ trans(δᵢⱼ ⊖ δ*ᵢⱼ)² + rot(δᵢⱼ ⊖ δ*ᵢⱼ)²,
//! reported, as in the paper, as mean ± std of the absolute and of the squared
//! translational [m] and rotational [deg] errors, separately.

use super::{lookup, mean_std, pose_at, sorted_by_time, PoseLookup, DEFAULT_MAX_DT};
use serde::Serialize;
use slam_io::relations::Relation;
use slam_models::TimedPose;

/// The relations metric. Standard deviations are population ones (÷ N). All statistics
/// are NaN when no relation could be used (`used == 0`; serde_json writes them as null).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RelationsResult {
    /// Mean translational error, m.
    pub trans_mean: f64,
    /// Std of the translational error, m.
    pub trans_std: f64,
    /// Mean squared translational error, m².
    pub trans_sq_mean: f64,
    /// Std of the squared translational error, m².
    pub trans_sq_std: f64,
    /// Mean absolute rotational error, degrees.
    pub rot_mean_deg: f64,
    /// Std of the absolute rotational error, degrees.
    pub rot_std_deg: f64,
    /// Mean squared rotational error, deg².
    pub rot_sq_mean: f64,
    /// Std of the squared rotational error, deg².
    pub rot_sq_std: f64,
    /// Relations evaluated.
    pub used: usize,
    /// Relations dropped because an end had no estimated pose within `max_dt`.
    pub dropped: usize,
    /// Used relations with an end read at an **ambiguous time**: a time at which the
    /// estimate holds several poses that are not all equal (a log whose clock repeats,
    /// e.g. `bench/intel.log`, where up to 11 records spanning half a metre share one
    /// printed time). Which of them the lookup reads is fixed by the tie rule (file order),
    /// not by the data, so such a relation's error mixes the estimate's error with the
    /// clock's.
    pub ambiguous: usize,
    /// Mean translational error over the used relations that are not ambiguous, m (NaN
    /// when there is none).
    pub unambiguous_trans_mean: f64,
    /// Mean absolute rotational error over the used relations that are not ambiguous,
    /// degrees (NaN when there is none).
    pub unambiguous_rot_mean_deg: f64,
}

/// [`relations_error_with`] with `max_dt` = [`DEFAULT_MAX_DT`] (6 ms, the README's rule).
pub fn relations_error(est: &[TimedPose], rel: &[Relation]) -> RelationsResult {
    relations_error_with(est, rel, DEFAULT_MAX_DT)
}

/// For each relation, the estimated poses x₁, x₂ at t1 and t2 (looked up as in the module
/// docs of [`crate::metrics`]), δ = x₁⁻¹ ⊕ x₂ (`x1.between(x2)`), and the error
/// E = δ*⁻¹ ⊕ δ: trans = ‖(E.x, E.y)‖ (which equals ‖t(δ) − t(δ*)‖) and
/// rot = |normalize(θ(δ) − θ(δ*))| in degrees. Relations with an end that finds no pose
/// are dropped and counted; non-finite estimated poses are not used. Relations read at an
/// ambiguous time are counted and also left out of a second pair of means
/// ([`RelationsResult::ambiguous`]).
pub fn relations_error_with(est: &[TimedPose], rel: &[Relation], max_dt: f64) -> RelationsResult {
    relations_error_lookup(est, rel, PoseLookup::Nearest { max_dt })
}

/// The relations metric with the estimate read at t1 and t2 as `how` says: the README's
/// nearest-pose rule, or interpolation for estimates that have no pose near a relation's
/// time (e.g. a trajectory kept only at keyframes).
pub fn relations_error_lookup(
    est: &[TimedPose],
    rel: &[Relation],
    how: PoseLookup,
) -> RelationsResult {
    let sorted: Vec<TimedPose> = sorted_by_time(est)
        .into_iter()
        .filter(|p| p.t.is_finite() && p.pose.is_finite())
        .collect();
    let mut tr = Vec::with_capacity(rel.len());
    let mut rot = Vec::with_capacity(rel.len());
    let (mut tr_clear, mut rot_clear) = (Vec::new(), Vec::new());
    for r in rel {
        let (Some(x1), Some(x2)) = (pose_at(&sorted, r.t1, how), pose_at(&sorted, r.t2, how))
        else {
            continue;
        };
        let delta = x1.between(&x2);
        let e = r.delta.between(&delta);
        tr.push(e.x.hypot(e.y));
        rot.push(e.theta.abs().to_degrees());
        if !ambiguous_at(&sorted, r.t1, how) && !ambiguous_at(&sorted, r.t2, how) {
            tr_clear.push(e.x.hypot(e.y));
            rot_clear.push(e.theta.abs().to_degrees());
        }
    }
    let sq = |v: &[f64]| v.iter().map(|x| x * x).collect::<Vec<f64>>();
    let (trans_mean, trans_std) = mean_std(&tr);
    let (trans_sq_mean, trans_sq_std) = mean_std(&sq(&tr));
    let (rot_mean_deg, rot_std_deg) = mean_std(&rot);
    let (rot_sq_mean, rot_sq_std) = mean_std(&sq(&rot));
    RelationsResult {
        trans_mean,
        trans_std,
        trans_sq_mean,
        trans_sq_std,
        rot_mean_deg,
        rot_std_deg,
        rot_sq_mean,
        rot_sq_std,
        used: tr.len(),
        dropped: rel.len() - tr.len(),
        ambiguous: tr.len() - tr_clear.len(),
        unambiguous_trans_mean: mean_std(&tr_clear).0,
        unambiguous_rot_mean_deg: mean_std(&rot_clear).0,
    }
}

/// Whether the pose `how` reads at `t` from `sorted` (sorted by time) comes from an
/// ambiguous time: one at which `sorted` holds poses that are not all equal. For
/// [`PoseLookup::Nearest`] that is the time of the pose picked; for
/// [`PoseLookup::Interpolate`], t itself when a pose lies exactly at t, else the times of
/// both poses interpolated between.
fn ambiguous_at(sorted: &[TimedPose], t: f64, how: PoseLookup) -> bool {
    let differing_at = |tau: f64| {
        let lo = sorted.partition_point(|p| p.t < tau);
        let hi = sorted.partition_point(|p| p.t <= tau);
        sorted[lo..hi].windows(2).any(|w| w[0].pose != w[1].pose)
    };
    match how {
        PoseLookup::Nearest { max_dt } => {
            lookup(sorted, t, max_dt).is_some_and(|i| differing_at(sorted[i].t))
        }
        PoseLookup::Interpolate { .. } => {
            let i = sorted.partition_point(|p| p.t < t);
            if i < sorted.len() && sorted[i].t == t {
                return differing_at(t);
            }
            let before = i.checked_sub(1).map(|b| sorted[b].t);
            let after = sorted.get(i).map(|a| a.t);
            before.is_some_and(differing_at) || after.is_some_and(differing_at)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use slam_models::Pose2;

    #[test]
    fn hand_computed() {
        // Estimate: origin at t=0, (1,0,0) at t=1, (1,1,90°) at t=2.
        let est = [
            TimedPose {
                t: 0.0,
                pose: Pose2::new(0.0, 0.0, 0.0),
            },
            TimedPose {
                t: 1.0,
                pose: Pose2::new(1.0, 0.0, 0.0),
            },
            TimedPose {
                t: 2.0,
                pose: Pose2::new(1.0, 1.0, std::f64::consts::FRAC_PI_2),
            },
        ];
        let rel = [
            // δ(0→1) = (1,0,0); truth (1,0,0): error 0.
            Relation {
                t1: 0.0,
                t2: 1.0,
                delta: Pose2::new(1.0, 0.0, 0.0),
            },
            // δ(1→2) = (0,1,90°); truth (0,0.5,80°): trans 0.5, rot 10°.
            Relation {
                t1: 1.004,
                t2: 2.0,
                delta: Pose2::new(0.0, 0.5, 80f64.to_radians()),
            },
            // An end far from every pose: dropped.
            Relation {
                t1: 0.5,
                t2: 2.0,
                delta: Pose2::IDENTITY,
            },
        ];
        let r = relations_error(&est, &rel);
        assert_eq!((r.used, r.dropped), (2, 1));
        assert!((r.trans_mean - 0.25).abs() < 1e-12);
        assert!((r.trans_std - 0.25).abs() < 1e-12);
        assert!((r.trans_sq_mean - 0.125).abs() < 1e-12);
        assert!((r.trans_sq_std - 0.125).abs() < 1e-12);
        assert!((r.rot_mean_deg - 5.0).abs() < 1e-9);
        assert!((r.rot_std_deg - 5.0).abs() < 1e-9);
        assert!((r.rot_sq_mean - 50.0).abs() < 1e-7);
        let none = relations_error(&[], &rel);
        assert_eq!((none.used, none.dropped), (0, 3));
        assert!(none.trans_mean.is_nan());
    }

    #[test]
    fn interpolated_lookup_scores_sparse_estimates() {
        use slam_models::Pose2;
        // Estimate only at whole seconds along the x axis at 1 m/s; relations between
        // half-second times, each true motion 1 m straight ahead (one off by 0.2 m).
        let est: Vec<TimedPose> = (0..4)
            .map(|k| TimedPose {
                t: k as f64,
                pose: Pose2::new(k as f64, 0.0, 0.0),
            })
            .collect();
        let rel = vec![
            Relation {
                t1: 0.5,
                t2: 1.5,
                delta: Pose2::new(1.0, 0.0, 0.0),
            },
            Relation {
                t1: 1.5,
                t2: 2.5,
                delta: Pose2::new(1.2, 0.0, 0.0),
            },
        ];
        // The README's nearest rule finds nothing within 6 ms.
        assert_eq!(relations_error(&est, &rel).used, 0);
        let r = relations_error_lookup(&est, &rel, PoseLookup::Interpolate { max_gap: 1.5 });
        assert_eq!(r.used, 2);
        assert!((r.trans_mean - 0.1).abs() < 1e-12, "{}", r.trans_mean);
        assert!(r.rot_mean_deg.abs() < 1e-12);
    }

    #[test]
    fn relations_read_at_a_repeated_time_are_ambiguous() {
        use slam_models::Pose2;
        let at = |t: f64, x: f64| TimedPose {
            t,
            pose: Pose2::new(x, 0.0, 0.0),
        };
        // Records at 1 m/s along x, except that three records (x = 2, 3, 4) were stamped
        // with one time, 2.0, as a clock that repeats prints them; two records at t = 6
        // hold the same pose (a scan and its odometry record).
        let est = [
            at(0.0, 0.0),
            at(1.0, 1.0),
            at(2.0, 2.0),
            at(2.0, 3.0),
            at(2.0, 4.0),
            at(5.0, 5.0),
            at(6.0, 6.0),
            at(6.0, 6.0),
        ];
        let straight = |t1: f64, t2: f64, d: f64| Relation {
            t1,
            t2,
            delta: Pose2::new(d, 0.0, 0.0),
        };
        let rel = [
            // 0 → 1: exact. Unambiguous.
            straight(0.0, 1.0, 1.0),
            // 1 → the record stamped 2.0 that truly was at x = 3: the tie rule reads the
            // first of the three (x = 2), 1 m short. Ambiguous.
            straight(1.0, 2.0, 2.0),
            // 5 → 6: both poses at 6 are equal, so reading either is the same. Off by
            // 0.5 m, unambiguous.
            straight(5.0, 6.0, 1.5),
            // Just after 2.0 (t = 2.004): the nearest is the last record stamped 2.0
            // (x = 4). 4 → 5 truly 1 m: exact, but ambiguous.
            straight(2.004, 5.0, 1.0),
        ];
        let r = relations_error(&est, &rel);
        assert_eq!((r.used, r.dropped, r.ambiguous), (4, 0, 2));
        assert!((r.trans_mean - 0.375).abs() < 1e-12, "{}", r.trans_mean);
        assert!((r.unambiguous_trans_mean - 0.25).abs() < 1e-12);
        assert_eq!(r.unambiguous_rot_mean_deg, 0.0);
        // Interpolation reads t = 2.0 exactly at the repeated time, and t = 3.5 between
        // its last record and t = 5: both ambiguous; t = 5.5 between 5 and the two equal
        // poses at 6 is not.
        let how = PoseLookup::Interpolate { max_gap: 3.5 };
        let r = relations_error_lookup(
            &est,
            &[
                straight(0.0, 2.0, 2.0),
                straight(3.5, 5.0, 0.5),
                straight(5.0, 5.5, 0.5),
            ],
            how,
        );
        assert_eq!((r.used, r.ambiguous), (3, 2));
        assert!(r.unambiguous_trans_mean.abs() < 1e-12);
        // Without a repeated time, nothing is ambiguous and both means agree.
        let clean = [at(0.0, 0.0), at(1.0, 1.0), at(2.0, 2.0)];
        let r = relations_error(&clean, &rel[..2]);
        assert_eq!(r.ambiguous, 0);
        assert_eq!(r.unambiguous_trans_mean, r.trans_mean);
        // No relation left unambiguous: NaN, not zero.
        let r = relations_error(&est, &rel[1..2]);
        assert!(r.unambiguous_trans_mean.is_nan());
    }
}
