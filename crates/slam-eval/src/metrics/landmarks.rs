//! Landmark map error: estimated against true landmark positions.

use super::{errors_as_is_and_aligned, rms};
use serde::Serialize;
use slam_models::{LandmarkEstimate, LandmarkId, Point2};

/// How estimated landmarks are paired with true ones.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LandmarkMatching {
    /// By identical [`LandmarkId`] (data association known).
    ById,
    /// Greedy nearest neighbour: all (estimate, truth) pairs sorted by distance, each taken
    /// when neither end is taken yet and the distance is at most `gate` metres.
    Nearest {
        /// Largest pairing distance, m.
        gate: f64,
    },
}

/// The gate of [`landmark_error`] when matching by nearest neighbour, m.
pub const DEFAULT_NN_GATE: f64 = 1.0;

/// Landmark map error.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LandmarkErrorResult {
    /// RMSE of ‖m_est − m_true‖ over matched pairs, as is, m (NaN when none matched).
    pub rmse: f64,
    /// RMSE after the least-squares SE(2) alignment of the estimated map onto the true one
    /// (over the matched pairs), m.
    pub rmse_aligned: f64,
    /// Matched pairs.
    pub matched: usize,
    /// True landmarks without an estimate.
    pub unmatched_true: usize,
    /// Estimated landmarks without a true one (spurious, e.g. from clutter).
    pub spurious: usize,
}

/// [`landmark_error_with`] with [`LandmarkMatching::ById`] when `match_by_id`, otherwise
/// nearest neighbour with the gate [`DEFAULT_NN_GATE`].
pub fn landmark_error(
    est: &[LandmarkEstimate],
    truth: &[(LandmarkId, Point2)],
    match_by_id: bool,
) -> LandmarkErrorResult {
    let m = if match_by_id {
        LandmarkMatching::ById
    } else {
        LandmarkMatching::Nearest {
            gate: DEFAULT_NN_GATE,
        }
    };
    landmark_error_with(est, truth, m)
}

/// Pairs estimates with true landmarks (see [`LandmarkMatching`]; by id, a duplicated
/// estimated id counts the later ones as spurious), then computes the RMSE of the position
/// errors as is and after [`align_se2`](super::align_se2) of the matched estimates onto the truth.
/// Non-finite estimates are counted as spurious.
pub fn landmark_error_with(
    est: &[LandmarkEstimate],
    truth: &[(LandmarkId, Point2)],
    matching: LandmarkMatching,
) -> LandmarkErrorResult {
    let mut used_est = vec![false; est.len()];
    let mut used_true = vec![false; truth.len()];
    let mut pairs: Vec<(Point2, Point2)> = Vec::new();
    let finite = |e: &LandmarkEstimate| e.mean.x.is_finite() && e.mean.y.is_finite();
    match matching {
        LandmarkMatching::ById => {
            for (i, e) in est.iter().enumerate() {
                if !finite(e) {
                    continue;
                }
                if let Some(j) = truth.iter().position(|(id, _)| *id == e.id) {
                    if !used_true[j] {
                        used_true[j] = true;
                        used_est[i] = true;
                        pairs.push((e.mean, truth[j].1));
                    }
                }
            }
        }
        LandmarkMatching::Nearest { gate } => {
            let mut cand: Vec<(f64, usize, usize)> = Vec::new();
            for (i, e) in est.iter().enumerate().filter(|(_, e)| finite(e)) {
                for (j, (_, p)) in truth.iter().enumerate() {
                    let d = (e.mean - p).norm();
                    if d <= gate {
                        cand.push((d, i, j));
                    }
                }
            }
            cand.sort_by(|a, b| a.0.total_cmp(&b.0));
            for (_, i, j) in cand {
                if !used_est[i] && !used_true[j] {
                    used_est[i] = true;
                    used_true[j] = true;
                    pairs.push((est[i].mean, truth[j].1));
                }
            }
        }
    }
    let a: Vec<Point2> = pairs.iter().map(|p| p.0).collect();
    let b: Vec<Point2> = pairs.iter().map(|p| p.1).collect();
    let (err, err_al, _) = errors_as_is_and_aligned(&a, &b);
    LandmarkErrorResult {
        rmse: rms(&err),
        rmse_aligned: rms(&err_al),
        matched: pairs.len(),
        unmatched_true: used_true.iter().filter(|u| !**u).count(),
        spurious: used_est.iter().filter(|u| !**u).count(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use slam_models::{Matrix2, Pose2};

    fn lm(id: u32, x: f64, y: f64) -> LandmarkEstimate {
        LandmarkEstimate {
            id: LandmarkId(id),
            mean: Point2::new(x, y),
            covariance: Matrix2::identity(),
        }
    }

    #[test]
    fn by_id_hand_computed() {
        let truth = [
            (LandmarkId(1), Point2::new(0.0, 0.0)),
            (LandmarkId(2), Point2::new(4.0, 0.0)),
            (LandmarkId(3), Point2::new(0.0, 9.0)),
        ];
        // Errors 3 (3-4-5 triangle → 5? no: (3,4) offset → 5) and 1: RMSE = √((25+1)/2) = √13.
        let est = [lm(1, 3.0, 4.0), lm(2, 4.0, 1.0), lm(7, 50.0, 50.0)];
        let r = landmark_error(&est, &truth, true);
        assert_eq!((r.matched, r.unmatched_true, r.spurious), (2, 1, 1));
        assert!((r.rmse - 13f64.sqrt()).abs() < 1e-12);
        // Two pairs can always be aligned to the same mid-distance: the pair distances are
        // |(4,0)−(0,0)| = 4 (true) and |(4,1)−(3,4)| = √10 (estimated), so the aligned
        // residuals are each (4 − √10)/2 and the RMSE is (4 − √10)/2.
        assert!((r.rmse_aligned - (4.0 - 10f64.sqrt()) / 2.0).abs() < 1e-12);
    }

    #[test]
    fn nearest_neighbour_with_gate_and_alignment() {
        let truth: Vec<(LandmarkId, Point2)> = (0..6)
            .map(|k| {
                (
                    LandmarkId(k),
                    Point2::new(k as f64 * 3.0, (k % 2) as f64 * 2.0),
                )
            })
            .collect();
        // Estimate: truth moved by a small rigid motion, ids unknown (shuffled), plus one
        // spurious landmark; the last true landmark is missing.
        let t = Pose2::new(0.1, -0.05, 0.01);
        let mut est: Vec<LandmarkEstimate> = truth[..5]
            .iter()
            .map(|(k, p)| {
                let q = t.transform_point(p);
                lm(100 - k.0, q.x, q.y)
            })
            .collect();
        est.push(lm(999, 40.0, 40.0));
        est.reverse();
        let r = landmark_error(&est, &truth, false);
        assert_eq!((r.matched, r.unmatched_true, r.spurious), (5, 1, 1));
        assert!(r.rmse > 0.05);
        assert!(r.rmse_aligned < 1e-9);
        let none = landmark_error(&[], &truth, false);
        assert_eq!((none.matched, none.unmatched_true), (0, 6));
        assert!(none.rmse.is_nan());
    }
}
