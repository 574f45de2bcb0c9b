//! Accuracy and consistency metrics, each checked against hand-computed cases.
//!
//! * [`ate`]: absolute trajectory error, as is and after least-squares SE(2) alignment.
//! * [`rpe`]: relative pose error of consecutive matched poses.
//! * [`relations_error`]: the Kümmerle et al. (2009) relations metric.
//! * [`landmark_error`]: landmark map error, matched by id or by nearest neighbour.
//! * [`nees_pose`], [`nis`], [`chi2_quantile`], [`chi2_band`]: filter consistency.
//! * [`map_contradictions`]: a laser run's map that contradicts itself (scans looking
//!   through walls other scans saw), without ground truth.
//!
//! **Matching by time.** Everywhere an estimate is looked up at a time t (the relations
//! metric, ATE, RPE) the same rule is used, the one the dataset README fixes for the
//! benchmark figures: sort the estimate by time, keeping file order among equal times;
//! take the last pose with time < t and the first with time ≥ t; use the nearer of the two
//! (the earlier on a tie); and give up if it is more than `max_dt` away
//! ([`DEFAULT_MAX_DT`] = 6 ms unless said otherwise). For estimates that are sparse in
//! time, [`relations_error_lookup`] with [`PoseLookup::Interpolate`] interpolates instead.
//!
//! **Pairing an estimate with its ground truth** (ATE, RPE, the "as is" anchor) is
//! [`associate`]: that lookup, except that two files from the same log (same length, same
//! stamps) are paired record by record, which keeps repeated and backward stamps apart.
//! `docs/evaluation.md` states the rule and the `evo` command lines that reproduce each
//! figure.

mod align;
mod associate;
mod consistency;
mod landmarks;
mod map_check;
mod relations;
mod trajectory;

pub use align::align_se2;
pub(crate) use align::errors_as_is_and_aligned;
pub use associate::{
    associate, lookup, pose_at, same_stamps, sorted_by_time, stamp_order, stamp_order_warning,
    stamp_order_warnings, PoseLookup, StampOrder, DEFAULT_MAX_DT,
};
pub use consistency::{
    chi2_band, chi2_quantile, nees_pose, nees_summary, nis, regularized_gamma_p, NeesSummary,
};
pub use landmarks::{
    landmark_error, landmark_error_with, LandmarkErrorResult, LandmarkMatching, DEFAULT_NN_GATE,
};
pub use map_check::{map_contradictions, MapCheck, MapCheckParams};
pub use relations::{
    relations_error, relations_error_lookup, relations_error_with, RelationsResult,
};
pub use trajectory::{anchor_at_first_match, ate, ate_with, rpe, rpe_with, AteResult, RpeResult};

/// Mean and population standard deviation (÷ n) of a sample; (NaN, NaN) when empty.
pub(crate) fn mean_std(v: &[f64]) -> (f64, f64) {
    if v.is_empty() {
        return (f64::NAN, f64::NAN);
    }
    let n = v.len() as f64;
    let m = v.iter().sum::<f64>() / n;
    let var = v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / n;
    (m, var.sqrt())
}

/// Root mean square; NaN when empty.
pub(crate) fn rms(v: &[f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt()
}
