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
//!   `match-min-std`): in a corridor it is large along the axis, so there the odometry
//!   keeps its weight instead of being overruled by a match that knows nothing of it.
//! * **Loop closure**: a finished submap (its last scan at least `loop-min-scan-gap`
//!   keyframes old) whose keyframes lie within reach of the keyframe's global position is
//!   searched with slam-grid's [`BranchBoundMatcher`] over a [`MaxPyramid`] of the submap,
//!   around the pose the current graph predicts; the radius and the rotation window grow
//!   linearly with the path length between the submap and the keyframe (the uncertainty
//!   of their relative pose before the closure), up to their caps. A match scoring at
//!   least `loop-min-score`, and not matched almost as well 0.25–1 m away
//!   (`loop-ambiguity-ratio`), is refined by Gauss-Newton and becomes an edge from the
//!   submap's keyframe nearest to the match. Finished submaps keep no grid: the search
//!   rebuilds one from its keyframes' scans (the same insertions, so the same grid) and
//!   keeps it with its pyramid in a small cache (`loop-pyramid-cache`), so memory does not
//!   grow with the number of submaps. After every keyframe that added a closure the
//!   keyframe graph is optimised (Levenberg-Marquardt with the configured robust kernel,
//!   DCS by default, against false closures).
//! * **Poses at every record**: the odometry is a measurement, not only a prediction. The
//!   trajectory comes from a second graph with **one node per record**: consecutive records
//!   are joined by odometry edges (increment o_{i−1}⁻¹ ⊕ o_i, covariance from
//!   [`OdometryNoise`]), keyframes additionally by the scan-matching and loop-closure
//!   edges above. It is initialised from the optimised keyframes and the odometry between
//!   them and optimised as a whole (without a robust kernel; loop closures the keyframe
//!   graph's kernel rejected are left out), so the correction a scan match makes is
//!   distributed over the records before it in proportion to their odometry uncertainty
//!   (a smoother), instead of being applied at the keyframe only.
//! * **The map** is rendered from the keyframes' scans at their smoothed poses.
//!
//! The world frame is the odometry frame placed at the constructor's `initial_pose` (the
//! identity: the odometry frame itself), and the first record's pose is its odometry
//! reading in that frame. Everything is deterministic: no random numbers are drawn.

pub mod config;
mod consistency;
mod covariance;

pub use config::{LaserGraphConfig, MatchCovariance, OdometryNoise, MAX_SUBMAP_SCANS};

use crate::error::GraphError;
use crate::graph::PoseGraph;
use crate::optimizer::Optimizer;
use slam_grid::{BranchBoundMatcher, MaxPyramid, OccupancyGrid, RangeData};
use slam_models::{
    normalize_angle, FilterError, GridMap, Matrix3, OdometryJumpGuard, Point2, Pose2, ScanRecord,
    ScanSlam, ScanUpdateInfo, TimedPose,
};
use std::cmp::Reverse;
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
}

/// A finished submap's grid, rebuilt from its keyframes' scans at their local poses (the
/// same insertions in the same order, so the same grid), and its loop-closure pyramid.
#[derive(Debug, Clone)]
struct LoopMap {
    submap: usize,
    grid: OccupancyGrid,
    pyramid: MaxPyramid,
}

/// A keyframe: the record it came from, its prepared scan and its poses.
#[derive(Debug, Clone)]
struct Keyframe {
    record: usize,
    scan: RangeData,
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
    z: Pose2,
    information: Matrix3,
    loop_closure: bool,
}

/// Counters of what the front end did (diagnostics, not errors).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct LaserGraphStats {
    /// Keyframes processed (scans matched and inserted).
    pub keyframes: usize,
    /// Keyframes whose local match was rejected or failed (odometry used instead).
    pub local_match_failures: usize,
    /// Branch-and-bound loop-closure searches run.
    pub loop_searches: usize,
    /// Of those, wide searches (radius above `loop-wide-radius`, at most one per
    /// `loop-wide-interval` keyframes).
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
            Some(s) => Some(RangeData::with_limits(
                s,
                &self.config.sensor_model,
                0.0,
                self.config.match_max_range,
            )?),
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
        if let Some(scan) = prepared {
            let due = match last {
                None => true,
                Some(k) => {
                    let d = self.odometry[self.keyframes[k].record].between(&odometry);
                    d.translation().coords.norm() >= self.config.keyframe_distance
                        || d.theta.abs() >= self.config.keyframe_angle
                }
            };
            if due {
                match self.add_keyframe(i, scan, &mut info) {
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
                let (local, information) = match self.local_match(&scan, &predicted) {
                    Some((pose, cov)) => (pose, self.match_information(&cov, prev_local.theta)),
                    None => {
                        self.stats.local_match_failures += 1;
                        info.match_failures = 1;
                        let cov = self.odometry_chain_covariance(prev_record, i);
                        (predicted, invert(&cov))
                    }
                };
                let z = prev_local.between(&local);
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
            scan,
            local,
            global,
            path: since,
        });
        if let Some(c) = edge {
            self.constraints.push(c);
        }
        self.stats.keyframes += 1;
        if self.config.loop_max_candidates > 0 {
            self.search_loops(k)?;
            if self.settle_group(k, false) {
                self.optimize_keyframes()?;
            }
        }
        Ok(())
    }

    /// Once the pending group of candidate closures is complete (`loop-group-span`
    /// keyframes since its first candidate, or `loop-group-gap` keyframes without one),
    /// or at once when `now`), checks it for mutual consistency
    /// ([`consistency::dominant_group`]) and adds the dominant cluster's closures to the
    /// graph; true when some were added.
    fn settle_group(&mut self, k: usize, now: bool) -> bool {
        let c = &self.config;
        let (first, last) = self.pending_span;
        if self.pending.is_empty()
            || (!now && k < first + c.loop_group_span && k < last + c.loop_group_gap)
        {
            return false;
        }
        let hyps: Vec<consistency::Hypothesis> = self
            .pending
            .iter()
            .map(|p| {
                let (a, b) = (&self.keyframes[p.from], &self.keyframes[p.to]);
                consistency::Hypothesis {
                    z: p.z,
                    covariance: invert(&p.information),
                    a: a.local,
                    b: b.local,
                    a_path: a.path,
                    b_path: b.path,
                }
            })
            .collect();
        let test = consistency::GroupTest {
            drift: c.loop_group_drift,
            min_size: c.loop_group_min_size,
            min_ratio: c.loop_group_min_ratio,
        };
        let decision = consistency::dominant_group(&hyps, &test);
        let pending = std::mem::take(&mut self.pending);
        self.stats.loop_groups += 1;
        self.stats.loop_inconsistent += pending.len() - decision.accepted.len();
        self.stats.loop_closures += decision.accepted.len();
        for &i in &decision.accepted {
            self.constraints.push(pending[i]);
        }
        !decision.accepted.is_empty()
    }

    /// True when the response of `scan` on `grid` around `pose` is flat along one
    /// direction: the translational block of its sampled covariance
    /// ([`covariance::response_covariance`]) has σ_max / σ_min above `loop-max-anisotropy`.
    fn flat_match(&self, grid: &OccupancyGrid, scan: &RangeData, pose: &Pose2) -> bool {
        let sampling = match self.config.match_covariance {
            MatchCovariance::Response {
                linear_window,
                angular_window,
                temperature,
            } => covariance::ResponseSampling {
                linear_window,
                angular_window,
                temperature,
            },
            MatchCovariance::Matcher => covariance::ResponseSampling {
                linear_window: 0.3,
                angular_window: 0.03,
                temperature: 10.0,
            },
        };
        let Some(cov) = covariance::response_covariance(grid, scan, pose, &sampling) else {
            return true;
        };
        let (a, b, d) = (cov[(0, 0)], cov[(0, 1)], cov[(1, 1)]);
        // Eigenvalues of the 2 × 2 block [[a, b], [b, d]].
        let mean = 0.5 * (a + d);
        let r = (0.25 * (a - d) * (a - d) + b * b).sqrt();
        let (hi, lo) = (mean + r, (mean - r).max(f64::MIN_POSITIVE));
        (hi / lo).sqrt() > self.config.loop_max_anisotropy
    }

    /// Local scan-to-submap match from `predicted`: pose and covariance, or `None` when
    /// there is no submap yet, the match failed or scored below `local-min-score`.
    fn local_match(&self, scan: &RangeData, predicted: &Pose2) -> Option<(Pose2, Matrix3)> {
        let &oldest = self.active.first()?;
        let grid = self.submaps[oldest].grid.as_ref()?;
        match self
            .config
            .local_matcher
            .match_prepared(grid, scan, predicted)
        {
            Ok(m) if m.score >= self.config.local_min_score => Some((
                m.pose,
                self.match_covariance(grid, scan, &m.pose, m.covariance),
            )),
            _ => None,
        }
    }

    /// The covariance of a match at `pose` on `grid` ([`MatchCovariance`]), `matcher`'s
    /// own when so configured or when the sampling has nothing to sample.
    fn match_covariance(
        &self,
        grid: &OccupancyGrid,
        scan: &RangeData,
        pose: &Pose2,
        matcher: Matrix3,
    ) -> Matrix3 {
        match self.config.match_covariance {
            MatchCovariance::Matcher => matcher,
            MatchCovariance::Response {
                linear_window,
                angular_window,
                temperature,
            } => {
                let sampling = covariance::ResponseSampling {
                    linear_window,
                    angular_window,
                    temperature,
                };
                covariance::response_covariance(grid, scan, pose, &sampling).unwrap_or(matcher)
            }
        }
    }

    /// Information of a match whose world-frame covariance is `cov`, expressed in the frame
    /// of a pose with heading `theta` (the edge's), with the `match-min-std` floor.
    fn match_information(&self, cov: &Matrix3, theta: f64) -> Matrix3 {
        let (s, c) = theta.sin_cos();
        let r = Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0);
        let mut local = r.transpose() * cov * r * self.config.match_covariance_scale;
        let [sxy, sth] = self.config.match_min_std;
        local[(0, 0)] += sxy * sxy;
        local[(1, 1)] += sxy * sxy;
        local[(2, 2)] += sth * sth;
        invert(&local)
    }

    /// Covariance of one odometry increment ([`OdometryNoise`]), in the earlier record's
    /// frame.
    fn odometry_covariance(&self, delta: &Pose2) -> Matrix3 {
        let n = &self.config.odometry_noise;
        let d = delta.translation().coords.norm();
        let a = normalize_angle(delta.theta).abs();
        let st = n.translation_per_metre * d + n.translation_per_radian * a + n.min_translation;
        let sr = n.rotation_per_radian * a + n.rotation_per_metre * d + n.min_rotation;
        Matrix3::from_diagonal(&slam_models::Vector3::new(st * st, st * st, sr * sr))
    }

    /// Covariance of the composed odometry from record `a` to record `b` (first order,
    /// in `a`'s frame): Σ ← J₁ Σ J₁ᵀ + J₂ Σᵢ J₂ᵀ along the chain.
    fn odometry_chain_covariance(&self, a: usize, b: usize) -> Matrix3 {
        let mut acc = Pose2::IDENTITY;
        let mut cov = Matrix3::zeros();
        for j in a + 1..=b {
            let delta = self.odometry[j - 1].between(&self.odometry[j]);
            let (j1, j2) = acc.compose_jacobians(&delta);
            cov =
                j1 * cov * j1.transpose() + j2 * self.odometry_covariance(&delta) * j2.transpose();
            acc = acc.compose(&delta);
        }
        if a == b {
            cov = self.odometry_covariance(&Pose2::IDENTITY);
        }
        (cov + cov.transpose()) * 0.5
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

    /// Searches finished submaps for loop closures of keyframe `k` and adds the matches to
    /// the pending group (`settle_group` decides which enter the graph); true when one was
    /// found.
    fn search_loops(&mut self, k: usize) -> Result<bool, GraphError> {
        let distances = self.graph_distances(k);
        let c = &self.config;
        let kf = &self.keyframes[k];
        let position = kf.global.translation();
        // Candidates: finished submaps old enough whose nearest keyframe lies within the
        // submap's search window (plus half the matching range) of the predicted position.
        let mut candidates: Vec<(f64, usize, f64, f64)> = Vec::new();
        for (s, submap) in self.submaps.iter().enumerate() {
            let Some(&last) = submap.keyframes.last() else {
                continue;
            };
            if !submap.finished || last + c.loop_min_scan_gap > k {
                continue;
            }
            let nearest = submap
                .keyframes
                .iter()
                .map(|&j| (self.keyframes[j].global.translation() - position).norm())
                .fold(f64::INFINITY, f64::min);
            // The window grows with the graph distance between the submap and keyframe k:
            // the uncertainty of their relative pose before this closure (metres of the
            // scan-matching chain, closures counting nothing).
            let d = submap
                .keyframes
                .iter()
                .map(|&j| distances[j])
                .fold(f64::INFINITY, f64::min);
            let (radius, angle) = loop_window(c, d);
            // The scan overlaps the submap when some of its keyframes is within the
            // matching range (plus the search radius) of the predicted position.
            if nearest <= radius + 0.5 * c.match_max_range {
                candidates.push((nearest, s, radius, angle));
            }
        }
        candidates.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        // The per-keyframe budget: at most `loop-max-candidates` searches, nearest first,
        // of which at most one wide one (radius above `loop-wide-radius`), and that only
        // once every `loop-wide-interval` keyframes.
        let mut wide_left = match self.last_wide_search {
            Some(w) if k < w + c.loop_wide_interval => 0,
            _ => 1,
        };
        let mut searched = 0;
        let mut found = false;
        for (_, s, radius, angle) in candidates {
            let c = &self.config;
            if searched >= c.loop_max_candidates {
                break;
            }
            if radius > c.loop_wide_radius {
                if wide_left == 0 {
                    continue;
                }
                wide_left -= 1;
                self.last_wide_search = Some(k);
                self.stats.loop_wide_searches += 1;
            }
            searched += 1;
            let matcher = BranchBoundMatcher {
                linear_window: radius,
                angular_window: angle,
                angular_step: 0.0,
                depth: c.loop_depth,
                min_score: c.loop_min_score,
                min_points: c.local_matcher.correlative.min_points,
            };
            let anchor = self.submaps[s].keyframes[0];
            let (a_local, a_global) = (self.keyframes[anchor].local, self.keyframes[anchor].global);
            // Keyframe k in the submap's (local) frame, as the current graph predicts it.
            let predicted = a_local.compose(&a_global.between(&self.keyframes[k].global));
            if !self.cache_loop_map(s)? {
                continue;
            }
            self.stats.loop_searches += 1;
            let loop_map = self.loop_maps.back().expect("cached above");
            let pyramid = &loop_map.pyramid;
            let scan = &self.keyframes[k].scan;
            let hit = match matcher.match_in(pyramid, scan, &predicted) {
                Ok(Some(m)) => m,
                Ok(None) | Err(_) => continue,
            };
            if self.config.loop_ambiguity_ratio < 1.0
                && self.ambiguous(pyramid, scan, &hit.pose, hit.score)
            {
                self.stats.loop_ambiguous += 1;
                continue;
            }
            // Sub-cell refinement on the submap itself; kept only if it stays close.
            let grid = &loop_map.grid;
            let refine = &self.config.local_matcher.refine;
            let m = match refine.match_prepared(grid, scan, &hit.pose) {
                Ok(f) if f.pose.distance(&hit.pose) <= 2.0 * self.config.resolution => f,
                _ => hit,
            };
            if self.flat_match(grid, scan, &m.pose) {
                self.stats.loop_flat += 1;
                continue;
            }
            // The edge starts at the submap's keyframe nearest to the match: the submap is
            // exact relative to its own keyframes' local poses only up to its internal
            // drift, which grows with the distance along it.
            let from = self.submaps[s]
                .keyframes
                .iter()
                .copied()
                .min_by(|&a, &b| {
                    let da = self.keyframes[a].local.distance(&m.pose);
                    let db = self.keyframes[b].local.distance(&m.pose);
                    da.total_cmp(&db).then(a.cmp(&b))
                })
                .unwrap_or(anchor);
            let from_local = self.keyframes[from].local;
            let z = from_local.between(&m.pose);
            // The matcher's own covariance: on the office the response's made the
            // closures slightly worse (docs/results/graph.md).
            let information = self.match_information(&m.covariance, from_local.theta);
            if self.pending.is_empty() {
                self.pending_span.0 = k;
            }
            self.pending_span.1 = k;
            self.pending.push(Constraint {
                from,
                to: k,
                z,
                information,
                loop_closure: true,
            });
            found = true;
        }
        Ok(found)
    }

    /// Ends the run: the pending group of candidate closures (collected over fewer than
    /// `loop-group-span` keyframes when the data ended) is checked and its consistent
    /// closures enter the graph, which is then optimised, instead of being dropped.
    /// Records may still follow (the group is simply settled early).
    pub fn finish_run(&mut self) -> Result<(), GraphError> {
        let Some(k) = self.keyframes.len().checked_sub(1) else {
            return Ok(());
        };
        if self.settle_group(k, true) {
            self.optimize_keyframes()?;
        }
        Ok(())
    }

    /// The graph distance of every keyframe from keyframe `k`, metres (Dijkstra over the
    /// keyframe graph): a scan-matching or odometry edge costs the path its ends are apart,
    /// a loop closure nothing. The shortest such path is the chain of local matches whose
    /// drift the relative pose of the two keyframes still carries: it is the path since
    /// the closures that last joined their neighbourhoods. Unreachable keyframes (none
    /// in a connected graph) are at infinity.
    fn graph_distances(&self, k: usize) -> Vec<f64> {
        let n = self.keyframes.len();
        let mut adjacent: Vec<Vec<(usize, f64)>> = vec![Vec::new(); n];
        for c in self.constraints.iter().chain(&self.pending) {
            if c.from >= n || c.to >= n {
                continue;
            }
            let w = if c.loop_closure {
                0.0
            } else {
                (self.keyframes[c.to].path - self.keyframes[c.from].path).abs()
            };
            adjacent[c.from].push((c.to, w));
            adjacent[c.to].push((c.from, w));
        }
        let mut distance = vec![f64::INFINITY; n];
        let mut heap = std::collections::BinaryHeap::new();
        if k < n {
            distance[k] = 0.0;
            heap.push(Reverse(Ordered(0.0, k)));
        }
        while let Some(Reverse(Ordered(d, i))) = heap.pop() {
            if d > distance[i] {
                continue;
            }
            for &(j, w) in &adjacent[i] {
                let e = d + w;
                if e < distance[j] {
                    distance[j] = e;
                    heap.push(Reverse(Ordered(e, j)));
                }
            }
        }
        distance
    }

    /// True when some pose 0.25 m, 0.5 m or 1 m away from `best` (8 directions, each
    /// followed by a small branch-and-bound search of ±0.1 m, ±0.2 m, ±0.2 m and
    /// ±0.05 rad) scores at least
    /// `loop-ambiguity-ratio` × `score`: the match is not unique.
    fn ambiguous(&self, pyramid: &MaxPyramid, scan: &RangeData, best: &Pose2, score: f64) -> bool {
        let bar = self.config.loop_ambiguity_ratio * score;
        let local = BranchBoundMatcher {
            linear_window: 0.2,
            angular_window: 0.05,
            angular_step: 0.0,
            depth: 3.min(pyramid.depth()),
            min_score: bar.clamp(0.0, 1.0),
            min_points: 1,
        };
        for (d, window) in [(0.25, 0.1), (0.5, 0.2), (1.0, 0.2)] {
            let local = BranchBoundMatcher {
                linear_window: window,
                ..local
            };
            for k in 0..8 {
                let a = k as f64 * std::f64::consts::FRAC_PI_4;
                let shifted = Pose2::new(best.x + d * a.cos(), best.y + d * a.sin(), best.theta);
                if let Ok(Some(_)) = local.match_in(pyramid, scan, &shifted) {
                    return true;
                }
            }
        }
        false
    }

    /// An empty submap grid (the configured resolution, sensor model and likelihood).
    fn empty_submap_grid(&self) -> Result<OccupancyGrid, GraphError> {
        Ok(
            OccupancyGrid::try_new(self.config.resolution, self.config.sensor_model)?
                .with_likelihood(self.config.likelihood)?,
        )
    }

    /// Puts finished submap `s`'s grid and loop-closure pyramid at the back of the cache,
    /// rebuilding them from its keyframes' scans if needed (the least recently used entry
    /// is dropped beyond `loop-pyramid-cache`); false for an empty submap.
    fn cache_loop_map(&mut self, s: usize) -> Result<bool, GraphError> {
        if let Some(pos) = self.loop_maps.iter().position(|m| m.submap == s) {
            let entry = self.loop_maps.remove(pos).expect("position is valid");
            self.loop_maps.push_back(entry);
            return Ok(true);
        }
        let mut grid = self.empty_submap_grid()?;
        for &k in &self.submaps[s].keyframes {
            let kf = &self.keyframes[k];
            grid.try_integrate_prepared(&kf.local, &kf.scan)?;
        }
        let Some(pyramid) = loop_pyramid(&grid, self.config.loop_depth)? else {
            return Ok(false);
        };
        if self.loop_maps.len() >= self.config.loop_pyramid_cache {
            self.loop_maps.pop_front();
        }
        self.loop_maps.push_back(LoopMap {
            submap: s,
            grid,
            pyramid,
        });
        Ok(true)
    }

    /// Optimises the keyframe graph (first keyframe held) and writes the poses back.
    fn optimize_keyframes(&mut self) -> Result<(), GraphError> {
        let mut graph = PoseGraph::new();
        for (k, kf) in self.keyframes.iter().enumerate() {
            graph.add_pose(k as u64, kf.global)?;
        }
        graph.fix(0)?;
        for c in &self.constraints {
            graph.add_between(c.from as u64, c.to as u64, c.z, c.information)?;
        }
        let mut opt = Optimizer::new(&graph, self.config.optimizer)?;
        opt.optimize(&mut graph)?;
        for (kf, p) in self.keyframes.iter_mut().zip(graph.poses()) {
            kf.global = p;
        }
        self.stats.optimizations += 1;
        // The smoothed trajectory (cached per record count) no longer holds.
        if let Ok(cached) = self.smoothed.get_mut() {
            *cached = None;
        }
        Ok(())
    }

    /// The pose of every record before smoothing: the last keyframe's optimised pose
    /// composed with the odometry since (the odometry itself before the first keyframe).
    fn composed_poses(&self) -> Vec<Pose2> {
        (0..self.times.len())
            .map(|i| match self.last_keyframe_at[i] {
                Some(k) => {
                    let kf = &self.keyframes[k];
                    kf.global
                        .compose(&self.odometry[kf.record].between(&self.odometry[i]))
                }
                None => self.odometry[i],
            })
            .collect()
    }

    /// The smoothed pose of every record: the graph of one node per record described in the
    /// module documentation, optimised from the composed poses. Falls back to the
    /// composed poses if the optimiser fails (it cannot on a connected chain with positive
    /// definite information, but the trait's accessors cannot return errors).
    pub fn smoothed_poses(&self) -> Vec<Pose2> {
        let n = self.times.len();
        if let Ok(guard) = self.smoothed.lock() {
            if let Some((m, poses)) = guard.as_ref() {
                if *m == n {
                    return poses.clone();
                }
            }
        }
        let initial = self.composed_poses();
        let poses = self.smooth(&initial).unwrap_or(initial);
        if let Ok(mut guard) = self.smoothed.lock() {
            *guard = Some((n, poses.clone()));
        }
        poses
    }

    fn smooth(&self, initial: &[Pose2]) -> Result<Vec<Pose2>, GraphError> {
        if initial.len() < 2 {
            return Ok(initial.to_vec());
        }
        let mut graph = PoseGraph::new();
        for (i, p) in initial.iter().enumerate() {
            graph.add_pose(i as u64, *p)?;
        }
        graph.fix(0)?;
        for i in 1..initial.len() {
            let delta = self.odometry[i - 1].between(&self.odometry[i]);
            let info = invert(&self.odometry_covariance(&delta));
            graph.add_between(i as u64 - 1, i as u64, delta, info)?;
        }
        for c in &self.constraints {
            if c.loop_closure && self.chi2(c) > self.config.smoother_max_closure_chi2 {
                continue;
            }
            let (a, b) = (self.keyframes[c.from].record, self.keyframes[c.to].record);
            graph.add_between(a as u64, b as u64, c.z, c.information)?;
        }
        let mut opt = Optimizer::new(&graph, self.config.smoother)?;
        opt.optimize(&mut graph)?;
        Ok(graph.poses())
    }

    /// eᵀΩe of a constraint at the keyframes' current poses, e = (z⁻¹ ⊕ x_from⁻¹ ⊕ x_to)
    /// as (x, y, θ) with θ normalised (g2o's `EDGE_SE2` error).
    fn chi2(&self, c: &Constraint) -> f64 {
        let rel = self.keyframes[c.from]
            .global
            .between(&self.keyframes[c.to].global);
        let e = c.z.between(&rel);
        let v = slam_models::Vector3::new(e.x, e.y, normalize_angle(e.theta));
        (v.transpose() * c.information * v)[(0, 0)]
    }

    /// The map rendered at `resolution` from every keyframe's scan at its smoothed pose.
    pub fn render(&self, resolution: f64) -> Result<GridMap, GraphError> {
        let poses = self.smoothed_poses();
        let mut grid = OccupancyGrid::try_new(resolution, self.config.sensor_model)?;
        for kf in &self.keyframes {
            grid.try_integrate_prepared(&poses[kf.record], &kf.scan)?;
        }
        Ok(grid.to_grid_map())
    }
}

/// The loop-closure search window (radius in metres, rotation half-width in radians) for
/// a relative pose carried by `d` metres of scan-matching chain: `loop-radius` +
/// `loop-radius-growth`·d and `loop-angle` + `loop-angle-growth`·d (a 3σ bound on a drift
/// whose standard deviation grows linearly with the path), capped at `loop-max-radius`
/// and `loop-max-angle`.
fn loop_window(c: &LaserGraphConfig, d: f64) -> (f64, f64) {
    let radius = (c.loop_radius + c.loop_radius_growth * d).min(c.loop_max_radius);
    let angle = (c.loop_angle + c.loop_angle_growth * d).min(c.loop_max_angle);
    (radius, angle)
}

/// A (distance, keyframe) pair ordered by the distance (total order), for the Dijkstra heap.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Ordered(f64, usize);

impl Eq for Ordered {}

impl PartialOrd for Ordered {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for Ordered {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        self.0.total_cmp(&other.0).then(self.1.cmp(&other.1))
    }
}

/// The loop-closure pyramid of a submap grid over the cells where its likelihood field
/// is not the far value: the obstacles' bounding box grown by the field's reach
/// (`max-distance`, plus two cells for the sub-cell hit positions). Outside it the
/// pyramid reads the far value, as the field there is, so the search is the same as
/// over every covered cell, on a smaller pyramid. `None` without obstacles.
fn loop_pyramid(grid: &OccupancyGrid, depth: u32) -> Result<Option<MaxPyramid>, GraphError> {
    let Some((lo, hi)) = grid.known_bounds() else {
        return Ok(None);
    };
    let (mut min, mut max) = (
        slam_grid::CellIndex::new(i32::MAX, i32::MAX),
        slam_grid::CellIndex::new(i32::MIN, i32::MIN),
    );
    for y in lo.y..=hi.y {
        for x in lo.x..=hi.x {
            if grid.is_obstacle(slam_grid::CellIndex::new(x, y)) {
                min = slam_grid::CellIndex::new(min.x.min(x), min.y.min(y));
                max = slam_grid::CellIndex::new(max.x.max(x), max.y.max(y));
            }
        }
    }
    if min.x > max.x {
        return Ok(None);
    }
    let reach = (grid.likelihood_params().max_distance / grid.resolution()).ceil() as i32 + 2;
    let min = slam_grid::CellIndex::new(min.x - reach, min.y - reach);
    let max = slam_grid::CellIndex::new(max.x + reach, max.y + reach);
    Ok(Some(MaxPyramid::new(grid, min, max, depth)?))
}

/// The inverse of a symmetric positive-definite 3×3 matrix, symmetrised (a covariance to an
/// information); a tiny diagonal is added if the inversion fails.
fn invert(cov: &Matrix3) -> Matrix3 {
    let m = cov.try_inverse().unwrap_or_else(|| {
        (cov + Matrix3::identity() * 1e-12)
            .try_inverse()
            .unwrap_or(Matrix3::identity())
    });
    (m + m.transpose()) * 0.5
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

    fn render_map(&self, resolution: f64) -> Option<GridMap> {
        if !(resolution > 0.0 && resolution.is_finite()) {
            return None;
        }
        self.render(resolution).ok()
    }
}

#[cfg(test)]
mod tests;
