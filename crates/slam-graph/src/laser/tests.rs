//! Unit tests of the laser front end (the simulated and Intel runs are in the workspace's
//! `tests/graph_laser.rs`).

use super::*;

fn record(t: f64, odometry: Pose2) -> ScanRecord {
    ScanRecord {
        t,
        odometry,
        scan: None,
    }
}

/// Without scans, the smoothed trajectory is the odometry itself (every odometry edge is
/// satisfied exactly, the first pose held).
#[test]
fn odometry_only_gives_the_odometry() {
    let mut f = LaserGraphSlam::new(LaserGraphConfig::default(), Pose2::IDENTITY, 0).unwrap();
    let mut o = Pose2::new(1.0, -2.0, 0.3);
    let mut expected = Vec::new();
    for i in 0..50 {
        f.process(&record(i as f64 * 0.1, o)).unwrap();
        expected.push(o);
        o = o.compose(&Pose2::new(0.05, 0.0, 0.02));
    }
    let tr = f.trajectory();
    assert_eq!(tr.len(), 50);
    for (a, b) in tr.iter().zip(&expected) {
        assert!(a.pose.approx_eq(b, 1e-9), "{:?} vs {b:?}", a.pose);
    }
}

/// A scan with a NaN range is an error and leaves the front end as it was; an odometry jump
/// beyond the limit is an error naming the bound.
#[test]
fn bad_records_are_errors_that_change_nothing() {
    let mut f = LaserGraphSlam::new(LaserGraphConfig::default(), Pose2::IDENTITY, 0).unwrap();
    f.process(&record(0.0, Pose2::IDENTITY)).unwrap();
    let bad = ScanRecord {
        t: 0.1,
        odometry: Pose2::new(0.1, 0.0, 0.0),
        scan: Some(slam_models::LaserScan {
            angle_min: -1.0,
            angle_increment: 0.1,
            ranges: vec![f64::NAN; 21],
            max_range: 20.0,
            sensor_pose: Pose2::IDENTITY,
        }),
    };
    assert!(f.process(&bad).is_err());
    assert_eq!(f.trajectory().len(), 1);
    let e = f.step(&record(0.2, Pose2::new(1e4, 0.0, 0.0))).unwrap_err();
    assert!(e.to_string().contains("5 m"), "{e}");
    assert_eq!(f.trajectory().len(), 1);
}

/// A scan from (`x0`, `y0`) inside the box 0 ≤ x ≤ 6, 0 ≤ y ≤ 4 with a 1 m square pillar
/// at (4 … 5, 1 … 2), 361 beams over 360°, 20 m max range (rays cast exactly).
fn room_scan(x0: f64, y0: f64) -> slam_models::LaserScan {
    let n = 361;
    let angle_min = -std::f64::consts::PI;
    let inc = 2.0 * std::f64::consts::PI / (n - 1) as f64;
    let segments = [
        ((0.0, 0.0), (6.0, 0.0)),
        ((6.0, 0.0), (6.0, 4.0)),
        ((6.0, 4.0), (0.0, 4.0)),
        ((0.0, 4.0), (0.0, 0.0)),
        ((4.0, 1.0), (5.0, 1.0)),
        ((5.0, 1.0), (5.0, 2.0)),
        ((5.0, 2.0), (4.0, 2.0)),
        ((4.0, 2.0), (4.0, 1.0)),
    ];
    let ranges = (0..n)
        .map(|i| {
            let a = angle_min + i as f64 * inc;
            let (dx, dy) = (a.cos(), a.sin());
            let mut best = 20.0f64;
            for ((ax, ay), (bx, by)) in segments {
                // Solve (x0, y0) + t·d = a + u·(b − a), t > 0, 0 ≤ u ≤ 1.
                let (ex, ey) = (bx - ax, by - ay);
                let det = dx * (-ey) - dy * (-ex);
                if det.abs() < 1e-12 {
                    continue;
                }
                let (rx, ry) = (ax - x0, ay - y0);
                let t = (rx * (-ey) - ry * (-ex)) / det;
                let u = (dx * ry - dy * rx) / det;
                if t > 1e-9 && (0.0..=1.0).contains(&u) {
                    best = best.min(t);
                }
            }
            best
        })
        .collect();
    slam_models::LaserScan {
        angle_min,
        angle_increment: inc,
        ranges,
        max_range: 20.0,
        sensor_pose: Pose2::IDENTITY,
    }
}

/// The loop-closure pyramid over the obstacles' reach finds exactly what the pyramid over
/// every covered cell finds (pose, score and covariance), from initial guesses up to 0.4 m
/// and 0.2 rad off, and it is smaller.
#[test]
fn obstacle_bounded_pyramid_searches_like_the_full_one() {
    let config = LaserGraphConfig::default();
    let mut grid = OccupancyGrid::try_new(config.resolution, config.sensor_model)
        .unwrap()
        .with_likelihood(config.likelihood)
        .unwrap();
    for (x, y) in [(1.0, 1.0), (2.0, 3.0), (3.0, 2.0)] {
        grid.try_integrate_scan(&Pose2::new(x, y, 0.0), &room_scan(x, y))
            .unwrap();
    }
    let full = MaxPyramid::covering(&grid, config.loop_depth)
        .unwrap()
        .unwrap();
    let bounded = loop_pyramid(&grid, config.loop_depth).unwrap().unwrap();
    assert!(bounded.memory_bytes() < full.memory_bytes());
    let scan = PreparedScan::new(&room_scan(2.5, 1.5)).unwrap();
    let matcher = BranchBoundMatcher {
        linear_window: 0.5,
        angular_window: 0.3,
        angular_step: 0.0,
        depth: config.loop_depth,
        min_score: 0.3,
        min_points: 10,
    };
    for (dx, dy, dth) in [(0.0, 0.0, 0.0), (0.3, -0.2, 0.1), (-0.4, 0.1, -0.2)] {
        let initial = Pose2::new(2.5 + dx, 1.5 + dy, dth);
        let a = matcher.match_in(&full, &scan, &initial).unwrap().unwrap();
        let b = matcher
            .match_in(&bounded, &scan, &initial)
            .unwrap()
            .unwrap();
        assert_eq!(a, b);
        assert!(a.pose.distance(&Pose2::new(2.5, 1.5, 0.0)) < 0.1, "{a:?}");
    }
}
