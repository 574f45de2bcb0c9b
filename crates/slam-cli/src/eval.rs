//! `slam eval`: scores a TUM trajectory (any program's) against ground truth (ATE as is and
//! aligned, RPE) and/or a Kümmerle et al. relations file.

use crate::cli::EvalArgs;
use crate::error::CliError;
use serde::Serialize;
use slam_eval::metrics_json::finite;
use std::io::Write;

/// The figures `slam eval` computed; `None` where no reference was given.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct EvalReport {
    /// Poses in the estimate.
    pub poses: usize,
    /// ATE RMSE as is, metres.
    pub ate_rmse_m: Option<f64>,
    /// ATE RMSE after SE(2) alignment, metres.
    pub ate_rmse_aligned_m: Option<f64>,
    /// Pose pairs matched in time for ATE.
    pub ate_matched: Option<usize>,
    /// RPE between consecutive poses: mean translational error, metres.
    pub rpe_trans_mean_m: Option<f64>,
    /// RPE between consecutive poses: mean rotational error, degrees.
    pub rpe_rot_mean_deg: Option<f64>,
    /// Relations metric: mean ± std of the absolute translational error, metres.
    pub relations_trans_mean_m: Option<f64>,
    /// Relations metric: std of the absolute translational error, metres.
    pub relations_trans_std_m: Option<f64>,
    /// Relations metric: mean absolute rotational error, degrees.
    pub relations_rot_mean_deg: Option<f64>,
    /// Relations metric: std of the absolute rotational error, degrees.
    pub relations_rot_std_deg: Option<f64>,
    /// Relations used (both ends found in the estimate).
    pub relations_used: Option<usize>,
    /// Relations dropped (an end not covered by the estimate).
    pub relations_dropped: Option<usize>,
    /// Relations with an end read at a time the estimate holds several different poses at
    /// (a repeating clock; [`slam_eval::metrics::RelationsResult::ambiguous`]).
    pub relations_ambiguous: Option<usize>,
    /// Relations metric over the relations that are not ambiguous: mean translational
    /// error, metres.
    pub relations_unambiguous_trans_mean_m: Option<f64>,
    /// Relations metric over the relations that are not ambiguous: mean rotational error,
    /// degrees.
    pub relations_unambiguous_rot_mean_deg: Option<f64>,
}

/// Prints to stderr one warning line per trajectory whose stamps repeat or step back (one
/// line for both when they come from the same log), saying how they are associated.
pub(crate) fn warn_stamp_order(est: &[slam_models::TimedPose], gt: &[slam_models::TimedPose]) {
    for l in slam_eval::metrics::stamp_order_warnings(est, gt) {
        eprintln!("slam: warning: {l}");
    }
}

/// Runs `slam eval` with `args`, printing the figures to `out`.
pub fn eval(args: &EvalArgs, out: &mut dyn Write) -> Result<EvalReport, CliError> {
    let est = slam_io::tum::read_tum(&args.estimate)?;
    let mut r = EvalReport {
        poses: est.len(),
        ..Default::default()
    };
    let _ = writeln!(
        out,
        "estimate: {} ({} poses)",
        args.estimate.display(),
        est.len()
    );
    if let Some(p) = &args.ground_truth {
        let gt = slam_io::tum::read_tum(p)?;
        warn_stamp_order(&est, &gt);
        let ate = slam_eval::metrics::ate(&est, &gt)?;
        r.ate_rmse_m = finite(Some(ate.rmse));
        r.ate_rmse_aligned_m = finite(Some(ate.rmse_aligned));
        r.ate_matched = Some(ate.matched);
        let rpe = slam_eval::metrics::rpe(&est, &gt)?;
        r.rpe_trans_mean_m = finite(Some(rpe.trans_mean));
        r.rpe_rot_mean_deg = finite(Some(rpe.rot_mean_deg));
        let _ = writeln!(
            out,
            "ground truth: {} ({} poses, {} matched)\n  ATE RMSE {:.4} m, aligned {:.4} m\n  RPE mean {:.4} m / {:.3} deg",
            p.display(),
            gt.len(),
            ate.matched,
            ate.rmse,
            ate.rmse_aligned,
            rpe.trans_mean,
            rpe.rot_mean_deg
        );
    }
    if let Some(p) = &args.relations {
        let rel = slam_io::relations::read_relations(p)?;
        let e = slam_eval::metrics::relations_error(&est, &rel);
        r.relations_used = Some(e.used);
        r.relations_dropped = Some(e.dropped);
        if e.used > 0 {
            r.relations_trans_mean_m = finite(Some(e.trans_mean));
            r.relations_trans_std_m = finite(Some(e.trans_std));
            r.relations_rot_mean_deg = finite(Some(e.rot_mean_deg));
            r.relations_rot_std_deg = finite(Some(e.rot_std_deg));
            let _ = writeln!(
                out,
                "relations: {} ({} used, {} dropped)\n  translational {:.4} ± {:.4} m, rotational {:.3} ± {:.3} deg",
                p.display(),
                e.used,
                e.dropped,
                e.trans_mean,
                e.trans_std,
                e.rot_mean_deg,
                e.rot_std_deg
            );
            r.relations_ambiguous = Some(e.ambiguous);
            r.relations_unambiguous_trans_mean_m = finite(Some(e.unambiguous_trans_mean));
            r.relations_unambiguous_rot_mean_deg = finite(Some(e.unambiguous_rot_mean_deg));
            if e.ambiguous > 0 {
                let _ = writeln!(
                    out,
                    "  {} relations end at a time the estimate holds several different poses at (a repeating clock: the tie rule picks one); the other {}: {:.4} m, {:.3} deg",
                    e.ambiguous,
                    e.used - e.ambiguous,
                    e.unambiguous_trans_mean,
                    e.unambiguous_rot_mean_deg
                );
            }
        } else {
            return Err(CliError::InvalidArgument(format!(
                "relations {}: none of the {} relations has both ends in the estimate (within 6 ms); is the estimate on the relations' clock?",
                p.display(),
                rel.len()
            )));
        }
    }
    Ok(r)
}
