//! Scans prepared once for many uses: beam directions and end points computed a single time,
//! so that integrating or scoring a scan at a pose costs one `sin_cos` per pose, never one
//! per beam.

use crate::error::GridError;
use slam_models::{LaserScan, Point2, Pose2};

/// One beam of a prepared scan: its unit direction in the sensor frame and its reading.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct PreparedBeam {
    /// cos and sin of the beam angle (sensor frame).
    pub(crate) dir: (f64, f64),
    /// Range reading, metres.
    pub(crate) range: f64,
    /// True for a return (`range < scan.max_range`).
    pub(crate) hit: bool,
}

/// A laser scan with its beam directions and hit end points precomputed.
///
/// * `beams`: every beam (direction in the sensor frame, reading, hit or no return), for
///   map updates;
/// * `points`: the end points of hits in the **robot** frame (the sensor offset applied),
///   for scan matching; a point p under robot pose x is at R(θ)·p + t in the world;
/// * `coarse`: every 4th of `points`, the cheap subset that coarse search phases score
///   ([`PreparedScan::coarse_points`]);
/// * `half`: every 2nd of `points`, for many evaluations close to one pose
///   ([`PreparedScan::half_points`]).
///
/// Build it once per scan and share it (e.g. across the particles of a filter): it is the
/// one prepared-scan type of every matcher, scan-matching odometry's and grid FastSLAM's.
#[derive(Debug, Clone, PartialEq)]
pub struct PreparedScan {
    pub(crate) sensor_pose: Pose2,
    pub(crate) beams: Vec<PreparedBeam>,
    pub(crate) points: Vec<Point2>,
    pub(crate) coarse: Vec<Point2>,
    pub(crate) half: Vec<Point2>,
    pub(crate) max_point_range: f64,
}

/// The coarse subset keeps every `COARSE_STRIDE`-th matching point.
const COARSE_STRIDE: usize = 4;

/// Below this many coarse points the coarse subset is too thin to decide anything, and
/// [`PreparedScan::coarse_points`] returns every point instead.
const MIN_COARSE_POINTS: usize = 20;

impl PreparedScan {
    /// Prepares a scan, rejecting NaN/∞ or negative readings and a non-finite geometry.
    /// All hits become matching points.
    pub fn new(scan: &LaserScan) -> Result<Self, GridError> {
        Self::with_limits(scan, 0.0, f64::INFINITY)
    }

    /// Like [`PreparedScan::new`], but only hits with `min_range ≤ r ≤ max_range` become
    /// matching points (all beams are still kept for map updates).
    pub fn with_limits(
        scan: &LaserScan,
        min_range: f64,
        max_range: f64,
    ) -> Result<Self, GridError> {
        Self::with_limits_every(scan, min_range, max_range, 1)
    }

    /// Like [`PreparedScan::with_limits`], keeping only every `step`-th of those matching
    /// points (`step` 0 counts as 1): beams are subsampled for matching as GMapping's
    /// `lskip` does, while every beam is still integrated into the map.
    pub fn with_limits_every(
        scan: &LaserScan,
        min_range: f64,
        max_range: f64,
        step: usize,
    ) -> Result<Self, GridError> {
        scan.validate()?;
        if !scan.sensor_pose.is_finite() {
            return Err(GridError::NonFinite {
                what: "scan sensor pose",
                value: f64::NAN,
            });
        }
        let mut beams = Vec::with_capacity(scan.len());
        let mut points = Vec::with_capacity(scan.len());
        let mut max_point_range: f64 = 0.0;
        let mut in_limits = 0usize;
        for (k, &r) in scan.ranges.iter().enumerate() {
            let (s, c) = scan.beam_angle(k).sin_cos();
            let hit = scan.is_hit(k);
            beams.push(PreparedBeam {
                dir: (c, s),
                range: r,
                hit,
            });
            if hit && r >= min_range && r <= max_range {
                in_limits += 1;
                if (in_limits - 1) % step.max(1) != 0 {
                    continue;
                }
                let p = scan.sensor_pose.transform_point(&Point2::new(r * c, r * s));
                max_point_range = max_point_range.max(p.coords.norm());
                points.push(p);
            }
        }
        let coarse = points.iter().step_by(COARSE_STRIDE).copied().collect();
        let half = points.iter().step_by(2).copied().collect();
        Ok(Self {
            sensor_pose: scan.sensor_pose,
            beams,
            points,
            coarse,
            half,
            max_point_range,
        })
    }

    /// Hit end points in the robot frame (metres) used for matching.
    #[inline]
    pub fn points(&self) -> &[Point2] {
        &self.points
    }

    /// The coarse subset of [`PreparedScan::points`] (every 4th), or all of them when that
    /// subset would have fewer than 20 points: coarse search phases score these.
    #[inline]
    pub fn coarse_points(&self) -> &[Point2] {
        self.subset_or_all(&self.coarse)
    }

    /// Every 2nd of [`PreparedScan::points`] (the first, third, …), or all of them when that
    /// subset would have fewer than 20 points: for evaluations that are many and close to
    /// one pose (grid FastSLAM's proposal samples), where half the beams still tell them
    /// apart.
    #[inline]
    pub fn half_points(&self) -> &[Point2] {
        self.subset_or_all(&self.half)
    }

    /// `subset` when it has at least [`MIN_COARSE_POINTS`], else every point.
    #[inline]
    fn subset_or_all<'a>(&'a self, subset: &'a [Point2]) -> &'a [Point2] {
        if subset.len() >= MIN_COARSE_POINTS {
            subset
        } else {
            &self.points
        }
    }

    /// True when [`PreparedScan::coarse_points`] is a proper subset (enough points for a
    /// coarse phase to be worth it).
    #[inline]
    pub fn has_coarse_subset(&self) -> bool {
        self.coarse.len() >= MIN_COARSE_POINTS
    }

    /// Largest distance of a matching point from the robot origin, metres.
    #[inline]
    pub fn max_point_range(&self) -> f64 {
        self.max_point_range
    }

    /// The sensor's pose in the robot frame.
    #[inline]
    pub fn sensor_pose(&self) -> Pose2 {
        self.sensor_pose
    }

    /// Number of beams (hits and no-returns).
    #[inline]
    pub fn beam_count(&self) -> usize {
        self.beams.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn points_match_laser_scan_hit_points() {
        let scan = LaserScan {
            angle_min: -1.0,
            angle_increment: 0.1,
            ranges: (0..21)
                .map(|k| 1.0 + 0.1 * k as f64)
                .chain([30.0])
                .collect(),
            max_range: 30.0,
            sensor_pose: Pose2::new(0.2, -0.1, 0.3),
        };
        let p = PreparedScan::new(&scan).unwrap();
        let expected = scan.hit_points();
        assert_eq!(p.points().len(), 21);
        assert_eq!(p.beam_count(), 22);
        for (a, b) in p.points().iter().zip(&expected) {
            assert!((a - b).norm() < 1e-12);
        }
        let mut bad = scan.clone();
        bad.ranges[3] = f64::NAN;
        assert!(PreparedScan::new(&bad).is_err());
    }

    /// Subsampling keeps every step-th of the in-limit hits (counted among those hits
    /// only) and every beam; the coarse subset is every 4th kept point and the half subset
    /// every 2nd, or all of them when they would be thinner than 20.
    #[test]
    fn subsampling_keeps_every_step_th_hit_in_limits() {
        let scan = LaserScan {
            angle_min: 0.0,
            angle_increment: 0.01,
            // 0.5 m is below the limit; 30 m is a no return.
            ranges: [0.5, 30.0]
                .into_iter()
                .chain((0..200).map(|k| 1.0 + 0.01 * k as f64))
                .collect(),
            max_range: 30.0,
            sensor_pose: Pose2::IDENTITY,
        };
        let all = PreparedScan::with_limits(&scan, 0.9, 10.0).unwrap();
        let every2 = PreparedScan::with_limits_every(&scan, 0.9, 10.0, 2).unwrap();
        assert_eq!(all.points().len(), 200);
        assert_eq!(every2.beam_count(), 202);
        let expected: Vec<Point2> = all.points().iter().step_by(2).copied().collect();
        assert_eq!(every2.points(), &expected[..]);
        assert!(every2.has_coarse_subset());
        let coarse: Vec<Point2> = expected.iter().step_by(4).copied().collect();
        assert_eq!(every2.coarse_points(), &coarse[..]);
        // 200 / 20 = 10 points: a coarse subset of 3 is too thin, all points are used.
        let thin = PreparedScan::with_limits_every(&scan, 0.9, 10.0, 20).unwrap();
        assert!(!thin.has_coarse_subset());
        assert_eq!(thin.coarse_points(), thin.points());
        // The half subset: every 2nd kept point (100 of 200), all 10 when thinner than 20.
        let half: Vec<Point2> = all.points().iter().step_by(2).copied().collect();
        assert_eq!(all.half_points(), &half[..]);
        assert_eq!(thin.half_points(), thin.points());
    }
}
