//! Running a filter over a dataset and scoring it: the one loop every front end calls.
//!
//! * [`run_landmarks`]: for each [`LandmarkStep`] in order,
//!   `predict` with its control, then `update` with its observations; the pose after the
//!   update is the online estimate at the step's time.
//! * [`run_scans`]: `process` on every record in file order; the trajectory is the filter's
//!   own, one pose per record.
//!
//! Both return every step's diagnostics (the filters' [`UpdateInfo`] / [`ScanUpdateInfo`]),
//! the trajectories, the time the filter took, and the [`Metrics`] `metrics.json` holds,
//! computed against the ground truth the dataset carries (or the one in [`RunOptions`]).
//! The `_observed` variants call an observer after every step: a progress bar, pictures of
//! the run, or a Ctrl-C check that returns [`Flow::Stop`]. Only the filter is timed: the
//! observer's time is taken off `wall_s`.
//!
//! Nothing here prints: what a front end should tell the user is in the run's `notes`
//! (summary lines) and `warnings`.

use crate::metrics::{self as m, anchor_at_first_match, nees_pose, nees_summary};
use crate::metrics_json::{finite, peak_rss_mb, Metrics};
use slam_io::estimates_csv::PoseEstimateRow;
use slam_io::relations::Relation;
use slam_models::{
    FilterError, GridMap, LandmarkDataset, LandmarkEstimate, LandmarkSlam, LandmarkStep,
    ScanDataset, ScanRecord, ScanSlam, ScanUpdateInfo, TimedPose, UpdateInfo,
};
use std::time::{Duration, Instant};
use thiserror::Error;

/// What an observer returns after a step: go on, or stop the run there.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Flow {
    /// Run the next step.
    Continue,
    /// Stop now: the run returns [`RunError::Stopped`].
    Stop,
}

/// An observer's own failure (a picture it could not write, …), handed back unchanged in
/// [`RunError::Observer`] so that the caller can downcast it to its own error type.
pub type ObserverError = Box<dyn std::error::Error + Send + Sync>;

/// Why a run did not finish.
#[derive(Debug, Error)]
pub enum RunError {
    /// The filter failed at a step.
    #[error("filter `{filter}` failed at step {step} (t = {t} s): {source}")]
    Step {
        /// The filter's name.
        filter: String,
        /// 0-based step (or record) index.
        step: usize,
        /// The step's time, seconds.
        t: f64,
        /// The filter's error.
        #[source]
        source: FilterError,
    },
    /// The observer asked to stop ([`Flow::Stop`]) after `done` of `steps` steps.
    #[error("stopped after {done} of {steps} steps")]
    Stopped {
        /// Steps completed.
        done: usize,
        /// Steps in the data.
        steps: usize,
    },
    /// The observer failed after step `step`.
    #[error("after step {step}: {source}")]
    Observer {
        /// 0-based step index.
        step: usize,
        /// The observer's error.
        source: ObserverError,
    },
    /// [`RunOptions::map_resolution`] was set but the filter keeps no scans to re-render its
    /// map from (checked before the first step).
    #[error("map resolution {resolution} m: filter `{filter}` keeps no scans to re-render its map from (gridfast does)")]
    CannotRender {
        /// The filter's name.
        filter: String,
        /// The resolution asked for, metres.
        resolution: f64,
    },
    /// The filter's map could not be re-rendered at the resolution asked for (a scan would
    /// make the map larger than the grid's cell bound).
    #[error("map resolution {resolution} m: filter `{filter}`'s map cannot be re-rendered at this cell size ({source}); choose a coarser --map-resolution")]
    Render {
        /// The filter's name.
        filter: String,
        /// The resolution asked for, metres.
        resolution: f64,
        /// Why: the grid's error.
        source: FilterError,
    },
}

/// What a run is scored against, and how its figures are labelled. `Default`: the dataset's
/// own ground truth and name, a real clock, no relations, the filter's own map.
#[derive(Debug, Clone, Copy, Default)]
pub struct RunOptions<'a> {
    /// The dataset's name in [`Metrics::dataset`]; default the dataset's own `name`.
    pub dataset_name: Option<&'a str>,
    /// A reference trajectory to score against instead of the dataset's own ground truth.
    pub ground_truth: Option<&'a [TimedPose]>,
    /// Kümmerle et al. relations to score the trajectory with.
    pub relations: Option<&'a [Relation]>,
    /// The data's times are step indices, not a clock (Freiburg course data): no data
    /// duration or real-time factor.
    pub times_are_indices: bool,
    /// Scan runs: the map returned is re-rendered at this cell size (metres) from the best
    /// trajectory and every scan, after the timed run, instead of the filter's own grid.
    pub map_resolution: Option<f64>,
}

/// After each landmark step: what an observer sees.
pub struct LandmarkProgress<'a> {
    /// 0-based index of the step just done.
    pub step: usize,
    /// Steps in the data.
    pub steps: usize,
    /// The filter, after the step.
    pub filter: &'a dyn LandmarkSlam,
    /// The online estimates so far, this step's last.
    pub online: &'a [TimedPose],
    /// What the step's update did.
    pub info: &'a UpdateInfo,
}

/// After each scan record: what an observer sees.
pub struct ScanProgress<'a> {
    /// 0-based index of the record just processed.
    pub step: usize,
    /// Records in the data.
    pub steps: usize,
    /// The filter, after the record.
    pub filter: &'a dyn ScanSlam,
    /// The record.
    pub record: &'a ScanRecord,
    /// What the step did.
    pub info: &'a ScanUpdateInfo,
}

/// Called after every landmark step; any `FnMut(&LandmarkProgress) -> Result<Flow,
/// ObserverError>` closure is one.
pub trait LandmarkObserver {
    /// Sees the step just done; [`Flow::Stop`] ends the run there.
    fn after_step(&mut self, progress: &LandmarkProgress<'_>) -> Result<Flow, ObserverError>;
}

impl<F: FnMut(&LandmarkProgress<'_>) -> Result<Flow, ObserverError>> LandmarkObserver for F {
    fn after_step(&mut self, progress: &LandmarkProgress<'_>) -> Result<Flow, ObserverError> {
        self(progress)
    }
}

/// Called after every scan record; any `FnMut(&ScanProgress) -> Result<Flow,
/// ObserverError>` closure is one.
pub trait ScanObserver {
    /// Sees the record just processed; [`Flow::Stop`] ends the run there.
    fn after_step(&mut self, progress: &ScanProgress<'_>) -> Result<Flow, ObserverError>;
}

impl<F: FnMut(&ScanProgress<'_>) -> Result<Flow, ObserverError>> ScanObserver for F {
    fn after_step(&mut self, progress: &ScanProgress<'_>) -> Result<Flow, ObserverError> {
        self(progress)
    }
}

/// A landmark filter's run over a dataset.
#[derive(Debug, Clone)]
pub struct LandmarkRun {
    /// The online estimates: the pose after each step, at the step's time.
    pub online: Vec<TimedPose>,
    /// The filter's full-SLAM path ([`LandmarkSlam::full_path`]) at the end, entry k the
    /// pose after step k at its time (the initial pose is left out); `None` for filters
    /// without one (the EKF), or, with a warning, when the path broke the trait's
    /// one-pose-per-update contract.
    pub full_path: Option<Vec<TimedPose>>,
    /// Each step's Gaussian pose summary ([`LandmarkSlam::pose_gaussian`]) with its NEES
    /// against the true pose, when the ground truth has exactly the steps' times.
    pub estimates: Vec<PoseEstimateRow>,
    /// Each step's update diagnostics.
    pub updates: Vec<UpdateInfo>,
    /// The map at the end (with `full_path`, the same particle's).
    pub landmarks: Vec<LandmarkEstimate>,
    /// The figures of `metrics.json`.
    pub metrics: Metrics,
    /// Summary lines for the user (landmark matching, the relations metric).
    pub notes: Vec<String>,
    /// Things the user should be warned about (a metric that could not be computed, …).
    pub warnings: Vec<String>,
}

impl LandmarkRun {
    /// The run's answer: the full-SLAM path where the filter has one, else the online
    /// estimates (what `trajectory.tum` holds and the `ate_*` figures score).
    pub fn trajectory(&self) -> &[TimedPose] {
        self.full_path.as_deref().unwrap_or(&self.online)
    }
}

/// A scan filter's run over a dataset.
#[derive(Debug, Clone)]
pub struct ScanRun {
    /// The filter's trajectory at the end, one pose per record.
    pub trajectory: Vec<TimedPose>,
    /// The filter's map at the end (re-rendered with [`RunOptions::map_resolution`]).
    pub map: GridMap,
    /// Each record's diagnostics.
    pub updates: Vec<ScanUpdateInfo>,
    /// The ground truth in the estimate's frame (anchored at their first common pose, as
    /// scan filters start at the first odometry pose), the one the figures are computed
    /// against.
    pub reference: Option<Vec<TimedPose>>,
    /// The figures of `metrics.json`.
    pub metrics: Metrics,
    /// Summary lines for the user (the relations metric, …).
    pub notes: Vec<String>,
    /// Things the user should be warned about (skipped odometry jumps, …).
    pub warnings: Vec<String>,
}

/// [`run_landmarks_observed`] without an observer.
pub fn run_landmarks(
    filter: &mut dyn LandmarkSlam,
    data: &LandmarkDataset,
    opts: &RunOptions<'_>,
) -> Result<LandmarkRun, RunError> {
    run_landmarks_observed(filter, data, opts, &mut |_: &LandmarkProgress<'_>| {
        Ok(Flow::Continue)
    })
}

/// Runs a landmark filter over `data` (predict, update, per step) and scores it: ATE and
/// RPE of [`LandmarkRun::trajectory`] and of the online estimates, the landmark map error
/// (matched by id when the observations carry ids, else by nearest neighbour), pose NEES
/// per step and its χ²(3) band fraction, the relations metric; each where its reference
/// exists. `observer` sees every step.
pub fn run_landmarks_observed(
    filter: &mut dyn LandmarkSlam,
    data: &LandmarkDataset,
    opts: &RunOptions<'_>,
    observer: &mut dyn LandmarkObserver,
) -> Result<LandmarkRun, RunError> {
    let steps = &data.steps;
    let ground_truth = opts.ground_truth.or(data.ground_truth.as_deref());
    // NEES needs the true pose at every step: a ground truth with exactly the steps' times.
    let truth_per_step = ground_truth.filter(|g| {
        g.len() == steps.len() && g.iter().zip(steps).all(|(p, s)| (p.t - s.t).abs() < 1e-9)
    });
    let mut online = Vec::with_capacity(steps.len());
    let mut estimates = Vec::with_capacity(steps.len());
    let mut updates = Vec::with_capacity(steps.len());
    let mut observed = Duration::ZERO;
    let filter_name = filter.name().to_string();
    let start = Instant::now();
    for (k, step) in steps.iter().enumerate() {
        let fail = |source| RunError::Step {
            filter: filter_name.clone(),
            step: k,
            t: step.t,
            source,
        };
        filter.predict(&step.control).map_err(fail)?;
        let info = filter.update(&step.observations).map_err(fail)?;
        updates.push(info);
        online.push(TimedPose {
            t: step.t,
            pose: filter.pose(),
        });
        let (mean, covariance) = filter.pose_gaussian();
        estimates.push(PoseEstimateRow {
            step: k,
            t: step.t,
            pose: mean,
            covariance,
            nees: truth_per_step.map(|truth| nees_pose(&mean, &covariance, &truth[k].pose)),
        });
        let t0 = Instant::now();
        let flow = observer
            .after_step(&LandmarkProgress {
                step: k,
                steps: steps.len(),
                filter: &*filter,
                online: &online,
                info: &info,
            })
            .map_err(|source| RunError::Observer { step: k, source })?;
        observed += t0.elapsed();
        if flow == Flow::Stop {
            return Err(RunError::Stopped {
                done: k + 1,
                steps: steps.len(),
            });
        }
    }
    // A smoother's last optimisation ([`LandmarkSlam::finish`]) is part of the run's time.
    if !steps.is_empty() {
        filter.finish().map_err(|source| RunError::Step {
            filter: filter_name.clone(),
            step: steps.len() - 1,
            t: steps[steps.len() - 1].t,
            source,
        })?;
    }
    let wall = start.elapsed().saturating_sub(observed).as_secs_f64();

    let mut warnings = Vec::new();
    let mut notes = Vec::new();
    // The full-SLAM path and the map, both the final best particle's: read together, with
    // no filter call between them.
    let full_path = full_trajectory(&*filter, steps, &mut warnings);
    let landmarks = filter.landmarks();
    let name = opts.dataset_name.unwrap_or(&data.name);
    let mut metrics = Metrics::new(filter.name(), name, steps.len());
    let times: Vec<f64> = steps.iter().map(|s| s.t).collect();
    let span = data_duration(&times, !opts.times_are_indices, &mut notes);
    metrics.set_timing(wall, span);
    let trajectory = full_path.as_ref().unwrap_or(&online);
    if let Some(gt) = ground_truth {
        trajectory_metrics(&mut metrics, trajectory, gt, &mut warnings);
        let mut o = Metrics::new(filter.name(), name, steps.len());
        trajectory_metrics(&mut o, &online, gt, &mut warnings);
        metrics.online_ate_rmse_m = o.ate_rmse_m;
        metrics.online_ate_rmse_aligned_m = o.ate_rmse_aligned_m;
        metrics.online_rpe_trans_mean_m = o.rpe_trans_mean_m;
        metrics.online_rpe_rot_mean_deg = o.rpe_rot_mean_deg;
    }
    if let Some(rel) = opts.relations {
        notes.push(relations_metrics(
            &mut metrics,
            trajectory,
            rel,
            &mut warnings,
        ));
    }
    if let Some(truth) = &data.landmarks {
        let by_id = steps
            .iter()
            .flat_map(|s| &s.observations)
            .any(|o| o.id.is_some());
        if !landmarks.is_empty() && !truth.is_empty() {
            let e = m::landmark_error(&landmarks, truth, by_id);
            metrics.landmark_rmse_m = finite(Some(e.rmse));
            metrics.landmark_rmse_aligned_m = finite(Some(e.rmse_aligned));
            notes.push(format!(
                "{} landmarks mapped: {} matched to the {} true ones ({}), {} true ones unmatched, {} spurious",
                landmarks.len(),
                e.matched,
                truth.len(),
                if by_id { "by id" } else { "by nearest neighbour within 1 m" },
                e.unmatched_true,
                e.spurious
            ));
        }
    }
    let nees: Vec<f64> = estimates.iter().filter_map(|e| e.nees).collect();
    if let Some(s) = nees_summary(&nees) {
        metrics.nees_pose_in_band_fraction = Some(s.in_band_fraction);
        metrics.nees_pose_median = finite(Some(s.median));
        metrics.nees_pose_mean = finite(Some(s.mean));
    }
    metrics.peak_rss_mb = peak_rss_mb();
    Ok(LandmarkRun {
        online,
        full_path,
        estimates,
        updates,
        landmarks,
        metrics,
        notes,
        warnings,
    })
}

/// [`run_scans_observed`] without an observer.
pub fn run_scans(
    filter: &mut dyn ScanSlam,
    data: &ScanDataset,
    opts: &RunOptions<'_>,
) -> Result<ScanRun, RunError> {
    run_scans_observed(filter, data, opts, &mut |_: &ScanProgress<'_>| {
        Ok(Flow::Continue)
    })
}

/// Runs a scan filter over `data` (`process` on every record) and scores its trajectory:
/// ATE and RPE against the ground truth re-expressed in the estimate's frame (anchored at
/// their first common pose: scan filters start at the first odometry pose, so "as is" means "sharing
/// the start frame", as for landmark runs), and the relations metric, each where its
/// reference exists. `observer` sees every record.
pub fn run_scans_observed(
    filter: &mut dyn ScanSlam,
    data: &ScanDataset,
    opts: &RunOptions<'_>,
    observer: &mut dyn ScanObserver,
) -> Result<ScanRun, RunError> {
    let cannot_render = |filter: &dyn ScanSlam, resolution: f64| RunError::CannotRender {
        filter: filter.name().to_string(),
        resolution,
    };
    // Ask before the run whether the filter can re-render its map at all.
    if let Some(res) = opts.map_resolution {
        if filter.render_map(res).is_none() {
            return Err(cannot_render(&*filter, res));
        }
    }
    let records = &data.records;
    let mut updates = Vec::with_capacity(records.len());
    let mut warnings = Vec::new();
    let mut notes = Vec::new();
    // Odometry jumps the filter skipped (only with `odometry-jump.on-jump = "skip"`): how
    // many, and the first record's index and time.
    let (mut jumps, mut first_jump) = (0usize, None);
    let mut observed = Duration::ZERO;
    let filter_name = filter.name().to_string();
    let start = Instant::now();
    for (k, record) in records.iter().enumerate() {
        let info = filter.process(record).map_err(|source| RunError::Step {
            filter: filter_name.clone(),
            step: k,
            t: record.t,
            source,
        })?;
        updates.push(info);
        if info.odometry_jumps_skipped > 0 {
            jumps += info.odometry_jumps_skipped;
            first_jump.get_or_insert((k, record.t));
        }
        let t0 = Instant::now();
        let flow = observer
            .after_step(&ScanProgress {
                step: k,
                steps: records.len(),
                filter: &*filter,
                record,
                info: &info,
            })
            .map_err(|source| RunError::Observer { step: k, source })?;
        observed += t0.elapsed();
        if flow == Flow::Stop {
            return Err(RunError::Stopped {
                done: k + 1,
                steps: records.len(),
            });
        }
    }
    // Work a filter held back ([`ScanSlam::finish`]) is part of the run's time.
    if let Some(last) = records.last() {
        filter.finish().map_err(|source| RunError::Step {
            filter: filter_name.clone(),
            step: records.len() - 1,
            t: last.t,
            source,
        })?;
    }
    if let Some((k, t)) = first_jump {
        warnings.push(format!(
            "skipped {jumps} odometry jump(s) beyond odometry-jump.max-jump, taken as no motion (first at record {k}, t = {t} s)"
        ));
    }
    let trajectory = filter.trajectory();
    // The filter's own map is part of the timed run; a re-rendering (output, not filtering)
    // is made after the clock and the memory peak are read, and replaces it.
    let own_map = opts.map_resolution.is_none().then(|| filter.map());
    let wall = start.elapsed().saturating_sub(observed).as_secs_f64();
    let peak = peak_rss_mb();
    let map = match (own_map, opts.map_resolution) {
        (Some(map), _) => map,
        (None, Some(res)) => filter
            .render_map(res)
            .ok_or_else(|| cannot_render(&*filter, res))?
            .map_err(|source| RunError::Render {
                filter: filter.name().to_string(),
                resolution: res,
                source,
            })?,
        (None, None) => unreachable!("own_map is set when map_resolution is not"),
    };
    if trajectory.len() != records.len() {
        warnings.push(format!(
            "filter `{}` returned {} poses for {} records (the ScanSlam contract is one per record)",
            filter.name(),
            trajectory.len(),
            records.len()
        ));
    }
    let name = opts.dataset_name.unwrap_or(&data.name);
    let mut metrics = Metrics::new(filter.name(), name, records.len());
    let times: Vec<f64> = records.iter().map(|r| r.t).collect();
    let span = data_duration(&times, !opts.times_are_indices, &mut notes);
    metrics.set_timing(wall, span);
    let reference = opts
        .ground_truth
        .or(data.ground_truth.as_deref())
        .map(|gt| anchor_at_first_match(&trajectory, gt));
    if let Some(gt) = &reference {
        trajectory_metrics(&mut metrics, &trajectory, gt, &mut warnings);
    }
    if let Some(rel) = opts.relations {
        notes.push(relations_metrics(
            &mut metrics,
            &trajectory,
            rel,
            &mut warnings,
        ));
    }
    metrics.peak_rss_mb = peak;
    // Scan matches that failed (motion model instead) and that a wider search recovered.
    metrics.match_failed = Some(updates.iter().map(|u| u.match_failures).sum());
    metrics.match_recovered = Some(updates.iter().map(|u| u.match_recoveries).sum());
    // Whether the map contradicts itself: every scan the filter processed (its keyframes:
    // the others' poses are dead-reckoned from them) at the pose of its record.
    if trajectory.len() == records.len() {
        let scans: Vec<_> = records
            .iter()
            .zip(&trajectory)
            .zip(&updates)
            .filter(|(_, u)| u.processed_scan)
            .filter_map(|((r, p), _)| r.scan.as_ref().map(|s| (p.pose, s)))
            .collect();
        let check = crate::metrics::map_contradictions(&scans, &Default::default());
        metrics.map_contradicting_fraction = Some(check.fraction);
        metrics.map_inconsistent = Some(check.inconsistent);
    }
    Ok(ScanRun {
        trajectory,
        map,
        updates,
        reference,
        metrics,
        notes,
        warnings,
    })
}

/// The filter's full-SLAM path paired with the steps' times: entry k + 1 of
/// [`LandmarkSlam::full_path`] is the pose after step k (entry 0, the initial pose, has no
/// step and is left out). `None` for filters without a path (the EKF), and, with a
/// warning, when the path breaks the one-pose-per-update contract.
fn full_trajectory(
    filter: &dyn LandmarkSlam,
    steps: &[LandmarkStep],
    warnings: &mut Vec<String>,
) -> Option<Vec<TimedPose>> {
    let path = filter.full_path()?;
    if path.len() != steps.len() + 1 {
        warnings.push(format!(
            "filter `{}` returned a path of {} poses for {} steps (the LandmarkSlam contract is the initial pose plus one per step); using its online estimates instead",
            filter.name(),
            path.len(),
            steps.len()
        ));
        return None;
    }
    Some(
        steps
            .iter()
            .zip(&path[1..])
            .map(|(s, &pose)| TimedPose { t: s.t, pose })
            .collect(),
    )
}

/// Time span of the data (last time − first, in file order), or `None` when the data has
/// no usable clock: step indices (Freiburg course data), or timestamps so coarse that fewer
/// than a tenth of the steps have distinct times (some GMapping logs printed times as
/// `1.13486e+09`); the latter adds a note.
fn data_duration(times: &[f64], has_clock: bool, notes: &mut Vec<String>) -> Option<f64> {
    if !has_clock || times.len() < 2 {
        return None;
    }
    let mut distinct = times.to_vec();
    distinct.sort_by(f64::total_cmp);
    distinct.dedup();
    if distinct.len() < 2 || distinct.len() * 10 < times.len() {
        notes.push(format!(
            "no data duration / real-time factor: timestamps too coarse ({} distinct times for {} steps)",
            distinct.len(),
            times.len()
        ));
        return None;
    }
    Some(times[times.len() - 1] - times[0])
}

/// ATE (as is, aligned) and RPE against a ground-truth trajectory. A metric that cannot be
/// computed (no pose matched in time, …) stays null, with a warning.
fn trajectory_metrics(
    metrics: &mut Metrics,
    trajectory: &[TimedPose],
    gt: &[TimedPose],
    warnings: &mut Vec<String>,
) {
    warnings.extend(m::stamp_order_warnings(trajectory, gt));
    match m::ate(trajectory, gt) {
        Ok(ate) => {
            metrics.ate_rmse_m = Some(ate.rmse);
            metrics.ate_rmse_aligned_m = Some(ate.rmse_aligned);
        }
        Err(e) => warnings.push(format!("no ATE: {e}")),
    }
    match m::rpe(trajectory, gt) {
        Ok(rpe) => {
            metrics.rpe_trans_mean_m = Some(rpe.trans_mean);
            metrics.rpe_rot_mean_deg = Some(rpe.rot_mean_deg);
        }
        Err(e) => warnings.push(format!("no RPE: {e}")),
    }
}

/// The Kümmerle et al. relations metric; returns a line for the summary.
fn relations_metrics(
    metrics: &mut Metrics,
    trajectory: &[TimedPose],
    relations: &[Relation],
    warnings: &mut Vec<String>,
) -> String {
    let r = m::relations_error(trajectory, relations);
    if r.used > 0 {
        metrics.relations_trans_mean_m = Some(r.trans_mean);
        metrics.relations_rot_mean_deg = Some(r.rot_mean_deg);
        metrics.relations_ambiguous = Some(r.ambiguous);
        metrics.relations_unambiguous_trans_mean_m = Some(r.unambiguous_trans_mean);
        metrics.relations_unambiguous_rot_mean_deg = Some(r.unambiguous_rot_mean_deg);
        let mut line = format!(
            "relations error {:.3} ± {:.3} m / {:.2} ± {:.2} deg ({} relations used, {} without both ends in the trajectory)",
            r.trans_mean, r.trans_std, r.rot_mean_deg, r.rot_std_deg, r.used, r.dropped
        );
        if r.ambiguous > 0 {
            line.push_str(&format!(
                "; {} of them end at a time the trajectory holds several different poses at (a repeating clock: the tie rule picks one), the other {}: {:.3} m / {:.2} deg",
                r.ambiguous,
                r.used - r.ambiguous,
                r.unambiguous_trans_mean,
                r.unambiguous_rot_mean_deg
            ));
        }
        line
    } else {
        let msg = format!(
            "no relations metric: none of the {} relations has both ends in the trajectory (within 6 ms); is it on the same clock?",
            relations.len()
        );
        warnings.push(msg.clone());
        msg
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn data_duration_needs_a_usable_clock() {
        let mut notes = Vec::new();
        assert_eq!(data_duration(&[1.0, 1.5, 4.0], true, &mut notes), Some(3.0));
        assert_eq!(data_duration(&[1.0, 1.5, 4.0], false, &mut notes), None);
        assert!(notes.is_empty());
        // 3 distinct times for 40 steps: printed with too few digits.
        let coarse: Vec<f64> = (0..40).map(|k| 1.0e9 + (k / 15) as f64 * 1e4).collect();
        assert_eq!(data_duration(&coarse, true, &mut notes), None);
        assert_eq!(notes.len(), 1);
    }
}
