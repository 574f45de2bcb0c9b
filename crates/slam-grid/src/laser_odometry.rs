//! Laser odometry: the odometry stream of a recording that has none, from matching each
//! scan against the map built from the scans before it.
//!
//! The front stage that lets every laser filter run on a laser-only recording (a handheld
//! lidar, a robot that logs only its laser): each scan is matched against the occupancy
//! map of the scans before it, from a prediction of its pose, and the matched poses are
//! handed to the filter as if they were wheel odometry. The design is Hector SLAM's
//! (Kohlbrecher et al., SSRR 2011: scan-to-map matching with no odometry at all) with
//! Cartographer's real-time correlative search in front of the local optimiser (Hess et
//! al., ICRA 2016, §V), using this crate's one scan-scoring model and matchers through
//! [`ScanMatchOdometry`]:
//!
//! 1. **Prediction** ([`MotionPrediction`]): the last pose (zero motion, the default) or
//!    the last pose ⊕ the last scan-to-scan increment (constant velocity, per scan). With a
//!    rotation prior (an IMU's yaw rate integrated over the scan interval,
//!    [`integrate_yaw_rate`]), the predicted heading change is the prior's instead.
//! 2. **Search**: the exact optimum of the truncated endpoint model over a window around
//!    the prediction by branch and bound over a coarse-to-fine pyramid
//!    ([`crate::matcher::endpoint::wide_search`]), then the hill climber. The window is
//!    `matcher.matching`'s (wide by default here: ±0.5 m, ±0.35 rad); with a rotation prior
//!    its rotation range is `prior_range_theta`; a weak Gaussian prior around the prediction
//!    breaks near-ties. A match with too few inliers (25 % of the end points) is retried in
//!    the recovery window (±`recovery_range_xy`, ±`recovery_range_theta`), accepted with
//!    60 % inliers; if that fails too the prediction is kept, the scan counted as failed,
//!    and the next prediction is zero motion.
//! 3. **Map update**: the scan is written into the map at its pose when the robot moved
//!    `matcher.linear_update` or turned `matcher.angular_update` since the last written
//!    scan (Hector's map update thresholds); the first scan is always written.
//!
//! The first scan defines the frame: its pose is the identity. Errors accumulate without
//! bound (no loop closure: that is the filters' work); [`laser_odometry`] makes the whole
//! stream for a dataset, one pose per record.

use crate::error::{ensure_config, GridError};
use crate::matcher::endpoint::SearchWindow;
use crate::scan::PreparedScan;
use crate::scanmatch::{EndpointMatchingConfig, ScanMatchConfig, ScanMatchOdometry};
use serde::{Deserialize, Serialize};
use slam_models::{normalize_angle, LaserScan, Pose2, ScanRecord, YawRate};

/// How the pose of the next scan is predicted before the search.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum MotionPrediction {
    /// The last pose ⊕ the increment between the two scans before (the same motion per
    /// scan again).
    ConstantVelocity,
    /// The last pose: no motion assumed; the search window alone finds the motion. Default
    /// (on the bench logs' keyframes, about 0.66 m and up to 0.6 rad apart, it loses track
    /// less often than constant velocity: Intel relations 4.6 m against 9.4 m).
    #[default]
    ZeroMotion,
}

/// Configuration of [`LaserOdometry`].
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields, default)]
pub struct LaserOdometryConfig {
    /// The map, the endpoint model and the first search window (scan-matching odometry's
    /// configuration; its `linear-update` / `angular-update` are the map update
    /// thresholds, its `odometry-jump` is not used). Defaults: scan-matching odometry's,
    /// with the window widened to ±0.5 m and ±0.35 rad and the thresholds 0.1 m / 0.1 rad.
    pub matcher: ScanMatchConfig,
    /// The prediction the search is centred on. Default zero motion.
    pub prediction: MotionPrediction,
    /// Recovery search, when the first fails: ± this in x and y, metres (≥ the first
    /// window's). Default 1.2 m.
    pub recovery_range_xy: f64,
    /// Recovery search: ± this in θ, radians, in [0, π]. Default 0.7 rad (40°).
    pub recovery_range_theta: f64,
    /// With a rotation prior, the first search's ± θ range around it, radians. Default
    /// 0.1 rad.
    pub prior_range_theta: f64,
    /// A recovery match is accepted only when this fraction of the end points fit the map
    /// (within `matcher.matching.likelihood-radius`), in [0, 1]: a wide window finds a
    /// wrong pose more easily. Default 0.6 (grid FastSLAM's wide matches).
    pub recovery_min_inlier_fraction: f64,
}

impl Default for LaserOdometryConfig {
    fn default() -> Self {
        Self {
            matcher: ScanMatchConfig {
                matching: EndpointMatchingConfig {
                    search_range_xy: 0.5,
                    search_range_theta: 0.35,
                    // A weak pull to the prediction: it decides only between near-equal
                    // fits (a corridor's length), not against the scan.
                    search_prior_std: [0.5, 0.3],
                    min_inlier_fraction: 0.25,
                    ..EndpointMatchingConfig::default()
                },
                ..ScanMatchConfig::default()
            },
            prediction: MotionPrediction::ZeroMotion,
            recovery_range_xy: 1.2,
            recovery_range_theta: 0.7,
            prior_range_theta: 0.1,
            recovery_min_inlier_fraction: 0.4,
        }
    }
}

/// How one scan's pose was found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MatchOutcome {
    /// The first scan: the identity, by definition.
    First,
    /// Matched in the first window.
    Matched,
    /// Matched in the recovery window after the first search failed.
    Recovered,
    /// Both searches failed: the prediction is kept.
    Failed,
}

/// Laser odometry: each scan matched against the map of the scans before it, from a
/// constant-velocity (or zero-motion) prediction, optionally with a rotation prior (module
/// documentation).
#[derive(Debug, Clone)]
pub struct LaserOdometry {
    config: LaserOdometryConfig,
    /// The map and the matching.
    matcher: ScanMatchOdometry,
    /// The pose of the last scan and the increment that led to it.
    last: Option<(Pose2, Pose2)>,
    /// The pose where a scan was last written into the map.
    written: Pose2,
    failures: usize,
    recoveries: usize,
}

impl LaserOdometry {
    /// An empty map; rejects an invalid configuration (by key).
    pub fn new(config: LaserOdometryConfig) -> Result<Self, GridError> {
        let first = &config.matcher.matching;
        ensure_config(
            config.recovery_range_xy >= first.search_range_xy
                && config.recovery_range_xy / first.search_step_xy
                    <= crate::scanmatch::MAX_SEARCH_STEPS,
            "recovery-range-xy",
            config.recovery_range_xy,
            ">= matcher.matching.search-range-xy and at most 1000 search steps",
        )?;
        ensure_config(
            (0.0..=std::f64::consts::PI).contains(&config.recovery_range_theta)
                && config.recovery_range_theta / first.search_step_theta
                    <= crate::scanmatch::MAX_SEARCH_STEPS,
            "recovery-range-theta",
            config.recovery_range_theta,
            "in [0, π] rad and at most 1000 search steps",
        )?;
        ensure_config(
            (0.0..=1.0).contains(&config.recovery_min_inlier_fraction),
            "recovery-min-inlier-fraction",
            config.recovery_min_inlier_fraction,
            "in [0, 1]",
        )?;
        ensure_config(
            (0.0..=std::f64::consts::PI).contains(&config.prior_range_theta),
            "prior-range-theta",
            config.prior_range_theta,
            "in [0, π] rad",
        )?;
        let matcher = ScanMatchOdometry::new(config.matcher.clone(), Pose2::IDENTITY, 0)?;
        Ok(Self {
            config,
            matcher,
            last: None,
            written: Pose2::IDENTITY,
            failures: 0,
            recoveries: 0,
        })
    }

    /// Scans whose searches both failed (the prediction kept).
    pub fn failures(&self) -> usize {
        self.failures
    }

    /// Scans matched only by the recovery search.
    pub fn recoveries(&self) -> usize {
        self.recoveries
    }

    /// The map built so far.
    pub fn grid(&self) -> &crate::OccupancyGrid {
        self.matcher.grid()
    }

    /// The pose of the next scan, in the frame of the first (metres, radians), and how it
    /// was found. `turn` is the heading change since the previous scan from a rotation
    /// prior (radians, counter-clockwise), if there is one.
    pub fn process(
        &mut self,
        scan: &LaserScan,
        turn: Option<f64>,
    ) -> Result<(Pose2, MatchOutcome), GridError> {
        let prepared = PreparedScan::with_limits(scan, 0.0, self.config.matcher.match_max_range)?;
        let Some((last, velocity)) = self.last else {
            self.matcher.integrate(&Pose2::IDENTITY, &prepared)?;
            self.last = Some((Pose2::IDENTITY, Pose2::IDENTITY));
            return Ok((Pose2::IDENTITY, MatchOutcome::First));
        };
        let mut increment = match self.config.prediction {
            // No more than the recovery window per scan: a larger step could not have been
            // matched, and a wrong one must not grow from scan to scan.
            MotionPrediction::ConstantVelocity => {
                let reach = self.config.recovery_range_xy;
                let d = velocity.x.hypot(velocity.y);
                let k = if d > reach { reach / d } else { 1.0 };
                Pose2::new(k * velocity.x, k * velocity.y, velocity.theta)
            }
            MotionPrediction::ZeroMotion => Pose2::IDENTITY,
        };
        let configured = self.matcher.window();
        let mut window = configured;
        if let Some(turn) = turn.filter(|t| t.is_finite()) {
            increment.theta = turn;
            if let Some(w) = window.as_mut() {
                w.range_theta = self.config.prior_range_theta;
            }
        }
        let predicted = last.compose(&increment);
        let m = self.config.matcher.matching.min_inlier_fraction;
        let (pose, outcome) =
            match self
                .matcher
                .match_scan_in(&prepared, &predicted, window.as_ref(), m)
            {
                Ok(Some(pose)) => (pose, MatchOutcome::Matched),
                Ok(None) => {
                    let wide = configured.map(|w| SearchWindow {
                        range_xy: self.config.recovery_range_xy,
                        range_theta: self.config.recovery_range_theta,
                        ..w
                    });
                    let needed = self.config.recovery_min_inlier_fraction;
                    match self.matcher.match_scan_in(
                        &prepared,
                        &predicted,
                        wide.as_ref(),
                        needed,
                    )? {
                        Some(pose) => {
                            self.recoveries += 1;
                            (pose, MatchOutcome::Recovered)
                        }
                        None => {
                            self.failures += 1;
                            (predicted, MatchOutcome::Failed)
                        }
                    }
                }
                Err(e) => return Err(e),
            };
        let c = self.matcher.config();
        if self.written.distance(&pose) >= c.linear_update
            || normalize_angle(pose.theta - self.written.theta).abs() >= c.angular_update
        {
            self.matcher.integrate(&pose, &prepared)?;
            self.written = pose;
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

/// Longest gap between yaw-rate samples (and between an interval's ends and the samples
/// nearest them) that [`integrate_yaw_rate`] bridges, seconds.
pub const MAX_RATE_GAP: f64 = 0.5;

/// The heading change ∫ω dt over [`t0`, `t1`] (radians) from yaw-rate samples sorted by
/// time, ω linear between samples (the trapezoidal rule) and held constant beyond the
/// first and last; `None` when `t1 ≤ t0`, a rate is not finite, or the samples leave a
/// gap longer than [`MAX_RATE_GAP`] in the interval (no prior then).
pub fn integrate_yaw_rate(rates: &[YawRate], t0: f64, t1: f64) -> Option<f64> {
    if t1.partial_cmp(&t0) != Some(std::cmp::Ordering::Greater) {
        return None;
    }
    // The samples in [t0 − gap, t1 + gap], and the rate at any time by interpolation.
    let lo = rates.partition_point(|r| r.t < t0 - MAX_RATE_GAP);
    let hi = rates.partition_point(|r| r.t <= t1 + MAX_RATE_GAP);
    let s = &rates[lo..hi];
    if s.is_empty() || s.iter().any(|r| !r.rate.is_finite() || !r.t.is_finite()) {
        return None;
    }
    let at = |t: f64| -> f64 {
        let k = s.partition_point(|r| r.t <= t);
        match k {
            0 => s[0].rate,
            k if k == s.len() => s[k - 1].rate,
            k => {
                let (a, b) = (s[k - 1], s[k]);
                if b.t > a.t {
                    a.rate + (b.rate - a.rate) * (t - a.t) / (b.t - a.t)
                } else {
                    b.rate
                }
            }
        }
    };
    // Knots: t0, every sample inside, t1; the rate is linear between knots.
    let mut knots = vec![t0];
    knots.extend(s.iter().map(|r| r.t).filter(|&t| t > t0 && t < t1));
    knots.push(t1);
    let covered = s[0].t <= t0 + MAX_RATE_GAP && s[s.len() - 1].t >= t1 - MAX_RATE_GAP;
    if !covered || knots.windows(2).any(|w| w[1] - w[0] > MAX_RATE_GAP) {
        return None;
    }
    Some(
        knots
            .windows(2)
            .map(|w| 0.5 * (at(w[0]) + at(w[1])) * (w[1] - w[0]))
            .sum(),
    )
}

/// The laser odometry of a whole recording ([`laser_odometry`]).
#[derive(Debug, Clone, PartialEq)]
pub struct LaserOdometryRun {
    /// One pose per record, in the frame of the first scan: at a scan record its matched
    /// pose; between two scan records the linear interpolation in time of theirs (x, y and
    /// the wrapped heading difference, the time fraction clamped to [0, 1]); before the
    /// first scan the identity, after the last scan its pose.
    pub odometry: Vec<Pose2>,
    /// Scans matched.
    pub scans: usize,
    /// Scans matched only by the recovery search.
    pub recoveries: usize,
    /// Scans whose searches both failed.
    pub failures: usize,
    /// Scans whose prediction had a rotation prior.
    pub with_prior: usize,
}

/// Runs [`LaserOdometry`] over `records` in file order (their own odometry is ignored),
/// with the rotation prior from `rates` (sorted by time here) when given.
pub fn laser_odometry(
    records: &[ScanRecord],
    rates: Option<&[YawRate]>,
    config: LaserOdometryConfig,
) -> Result<LaserOdometryRun, GridError> {
    let mut rates: Vec<YawRate> = rates.map(<[YawRate]>::to_vec).unwrap_or_default();
    rates.sort_by(|a, b| a.t.total_cmp(&b.t));
    let mut lo = LaserOdometry::new(config)?;
    let mut at_scans: Vec<(usize, Pose2)> = Vec::new();
    let mut with_prior = 0;
    let mut last_t: Option<f64> = None;
    for (k, r) in records.iter().enumerate() {
        let Some(scan) = &r.scan else { continue };
        let turn = last_t.and_then(|t0| integrate_yaw_rate(&rates, t0, r.t));
        with_prior += usize::from(turn.is_some());
        let (pose, _) = lo.process(scan, turn)?;
        at_scans.push((k, pose));
        last_t = Some(r.t);
    }
    let mut odometry = Vec::with_capacity(records.len());
    let mut next = 0;
    for (k, r) in records.iter().enumerate() {
        while next < at_scans.len() && at_scans[next].0 < k {
            next += 1;
        }
        let pose = match (next.checked_sub(1).map(|i| at_scans[i]), at_scans.get(next)) {
            (_, Some(&(j, p))) if j == k => p,
            (Some((i, a)), Some(&(j, b))) => {
                let (ta, tb) = (records[i].t, records[j].t);
                let s = if tb > ta {
                    ((r.t - ta) / (tb - ta)).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                Pose2::new(
                    a.x + s * (b.x - a.x),
                    a.y + s * (b.y - a.y),
                    normalize_angle(a.theta + s * normalize_angle(b.theta - a.theta)),
                )
            }
            (Some((_, a)), None) => a,
            (None, _) => Pose2::IDENTITY,
        };
        odometry.push(pose);
    }
    Ok(LaserOdometryRun {
        odometry,
        scans: at_scans.len(),
        recoveries: lo.recoveries(),
        failures: lo.failures(),
        with_prior,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testutil::SegmentWorld;

    /// A path through the simulated office (true poses), with the heading turning.
    fn office_path(n: usize) -> Vec<Pose2> {
        (0..n)
            .map(|k| {
                let s = k as f64 / n as f64;
                Pose2::new(
                    1.5 + 9.0 * s,
                    3.0 + 0.6 * (6.0 * s).sin(),
                    0.5 * (5.0 * s).sin(),
                )
            })
            .collect()
    }

    fn records(path: &[Pose2], world: &SegmentWorld) -> Vec<ScanRecord> {
        path.iter()
            .enumerate()
            .map(|(k, p)| ScanRecord {
                t: k as f64 * 0.2,
                // Odometry a laser-only recording does not have: it must be ignored.
                odometry: Pose2::new(1e3, -1e3, 2.0),
                scan: Some(world.scan(p, 361, std::f64::consts::TAU * 0.75, 20.0)),
            })
            .collect()
    }

    /// Laser odometry through the office with no odometry: every pose within 5 cm and
    /// 1° of the truth (expressed in the frame of the first pose), by simulator truth.
    /// With zero-motion prediction the search alone finds the ~8 cm, ~2° steps.
    #[test]
    fn tracks_the_office_without_odometry() {
        let world = SegmentWorld::office();
        let path = office_path(90);
        let recs = records(&path, &world);
        for prediction in [
            MotionPrediction::ConstantVelocity,
            MotionPrediction::ZeroMotion,
        ] {
            let config = LaserOdometryConfig {
                prediction,
                ..Default::default()
            };
            let run = laser_odometry(&recs, None, config).unwrap();
            assert_eq!((run.odometry.len(), run.scans), (90, 90));
            assert_eq!((run.failures, run.with_prior), (0, 0), "{prediction:?}");
            for (k, (est, truth)) in run.odometry.iter().zip(&path).enumerate() {
                let truth = path[0].between(truth);
                assert!(
                    est.distance(&truth) < 0.05
                        && normalize_angle(est.theta - truth.theta).abs() < 1f64.to_radians(),
                    "{prediction:?} scan {k}: {est:?} vs {truth:?}"
                );
            }
        }
    }

    /// Scans 0.5 m and 0.3 rad apart with a rotation rate prior (the true rate): the prior
    /// sets the heading and a narrow θ window finds the match; a sudden turn the constant
    /// velocity prediction misses by 0.6 rad is found with the prior.
    #[test]
    fn a_rotation_prior_carries_a_sudden_turn() {
        let world = SegmentWorld::office();
        // Straight along the corridor, then a sudden 0.6 rad turn on the spot.
        let mut path: Vec<Pose2> = (0..8)
            .map(|k| Pose2::new(2.0 + 0.4 * k as f64, 3.0, 0.0))
            .collect();
        path.push(Pose2::new(4.8, 3.0, 0.6));
        path.push(Pose2::new(5.1, 3.2, 0.6));
        let recs = records(&path, &world);
        let rates: Vec<YawRate> = (0..=100)
            .map(|i| {
                let t = i as f64 * 0.02;
                // The turn happens between scans 7 (t = 1.4) and 8 (t = 1.6).
                let rate = if (1.4..1.6).contains(&t) { 3.0 } else { 0.0 };
                YawRate { t, rate }
            })
            .collect();
        let run = laser_odometry(&recs, Some(&rates), LaserOdometryConfig::default()).unwrap();
        assert_eq!(run.with_prior, 9);
        for (est, truth) in run.odometry.iter().zip(&path) {
            let truth = path[0].between(truth);
            assert!(est.distance(&truth) < 0.05, "{est:?} vs {truth:?}");
            assert!(normalize_angle(est.theta - truth.theta).abs() < 0.02);
        }
    }

    /// ∫ω dt by the trapezoidal rule is exact for a rate linear in time, and a gap or an
    /// interval outside the samples gives no prior.
    #[test]
    fn yaw_rate_integration() {
        let rates: Vec<YawRate> = (0..=50)
            .map(|i| {
                let t = i as f64 * 0.1;
                YawRate {
                    t,
                    rate: 0.2 + 0.3 * t,
                }
            })
            .collect();
        // ∫ (0.2 + 0.3 t) dt from 1.05 to 3.33 = 0.2·Δt + 0.15·(t1² − t0²).
        let (t0, t1) = (1.05, 3.33);
        let exact = 0.2 * (t1 - t0) + 0.15 * (t1 * t1 - t0 * t0);
        let got = integrate_yaw_rate(&rates, t0, t1).unwrap();
        assert!((got - exact).abs() < 1e-12, "{got} vs {exact}");
        assert_eq!(integrate_yaw_rate(&rates, 2.0, 2.0), None);
        assert_eq!(integrate_yaw_rate(&rates, 3.0, 2.0), None);
        assert_eq!(integrate_yaw_rate(&rates, 6.0, 7.0), None);
        let gappy: Vec<YawRate> = rates
            .iter()
            .copied()
            .filter(|r| !(2.0..3.0).contains(&r.t))
            .collect();
        assert_eq!(integrate_yaw_rate(&gappy, 1.0, 4.0), None);
        assert!(integrate_yaw_rate(&gappy, 0.5, 1.5).is_some());
    }

    /// Records without a scan take the time interpolation of the scan poses around them.
    #[test]
    fn records_between_scans_are_interpolated() {
        let world = SegmentWorld::office();
        let path = office_path(20);
        let mut recs = records(&path, &world);
        // Insert a scan-less record halfway in time between scans 4 and 5.
        recs.insert(
            5,
            ScanRecord {
                t: 0.9,
                odometry: Pose2::IDENTITY,
                scan: None,
            },
        );
        let run = laser_odometry(&recs, None, LaserOdometryConfig::default()).unwrap();
        let (a, b, m) = (run.odometry[4], run.odometry[6], run.odometry[5]);
        assert!((m.x - 0.5 * (a.x + b.x)).abs() < 1e-12 && (m.y - 0.5 * (a.y + b.y)).abs() < 1e-12);
        assert_eq!(run.scans, 20);
    }

    #[test]
    fn bad_config_is_refused_by_key() {
        let e = LaserOdometry::new(LaserOdometryConfig {
            recovery_range_xy: 0.1,
            ..Default::default()
        })
        .unwrap_err();
        assert!(
            matches!(&e, GridError::InvalidConfig(c) if c.field == "recovery-range-xy"),
            "{e}"
        );
        let e = LaserOdometry::new(LaserOdometryConfig {
            prior_range_theta: f64::NAN,
            ..Default::default()
        })
        .unwrap_err();
        assert!(
            matches!(&e, GridError::InvalidConfig(c) if c.field == "prior-range-theta"),
            "{e}"
        );
    }
}
