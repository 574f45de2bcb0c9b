//! Scan-matching odometry: every scan matched against the map built so far, with the one
//! scan-scoring model of the crate (the truncated endpoint model of
//! [`crate::matcher::endpoint`], grid FastSLAM's).

use crate::error::{ensure_config, GridError};
use crate::grid::OccupancyGrid;
use crate::matcher::check_input;
use crate::matcher::endpoint::{
    hill_climb, wide_search, EndpointMatch, EndpointModel, HillClimbSteps, SearchWindow,
};
use crate::scan::RangeData;
use crate::{InverseSensorModel, MAX_DISTANCE_RADIUS};
use serde::{Deserialize, Serialize};
use slam_models::{normalize_angle, FilterError, GridMap, Pose2, ScanRecord, ScanSlam};
use slam_models::{ConfigError, Vector3};
use slam_models::{Matrix3, OdometryJumpGuard, OdometryJumpLimit, ScanUpdateInfo, TimedPose};

/// The matching of [`ScanMatchOdometry`]: the truncated endpoint model (PR §6.4; the
/// parameters of grid FastSLAM's `[matching]` table, defaults its indoor preset's), a
/// window search around the odometry prediction and the hill climber.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields, default)]
pub struct EndpointMatchingConfig {
    /// Standard deviation σ of the endpoint model: a beam ending at distance d from the
    /// nearest occupied cell contributes −d²/(2σ²) to the log-likelihood, metres. Default
    /// 0.05 (grid FastSLAM's indoor preset: one 5 cm cell).
    pub sigma: f64,
    /// Reach of the map's incrementally repaired distance field, metres, a whole number
    /// of 1 to 15 cells: the capture range of the window search and of the hill climber's
    /// coarse phase, which score with the model truncated here. Default 0.2 (four 5 cm
    /// cells, grid FastSLAM's indoor preset).
    pub field_radius: f64,
    /// The model's truncation r (the outlier floor −r²/(2σ²)) where the pose is decided:
    /// the hill climber's fine phase and the inlier count, metres, in (0, `field_radius`].
    /// Default 0.15 (grid FastSLAM's indoor preset).
    pub likelihood_radius: f64,
    /// The summed beam log-likelihood is divided by this where it is weighed against the
    /// search's prior (GMapping's `ogain`; it changes nothing without a prior). Default 3
    /// (grid FastSLAM's).
    pub gain: f64,
    /// Hill climber: initial translation step, metres. Default 0.1 (grid FastSLAM's indoor
    /// preset).
    pub linear_step: f64,
    /// Hill climber: initial rotation step, radians. Default 0.1.
    pub angular_step: f64,
    /// Hill climber: how often the steps are halved (0 to 30). Default 6 (final steps
    /// 1.6 mm / 1.6 mrad).
    pub refinements: usize,
    /// Window search before the climb: ± this in x and y around the prediction, metres
    /// (0 with `search_range_theta` 0 switches the search off). Default 0.4 (the window the
    /// correlative matcher searched before, issue 21).
    pub search_range_xy: f64,
    /// Window search translation step, metres, rounded to whole map cells (at least one).
    /// Default 0.05 (one cell).
    pub search_step_xy: f64,
    /// Window search: ± this in θ, radians, in [0, π]. Default 0.21 (12°, the correlative
    /// matcher's window before).
    pub search_range_theta: f64,
    /// Window search rotation step, radians (> 0). Default 0.01.
    pub search_step_theta: f64,
    /// Standard deviations of the Gaussian prior N(prediction, diag(s_xy², s_xy², s_θ²))
    /// that weighs the window search, (metres, radians); 0 for none (the plain maximum of
    /// the likelihood over the window). Default (0, 0).
    pub search_prior_std: [f64; 2],
    /// A match counts as failed, and the odometry prediction is kept, when fewer than this
    /// fraction of the matching end points end within `likelihood_radius` of an occupied
    /// cell at the matched pose, in [0, 1]. Default 0.25 (grid FastSLAM's).
    pub min_inlier_fraction: f64,
    /// Fewer matching end points than this is a failed match. Default 10.
    pub min_points: usize,
}

impl Default for EndpointMatchingConfig {
    fn default() -> Self {
        Self {
            sigma: 0.05,
            field_radius: 0.2,
            likelihood_radius: 0.15,
            gain: 3.0,
            linear_step: 0.1,
            angular_step: 0.1,
            refinements: 6,
            search_range_xy: 0.4,
            search_step_xy: 0.05,
            search_range_theta: 0.21,
            search_step_theta: 0.01,
            search_prior_std: [0.0, 0.0],
            min_inlier_fraction: 0.25,
            min_points: 10,
        }
    }
}

/// Most lattice steps per side of the window search in each dimension: beyond it the
/// search's tables (one cell per end point and rotation) grow past tens of megabytes.
pub const MAX_SEARCH_STEPS: f64 = 1000.0;

impl EndpointMatchingConfig {
    /// Checks every value (finite, in its range; the field's reach 1 to 15 cells of
    /// `resolution`, the truncation within it).
    pub fn validate(&self, resolution: f64) -> Result<(), GridError> {
        let positive = |v: f64| v > 0.0 && v.is_finite();
        ensure_config(positive(self.sigma), "matching.sigma", self.sigma, "> 0 m")?;
        let cells = self.field_radius / resolution;
        ensure_config(
            (1.0..=MAX_DISTANCE_RADIUS as f64).contains(&cells),
            "matching.field_radius",
            self.field_radius,
            "between 1 and 15 cells of resolution",
        )?;
        ensure_config(
            self.likelihood_radius > 0.0 && self.likelihood_radius <= self.field_radius,
            "matching.likelihood_radius",
            self.likelihood_radius,
            "in (0, matching.field-radius] m",
        )?;
        ensure_config(positive(self.gain), "matching.gain", self.gain, "> 0")?;
        ensure_config(
            positive(self.linear_step),
            "matching.linear_step",
            self.linear_step,
            "> 0 m",
        )?;
        ensure_config(
            positive(self.angular_step),
            "matching.angular_step",
            self.angular_step,
            "> 0 rad",
        )?;
        ensure_config(
            self.refinements <= 30,
            "matching.refinements",
            self.refinements as f64,
            "<= 30",
        )?;
        ensure_config(
            positive(self.search_step_xy),
            "matching.search_step_xy",
            self.search_step_xy,
            "> 0 m",
        )?;
        ensure_config(
            positive(self.search_step_theta),
            "matching.search_step_theta",
            self.search_step_theta,
            "> 0 rad",
        )?;
        ensure_config(
            self.search_range_xy >= 0.0
                && self.search_range_xy / self.search_step_xy <= MAX_SEARCH_STEPS,
            "matching.search_range_xy",
            self.search_range_xy,
            ">= 0 m and at most 1000 search-step-xy",
        )?;
        ensure_config(
            (0.0..=std::f64::consts::PI).contains(&self.search_range_theta)
                && self.search_range_theta / self.search_step_theta <= MAX_SEARCH_STEPS,
            "matching.search_range_theta",
            self.search_range_theta,
            "in [0, π] rad and at most 1000 search-step-theta",
        )?;
        for (v, name) in self.search_prior_std.into_iter().zip([
            "matching.search_prior_std[0]",
            "matching.search_prior_std[1]",
        ]) {
            ensure_config(v >= 0.0 && v.is_finite(), name, v, ">= 0 (0: no prior)")?;
        }
        ensure_config(
            (0.0..=1.0).contains(&self.min_inlier_fraction),
            "matching.min_inlier_fraction",
            self.min_inlier_fraction,
            "in [0, 1]",
        )
    }
}

/// Configuration of [`ScanMatchOdometry`].
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields, default)]
pub struct ScanMatchConfig {
    /// Map cell size, metres. Default 0.05 m.
    pub resolution: f64,
    /// Inverse sensor model of the map updates.
    pub sensor_model: InverseSensorModel,
    /// The endpoint model and the matching.
    pub matching: EndpointMatchingConfig,
    /// End points farther than this from the sensor are not used for matching, metres.
    /// Default 20 m.
    pub match_max_range: f64,
    /// A scan is processed only once the robot moved this far since the last processed
    /// scan (by odometry), metres. Default 0.1 m. The first scan is always processed.
    pub linear_update: f64,
    /// … or turned this much, radians. Default 0.1 rad.
    pub angular_update: f64,
    /// The largest odometry jump between two consecutive records, and whether a larger
    /// one is an error (default: beyond 5 m) or skipped ([`OdometryJumpLimit`]).
    pub odometry_jump: OdometryJumpLimit,
}

impl Default for ScanMatchConfig {
    fn default() -> Self {
        Self {
            resolution: 0.05,
            sensor_model: InverseSensorModel::default(),
            matching: EndpointMatchingConfig::default(),
            match_max_range: 20.0,
            linear_update: 0.1,
            angular_update: 0.1,
            odometry_jump: OdometryJumpLimit::default(),
        }
    }
}

/// The matching parameters in the form the endpoint functions take.
#[derive(Debug, Clone, Copy)]
struct Matching {
    /// The model truncated at `likelihood_radius`: the climb's fine phase, the inliers.
    lk: EndpointModel,
    /// The model truncated at the field's reach: the window search, the coarse phase.
    capture: EndpointModel,
    hc: HillClimbSteps,
    /// `None` when the window is empty (no search).
    window: Option<SearchWindow>,
    min_inlier_fraction: f64,
    min_points: usize,
}

impl Matching {
    fn new(m: &EndpointMatchingConfig, field_cells: u32, resolution: f64) -> Self {
        let lk = EndpointModel::new(m.sigma, m.likelihood_radius, m.gain);
        let information = |s: f64| if s > 0.0 { 1.0 / (s * s) } else { 0.0 };
        let [s_xy, s_theta] = m.search_prior_std;
        Self {
            lk,
            capture: EndpointModel {
                radius: field_cells as f64 * resolution,
                ..lk
            },
            hc: HillClimbSteps {
                linear_step: m.linear_step,
                angular_step: m.angular_step,
                refinements: m.refinements,
            },
            window: (m.search_range_xy > 0.0 || m.search_range_theta > 0.0).then(|| SearchWindow {
                range_xy: m.search_range_xy,
                step_xy: m.search_step_xy,
                range_theta: m.search_range_theta,
                step_theta: m.search_step_theta,
                information: Matrix3::from_diagonal(&Vector3::new(
                    information(s_xy),
                    information(s_xy),
                    information(s_theta),
                )),
            }),
            min_inlier_fraction: m.min_inlier_fraction,
            min_points: m.min_points,
        }
    }
}

/// Scan-matching odometry, the baseline of the SLAM benchmarks: each processed scan is
/// matched against the map built from all earlier processed scans, starting from the last
/// corrected pose composed with the odometry increment since; the scan is then written
/// into the map at the matched pose. No loop closure: errors accumulate, more slowly than
/// with odometry alone.
///
/// The match uses the one scan-scoring model of the crate, grid FastSLAM's
/// ([`crate::matcher::endpoint`]): the truncated endpoint log-likelihood on the map's
/// incrementally repaired distance field; a branch-and-bound search of a window around the
/// prediction ([`wide_search`], the exact optimum of its lattice, weighed by an optional
/// Gaussian prior), then the hill climber ([`hill_climb`]) from its best pose. A match with
/// too few beams on the map keeps the prediction.
///
/// Every record gets a pose: the last corrected pose ⊕ (odometry since that scan), so
/// [`ScanSlam::trajectory`] has one entry per record.
///
/// Frame (the one convention of every laser filter, docs/evaluation.md): the world frame is
/// the odometry frame placed at the constructor's `initial_pose`, so the first record's
/// pose is `initial_pose ⊕ o₀` for its odometry reading o₀; with `Pose2::IDENTITY` (what
/// `slam run` passes) the map frame coincides with the odometry frame at the first scan
/// (REP 105's `map` = `odom` at start, as slam_toolbox, GMapping and this workspace's grid
/// FastSLAM and laser graph do). A recording without odometry reads o₀ = identity.
#[derive(Debug, Clone)]
pub struct ScanMatchOdometry {
    config: ScanMatchConfig,
    matching: Matching,
    grid: OccupancyGrid,
    /// Pose of the odometry frame in the world: the first record is at `initial_pose ⊕ o₀`.
    initial_pose: Pose2,
    /// Pose at the last processed scan and the odometry reading there.
    anchor: Option<(Pose2, Pose2)>,
    current: Pose2,
    trajectory: Vec<TimedPose>,
    map_has_scan: bool,
    failures: usize,
    guard: OdometryJumpGuard,
}

/// The farthest a pose may move in the hill climb, in initial linear steps: more than the
/// climber's budget of moves, for the range check of [`check_input`].
const CLIMB_REACH_STEPS: f64 = 100.0;

impl ScanMatchOdometry {
    /// A filter with an empty map whose odometry frame lies at `initial_pose` in the world
    /// (the first record, of odometry o₀, is at `initial_pose ⊕ o₀`; see the type's doc);
    /// rejects invalid configuration and a non-finite pose. Scan matching draws nothing at
    /// random: `seed` is taken for the one constructor shape of every filter
    /// ([`slam_models::FromConfig`]) and ignored.
    pub fn new(config: ScanMatchConfig, initial_pose: Pose2, seed: u64) -> Result<Self, GridError> {
        let _ = seed;
        if !initial_pose.is_finite() {
            return Err(GridError::NonFinite {
                what: "initial pose",
                value: [initial_pose.x, initial_pose.y, initial_pose.theta]
                    .into_iter()
                    .find(|v| !v.is_finite())
                    .unwrap_or(f64::NAN),
            });
        }
        ensure_config(
            config.resolution > 0.0 && config.resolution.is_finite(),
            "resolution",
            config.resolution,
            "> 0 m",
        )?;
        // At least one cell: end points nearer than that all fall in the robot's own cell,
        // so a shorter limit matches nothing and the run silently kept its odometry
        // (`match-max-range = 1e-300` with exit code 0).
        ensure_config(
            config.match_max_range >= config.resolution,
            "match_max_range",
            config.match_max_range,
            "at least resolution (one cell; a shorter limit matches no end point)",
        )?;
        ensure_config(
            config.linear_update >= 0.0,
            "linear_update",
            config.linear_update,
            ">= 0 m",
        )?;
        ensure_config(
            config.angular_update >= 0.0,
            "angular_update",
            config.angular_update,
            ">= 0 rad",
        )?;
        config.matching.validate(config.resolution)?;
        let guard = OdometryJumpGuard::new(config.odometry_jump)?;
        // In 1..=15 by the validation above.
        let field_cells = (config.matching.field_radius / config.resolution).round() as u32;
        let grid = OccupancyGrid::try_new(config.resolution, config.sensor_model)?
            .with_incremental_distance(field_cells)?;
        Ok(Self {
            matching: Matching::new(&config.matching, field_cells, config.resolution),
            config,
            grid,
            initial_pose,
            anchor: None,
            current: initial_pose,
            trajectory: Vec::new(),
            map_has_scan: false,
            failures: 0,
            guard,
        })
    }

    /// The working occupancy grid.
    pub fn grid(&self) -> &OccupancyGrid {
        &self.grid
    }

    /// Processed scans whose match was rejected or failed (odometry used instead).
    pub fn match_failures(&self) -> usize {
        self.failures
    }

    /// The matched pose of `scan` around `predicted`, or `None` when the match fails: too
    /// few end points, a prediction out of the matchers' range, or too few inliers at the
    /// best pose. Errors only when the window is too large for the search's pyramid.
    fn match_scan(&self, scan: &RangeData, predicted: &Pose2) -> Result<Option<Pose2>, GridError> {
        self.match_scan_in(
            scan,
            predicted,
            self.matching.window.as_ref(),
            self.matching.min_inlier_fraction,
        )
    }

    /// [`Self::match_scan`] with the window search over `window` (none: the climb alone)
    /// and the inlier fraction `min_inlier_fraction` instead of the configured ones (laser
    /// odometry's searches).
    pub(crate) fn match_scan_in(
        &self,
        scan: &RangeData,
        predicted: &Pose2,
        window: Option<&SearchWindow>,
        min_inlier_fraction: f64,
    ) -> Result<Option<Pose2>, GridError> {
        let Some(matched) = self.match_scored(scan, predicted, window)? else {
            return Ok(None);
        };
        let needed = ((min_inlier_fraction * scan.points().len() as f64).ceil() as usize).max(1);
        Ok((matched.score.inliers >= needed).then_some(matched.pose))
    }

    /// The best pose of the window search over `window` (none: the climb alone) around
    /// `predicted` after the hill climb, with its fine score (log-likelihood and inliers,
    /// whatever they are); `None` when the scan or the prediction cannot be matched (too
    /// few end points, out of the matchers' range). Errors only when the window is too
    /// large for the search's pyramid.
    pub(crate) fn match_scored(
        &self,
        scan: &RangeData,
        predicted: &Pose2,
        window: Option<&SearchWindow>,
    ) -> Result<Option<EndpointMatch>, GridError> {
        let m = &self.matching;
        let reach = window.map_or(0.0, |w| w.range_xy)
            + CLIMB_REACH_STEPS * self.config.matching.linear_step;
        if check_input(&self.grid, scan, predicted, m.min_points, reach).is_err() {
            return Ok(None);
        }
        let Some(field) = self.grid.distance_field() else {
            // Unreachable: the grid is made with its distance field in `new`.
            return Ok(None);
        };
        let start = match window {
            Some(window) => {
                wide_search(&field, scan, predicted, &m.capture, window)
                    .map_err(|e| match e {
                        // The pyramid over the window and the scan is too large: say which
                        // setting makes it so.
                        GridError::InvalidConfig(_) => GridError::InvalidConfig(ConfigError::new(
                            "grid",
                            "matching.search_range_xy",
                            window.range_xy,
                            "small enough that the window and the scan (match-max-range) fit \
                             a search pyramid of 16e6 cells",
                        )),
                        other => other,
                    })?
                    .pose
            }
            None => *predicted,
        };
        Ok(Some(hill_climb(
            &field, scan, &start, &m.capture, &m.lk, &m.hc,
        )))
    }

    /// The configured window search ([`EndpointMatchingConfig`]), `None` when it is off.
    pub(crate) fn window(&self) -> Option<SearchWindow> {
        self.matching.window
    }

    /// Writes `scan` into the map at `pose` (world frame).
    pub(crate) fn integrate(&mut self, pose: &Pose2, scan: &RangeData) -> Result<(), GridError> {
        self.grid.try_integrate_prepared(pose, scan)?;
        self.map_has_scan = true;
        Ok(())
    }

    fn step(&mut self, record: &ScanRecord) -> Result<ScanUpdateInfo, GridError> {
        if !record.odometry.is_finite() || !record.t.is_finite() {
            return Err(GridError::NonFinite {
                what: "record odometry or time",
                value: f64::NAN,
            });
        }
        let (odometry, skipped) = self.guard.check(&record.odometry)?;
        let initial = self.initial_pose;
        let (anchor_pose, anchor_odom) = *self
            .anchor
            .get_or_insert_with(|| (initial.compose(&odometry), odometry));
        let predicted = anchor_pose.compose(&anchor_odom.between(&odometry));
        let mut info = ScanUpdateInfo {
            odometry_jumps_skipped: skipped as usize,
            ..ScanUpdateInfo::default()
        };
        self.current = predicted;
        if let Some(scan) = &record.scan {
            let moved = anchor_pose.distance(&predicted);
            let turned = normalize_angle(predicted.theta - anchor_pose.theta).abs();
            let due = !self.map_has_scan
                || moved >= self.config.linear_update
                || turned >= self.config.angular_update;
            if due {
                let prepared = RangeData::with_limits(
                    scan,
                    &self.config.sensor_model,
                    0.0,
                    self.config.match_max_range,
                )?;
                let pose = if self.map_has_scan {
                    match self.match_scan(&prepared, &predicted)? {
                        Some(pose) => pose,
                        None => {
                            self.failures += 1;
                            info.match_failures = 1;
                            predicted
                        }
                    }
                } else {
                    predicted
                };
                self.grid.try_integrate_prepared(&pose, &prepared)?;
                self.map_has_scan = true;
                self.anchor = Some((pose, odometry));
                self.current = pose;
                info.processed_scan = true;
            }
        }
        self.trajectory.push(TimedPose {
            t: record.t,
            pose: self.current,
        });
        Ok(info)
    }
}

slam_models::from_config_by_new!(ScanMatchOdometry, ScanMatchConfig, GridError);

impl ScanSlam for ScanMatchOdometry {
    fn name(&self) -> &str {
        "scanmatch"
    }

    /// Errors keep their type: `FilterError::downcast_ref::<GridError>()` gives them back.
    fn process(&mut self, record: &ScanRecord) -> Result<ScanUpdateInfo, FilterError> {
        self.step(record).map_err(FilterError::from)
    }

    fn pose(&self) -> Pose2 {
        self.current
    }

    fn trajectory(&self) -> Vec<TimedPose> {
        self.trajectory.clone()
    }

    fn map(&self) -> GridMap {
        self.grid.to_grid_map()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testutil::SegmentWorld;

    /// Drive through the synthetic office with odometry that under-reports translation by
    /// 5 % and drifts in heading: scan matching keeps the pose within 10 cm over 9 m,
    /// odometry alone does not.
    #[test]
    fn corrects_biased_odometry_and_keeps_one_pose_per_record() {
        // Once in the frame of the first record, once with the first record placed at its
        // true world pose (the constructor's `initial_pose`).
        for initial in [Pose2::IDENTITY, Pose2::new(1.5, 3.0, 0.0)] {
            corrects_biased_odometry_from(initial);
        }
    }

    /// The frame convention: the world is the odometry frame placed at `initial_pose`. With
    /// odometry that starts at the robot's true pose away from the origin (the odometry frame
    /// is the world) and `initial_pose` the identity, the first pose is that odometry
    /// reading and every pose is in the world frame, within 10 cm of the truth with no
    /// anchoring; with `initial_pose` = T, each pose is T ⊕ that.
    #[test]
    fn the_world_is_the_odometry_frame_at_the_first_scan() {
        let world = SegmentWorld::office();
        let shift = Pose2::new(-4.0, 1.0, 0.3);
        for initial in [Pose2::IDENTITY, shift] {
            let mut f = ScanMatchOdometry::new(ScanMatchConfig::default(), initial, 0).unwrap();
            let mut worst: f64 = 0.0;
            for k in 0..60 {
                let truth = Pose2::new(1.5 + 0.075 * k as f64, 3.0, 0.1);
                let rec = ScanRecord {
                    t: k as f64 * 0.1,
                    odometry: truth,
                    scan: Some(world.scan(&truth, 181, std::f64::consts::PI, 20.0)),
                };
                f.process(&rec).unwrap();
                if k == 0 {
                    let first = initial.compose(&truth);
                    assert!(f.pose().distance(&first) < 1e-12, "{:?}", f.pose());
                }
                worst = worst.max(initial.between(&f.pose()).distance(&truth));
            }
            assert!(
                worst < 0.1,
                "{worst} m from the truth (initial {initial:?})"
            );
        }
    }

    fn corrects_biased_odometry_from(initial: Pose2) {
        let world = SegmentWorld::office();
        let mut f = ScanMatchOdometry::new(ScanMatchConfig::default(), initial, 0).unwrap();
        assert_eq!(f.pose(), initial);
        let mut odo = Pose2::IDENTITY;
        let mut prev_true = Pose2::new(1.5, 3.0, 0.0);
        let start = prev_true;
        let mut worst: f64 = 0.0;
        let mut odo_err: f64 = 0.0;
        let n = 120;
        for k in 0..n {
            // Along the room y = 3 to x = 10.5, turning slowly.
            let truth = Pose2::new(
                1.5 + 9.0 * k as f64 / n as f64,
                3.0 + 0.5 * (k as f64 * 0.05).sin(),
                0.3 * (k as f64 * 0.03).sin(),
            );
            let d = prev_true.between(&truth);
            odo = odo.compose(&Pose2::new(0.95 * d.x, 0.95 * d.y, d.theta + 0.004));
            prev_true = truth;
            let scan = (k % 2 == 0).then(|| world.scan(&truth, 181, std::f64::consts::PI, 20.0));
            let rec = ScanRecord {
                t: k as f64 * 0.1,
                odometry: odo,
                scan,
            };
            f.process(&rec).unwrap();
            // The estimate in the world frame: the first record is at `start` in truth.
            let est = start.compose(&initial.between(&f.pose()));
            worst = worst.max(est.distance(&truth));
            odo_err = odo_err.max(start.compose(&odo).distance(&truth));
        }
        assert_eq!(f.trajectory().len(), n);
        assert!(worst < 0.1, "scan matching error {worst}");
        assert!(odo_err > 0.3, "odometry error {odo_err}");
        assert_eq!(f.name(), "scanmatch");
        let bad = ScanRecord {
            t: 0.0,
            odometry: Pose2::new(f64::NAN, 0.0, 0.0),
            scan: None,
        };
        let e = f.process(&bad).unwrap_err();
        assert!(matches!(e, FilterError::InvalidInput { .. }), "{e:?}");
        assert!(
            matches!(
                e.downcast_ref::<GridError>(),
                Some(GridError::NonFinite { .. })
            ),
            "{e:?}"
        );
    }

    /// A filter that processed one scan of the office taken at `first` (world frame),
    /// its first record placed at `first` + `shift` (the filter's frame: the world moved by
    /// `shift`).
    fn after_one_scan(first: &Pose2, shift: (f64, f64)) -> ScanMatchOdometry {
        after_one_scan_with(first, shift, ScanMatchConfig::default())
    }

    /// [`after_one_scan`] with `config`.
    fn after_one_scan_with(
        first: &Pose2,
        shift: (f64, f64),
        config: ScanMatchConfig,
    ) -> ScanMatchOdometry {
        let world = SegmentWorld::office();
        let placed = Pose2::new(first.x + shift.0, first.y + shift.1, first.theta);
        let mut f = ScanMatchOdometry::new(config, placed, 0).unwrap();
        f.process(&ScanRecord {
            t: 0.0,
            odometry: Pose2::IDENTITY,
            scan: Some(world.scan(first, 181, std::f64::consts::PI, 20.0)),
        })
        .unwrap();
        f
    }

    /// The match finds the true pose from odometry errors up to 0.35 m and 0.18 rad (within
    /// the window search's ±0.4 m / ±0.21 rad): the matched pose is within 1 cm and 0.2° of
    /// the pose the scan was simulated at.
    ///
    /// The office's walls lie on whole metres, i.e. on cell boundaries of a 5 cm grid at
    /// the world origin, where rounding puts a wall's hits on either side and the mapped
    /// wall moves by up to half a cell (2.5 cm), and the matched pose with it: the filter's
    /// frame is the world moved by half a cell, so that the walls run through cell centres.
    #[test]
    fn recovers_large_odometry_errors() {
        let world = SegmentWorld::office();
        let shift = (0.025, 0.025);
        let first = Pose2::new(2.0, 3.0, 0.2);
        let truth = Pose2::new(2.5, 3.1, 0.25);
        let expected = Pose2::new(truth.x + shift.0, truth.y + shift.1, truth.theta);
        for (dx, dy, dtheta) in [
            (0.3, -0.25, 0.15),
            (-0.35, 0.2, -0.18),
            (0.1, 0.3, 0.0),
            (0.0, 0.0, 0.0),
        ] {
            let mut f = after_one_scan(&first, shift);
            // The odometry (first record at the identity) reports truth ⊕ error.
            let reported = Pose2::new(truth.x + dx, truth.y + dy, truth.theta + dtheta);
            let info = f
                .process(&ScanRecord {
                    t: 0.1,
                    odometry: first.between(&reported),
                    scan: Some(world.scan(&truth, 181, std::f64::consts::PI, 20.0)),
                })
                .unwrap();
            assert!(info.processed_scan && info.match_failures == 0, "{info:?}");
            let got = f.pose();
            assert!(
                got.distance(&expected) < 0.01
                    && normalize_angle(got.theta - expected.theta).abs() < 0.0035,
                "from an error of ({dx}, {dy}, {dtheta}): {got:?} against {expected:?}"
            );
        }
    }

    /// A scan that does not fit the map (a ring of returns 0.3 m around the robot, in the
    /// middle of a room) is a failed match: counted, and the pose is the odometry's.
    #[test]
    fn a_scan_that_does_not_fit_keeps_the_prediction() {
        let first = Pose2::new(9.0, 6.5, 0.0);
        let mut f = after_one_scan(&first, (0.0, 0.0));
        let ring = slam_models::LaserScan {
            angle_min: -std::f64::consts::PI,
            angle_increment: std::f64::consts::TAU / 180.0,
            ranges: vec![0.3; 180],
            max_range: 20.0,
            sensor_pose: Pose2::IDENTITY,
        };
        let odometry = Pose2::new(0.2, 0.0, 0.0);
        let info = f
            .process(&ScanRecord {
                t: 0.1,
                odometry,
                scan: Some(ring),
            })
            .unwrap();
        assert!(info.processed_scan, "{info:?}");
        assert_eq!((info.match_failures, f.match_failures()), (1, 1));
        assert_eq!(f.pose(), first.compose(&odometry));
    }

    /// Every matching value out of its range is refused, naming its key and bound.
    #[test]
    fn bad_matching_values_are_refused_by_key() {
        type Edit = fn(&mut EndpointMatchingConfig);
        let cases: [(Edit, &str); 9] = [
            (|m| m.sigma = f64::NAN, "matching.sigma"),
            // 20 cells of 5 cm: beyond the distance field's 15.
            (|m| m.field_radius = 1.0, "matching.field_radius"),
            (|m| m.field_radius = 0.02, "matching.field_radius"),
            (|m| m.likelihood_radius = 0.25, "matching.likelihood_radius"),
            (|m| m.refinements = 31, "matching.refinements"),
            (
                |m| m.search_range_theta = 4.0,
                "matching.search_range_theta",
            ),
            (|m| m.search_range_xy = 100.0, "matching.search_range_xy"),
            (
                |m| m.search_prior_std[1] = -0.1,
                "matching.search_prior_std[1]",
            ),
            (
                |m| m.min_inlier_fraction = 1.5,
                "matching.min_inlier_fraction",
            ),
        ];
        for (edit, key) in cases {
            let mut config = ScanMatchConfig::default();
            edit(&mut config.matching);
            let e = ScanMatchOdometry::new(config, Pose2::IDENTITY, 0).unwrap_err();
            assert!(
                matches!(&e, GridError::InvalidConfig(c) if c.field == key),
                "{key}: {e}"
            );
        }
        // A match range below one cell matches no end point (`match-max-range = 1e-300`
        // ran with exit code 0, the output its odometry): refused by key; one cell is taken.
        for (m, ok) in [(1e-300, false), (0.049, false), (0.05, true)] {
            let config = ScanMatchConfig {
                match_max_range: m,
                ..ScanMatchConfig::default()
            };
            match ScanMatchOdometry::new(config, Pose2::IDENTITY, 0) {
                Err(GridError::InvalidConfig(c)) if !ok => assert_eq!(c.field, "match_max_range"),
                Ok(_) if ok => {}
                Err(e) => panic!("match_max_range {m}: {e}"),
                Ok(_) => panic!("match_max_range {m} taken"),
            }
        }
        // A window too large for the search's pyramid is refused at the first match, by key.
        let mut config = ScanMatchConfig::default();
        config.matching.search_range_xy = 400.0;
        config.matching.search_step_xy = 0.5;
        let mut f = after_one_scan_with(&Pose2::new(2.0, 3.0, 0.0), (0.0, 0.0), config);
        let e = f
            .process(&ScanRecord {
                t: 0.1,
                odometry: Pose2::new(0.2, 0.0, 0.0),
                scan: Some(SegmentWorld::office().scan(
                    &Pose2::new(2.2, 3.0, 0.0),
                    181,
                    std::f64::consts::PI,
                    20.0,
                )),
            })
            .unwrap_err();
        assert!(
            e.to_string().contains("search-range-xy") && e.to_string().contains("16e6"),
            "{e}"
        );
        // The defaults are grid FastSLAM's indoor preset's.
        let m = EndpointMatchingConfig::default();
        assert_eq!(
            (m.sigma, m.field_radius, m.likelihood_radius, m.gain),
            (0.05, 0.2, 0.15, 3.0)
        );
    }

    /// Records along the office with true odometry, one of them moved by 10 km (a glitch).
    fn glitched_records() -> Vec<ScanRecord> {
        let world = SegmentWorld::office();
        (0..40)
            .map(|k| {
                let truth = Pose2::new(1.5 + 0.1 * k as f64, 3.0, 0.0);
                let mut odometry = Pose2::new(truth.x - 1.5, 0.0, 0.0);
                if k == 20 {
                    odometry.x += 10_000.0;
                }
                ScanRecord {
                    t: k as f64 * 0.1,
                    odometry,
                    scan: Some(world.scan(&truth, 181, std::f64::consts::PI, 20.0)),
                }
            })
            .collect()
    }

    /// A 10 km odometry jump is an error naming the jump and the bound (it used to
    /// stretch the grid over 10 km and ask for 18 GB); with `on_jump = "skip"` the record
    /// counts as no motion, is counted in the step info, and the map stays the office's.
    #[test]
    fn an_odometry_jump_is_an_error_or_skipped_on_request() {
        let records = glitched_records();
        let mut f = ScanMatchOdometry::new(ScanMatchConfig::default(), Pose2::IDENTITY, 0).unwrap();
        for r in &records[..20] {
            f.process(r).unwrap();
        }
        let err = f.process(&records[20]).unwrap_err().to_string();
        assert!(
            err.contains("odometry jumped 10000") && err.contains("max-jump = 5 m"),
            "{err}"
        );

        let config = ScanMatchConfig {
            odometry_jump: slam_models::OdometryJumpLimit {
                max_jump: 5.0,
                on_jump: slam_models::OnOdometryJump::Skip,
            },
            ..ScanMatchConfig::default()
        };
        let mut f = ScanMatchOdometry::new(config, Pose2::IDENTITY, 0).unwrap();
        let mut skipped = Vec::new();
        for r in &records {
            skipped.push(f.process(r).unwrap().odometry_jumps_skipped);
        }
        // Out at record 20 and back at record 21: both jumps taken as no motion.
        let at: Vec<usize> = (0..skipped.len()).filter(|&k| skipped[k] > 0).collect();
        assert_eq!(at, [20, 21]);
        let traj = f.trajectory();
        // The robot moved 3.9 m in all; the two skipped records lose at most their 0.2 m
        // of odometry (scan matching recovers it against the map), never kilometres.
        let last = traj.last().unwrap().pose;
        assert!((last.x - 3.9).abs() < 0.25, "{last:?}");
        let map = f.map();
        assert!(
            map.width as f64 * map.resolution < 50.0,
            "{} cells wide",
            map.width
        );
        assert!(ScanMatchOdometry::new(
            ScanMatchConfig {
                odometry_jump: slam_models::OdometryJumpLimit {
                    max_jump: f64::NAN,
                    ..Default::default()
                },
                ..ScanMatchConfig::default()
            },
            Pose2::IDENTITY,
            0
        )
        .is_err());
    }
}
