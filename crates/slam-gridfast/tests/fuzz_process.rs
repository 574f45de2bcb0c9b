//! Property-based fuzz of the laser filters' `process` (issue 17): scan-matching odometry
//! and grid FastSLAM fed random logs with glitched odometry (jumps of 50 m to 1e300 m),
//! glitched sensor poses and absurd ranges (0, max range, 1e6, 1e308) must answer every
//! record with a result or an error, never a panic, and keep their maps small: memory
//! bounded by the area seen (a glitch is refused by the odometry-jump limit, the grid's
//! maximum extent or the matchers' reach, never mapped across kilometres).
//!
//! A fixed case count and a fixed seed: a few seconds, the same cases on every run.

use proptest::prelude::*;
use proptest::test_runner::{Config, RngSeed};
use slam_grid::{ScanMatchConfig, ScanMatchOdometry};
use slam_gridfast::{GridFastConfig, GridFastSlam};
use slam_models::{LaserScan, OdometryJumpLimit, OnOdometryJump, Pose2, ScanRecord, ScanSlam};

/// A glitch offset, metres: most records have none.
fn glitch() -> impl Strategy<Value = f64> {
    prop_oneof![
        8 => Just(0.0),
        1 => Just(50.0),
        1 => Just(-1e5),
        1 => Just(1e10),
        1 => Just(1e300),
    ]
}

/// One beam's range, metres (max range 30 m).
fn range() -> impl Strategy<Value = f64> {
    prop_oneof![
        8 => 0.3f64..12.0,
        1 => Just(0.0),
        1 => Just(30.0),
        1 => Just(1e6),
        1 => Just(1e308),
    ]
}

/// (odometry step, odometry glitch in x and y, sensor-pose glitch, ranges, has scan).
type Rec = ((f64, f64, f64), (f64, f64), f64, Vec<f64>, bool);

fn records() -> impl Strategy<Value = Vec<Rec>> {
    prop::collection::vec(
        (
            (0.0f64..0.3, -0.05f64..0.05, -0.2f64..0.2),
            (glitch(), glitch()),
            glitch(),
            prop::collection::vec(range(), 40),
            prop::bool::weighted(0.8),
        ),
        4..14,
    )
}

fn to_records(recs: &[Rec]) -> Vec<ScanRecord> {
    let mut odo = Pose2::IDENTITY;
    recs.iter()
        .enumerate()
        .map(|(k, ((dx, dy, dth), (gx, gy), gs, ranges, has_scan))| {
            odo = odo.compose(&Pose2::new(*dx, *dy, *dth));
            let (a, inc) = LaserScan::flaser_geometry(ranges.len());
            ScanRecord {
                t: k as f64 * 0.1,
                odometry: Pose2::new(odo.x + gx, odo.y + gy, odo.theta),
                scan: has_scan.then(|| LaserScan {
                    angle_min: a,
                    angle_increment: inc,
                    ranges: ranges.clone(),
                    max_range: 30.0,
                    sensor_pose: Pose2::new(*gs, 0.0, 0.0),
                }),
            }
        })
        .collect()
}

/// Runs `filter` over `records`, records' errors allowed; the map stays within a few
/// hundred metres (every accepted glitch is at most 50 m, 1000 cells).
fn run(filter: &mut dyn ScanSlam, records: &[ScanRecord]) {
    for r in records {
        let _ = filter.process(r);
    }
    let map = filter.map();
    assert!(
        map.width <= 20_000 && map.height <= 20_000,
        "{} × {} cells",
        map.width,
        map.height
    );
    assert!(filter.trajectory().len() <= records.len());
}

fn limit(skip: bool, unchecked: bool) -> OdometryJumpLimit {
    OdometryJumpLimit {
        max_jump: if unchecked { 1e12 } else { 5.0 },
        on_jump: if skip {
            OnOdometryJump::Skip
        } else {
            OnOdometryJump::Error
        },
    }
}

proptest! {
    #![proptest_config(Config {
        cases: 64,
        rng_seed: RngSeed::Fixed(17),
        failure_persistence: None,
        ..Config::default()
    })]

    #[test]
    fn laser_filters_process_glitched_logs_without_panicking(
        recs in records(),
        skip in any::<bool>(),
        unchecked in any::<bool>(),
    ) {
        let records = to_records(&recs);
        let mut sm = ScanMatchOdometry::new(ScanMatchConfig {
            odometry_jump: limit(skip, unchecked),
            ..ScanMatchConfig::default()
        }, Pose2::IDENTITY, 0)
        .unwrap();
        run(&mut sm, &records);
        let mut gf = GridFastSlam::new(GridFastConfig {
                particles: 2,
                odometry_jump: limit(skip, unchecked),
                ..GridFastConfig::default()
            }, Pose2::IDENTITY, 3)
        .unwrap();
        run(&mut gf, &records);
    }
}
