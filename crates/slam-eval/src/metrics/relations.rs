//! The relations metric of Kümmerle et al., *On measuring the accuracy of SLAM algorithms*
//! (Autonomous Robots 27, 2009), eq. 1: ε(δ) = 1/N Σ trans(δᵢⱼ ⊖ δ*ᵢⱼ)² + rot(δᵢⱼ ⊖ δ*ᵢⱼ)²,
//! reported, as in the paper, as mean ± std of the absolute and of the squared
//! translational [m] and rotational [deg] errors, separately.

use super::{mean_std, pose_at, sorted_by_time, PoseLookup, DEFAULT_MAX_DT};
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
}

/// [`relations_error_with`] with `max_dt` = [`DEFAULT_MAX_DT`] (6 ms, the README's rule).
pub fn relations_error(est: &[TimedPose], rel: &[Relation]) -> RelationsResult {
    relations_error_with(est, rel, DEFAULT_MAX_DT)
}

/// For each relation, the estimated poses x₁, x₂ at t1 and t2 (looked up as in the module
/// docs of [`crate::metrics`]), δ = x₁⁻¹ ⊕ x₂ (`x1.between(x2)`), and the error
/// E = δ*⁻¹ ⊕ δ: trans = ‖(E.x, E.y)‖ (which equals ‖t(δ) − t(δ*)‖) and
/// rot = |normalize(θ(δ) − θ(δ*))| in degrees. Relations with an end that finds no pose
/// are dropped and counted; non-finite estimated poses are not used.
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
    for r in rel {
        let (Some(x1), Some(x2)) = (pose_at(&sorted, r.t1, how), pose_at(&sorted, r.t2, how))
        else {
            continue;
        };
        let delta = x1.between(&x2);
        let e = r.delta.between(&delta);
        tr.push(e.x.hypot(e.y));
        rot.push(e.theta.abs().to_degrees());
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
}
