//! The laser front end: pose-graph SLAM from odometry and laser scans (`ScanSlam`, name
//! `"graph"`), after Hess, Kohler, Rapp and Andor, "Real-time loop closure in 2D LIDAR SLAM"
//! (ICRA 2016; Cartographer) and Grisetti et al.'s graph-SLAM tutorial (2010).
//!
//! * **Keyframes**: a scan is processed once the odometry moved `keyframe-distance` or turned
//!   `keyframe-angle` since the last keyframe.
//! * **Local SLAM**: each keyframe is matched (slam-grid's correlative search, then
//!   Gauss-Newton) against the older of two overlapping submaps, starting from the last
//!   keyframe's local pose composed with the odometry since; it is then inserted into both.
//!   Local poses live in a frame of their own that loop closures never move, so the
//!   submaps stay consistent. Consecutive keyframes are joined by an edge with their local
//!   relative pose and, as information, the inverse of the match's covariance estimated
//!   from the tempered likelihood sampled over a window of poses (Olson 2009's response
//!   covariance, [`MatchCovariance`]; rotated into the earlier keyframe's frame, floored by
//!   `match-min-std`, and given to the optimiser in the frame of the edge's error, the
//!   measured later pose's): in a corridor it is large along the axis, so there a loop closure
//!   moves the keyframe along the corridor more easily than across it. A match that is
//!   degenerate (`degenerate-anisotropy`: a corridor slides short along its axis) takes
//!   the odometry along its weak direction in that edge; the submaps keep the match.
//! * **Loop closure**: a finished submap (its last scan at least `loop-min-scan-gap`
//!   keyframes old) whose keyframes lie within reach of the keyframe's global position is
//!   searched with slam-grid's [`BranchBoundMatcher`](slam_grid::BranchBoundMatcher) over
//!   a [`MaxPyramid`] of the submap, around the pose the current graph predicts; the radius
//!   and the rotation window grow linearly with the graph distance between the submap and
//!   the keyframe (the scan-matching chain since the closures that last joined them: the
//!   uncertainty of their relative pose before this closure), up to their caps (12 m,
//!   0.8 rad). Each submap is searched narrow first (3 m, 0.6 rad); the whole window only
//!   when that finds nothing, under a per-keyframe budget. A match scoring at
//!   least `loop-min-score`, and not matched almost as well 0.25–1 m away
//!   (`loop-ambiguity-ratio`), is refined by Gauss-Newton and becomes an edge from the
//!   submap's keyframe nearest to the match. Finished submaps keep no grid: the search
//!   rebuilds one from its keyframes' scans (the same insertions, so the same grid) and
//!   keeps it with its pyramid in a cache (`loop-pyramid-cache-bytes`), so memory does not
//!   grow with the number of submaps (the pyramids' coarse levels in 8-bit codes,
//!   [`MaxPyramid::new_compact`]; the grids only of the `loop-max-candidates` most
//!   recently searched). After every keyframe that added a closure the
//!   keyframe graph is optimised (Levenberg-Marquardt with the configured robust kernel,
//!   DCS by default, against false closures); the closures into one submap share one
//!   closure's information there (`closures-share-submap`: their errors are the grid's,
//!   common to all of them).
//! * **Poses at every record**: the trajectory comes from a second graph with **one node
//!   per record**, consecutive records joined by odometry edges (increment o_{i−1}⁻¹ ⊕ o_i,
//!   covariance from [`OdometryNoise`]). By default it holds every keyframe at the keyframe
//!   graph's optimum and places only the records between them: each run of records is the
//!   odometry chain bent to meet the keyframes at both ends, the correction shared in
//!   proportion to the odometry edges' uncertainty (a smoother between keyframes, instead
//!   of a correction applied at the keyframe only). With `smoother-holds-keyframes =
//!   false` the keyframes are estimated again jointly with the odometry: the keyframes
//!   are then additionally joined by the scan-matching and loop-closure edges above
//!   (without a robust kernel; loop closures the keyframe graph's kernel rejected are
//!   left out). The joint estimate lets the odometry pull on the keyframes; on the
//!   simulated campus it shrank the map by 0.28 % and doubled the aligned ATE, on Intel's
//!   relations it cost 6 mm, so it is not the default.
//! * **The map** is rendered from the keyframes' scans at their smoothed poses. Keyframes
//!   keep their scans as recorded and prepare them again when needed.
//!
//! The world frame is the odometry frame placed at the constructor's `initial_pose` (the
//! identity: the odometry frame itself), and the first record's pose is its odometry
//! reading in that frame. Everything is deterministic: no random numbers are drawn.

pub mod config;
mod consistency;
mod covariance;
mod loops;
mod recovery;
mod smoothing;

pub use config::{LaserGraphConfig, MatchCovariance, OdometryNoise, MAX_SUBMAP_SCANS};
pub use recovery::LocalRecovery;

use covariance::invert;

use crate::error::GraphError;
use slam_grid::{MaxPyramid, OccupancyGrid, RangeData};
use slam_models::{
    FilterError, GridMap, LaserScan, Matrix3, OdometryJumpGuard, Point2, Pose2, ScanRecord,
    ScanSlam, ScanUpdateInfo, TimedPose,
};
use std::collections::VecDeque;
use std::sync::Mutex;

/// A submap: an occupancy grid in the local frame built from consecutive keyframes.
#[derive(Debug, Clone)]
struct Submap {
    /// The grid while the submap is active; `None` once finished (the loop search rebuilds
    /// it from the keyframes' scans, [`LoopMap`]).
    grid: Option<OccupancyGrid>,
    /// Keyframe indices inserted, in order.
    keyframes: Vec<usize>,
    /// True once it receives no more scans.
    finished: bool,
    /// The loop search's sampler of this submap (`loop-sampling-ratio`).
    sampler: loops::Sampler,
}

/// A finished submap's grid, rebuilt from its keyframes' scans at their local poses (the
/// same insertions in the same order, so the same grid), and its loop-closure pyramid.
#[derive(Debug, Clone)]
struct LoopMap {
    submap: usize,
    /// `None` once the entry is no longer among the most recently used (rebuilt on a
    /// match).
    grid: Option<OccupancyGrid>,
    pyramid: MaxPyramid,
}

/// A keyframe: the record it came from, its scan and its poses.
#[derive(Debug, Clone)]
struct Keyframe {
    record: usize,
    /// The scan as recorded (8 bytes a beam, against about 50 prepared): prepared again
    /// ([`LaserGraphSlam::prepare`], the same [`RangeData`]) when a loop map or the map
    /// is rebuilt from it. The newest keyframe's prepared scan is `newest_scan`.
    scan: LaserScan,
    /// Pose in the local (scan-matching) frame.
    local: Pose2,
    /// Current estimate in the world frame (the optimised keyframe graph).
    global: Pose2,
    /// Distance travelled from the first keyframe, metres (along the local poses).
    path: f64,
}

/// One relative-pose constraint between two keyframes (indices), with its information.
#[derive(Debug, Clone, Copy)]
struct Constraint {
    from: usize,
    to: usize,
    /// The measured pose of `to` in the frame of `from`.
    z: Pose2,
    /// Information of `z` as (x, y, θ) with x, y in `from`'s frame (the frame the match's
    /// covariance was rotated into, and the one the consistency test composes in).
    information: Matrix3,
    loop_closure: bool,
}

impl Constraint {
    /// The information of the graph edge's error: g2o's `EDGE_SE2` error
    /// e = z⁻¹ ⊕ (x_from⁻¹ ⊕ x_to) has its translation in the frame of the measured `to`
    /// pose, e_t = R_zᵀ (R_fromᵀ (t_to − t_from) − z_t), so a covariance C of z_t in
    /// `from`'s frame is R_zᵀ C R_z there and the information R_zᵀ Ω R_z (R_z the rotation
    /// by z_θ, the identity on θ). Without it a closure from a keyframe heading the other
    /// way across a corridor has its weak direction turned by the keyframes' relative
    /// heading (90° at a junction: the corridor's axis taken for its firm direction).
    fn edge_information(&self) -> Matrix3 {
        let r = covariance::planar_rotation(self.z.theta);
        let m = r.transpose() * self.information * r;
        (m + m.transpose()) * 0.5
    }
}

/// Counters of what the front end did (diagnostics, not errors).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct LaserGraphStats {
    /// Keyframes processed (scans matched and inserted).
    pub keyframes: usize,
    /// Keyframes whose local match was rejected or failed (odometry used instead).
    pub local_match_failures: usize,
    /// Keyframes whose local match was replaced by the recovery's search over every
    /// heading ([`LocalRecovery`]).
    pub local_match_recovered: usize,
    /// Keyframes whose local match was degenerate along one direction and took the
    /// odometry along it (`degenerate-anisotropy`).
    pub degenerate_matches: usize,
    /// Branch-and-bound loop-closure searches run.
    pub loop_searches: usize,
    /// Of those, wide searches (the whole window, beyond `loop-wide-radius` or
    /// `loop-wide-angle`, after a narrow search of the same submap found nothing).
    pub loop_wide_searches: usize,
    /// Loop-closure matches rejected as ambiguous (`loop-ambiguity-ratio`).
    pub loop_ambiguous: usize,
    /// Loop-closure matches rejected because their score surface is flat along one
    /// direction (`loop-max-anisotropy`).
    pub loop_flat: usize,
    /// Groups of candidate closures checked for mutual consistency.
    pub loop_groups: usize,
    /// Candidate closures the consistency check rejected (outside the dominant cluster, or
    /// in a group without a clearly dominant one).
    pub loop_inconsistent: usize,
    /// Loop closures accepted (edges added).
    pub loop_closures: usize,
    /// Optimisations of the keyframe graph.
    pub optimizations: usize,
}

/// Pose-graph SLAM from odometry and laser scans; see the module documentation.
///
/// # Example
///
/// ```
/// use slam_graph::laser::{LaserGraphConfig, LaserGraphSlam};
/// use slam_models::{Pose2, ScanRecord, ScanSlam};
///
/// let mut slam = LaserGraphSlam::new(LaserGraphConfig::default(), Pose2::IDENTITY, 0).unwrap();
/// slam.process(&ScanRecord { t: 0.0, odometry: Pose2::IDENTITY, scan: None }).unwrap();
/// assert_eq!(slam.trajectory().len(), 1);
/// ```
#[derive(Debug)]
pub struct LaserGraphSlam {
    config: LaserGraphConfig,
    /// The pose of the odometry frame in the world (the constructor's `initial_pose`).
    frame: Pose2,
    guard: OdometryJumpGuard,
    times: Vec<f64>,
    odometry: Vec<Pose2>,
    keyframes: Vec<Keyframe>,
    /// For every record, the index of the last keyframe at or before it.
    last_keyframe_at: Vec<Option<usize>>,
    submaps: Vec<Submap>,
    /// Indices of the active submaps, oldest first (at most two).
    active: Vec<usize>,
    constraints: Vec<Constraint>,
    /// Candidate loop closures of the group being collected, not yet in the graph.
    pending: Vec<Constraint>,
    /// Keyframes of the group's first and last candidate.
    pending_span: (usize, usize),
    /// Finished submaps' grids and pyramids for loop closure, most recently used last.
    loop_maps: VecDeque<LoopMap>,
    /// The keyframe of the last wide loop search (the per-scan budget).
    last_wide_search: Option<usize>,
    /// The newest keyframe's prepared scan, the one its loop search matches.
    newest_scan: Option<RangeData>,
    stats: LaserGraphStats,
    /// The smoothed trajectory and the number of records it covers.
    smoothed: Mutex<Option<(usize, Vec<Pose2>)>>,
}

impl Clone for LaserGraphSlam {
    fn clone(&self) -> Self {
        Self {
            config: self.config.clone(),
            frame: self.frame,
            guard: self.guard.clone(),
            times: self.times.clone(),
            odometry: self.odometry.clone(),
            keyframes: self.keyframes.clone(),
            last_keyframe_at: self.last_keyframe_at.clone(),
            submaps: self.submaps.clone(),
            active: self.active.clone(),
            constraints: self.constraints.clone(),
            pending: self.pending.clone(),
            pending_span: self.pending_span,
            loop_maps: self.loop_maps.clone(),
            last_wide_search: self.last_wide_search,
            newest_scan: self.newest_scan.clone(),
            stats: self.stats,
            smoothed: Mutex::new(self.smoothed.lock().map(|s| s.clone()).unwrap_or(None)),
        }
    }
}

impl LaserGraphSlam {
    /// A front end with no data yet, in the one constructor shape of every filter
    /// ([`slam_models::FromConfig`]); rejects an invalid configuration (the error names the
    /// field and its bound).
    ///
    /// `initial_pose` is the pose of the odometry frame in the world, as for grid FastSLAM:
    /// every odometry reading o is taken as the world pose `initial_pose ⊕ o`, so the map
    /// and the trajectory are in the world frame (relative increments, and with them every
    /// edge, do not change under that rigid motion). `seed` is taken for uniformity and
    /// ignored: the front end draws no random numbers.
    pub fn new(
        config: LaserGraphConfig,
        initial_pose: Pose2,
        seed: u64,
    ) -> Result<Self, GraphError> {
        let _ = seed;
        if !initial_pose.is_finite() {
            return Err(slam_models::ConfigError::new(
                "laser graph",
                "initial_pose",
                format!(
                    "({}, {}, {})",
                    initial_pose.x, initial_pose.y, initial_pose.theta
                ),
                "a finite pose",
            )
            .into());
        }
        config.validate()?;
        let guard = OdometryJumpGuard::new(config.odometry_jump)?;
        Ok(Self {
            config,
            frame: initial_pose,
            guard,
            times: Vec::new(),
            odometry: Vec::new(),
            keyframes: Vec::new(),
            last_keyframe_at: Vec::new(),
            submaps: Vec::new(),
            active: Vec::new(),
            constraints: Vec::new(),
            pending: Vec::new(),
            pending_span: (0, 0),
            loop_maps: VecDeque::new(),
            last_wide_search: None,
            newest_scan: None,
            stats: LaserGraphStats::default(),
            smoothed: Mutex::new(None),
        })
    }

    /// The configuration.
    pub fn config(&self) -> &LaserGraphConfig {
        &self.config
    }

    /// What the front end did so far.
    pub fn stats(&self) -> LaserGraphStats {
        self.stats
    }

    /// The keyframes' optimised world poses and their record indices, in order.
    pub fn keyframe_poses(&self) -> Vec<(usize, Pose2)> {
        self.keyframes
            .iter()
            .map(|k| (k.record, k.global))
            .collect()
    }

    /// The accepted loop closures: (earlier record, later record, measured pose of the
    /// later in the frame of the earlier), for checks against ground truth.
    pub fn loop_closures(&self) -> Vec<(usize, usize, Pose2)> {
        self.constraints
            .iter()
            .filter(|c| c.loop_closure)
            .map(|c| {
                (
                    self.keyframes[c.from].record,
                    self.keyframes[c.to].record,
                    c.z,
                )
            })
            .collect()
    }

    /// Candidate loop closures waiting for the group test (they enter the graph, or not,
    /// when the group is complete or at [`finish_run`](Self::finish_run)).
    pub fn pending_closures(&self) -> usize {
        self.pending.len()
    }

    /// Processes one record (see the module documentation).
    pub fn step(&mut self, record: &ScanRecord) -> Result<ScanUpdateInfo, GraphError> {
        if !record.odometry.is_finite() || !record.t.is_finite() {
            return Err(GraphError::NonFinite {
                what: "record odometry or time",
                value: f64::NAN,
            });
        }
        // Prepare the scan before anything changes, so that a bad scan leaves the state as
        // it was.
        let prepared = match &record.scan {
            Some(s) => Some(self.prepare(s)?),
            None => None,
        };
        let (odometry, skipped) = self.guard.check(&record.odometry)?;
        let odometry = self.frame.compose(&odometry);
        let mut info = ScanUpdateInfo {
            odometry_jumps_skipped: skipped as usize,
            ..ScanUpdateInfo::default()
        };
        let i = self.times.len();
        self.times.push(record.t);
        self.odometry.push(odometry);
        let last = self.keyframes.len().checked_sub(1);
        self.last_keyframe_at.push(last);
        if let (Some(scan), Some(raw)) = (prepared, &record.scan) {
            let due = match last {
                None => true,
                Some(k) => {
                    let d = self.odometry[self.keyframes[k].record].between(&odometry);
                    d.translation().coords.norm() >= self.config.keyframe_distance
                        || d.theta.abs() >= self.config.keyframe_angle
                }
            };
            if due {
                match self.add_keyframe(i, raw.clone(), scan, &mut info) {
                    Ok(()) => {}
                    Err(e) => {
                        // Leave the record as an odometry-only one.
                        self.times.pop();
                        self.odometry.pop();
                        self.last_keyframe_at.pop();
                        return Err(e);
                    }
                }
                *self.last_keyframe_at.last_mut().expect("pushed above") =
                    Some(self.keyframes.len() - 1);
                info.processed_scan = true;
            }
        }
        Ok(info)
    }

    /// Matches, inserts and links a new keyframe at record `i`; then searches for loops.
    fn add_keyframe(
        &mut self,
        i: usize,
        raw: LaserScan,
        scan: RangeData,
        info: &mut ScanUpdateInfo,
    ) -> Result<(), GraphError> {
        let odometry = self.odometry[i];
        let k = self.keyframes.len();
        let previous = self
            .keyframes
            .last()
            .map(|p| (p.record, p.local, p.global, p.path));
        let (local, global, since, edge) = match previous {
            None => (odometry, odometry, 0.0, None),
            Some((prev_record, prev_local, prev_global, prev_since)) => {
                let delta = self.odometry[prev_record].between(&odometry);
                let predicted = prev_local.compose(&delta);
                let matched = self.local_match(&scan, &predicted, &delta);
                let (local, z, information) = match matched {
                    Some((pose, cov)) => {
                        let information = self.match_information(&cov, prev_local.theta);
                        let z = prev_local.between(&pose);
                        let fused =
                            self.degenerate_edge(&z, &information, &delta, (prev_record, i));
                        match fused {
                            // The submaps keep the match's pose; the graph gets the
                            // fused edge.
                            Some((fz, information)) => {
                                self.stats.degenerate_matches += 1;
                                (pose, fz, information)
                            }
                            None => (pose, z, information),
                        }
                    }
                    None => {
                        self.stats.local_match_failures += 1;
                        info.match_failures = 1;
                        let cov = self.odometry_chain_covariance(prev_record, i);
                        (predicted, prev_local.between(&predicted), invert(&cov))
                    }
                };
                let global = prev_global.compose(&z);
                let since = prev_since + z.translation().coords.norm();
                (
                    local,
                    global,
                    since,
                    Some(Constraint {
                        from: k - 1,
                        to: k,
                        z,
                        information,
                        loop_closure: false,
                    }),
                )
            }
        };
        // Insert into the active submaps (growing them first is what can fail).
        self.insert_into_submaps(k, &local, &scan)?;
        self.keyframes.push(Keyframe {
            record: i,
            scan: raw,
            local,
            global,
            path: since,
        });
        if let Some(c) = edge {
            self.constraints.push(c);
        }
        self.newest_scan = Some(scan);
        self.stats.keyframes += 1;
        if self.config.loop_max_candidates > 0 {
            self.search_loops(k)?;
            if self.settle_group(k, false) {
                self.optimize_keyframes()?;
            }
        }
        Ok(())
    }

    /// Local scan-to-submap match from `predicted`: pose and covariance, or `None` when
    /// there is no submap yet, the match failed or scored below `local-min-score`. A
    /// keyframe whose odometry `delta` since the previous keyframe turned by at least
    /// `local-recovery.turn`, or whose match failed, is searched over every heading as
    /// well ([`LocalRecovery`]), and the better match taken.
    fn local_match(
        &mut self,
        scan: &RangeData,
        predicted: &Pose2,
        delta: &Pose2,
    ) -> Option<(Pose2, Matrix3)> {
        let &oldest = self.active.first()?;
        let grid = self.submaps[oldest].grid.as_ref()?;
        let local = self
            .config
            .local_matcher
            .match_prepared(grid, scan, predicted)
            .ok();
        let recovered = self.recover_local_match(grid, scan, predicted, delta, local.as_ref());
        let was_recovered = recovered.is_some();
        let m = recovered.or(local.filter(|m| m.score >= self.config.local_min_score))?;
        let covariance = self.match_covariance(grid, scan, &m.pose, m.covariance);
        self.stats.local_match_recovered += usize::from(was_recovered);
        Some((m.pose, covariance))
    }

    /// Inserts keyframe `k`'s scan into the active submaps, starting and finishing submaps
    /// as the module documentation describes.
    fn insert_into_submaps(
        &mut self,
        k: usize,
        local: &Pose2,
        scan: &RangeData,
    ) -> Result<(), GraphError> {
        let n = self.config.submap_scans;
        let start_new = match self.active.last() {
            None => true,
            Some(&s) => self.submaps[s].keyframes.len() >= n / 2 && self.active.len() < 2,
        };
        if start_new {
            self.submaps.push(Submap {
                grid: Some(self.empty_submap_grid()?),
                keyframes: Vec::new(),
                finished: false,
                sampler: loops::Sampler::default(),
            });
            self.active.push(self.submaps.len() - 1);
        }
        // Integrate into copies first so that an error leaves every submap as it was.
        let mut updated = Vec::with_capacity(self.active.len());
        for &s in &self.active {
            let mut g = match &self.submaps[s].grid {
                Some(g) => g.clone(),
                None => self.empty_submap_grid()?,
            };
            g.try_integrate_prepared(local, scan)?;
            updated.push(g);
        }
        for (&s, g) in self.active.iter().zip(updated) {
            self.submaps[s].grid = Some(g);
            self.submaps[s].keyframes.push(k);
        }
        if let Some(&oldest) = self.active.first() {
            if self.submaps[oldest].keyframes.len() >= n {
                self.submaps[oldest].finished = true;
                // Its grid is rebuilt when a loop search needs it: memory stays bounded by
                // the loop-map cache instead of growing with every submap.
                self.submaps[oldest].grid = None;
                self.active.remove(0);
            }
        }
        Ok(())
    }

    /// An empty submap grid (the configured resolution, sensor model and likelihood).
    fn empty_submap_grid(&self) -> Result<OccupancyGrid, GraphError> {
        Ok(
            OccupancyGrid::try_new(self.config.resolution, self.config.sensor_model)?
                .with_likelihood(self.config.likelihood)?,
        )
    }
}

slam_models::from_config_by_new!(LaserGraphSlam, LaserGraphConfig, GraphError);

impl ScanSlam for LaserGraphSlam {
    fn name(&self) -> &str {
        "graph"
    }

    fn process(&mut self, record: &ScanRecord) -> Result<ScanUpdateInfo, FilterError> {
        self.step(record).map_err(FilterError::other)
    }

    fn finish(&mut self) -> Result<(), FilterError> {
        self.finish_run().map_err(FilterError::other)
    }

    fn pose(&self) -> Pose2 {
        match self.last_keyframe_at.last() {
            Some(Some(k)) => {
                let kf = &self.keyframes[*k];
                let o = self.odometry.last().expect("a record exists");
                kf.global.compose(&self.odometry[kf.record].between(o))
            }
            Some(None) => *self.odometry.last().expect("a record exists"),
            None => Pose2::IDENTITY,
        }
    }

    fn trajectory(&self) -> Vec<TimedPose> {
        self.smoothed_poses()
            .into_iter()
            .zip(&self.times)
            .map(|(pose, &t)| TimedPose { t, pose })
            .collect()
    }

    fn map(&self) -> GridMap {
        self.render(self.config.resolution)
            .unwrap_or_else(|_| GridMap::unknown(self.config.resolution, Point2::origin(), 0, 0))
    }

    fn render_map(&self, resolution: f64) -> Option<Result<GridMap, FilterError>> {
        if !(resolution > 0.0 && resolution.is_finite()) {
            return None;
        }
        self.render(resolution).ok().map(Ok)
    }
}

#[cfg(test)]
mod tests;
