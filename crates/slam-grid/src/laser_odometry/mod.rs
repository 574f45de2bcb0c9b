//! Laser odometry: the odometry stream of a recording that has none, from matching each
//! scan against a local map of the scans before it.
//!
//! The front stage that lets every laser filter run on a laser-only recording (a handheld
//! lidar, a robot that logs only its laser): each scan is matched against an occupancy map
//! of the scans just before it, around several predictions of its pose, and the matched
//! poses are handed to the filter as if they were wheel odometry. The design is Hector
//! SLAM's (Kohlbrecher et al., SSRR 2011: scan-to-map matching with no odometry at all)
//! with Cartographer's local SLAM (Hess et al., ICRA 2016: a real-time correlative search
//! in front of the local optimiser, §V, against the newest submaps, §III-B), using this
//! crate's one scan-scoring model and matchers through [`ScanMatchOdometry`]:
//!
//! 1. **Hypotheses** ([`MotionPrediction`], the configured list, default both): the last
//!    pose (zero motion) and the last pose ⊕ the last scan-to-scan increment (constant
//!    velocity, its translation clamped to the window); with a rotation prior (an IMU's
//!    yaw rate integrated over the scan interval, [`integrate_yaw_rate`]) one more, the
//!    constant-velocity translation with the prior's heading change. Hypotheses closer
//!    than one search step to an earlier one are searched once.
//! 2. **Search**, narrow first (Olson, ICRA 2009): the prediction (the rotation prior's
//!    hypothesis, else constant velocity's) is searched over a narrow window (default
//!    ±0.3 m, ±0.25 rad; 0 switches it off) and climbed; when `good-fit` of the end points
//!    fit the map there that is the pose (by default never: `good-fit` above 1, the wide
//!    search runs on every scan). Then the exact optimum of the truncated endpoint model over a wide window
//!    (default ±1.5 m, ±0.8 rad; with the rotation prior's hypothesis ±`prior-range-theta`
//!    in θ) is found around each hypothesis by branch and bound over precomputed max-pooled
//!    grids ([`crate::matcher::endpoint::wide_search`]: Olson 2009, §IV-C; Cartographer's
//!    `FastCorrelativeScanMatcher2D`), then climbed. A weak Gaussian prior around each
//!    hypothesis breaks near-ties within its window (a corridor's length). The wide
//!    results are weighed by the motion prior around the prediction, L − ½eᵀΣ⁻¹e (L the
//!    fine log-likelihood, e the offset from the prediction, Σ = diag(`motion-prior-std`²);
//!    none by default: the plain highest L), and the best is taken over the narrow match
//!    (if any) only when it fits more than
//!    `wide-margin` of the end points more (a place that fits about as well far from the
//!    prediction is aliasing: the start, a turn on the spot, a corridor, a row of like
//!    offices). The pose is accepted when `matcher.matching.min-inlier-fraction` of the
//!    end points fit the map. Otherwise the first hypothesis is kept, the scan counted as
//!    failed, and the next constant-velocity prediction is zero motion.
//! 3. **Local map** (Cartographer's two active submaps): a scan is written, when the robot
//!    moved `matcher.linear-update` or turned `matcher.angular-update` since the last
//!    written scan (Hector's map update thresholds; the first scan always), into both
//!    active submaps; the next scan is matched against the older one. A new submap starts
//!    when the newer holds `submap-scans` scans, and the older is then dropped, so the map
//!    matched against holds the last `submap-scans` to 2 × `submap-scans` written scans: a
//!    bad scan or accumulated drift spoils only the local map, for a while, not the
//!    whole map (0: one map of every scan).
//!
//! 4. **Branches** (over a whole recording, [`laser_odometry`], or a stream of scans,
//!    [`LaserOdometryStream`], as the live node runs it; `branch-lag`, default 5
//!    scans): a step whose narrow match and wide search's best are distinct poses fitting
//!    within `ambiguity-margin` (20 %) of the end points of each other, or whose match
//!    fits under `turn-search-fit` (70 %) of them while a turn beyond the window (up to
//!    `turn-search-range`, 1.6 rad) fits more, is followed as up to `max-branches` (3)
//!    copies of the laser odometry, each with its own local map; `branch-lag` scans later
//!    the branch whose matches fit the most of their end points in mapped cells is kept
//!    (`hypotheses`; Reid 1979's multiple-hypothesis tracking with N-scan-back pruning).
//!    [`LaserOdometry::process`] decides every step at once.
//!
//! The first scan defines the frame: its pose is the identity. Errors accumulate without
//! bound (no loop closure: that is the filters' work); [`laser_odometry`] makes the whole
//! stream for a dataset, one pose per record.

mod config;
mod hypotheses;
mod run;
#[cfg(test)]
mod tests;

pub use config::{
    LaserOdometryConfig, MotionPrediction, DISTINCT_THETA, DISTINCT_XY, MAX_BRANCHES,
    MAX_HYPOTHESES,
};
pub use run::{
    integrate_yaw_rate, laser_odometry, LaserOdometryRun, LaserOdometryStream, MAX_RATE_GAP,
};

use crate::error::GridError;
use crate::matcher::endpoint::{EndpointMatch, SearchWindow};
use crate::scan::RangeData;
use crate::scanmatch::{ScanMatchConfig, ScanMatchOdometry};
use slam_models::{normalize_angle, LaserScan, Pose2};

/// How one scan's pose was found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MatchOutcome {
    /// The first scan: the identity, by definition.
    First,
    /// Matched; the index of the winning hypothesis in the order searched (the configured
    /// list, then the rotation prior's); the narrow search's match counts as the
    /// prediction's (the rotation prior's, else constant velocity's, else the first).
    Matched(usize),
    /// No hypothesis gave enough inliers: the first hypothesis is kept.
    Failed,
}

/// One scan's matches before [`LaserOdometry::commit`] takes one.
#[derive(Debug, Clone)]
pub(crate) struct Step {
    /// The scan, prepared for matching.
    prepared: RangeData,
    /// The pose of the scan before (`None`: this is the first scan).
    last: Option<Pose2>,
    /// The pose kept when no match is accepted (the first hypothesis).
    fallback: Pose2,
    /// The match taken: the winning hypothesis's index and the match.
    pub(crate) matched: Option<(usize, EndpointMatch)>,
    /// Distinct poses that fit about as well (only when asked for).
    pub(crate) alternatives: Vec<(usize, EndpointMatch)>,
}

/// One submap: its map (and matching) and how many scans were written into it.
#[derive(Debug, Clone)]
struct Submap {
    matcher: ScanMatchOdometry,
    scans: usize,
}

/// Laser odometry: each scan matched against a local map of the scans before it, around
/// several predictions, optionally with a rotation prior (module documentation).
#[derive(Debug, Clone)]
pub struct LaserOdometry {
    config: LaserOdometryConfig,
    /// Each submap's matching ([`LaserOdometryConfig::matcher_config`]).
    matcher: ScanMatchConfig,
    /// The active submaps, oldest first (at most two); the scan is matched against the
    /// first.
    submaps: Vec<Submap>,
    /// Submaps started so far.
    started: usize,
    /// The pose of the last scan and the increment that led to it.
    last: Option<(Pose2, Pose2)>,
    /// The pose where a scan was last written into the map.
    written: Pose2,
    failures: usize,
    /// Scans processed.
    scans: usize,
    /// Scans the narrow search matched (no wide search).
    narrow_hits: usize,
    /// Scans that needed the wide search.
    wide_searches: usize,
}

impl LaserOdometry {
    /// An empty map; rejects an invalid configuration (by key).
    pub fn new(config: LaserOdometryConfig) -> Result<Self, GridError> {
        config.validate()?;
        Ok(Self {
            matcher: config.matcher_config(),
            config,
            submaps: Vec::new(),
            started: 0,
            last: None,
            written: Pose2::IDENTITY,
            failures: 0,
            scans: 0,
            narrow_hits: 0,
            wide_searches: 0,
        })
    }

    /// Scans no hypothesis matched (the prediction kept).
    pub fn failures(&self) -> usize {
        self.failures
    }

    /// Scans the narrow search alone matched (a good fit around the prediction).
    pub fn narrow_matches(&self) -> usize {
        self.narrow_hits
    }

    /// Scans that needed the wide search.
    pub fn wide_searches(&self) -> usize {
        self.wide_searches
    }

    /// Submaps started so far.
    pub fn submaps(&self) -> usize {
        self.started
    }

    /// The local map the next scan is matched against (`None` before the first scan).
    pub fn grid(&self) -> Option<&crate::OccupancyGrid> {
        self.submaps.first().map(|s| s.matcher.grid())
    }

    /// Writes `scan` at `pose` into the active submaps, starting a new one when the newer
    /// is full and dropping the older then (Cartographer's `ActiveSubmaps2D`).
    fn insert(&mut self, pose: &Pose2, scan: &RangeData) -> Result<(), GridError> {
        let n = self.config.submap_scans;
        let full = self.submaps.last().is_some_and(|s| n > 0 && s.scans >= n);
        if self.submaps.is_empty() || full {
            let matcher = ScanMatchOdometry::new(self.matcher.clone(), Pose2::IDENTITY, 0)?;
            self.submaps.push(Submap { matcher, scans: 0 });
            self.started += 1;
            if self.submaps.len() > 2 {
                self.submaps.remove(0);
            }
        }
        for s in &mut self.submaps {
            s.matcher.integrate(pose, scan)?;
            s.scans += 1;
        }
        self.written = *pose;
        Ok(())
    }

    /// The pose of the next scan, in the frame of the first (metres, radians), and how it
    /// was found. `turn` is the heading change since the previous scan from a rotation
    /// prior (radians, counter-clockwise), if there is one.
    pub fn process(
        &mut self,
        scan: &LaserScan,
        turn: Option<f64>,
    ) -> Result<(Pose2, MatchOutcome), GridError> {
        let step = self.propose(scan, turn, false)?;
        let matched = step.matched.map(|(i, m)| (i, m.pose));
        self.commit(&step, matched)
    }

    /// The matches of the next scan without committing to one (nothing written into the
    /// map; the scan counters advance): the match [`Self::process`] would take, and with
    /// `alternatives` the distinct poses that fit about as well
    /// ([`LaserOdometryConfig::ambiguity_margin`], and the turn search of
    /// [`LaserOdometryConfig::turn_search_fit`]).
    pub(crate) fn propose(
        &mut self,
        scan: &LaserScan,
        turn: Option<f64>,
        alternatives: bool,
    ) -> Result<Step, GridError> {
        let prepared = RangeData::with_limits(
            scan,
            &self.matcher.sensor_model,
            0.0,
            self.matcher.match_max_range,
        )?;
        self.scans += 1;
        let mut step = Step {
            prepared,
            last: None,
            fallback: Pose2::IDENTITY,
            matched: None,
            alternatives: Vec::new(),
        };
        let (Some((last, velocity)), Some(map)) = (self.last, self.submaps.first()) else {
            return Ok(step);
        };
        step.last = Some(last);
        step.fallback = last;
        let prepared = &step.prepared;
        let Some(window) = map.matcher.window() else {
            // The window search is off: no match, the first hypothesis kept.
            return Ok(step);
        };
        // No more than the window per scan: a larger step could not have been matched,
        // and a wrong one must not grow from scan to scan.
        let reach = window.range_xy;
        let d = velocity.x.hypot(velocity.y);
        let k = if d > reach { reach / d } else { 1.0 };
        let moved = Pose2::new(k * velocity.x, k * velocity.y, velocity.theta);
        let mut hypotheses: Vec<(Pose2, SearchWindow)> = self
            .config
            .hypotheses
            .iter()
            .map(|h| match h {
                MotionPrediction::ZeroMotion => (last, window),
                MotionPrediction::ConstantVelocity => (last.compose(&moved), window),
            })
            .collect();
        if let Some(turn) = turn.filter(|t| t.is_finite()) {
            let prior = Pose2::new(moved.x, moved.y, turn);
            let narrow = SearchWindow {
                range_theta: self.config.prior_range_theta,
                ..window
            };
            hypotheses.push((last.compose(&prior), narrow));
        }
        // The motion prior's mean: the best-informed hypothesis (the rotation prior's, else
        // constant velocity, else the first).
        let mean = if turn.is_some_and(f64::is_finite) {
            hypotheses.len() - 1
        } else {
            self.config
                .hypotheses
                .iter()
                .position(|h| *h == MotionPrediction::ConstantVelocity)
                .unwrap_or(0)
        };
        let predicted = hypotheses[mean].0;
        let points = prepared.points().len() as f64;
        let needed = (self.matcher.matching.min_inlier_fraction * points)
            .ceil()
            .max(1.0);
        // 1. Narrow: around the prediction, within the narrow window; a good fit there is
        //    taken without the wide search (Olson 2009, §IV: the wide search only when the
        //    narrow one fails).
        let narrow_window = SearchWindow {
            range_xy: self.config.narrow_range_xy.min(window.range_xy),
            range_theta: self
                .config
                .narrow_range_theta
                .min(hypotheses[mean].1.range_theta),
            ..window
        };
        let narrow = if self.config.narrow_range_xy > 0.0 || self.config.narrow_range_theta > 0.0 {
            map.matcher
                .match_scored(prepared, &predicted, Some(&narrow_window))?
        } else {
            None
        };
        let good = self.config.good_fit * points;
        if let Some(m) = narrow.filter(|m| m.score.inliers as f64 >= good.max(needed)) {
            self.narrow_hits += 1;
            step.matched = Some((mean, m));
            return Ok(step);
        }
        // 2. Wide: around each hypothesis, each result weighed by the motion prior around
        //    the prediction: the highest L − ½ eᵀ Σ⁻¹ e wins (the earlier on a tie).
        self.wide_searches += 1;
        let [s_xy, s_theta] = self.config.motion_prior_std;
        let information = |s: f64| if s > 0.0 { 1.0 / (s * s) } else { 0.0 };
        let (i_xy, i_theta) = (information(s_xy), information(s_theta));
        let weigh = |m: &EndpointMatch| {
            let (dx, dy) = (m.pose.x - predicted.x, m.pose.y - predicted.y);
            let dtheta = normalize_angle(m.pose.theta - predicted.theta);
            m.score.log_likelihood - 0.5 * (i_xy * (dx * dx + dy * dy) + i_theta * dtheta * dtheta)
        };
        let mut best: Option<(usize, EndpointMatch, f64)> = None;
        for (i, (centre, w)) in hypotheses.iter().enumerate() {
            let seen = hypotheses[..i].iter().any(|(c, _)| {
                c.distance(centre) < w.step_xy
                    && normalize_angle(c.theta - centre.theta).abs() < w.step_theta
            });
            if seen {
                continue;
            }
            if let Some(m) = map.matcher.match_scored(prepared, centre, Some(w))? {
                let j = weigh(&m);
                if best.is_none_or(|(_, _, b)| j > b) {
                    best = Some((i, m, j));
                }
            }
        }
        // 3. The narrow match stands unless the wide one fits clearly better: a place far
        //    from the prediction that fits about as well is aliasing (a corridor's length,
        //    a row of like offices), not evidence.
        let margin = self.config.wide_margin * points;
        let wide = best.map(|(i, m, _)| (i, m));
        if let Some(n) = narrow {
            if best
                .is_none_or(|(_, m, _)| m.score.inliers as f64 <= n.score.inliers as f64 + margin)
            {
                best = Some((mean, n, 0.0));
            }
        }
        step.fallback = hypotheses[0].0;
        step.matched = best
            .filter(|(_, m, _)| m.score.inliers as f64 >= needed)
            .map(|(i, m, _)| (i, m));
        if !alternatives {
            return Ok(step);
        }
        // 4. The alternatives (multi-hypothesis laser odometry, [`hypotheses`]): the match
        //    not taken of the narrow and the wide one, and with a poor fit the best of a
        //    turn search beyond the window, each when it is a distinct pose that fits about
        //    as well as the match taken.
        let Some((_, taken)) = step.matched else {
            return Ok(step);
        };
        let mut others: Vec<(usize, EndpointMatch)> = Vec::new();
        if let (Some(n), Some(w)) = (narrow, wide) {
            others.push(if taken.pose == n.pose { w } else { (mean, n) });
        }
        if (taken.score.inliers as f64) < self.config.turn_search_fit * points
            && self.config.turn_search_range > window.range_theta
        {
            let mut turned: Option<EndpointMatch> = None;
            // The headings beyond the window up to `turn-search-range` from the last pose.
            let half = 0.5 * (self.config.turn_search_range - window.range_theta).max(0.0);
            let beyond = SearchWindow {
                range_theta: half,
                ..window
            };
            for sign in [1.0, -1.0] {
                let turn = sign * (window.range_theta + half);
                let centre = last.compose(&Pose2::new(0.0, 0.0, turn));
                if let Some(m) = map.matcher.match_scored(prepared, &centre, Some(&beyond))? {
                    if turned.is_none_or(|t| m.score.log_likelihood > t.score.log_likelihood) {
                        turned = Some(m);
                    }
                }
            }
            // A heading beyond the window must fit more end points than the match taken:
            // a scan that fits poorly everywhere (open space, people) makes no branch.
            others.extend(
                turned
                    .filter(|m| m.score.inliers > taken.score.inliers)
                    .map(|m| (0, m)),
            );
        }
        let slack = self.config.ambiguity_margin * points;
        step.alternatives = others
            .into_iter()
            .filter(|(_, m)| {
                let apart = m.pose.distance(&taken.pose) > DISTINCT_XY
                    || normalize_angle(m.pose.theta - taken.pose.theta).abs() > DISTINCT_THETA;
                apart
                    && m.score.inliers as f64 >= needed
                    && m.score.inliers as f64 + slack >= taken.score.inliers as f64
            })
            .collect();
        Ok(step)
    }

    /// How well `m` (a match of `step`'s scan) fits the local map where the map knows
    /// anything: its inliers over its end points that fall in cells the map has observed
    /// (log-odds not 0), in [0, 1]. An end point in unmapped space is neither evidence for
    /// nor against a pose, so a pose that lays the scan over the mapped part (behind the
    /// robot in a corridor) gains nothing by it; 0 before the first scan or without end
    /// points in observed cells.
    pub(crate) fn known_fit(&self, step: &Step, m: &EndpointMatch) -> f64 {
        let Some(map) = self.submaps.first() else {
            return 0.0;
        };
        let grid = map.matcher.grid();
        let known = step
            .prepared
            .points()
            .iter()
            .filter(|p| {
                let w = m.pose.transform_point(p);
                grid.log_odds(grid.world_to_cell(&w)) != 0.0
            })
            .count();
        if known == 0 {
            return 0.0;
        }
        (m.score.inliers as f64 / known as f64).min(1.0)
    }

    /// Commits to a pose of a proposed step (`matched`: the winning hypothesis and pose;
    /// `None`: failed, the step's fallback kept; on the first scan the identity) and
    /// writes the scan into the map when due.
    pub(crate) fn commit(
        &mut self,
        step: &Step,
        matched: Option<(usize, Pose2)>,
    ) -> Result<(Pose2, MatchOutcome), GridError> {
        let prepared = &step.prepared;
        let Some(last) = step.last else {
            self.insert(&Pose2::IDENTITY, prepared)?;
            self.last = Some((Pose2::IDENTITY, Pose2::IDENTITY));
            return Ok((Pose2::IDENTITY, MatchOutcome::First));
        };
        let (pose, outcome) = match matched {
            Some((i, pose)) => (pose, MatchOutcome::Matched(i)),
            None => {
                self.failures += 1;
                (step.fallback, MatchOutcome::Failed)
            }
        };
        let c = &self.matcher;
        if self.written.distance(&pose) >= c.linear_update
            || normalize_angle(pose.theta - self.written.theta).abs() >= c.angular_update
        {
            self.insert(&pose, prepared)?;
        }
        // After a failed match the motion is unknown: predict none next time rather than
        // repeat a guess (a constant velocity kept through failures runs away).
        let velocity = if outcome == MatchOutcome::Failed {
            Pose2::IDENTITY
        } else {
            last.between(&pose)
        };
        self.last = Some((pose, velocity));
        Ok((pose, outcome))
    }
}
