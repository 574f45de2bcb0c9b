//! The one front door of a laser scan into slam-grid: [`RangeData`], Cartographer's
//! `RangeData {origin, returns, misses}` (`local_trajectory_builder_2d.cc`). A scan is
//! checked and each of its beams classified once, as it enters; map integration
//! ([`crate::OccupancyGrid::try_integrate_prepared`]), every scan matcher and a filter's
//! re-rendered map take the classified beams and never ask a reading again. Beam directions
//! and matching end points are computed here too, so that integrating or scoring a scan at
//! a pose costs one `sin_cos` per pose, never one per beam.

use crate::error::GridError;
use crate::InverseSensorModel;
use slam_models::{LaserScan, Point2, Pose2};

/// One beam as the map takes it: its unit direction in the sensor frame and a length.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Ray {
    /// cos and sin of the beam angle (sensor frame).
    pub(crate) dir: (f64, f64),
    /// For a return, the reading (the obstacle's distance); for a miss, how far the beam
    /// clears space. Metres, > 0.
    pub(crate) length: f64,
}

/// The range rules of an [`InverseSensorModel`] that classify a beam (its log-odds and
/// `hit_margin` belong to the integration): the rules a [`RangeData`] was classified under,
/// which the grid that integrates it must share.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct RangeRules {
    min_range: f64,
    max_range: f64,
    no_return_range: f64,
    far_hits_clear: bool,
}

impl RangeRules {
    /// The range rules of `model`.
    pub(crate) fn of(model: &InverseSensorModel) -> Self {
        Self {
            min_range: model.min_range,
            max_range: model.max_range,
            no_return_range: model.no_return_range,
            far_hits_clear: model.far_hits_clear,
        }
    }

    /// Where beam reading `r` goes (`hit`: below the scan's own `max_range`,
    /// [`LaserScan::is_hit`]): `Some((length, true))` a return, `Some((length, false))` a
    /// miss, `None` dropped (the model's table, [`InverseSensorModel`]: below `min_range`
    /// dropped; a hit within `max_range` a return; a hit beyond it a miss to `max_range`
    /// when far hits clear; any other reading a miss to `no_return_range`; nothing to
    /// clear, dropped).
    fn classify(&self, r: f64, hit: bool) -> Option<(f64, bool)> {
        if r < self.min_range {
            return None;
        }
        // A hit beyond max_range (at or beyond it when far hits do not clear).
        let far = hit
            && if self.far_hits_clear {
                r > self.max_range
            } else {
                r >= self.max_range
            };
        let (length, is_return) = if hit && !far {
            (r, true)
        } else if far && self.far_hits_clear {
            (self.max_range, false)
        } else {
            (self.no_return_range.min(r), false)
        };
        (length > 0.0).then_some((length, is_return))
    }
}

/// A laser scan checked and classified once, at the door (Cartographer's `RangeData`):
///
/// * `origin`: the sensor's pose in the **robot** frame (the laser offset);
/// * `returns`: the beams that end on an obstacle, in scan order: the map marks their end
///   cell and clears the space before it;
/// * `misses`: the beams that only clear space (no return, or a hit too far to mark), in
///   scan order, each with the length it clears;
/// * `points`: the end points of the hits within the matching limits, in the robot frame
///   (`origin` applied), for scan matching; a point p under robot pose x is at
///   R(θ)·p + t in the world. `coarse` (every 4th, [`RangeData::coarse_points`]) and `half`
///   (every 2nd, [`RangeData::half_points`]) are their cheap subsets.
///
/// Returns and misses follow the range rules of the [`InverseSensorModel`] it is built with
/// (`min_range`, `max_range`, `far_hits_clear`, `no_return_range`); a grid integrates it
/// only under a model with the same rules. Build it once per scan and share it (across the
/// particles of a filter, the grids of a pose graph, a re-rendered map): it is the one
/// scan type of every matcher and of map integration.
#[derive(Debug, Clone, PartialEq)]
pub struct RangeData {
    pub(crate) origin: Pose2,
    pub(crate) returns: Vec<Ray>,
    pub(crate) misses: Vec<Ray>,
    pub(crate) rules: RangeRules,
    beams: usize,
    pub(crate) points: Vec<Point2>,
    pub(crate) coarse: Vec<Point2>,
    pub(crate) half: Vec<Point2>,
    pub(crate) max_point_range: f64,
}

/// The coarse subset keeps every `COARSE_STRIDE`-th matching point.
const COARSE_STRIDE: usize = 4;

/// Below this many coarse points the coarse subset is too thin to decide anything, and
/// [`RangeData::coarse_points`] returns every point instead.
const MIN_COARSE_POINTS: usize = 20;

impl RangeData {
    /// Checks and classifies a scan for a map under `model`, rejecting NaN/∞ or negative
    /// readings and a non-finite geometry. All hits become matching points.
    pub fn new(scan: &LaserScan, model: &InverseSensorModel) -> Result<Self, GridError> {
        Self::with_limits(scan, model, 0.0, f64::INFINITY)
    }

    /// Like [`RangeData::new`], but only hits with `min_range ≤ r ≤ max_range` become
    /// matching points (the map's returns and misses are as the model says).
    pub fn with_limits(
        scan: &LaserScan,
        model: &InverseSensorModel,
        min_range: f64,
        max_range: f64,
    ) -> Result<Self, GridError> {
        Self::with_limits_every(scan, model, min_range, max_range, 1)
    }

    /// Like [`RangeData::with_limits`], keeping only every `step`-th of those matching
    /// points (`step` 0 counts as 1): beams are subsampled for matching as GMapping's
    /// `lskip` does, while every beam still goes to the map.
    pub fn with_limits_every(
        scan: &LaserScan,
        model: &InverseSensorModel,
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
        let rules = RangeRules::of(model);
        let (mut returns, mut misses) = (Vec::with_capacity(scan.len()), Vec::new());
        let mut points = Vec::with_capacity(scan.len());
        let mut max_point_range: f64 = 0.0;
        let mut in_limits = 0usize;
        for (k, &r) in scan.ranges.iter().enumerate() {
            let (s, c) = scan.beam_angle(k).sin_cos();
            let hit = scan.is_hit(k);
            match rules.classify(r, hit) {
                Some((length, true)) => returns.push(Ray {
                    dir: (c, s),
                    length,
                }),
                Some((length, false)) => misses.push(Ray {
                    dir: (c, s),
                    length,
                }),
                None => {}
            }
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
            origin: scan.sensor_pose,
            returns,
            misses,
            rules,
            beams: scan.len(),
            points,
            coarse,
            half,
            max_point_range,
        })
    }

    /// Frees the matching points ([`RangeData::points`] and its subsets) of a scan whose
    /// matching is over, keeping what map integration reads (origin, returns, misses): a
    /// filter that keeps its scans to re-render maps keeps them at the size of the raw
    /// beams. Matching this scan afterwards finds no points.
    pub fn release_matching_points(&mut self) {
        self.points = Vec::new();
        self.coarse = Vec::new();
        self.half = Vec::new();
    }

    /// Hit end points in the robot frame (metres) used for matching.
    #[inline]
    pub fn points(&self) -> &[Point2] {
        &self.points
    }

    /// The coarse subset of [`RangeData::points`] (every 4th), or all of them when that
    /// subset would have fewer than 20 points: coarse search phases score these.
    #[inline]
    pub fn coarse_points(&self) -> &[Point2] {
        self.subset_or_all(&self.coarse)
    }

    /// Every 2nd of [`RangeData::points`] (the first, third, …), or all of them when that
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

    /// True when [`RangeData::coarse_points`] is a proper subset (enough points for a
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

    /// The sensor's pose in the robot frame (`origin`).
    #[inline]
    pub fn sensor_pose(&self) -> Pose2 {
        self.origin
    }

    /// Number of beams of the scan (hits and no-returns, dropped ones included).
    #[inline]
    pub fn beam_count(&self) -> usize {
        self.beams
    }

    /// Number of returns: the beams the map marks an obstacle at.
    #[inline]
    pub fn return_count(&self) -> usize {
        self.returns.len()
    }

    /// Number of misses: the beams that only clear space in the map.
    #[inline]
    pub fn miss_count(&self) -> usize {
        self.misses.len()
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
        let p = RangeData::new(&scan, &Default::default()).unwrap();
        let expected = scan.hit_points();
        assert_eq!(p.points().len(), 21);
        assert_eq!(p.beam_count(), 22);
        for (a, b) in p.points().iter().zip(&expected) {
            assert!((a - b).norm() < 1e-12);
        }
        let mut bad = scan.clone();
        bad.ranges[3] = f64::NAN;
        assert!(RangeData::new(&bad, &Default::default()).is_err());
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
        let all = RangeData::with_limits(&scan, &Default::default(), 0.9, 10.0).unwrap();
        let every2 =
            RangeData::with_limits_every(&scan, &Default::default(), 0.9, 10.0, 2).unwrap();
        assert_eq!(all.points().len(), 200);
        assert_eq!(every2.beam_count(), 202);
        let expected: Vec<Point2> = all.points().iter().step_by(2).copied().collect();
        assert_eq!(every2.points(), &expected[..]);
        assert!(every2.has_coarse_subset());
        let coarse: Vec<Point2> = expected.iter().step_by(4).copied().collect();
        assert_eq!(every2.coarse_points(), &coarse[..]);
        // 200 / 20 = 10 points: a coarse subset of 3 is too thin, all points are used.
        let thin = RangeData::with_limits_every(&scan, &Default::default(), 0.9, 10.0, 20).unwrap();
        assert!(!thin.has_coarse_subset());
        assert_eq!(thin.coarse_points(), thin.points());
        // The half subset: every 2nd kept point (100 of 200), all 10 when thinner than 20.
        let half: Vec<Point2> = all.points().iter().step_by(2).copied().collect();
        assert_eq!(all.half_points(), &half[..]);
        assert_eq!(thin.half_points(), thin.points());
    }

    /// Each beam goes where the sensor model's table (PR table 9.2 with GMapping's
    /// `maxUrange`, [`InverseSensorModel`]) puts it, checked beam by beam against that
    /// table written out: below `min_range` dropped; a hit within `max_range` a return; a
    /// far hit a miss to `max_range` (or, with far hits not clearing, to
    /// `no_return_range`); a no return a miss to `no_return_range`.
    #[test]
    fn beams_are_classified_once_by_the_model_table() {
        // min_range 0.05, max_range 4, no_return_range 2; the scan's own limit is 10.
        let ranges = vec![0.01, 1.0, 3.0, 4.0, 5.0, 10.0, 12.0, 1.5];
        let scan = LaserScan {
            angle_min: 0.0,
            angle_increment: 0.1,
            ranges,
            max_range: 10.0,
            sensor_pose: Pose2::new(0.1, 0.0, 0.0),
        };
        let lengths = |v: &[Ray]| v.iter().map(|r| r.length).collect::<Vec<_>>();
        let model = |far_hits_clear: bool, no_return_range: f64| InverseSensorModel {
            min_range: 0.05,
            max_range: 4.0,
            no_return_range,
            far_hits_clear,
            ..Default::default()
        };
        let d = RangeData::new(&scan, &model(true, 2.0)).unwrap();
        assert_eq!(lengths(&d.returns), [1.0, 3.0, 4.0, 1.5]);
        // 5 is a far hit (clears to 4); 10 and 12 are no returns (clear to 2).
        assert_eq!(lengths(&d.misses), [4.0, 2.0, 2.0]);
        assert_eq!(
            (d.beam_count(), d.return_count(), d.miss_count()),
            (8, 4, 3)
        );
        // The returns keep their directions in scan order (beams 1, 2, 3, 7).
        let dirs: Vec<f64> = d.returns.iter().map(|r| r.dir.1.atan2(r.dir.0)).collect();
        for (a, k) in dirs.iter().zip([1.0, 2.0, 3.0, 7.0]) {
            assert!((a - 0.1 * k).abs() < 1e-12);
        }
        // Far hits not clearing: the limit itself and beyond are no returns.
        let d = RangeData::new(&scan, &model(false, 2.0)).unwrap();
        assert_eq!(lengths(&d.returns), [1.0, 3.0, 1.5]);
        assert_eq!(lengths(&d.misses), [2.0, 2.0, 2.0, 2.0]);
        // ... and with no_return_range 0 nothing is cleared by them (grid FastSLAM's rule).
        let d = RangeData::new(&scan, &model(false, 0.0)).unwrap();
        assert_eq!(d.miss_count(), 0);
        // Matching points are the hits, whatever the map makes of them.
        assert_eq!(d.points().len(), 6);
    }

    /// A grid takes a `RangeData` only under the range rules it was classified by: another
    /// model's grid refuses it (and is left unchanged) rather than re-classify its beams.
    #[test]
    fn a_grid_refuses_range_data_classified_for_other_rules() {
        let scan = LaserScan {
            angle_min: 0.0,
            angle_increment: 0.1,
            ranges: vec![1.0, 2.0, 30.0],
            max_range: 30.0,
            sensor_pose: Pose2::IDENTITY,
        };
        let theirs = InverseSensorModel {
            far_hits_clear: false,
            ..Default::default()
        };
        let data = RangeData::new(&scan, &theirs).unwrap();
        let mut grid = crate::OccupancyGrid::new(0.05, InverseSensorModel::default());
        let r = grid.try_integrate_prepared(&Pose2::IDENTITY, &data);
        assert!(matches!(r, Err(GridError::OtherRangeRules)), "{r:?}");
        assert!(grid.to_grid_map().cells.iter().all(|&c| c == -1));
        // Only the log-odds differing is fine: they are the integration's.
        let mut other = crate::OccupancyGrid::new(
            0.05,
            InverseSensorModel {
                l_occ: 2.0,
                ..theirs
            },
        );
        other
            .try_integrate_prepared(&Pose2::IDENTITY, &data)
            .unwrap();
    }
}
