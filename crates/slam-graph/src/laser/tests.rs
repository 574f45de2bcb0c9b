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
