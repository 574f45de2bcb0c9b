//! The particle maps' distance field, and tests of slam-grid's endpoint matching
//! ([`slam_grid::matcher::endpoint`]: the scorer, hill climber and grid search this filter
//! uses) on the map shapes the filter builds.
//!
//! Why the endpoint model and not the mean-field matchers of slam-grid: the improved
//! proposal needs the scan's log-likelihood under the truncated Gaussian endpoint model on
//! the incremental field (weights, the Gaussian fit of eqs. 14–16), evaluated ~100 times
//! per particle and scan.

use slam_grid::DistanceField;

/// The particle map's distance field. Every map of the filter is created with
/// [`slam_grid::OccupancyGrid::with_incremental_distance`] (see
/// [`crate::setup::Setup::empty`]), so it is always there.
#[inline]
pub(crate) fn field(map: &slam_grid::OccupancyGrid) -> DistanceField<'_> {
    map.distance_field()
        .expect("every gridfast map is created with an incremental distance field")
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use slam_grid::matcher::endpoint::{
        hill_climb, score, score_scan, EndpointModel, HillClimbSteps,
    };
    use slam_grid::{InverseSensorModel, LaserScan, OccupancyGrid, Point2, Pose2, RangeData};

    pub(crate) fn empty_map() -> OccupancyGrid {
        let model = InverseSensorModel {
            l_free: -0.4,
            no_return_range: 0.0,
            hit_margin: 0.0,
            protect_scan_hits: true,
            ..Default::default()
        };
        OccupancyGrid::new(0.05, model)
            .with_incremental_distance(4)
            .unwrap()
    }

    /// A closed room ≈ 8 m × 5 m with a pillar, scanned with 361 beams over 360°. The walls
    /// run through cell centres (x = ±4.025, y = ±2.525 on the 5 cm grid): a wall on a cell
    /// boundary puts its hits on either side by floating-point rounding, which moves the
    /// mapped wall by up to half a cell and the best match with it.
    pub(crate) fn room_scan(pose: &Pose2) -> LaserScan {
        let n = 361;
        let inc = 2.0 * std::f64::consts::PI / n as f64;
        let ranges = (0..n)
            .map(|k| {
                let a = pose.theta - std::f64::consts::PI + k as f64 * inc;
                let (dx, dy) = (a.cos(), a.sin());
                let mut t = f64::INFINITY;
                for (wall, dir, coord) in [
                    (4.025, dx, pose.x),
                    (-4.025, dx, pose.x),
                    (2.525, dy, pose.y),
                    (-2.525, dy, pose.y),
                ] {
                    if dir != 0.0 {
                        let tt = (wall - coord) / dir;
                        if tt > 0.0 {
                            t = t.min(tt);
                        }
                    }
                }
                // Pillar: a circle of radius 0.3 m at (1.5, 1.0).
                let (ox, oy) = (pose.x - 1.5, pose.y - 1.0);
                let b = ox * dx + oy * dy;
                let disc = b * b - (ox * ox + oy * oy - 0.09);
                if disc > 0.0 && -b - disc.sqrt() > 0.0 {
                    t = t.min(-b - disc.sqrt());
                }
                t
            })
            .collect();
        LaserScan {
            angle_min: -std::f64::consts::PI,
            angle_increment: inc,
            ranges,
            max_range: 30.0,
            sensor_pose: Pose2::IDENTITY,
        }
    }

    /// A beam ending 0.18 m from the nearest wall cell scores min(d, r)²: d itself under the
    /// 0.2 m capture truncation (an inlier), r under a 0.15 m one (an outlier).
    #[test]
    fn each_beam_is_truncated_at_the_likelihood_radius() {
        let mut map = empty_map();
        let origin = Pose2::new(0.0, 0.0, 0.0);
        map.integrate_scan(&origin, &room_scan(&origin));
        // The wall x = 4.025 runs through cell centres; the end point lies 0.4 of the way
        // from the centre 0.2 m from it to the one 0.15 m from it, on a row of centres.
        let point = [Point2::new(4.025 - 0.18, 0.025)];
        let lk = |radius: f64| EndpointModel {
            k: 1.0,
            radius,
            gain: 1.0,
        };
        let wide = score(&field(&map), &point, &origin, &lk(0.2));
        let tight = score(&field(&map), &point, &origin, &lk(0.15));
        assert!(
            (wide.log_likelihood + 0.18 * 0.18).abs() < 1e-4,
            "{}",
            wide.log_likelihood
        );
        assert_eq!(wide.inliers, 1);
        assert!((tight.log_likelihood + 0.15 * 0.15).abs() < 1e-9);
        assert_eq!(tight.inliers, 0);
    }

    /// The room of [`room_scan`] mapped from three poses that see it from different
    /// places and headings.
    pub(crate) fn room_map() -> OccupancyGrid {
        let mut map = empty_map();
        for p in [
            Pose2::new(0.0, 0.0, 0.0),
            Pose2::new(-1.0, -0.5, 1.0),
            Pose2::new(1.0, -1.0, -2.0),
        ] {
            map.integrate_scan(&p, &room_scan(&p));
        }
        map
    }

    #[test]
    fn hill_climbing_recovers_an_offset_pose() {
        let map = room_map();
        let truth = Pose2::new(0.3, 0.4, 0.3);
        let scan =
            RangeData::with_limits(&room_scan(&truth), &Default::default(), 0.0, 50.0).unwrap();
        let lk = EndpointModel {
            k: 1.0 / (2.0 * 0.05 * 0.05 * 3.0),
            radius: 0.2,
            gain: 3.0,
        };
        let hc = HillClimbSteps {
            linear_step: 0.05,
            angular_step: 0.05,
            refinements: 5,
        };
        for off in [
            Pose2::new(0.1, -0.08, 0.05),
            Pose2::new(-0.12, 0.1, -0.08),
            Pose2::new(0.0, 0.15, 0.0),
        ] {
            let init = Pose2::new(truth.x + off.x, truth.y + off.y, truth.theta + off.theta);
            let m = hill_climb(&field(&map), &scan, &init, &lk, &lk, &hc);
            assert!(
                m.pose.distance(&truth) < 0.02,
                "{:?} from {:?}",
                m.pose,
                init
            );
            assert!(slam_models::normalize_angle(m.pose.theta - truth.theta).abs() < 0.01);
            assert!(m.score.inliers as f64 > 0.9 * scan.points().len() as f64);
        }
        // An empty map has no inliers.
        let empty = empty_map();
        assert_eq!(score_scan(&field(&empty), &scan, &truth, &lk).inliers, 0);
    }
}
