//! Absolute trajectory error (ATE) and relative pose error (RPE) (Sturm et al., IROS 2012,
//! the TUM RGB-D benchmark definitions, restricted to SE(2)).

use super::{associate, errors_as_is_and_aligned, mean_std, rms, DEFAULT_MAX_DT};
use crate::error::EvalError;
use serde::Serialize;
use slam_models::{Point2, Pose2, TimedPose};

/// Absolute trajectory error over the ground-truth poses that found an estimate.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct AteResult {
    /// RMSE of ‖p_est − p_gt‖ as is (estimate and ground truth in the same frame), m.
    pub rmse: f64,
    /// RMSE after the least-squares SE(2) alignment of the estimate onto the ground truth, m.
    pub rmse_aligned: f64,
    /// Mean position error as is, m.
    pub mean: f64,
    /// Largest position error as is, m.
    pub max: f64,
    /// Ground-truth poses matched with an estimate.
    pub matched: usize,
    /// Ground-truth poses without an estimate within `max_dt`.
    pub unmatched: usize,
    /// The alignment T applied to the estimate (p ↦ T·p) for `rmse_aligned`.
    pub alignment: Pose2,
}

/// Pairs (estimate, ground truth) by [`associate`], in ground-truth file order.
fn matched_pairs(est: &[TimedPose], gt: &[TimedPose], max_dt: f64) -> Vec<(Pose2, Pose2)> {
    associate(est, gt, max_dt)
        .into_iter()
        .map(|(i, j)| (est[i].pose, gt[j].pose))
        .collect()
}

/// The ground truth `gt` moved rigidly so that the ground-truth partner of the estimate's
/// first pose in file (record) order coincides with that pose: T = e ⊕ g⁻¹ applied to every
/// ground-truth pose, with (e, g) the pair of [`associate`] (within [`DEFAULT_MAX_DT`]) of
/// lowest estimate index. This is `evo_ape --align_origin`. Unchanged when no pose matches
/// in time (ATE then says so).
///
/// Use it when the estimate starts in its own frame (a laser filter starts at the first
/// odometry pose, in the odometry frame, which need not be the ground truth's):
/// "as is" metrics then mean "sharing the start frame". The anchor is the first record, not
/// the earliest stamp: logs with a few late records stamped before the start (Intel) would
/// otherwise anchor at a pose far into the run.
pub fn anchor_at_first_match(trajectory: &[TimedPose], gt: &[TimedPose]) -> Vec<TimedPose> {
    let first = associate(trajectory, gt, DEFAULT_MAX_DT)
        .into_iter()
        .min_by_key(|&(i, j)| (i, j));
    match first {
        Some((i, j)) => {
            let t = trajectory[i].pose.compose(&gt[j].pose.inverse());
            gt.iter()
                .map(|g| TimedPose {
                    t: g.t,
                    pose: t.compose(&g.pose),
                })
                .collect()
        }
        None => gt.to_vec(),
    }
}

/// [`ate_with`] with `max_dt` = [`DEFAULT_MAX_DT`].
pub fn ate(est: &[TimedPose], gt: &[TimedPose]) -> Result<AteResult, EvalError> {
    ate_with(est, gt, DEFAULT_MAX_DT)
}

/// ATE: the pairs of [`associate`] (every ground-truth pose with the estimate nearest its
/// time within `max_dt`, or record by record for files from the same log), then
/// RMSE = √(1/n Σ‖p_est,i − p_gt,i‖²) as is and after aligning the estimate's positions
/// onto the ground truth's with [`align_se2`](super::align_se2) (Umeyama without scale). Errors when no
/// ground-truth pose finds an estimate, or values are not finite.
///
/// # Example
///
/// ```
/// use slam_eval::metrics::ate;
/// use slam_models::{Pose2, TimedPose};
/// let gt = [TimedPose { t: 0.0, pose: Pose2::new(0.0, 0.0, 0.0) }, TimedPose { t: 1.0, pose: Pose2::new(1.0, 0.0, 0.0) }];
/// let est = [TimedPose { t: 0.0, pose: Pose2::new(0.0, 0.0, 0.0) }, TimedPose { t: 1.0, pose: Pose2::new(1.0, 0.2, 0.0) }];
/// let r = ate(&est, &gt)?;
/// assert!((r.rmse - (0.04f64 / 2.0).sqrt()).abs() < 1e-12); // errors 0 and 0.2 m
/// # Ok::<(), slam_eval::EvalError>(())
/// ```
pub fn ate_with(est: &[TimedPose], gt: &[TimedPose], max_dt: f64) -> Result<AteResult, EvalError> {
    check(est, "estimate")?;
    check(gt, "ground truth")?;
    let pairs = matched_pairs(est, gt, max_dt);
    if pairs.is_empty() {
        return Err(EvalError::Metric(format!(
            "ATE: none of the {} ground-truth poses has an estimate within {max_dt} s ({} estimated poses)",
            gt.len(),
            est.len()
        )));
    }
    let a: Vec<Point2> = pairs.iter().map(|(e, _)| e.translation()).collect();
    let b: Vec<Point2> = pairs.iter().map(|(_, g)| g.translation()).collect();
    let (err, err_al, t) = errors_as_is_and_aligned(&a, &b);
    Ok(AteResult {
        rmse: rms(&err),
        rmse_aligned: rms(&err_al),
        mean: mean_std(&err).0,
        max: err.iter().copied().fold(0.0, f64::max),
        matched: pairs.len(),
        unmatched: gt.len() - pairs.len(),
        alignment: t,
    })
}

fn check(t: &[TimedPose], what: &str) -> Result<(), EvalError> {
    match t
        .iter()
        .position(|p| !(p.t.is_finite() && p.pose.is_finite()))
    {
        Some(i) => Err(EvalError::Metric(format!("{what} pose {i} is not finite"))),
        None => Ok(()),
    }
}

/// Relative pose error over pairs of matched poses.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RpeResult {
    /// Mean translational error ‖trans(Δ_gt⁻¹ ⊕ Δ_est)‖, m.
    pub trans_mean: f64,
    /// RMSE of the translational error, m.
    pub trans_rmse: f64,
    /// Mean absolute rotational error |rot(Δ_gt⁻¹ ⊕ Δ_est)|, degrees.
    pub rot_mean_deg: f64,
    /// RMSE of the rotational error, degrees.
    pub rot_rmse_deg: f64,
    /// Number of pose pairs compared.
    pub pairs: usize,
}

/// [`rpe_with`] with `max_dt` = [`DEFAULT_MAX_DT`] and consecutive matched poses (stride 1).
pub fn rpe(est: &[TimedPose], gt: &[TimedPose]) -> Result<RpeResult, EvalError> {
    rpe_with(est, gt, DEFAULT_MAX_DT, 1)
}

/// RPE: pair the poses by [`associate`] (as for ATE); for matched poses i and
/// i + `stride` (in ground-truth order) compare the relative motions Δ = e_i⁻¹ ⊕ e_j (`e_i.between(e_j)`), and the error E = Δ_gt⁻¹ ⊕ Δ_est; report its
/// translation norm (m) and |rotation| (degrees, normalised). Errors when fewer than
/// `stride + 1` poses match or `stride` is 0.
pub fn rpe_with(
    est: &[TimedPose],
    gt: &[TimedPose],
    max_dt: f64,
    stride: usize,
) -> Result<RpeResult, EvalError> {
    check(est, "estimate")?;
    check(gt, "ground truth")?;
    if stride == 0 {
        return Err(EvalError::Metric("RPE: stride must be at least 1".into()));
    }
    let pairs = matched_pairs(est, gt, max_dt);
    if pairs.len() <= stride {
        return Err(EvalError::Metric(format!(
            "RPE: {} matched poses, need at least {}",
            pairs.len(),
            stride + 1
        )));
    }
    let mut tr = Vec::with_capacity(pairs.len());
    let mut rot = Vec::with_capacity(pairs.len());
    for w in 0..pairs.len() - stride {
        let (ei, gi) = pairs[w];
        let (ej, gj) = pairs[w + stride];
        let e = gi.between(&gj).between(&ei.between(&ej));
        tr.push(e.x.hypot(e.y));
        rot.push(e.theta.abs().to_degrees());
    }
    Ok(RpeResult {
        trans_mean: mean_std(&tr).0,
        trans_rmse: rms(&tr),
        rot_mean_deg: mean_std(&rot).0,
        rot_rmse_deg: rms(&rot),
        pairs: tr.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tp(t: f64, x: f64, y: f64, th: f64) -> TimedPose {
        TimedPose {
            t,
            pose: Pose2::new(x, y, th),
        }
    }

    #[test]
    fn ate_hand_computed() {
        // Errors 0, 1 (x), 1 (y), 2: RMSE = √((0+1+1+4)/4) = √1.5.
        let gt = [
            tp(0.0, 0.0, 0.0, 0.0),
            tp(1.0, 1.0, 0.0, 0.0),
            tp(2.0, 2.0, 0.0, 0.0),
            tp(3.0, 3.0, 0.0, 0.0),
            tp(9.0, 0.0, 0.0, 0.0),
        ];
        let est = [
            tp(0.0, 0.0, 0.0, 0.0),
            tp(1.001, 2.0, 0.0, 0.0),
            tp(2.0, 2.0, 1.0, 0.0),
            tp(3.0, 5.0, 0.0, 0.0),
        ];
        let r = ate(&est, &gt).unwrap();
        assert!((r.rmse - 1.5f64.sqrt()).abs() < 1e-12);
        assert!((r.mean - 1.0).abs() < 1e-12);
        assert_eq!(r.max, 2.0);
        assert_eq!((r.matched, r.unmatched), (4, 1));
        assert!(r.rmse_aligned <= r.rmse);
        assert!(ate(&est, &gt[4..]).is_err());
    }

    #[test]
    fn ate_aligned_removes_a_rigid_motion() {
        let gt: Vec<TimedPose> = (0..30)
            .map(|i| {
                tp(
                    i as f64,
                    (i as f64 * 0.3).sin() * 4.0,
                    i as f64 * 0.2,
                    0.1 * i as f64,
                )
            })
            .collect();
        let t = Pose2::new(3.0, -1.0, 1.1);
        let est: Vec<TimedPose> = gt
            .iter()
            .map(|g| TimedPose {
                t: g.t,
                pose: t.compose(&g.pose),
            })
            .collect();
        let r = ate(&est, &gt).unwrap();
        assert!(r.rmse > 1.0);
        assert!(r.rmse_aligned < 1e-9);
        assert!(r.alignment.approx_eq(&t.inverse(), 1e-9));
    }

    #[test]
    fn rpe_hand_computed() {
        // Ground truth moves 1 m along x per step; the estimate moves 1 m then turns 90°
        // with no translation. Pair 0→1: Δ_gt = (1,0,0), Δ_est = (1,0,0): error 0.
        // Pair 1→2: Δ_gt = (1,0,0), Δ_est = (0,0,90°): E = Δ_gt⁻¹⊕Δ_est = (−1,0,90°).
        let gt = [
            tp(0.0, 0.0, 0.0, 0.0),
            tp(1.0, 1.0, 0.0, 0.0),
            tp(2.0, 2.0, 0.0, 0.0),
        ];
        let est = [
            tp(0.0, 0.0, 0.0, 0.0),
            tp(1.0, 1.0, 0.0, 0.0),
            tp(2.0, 1.0, 0.0, std::f64::consts::FRAC_PI_2),
        ];
        let r = rpe(&est, &gt).unwrap();
        assert_eq!(r.pairs, 2);
        assert!((r.trans_mean - 0.5).abs() < 1e-12);
        assert!((r.trans_rmse - 0.5f64.sqrt()).abs() < 1e-12);
        assert!((r.rot_mean_deg - 45.0).abs() < 1e-9);
        assert!(rpe_with(&est, &gt, 0.006, 0).is_err());
        assert!(rpe_with(&est, &gt, 0.006, 3).is_err());
    }

    #[test]
    fn ground_truth_is_anchored_at_the_first_common_pose() {
        let est = [
            TimedPose {
                t: 1.0,
                pose: Pose2::new(0.0, 0.0, 0.0),
            },
            TimedPose {
                t: 2.0,
                pose: Pose2::new(1.0, 0.0, 0.0),
            },
        ];
        // The same motion seen from a frame rotated by 90° and shifted; the first truth
        // pose has no estimate at its time.
        let gt = [
            TimedPose {
                t: 0.0,
                pose: Pose2::new(9.0, 9.0, 0.0),
            },
            TimedPose {
                t: 1.0,
                pose: Pose2::new(5.0, 3.0, std::f64::consts::FRAC_PI_2),
            },
            TimedPose {
                t: 2.0,
                pose: Pose2::new(5.0, 4.0, std::f64::consts::FRAC_PI_2),
            },
        ];
        let a = anchor_at_first_match(&est, &gt);
        assert!(a[1].pose.approx_eq(&est[0].pose, 1e-12), "{:?}", a[1]);
        assert!(a[2].pose.approx_eq(&est[1].pose, 1e-12), "{:?}", a[2]);
        assert_eq!(a[0].t, 0.0);
    }

    #[test]
    fn anchor_is_the_first_record_not_the_earliest_stamp() {
        // The last estimate record carries a stamp before the first one (as 22 late records
        // of the Intel log do); the anchor is still the first record.
        let est = [
            tp(1.0, 0.0, 0.0, 0.0),
            tp(2.0, 1.0, 0.0, 0.0),
            tp(0.5, 7.0, 7.0, 0.0),
        ];
        let gt = [
            tp(0.5, 4.0, 4.0, 0.0),
            tp(1.0, 3.0, 0.0, 0.0),
            tp(2.0, 4.0, 0.0, 0.0),
        ];
        let a = anchor_at_first_match(&est, &gt);
        // T moves gt(1.0) = (3, 0) onto est(1.0) = (0, 0): a shift by (−3, 0).
        assert!(a[1].pose.approx_eq(&est[0].pose, 1e-12));
        assert!(a[2].pose.approx_eq(&est[1].pose, 1e-12));
        assert!(a[0].pose.approx_eq(&Pose2::new(1.0, 4.0, 0.0), 1e-12));
    }

    #[test]
    fn a_trajectory_scored_against_itself_is_exactly_zero() {
        // Repeated and backward stamps, as in every bench reference.
        let t = [
            tp(1.0, 0.0, 0.0, 0.0),
            tp(1.0, 0.3, 0.1, 0.2),
            tp(1.5, 0.9, 0.2, 0.4),
            tp(0.9, 1.4, 0.6, 1.1),
            tp(2.0, 2.0, 1.0, -3.0),
        ];
        let a = ate(&t, &t).unwrap();
        assert_eq!((a.rmse, a.rmse_aligned, a.matched), (0.0, 0.0, 5));
        let r = rpe(&t, &t).unwrap();
        assert_eq!((r.trans_mean, r.rot_mean_deg, r.pairs), (0.0, 0.0, 4));
    }
}
