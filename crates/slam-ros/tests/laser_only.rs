//! The node's laser-only mode (`--odom-topic none`) against `slam run` on a laser-only
//! recording: the same scans, as messages through the node's processing core
//! ([`slam_ros::ScanStepper`]) and offline as `slam run` reads a recording without odometry
//! (slam-eval's `withhold_odometry`: [`slam_grid::laser_odometry()`] over the records, then
//! the filter), must give the same estimates where no step is ambiguous (offline, laser
//! odometry follows an ambiguous step as branches; the node decides each step at once).

use slam_eval::factory::{DataKind, FilterConfig};
use slam_eval::input::{self, InputData};
use slam_io::ros_msg::{self, Stamp};
use slam_io::Dataset;
use slam_models::{Pose2, ScanSlam};
use slam_ros::{OdomSource, ScanStepper};
use std::path::PathBuf;

/// Scans of the fixture used (its first ones; the laser odometry is causal).
const SCANS: usize = 40;

fn fixture() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../slam-io/tests/fixtures/rosbag/intel-laser-only.mcap")
}

fn filter(name: &str) -> Box<dyn ScanSlam> {
    let mut c = FilterConfig::default_for_kind(name, DataKind::Laser).unwrap();
    if name == "gridfast" {
        c.set_particles(5).unwrap();
    }
    c.build_scan(0).unwrap()
}

#[test]
fn laser_only_node_matches_the_offline_laser_only_run() {
    let (raw, _) = slam_io::open_dataset(&fixture(), None).unwrap();
    let Dataset::Scan(mut raw) = raw else {
        panic!("laser data expected")
    };
    assert!(raw.records.len() >= SCANS);
    assert!(raw.records.iter().all(|r| r.scan.is_some()));
    raw.records.truncate(SCANS);
    // Offline: `slam run`'s input of a recording with no odometry.
    let mut offline_input = input::Input {
        name: "intel-laser-only".into(),
        label: "intel-laser-only".into(),
        description: String::new(),
        times_are_indices: false,
        simulated: false,
        data: InputData::Laser(raw.clone()),
        laser_odometry: None,
    };
    input::withhold_odometry(
        &mut offline_input,
        &[],
        input::NoOdometry::InRecording,
        &Default::default(),
    )
    .unwrap();
    let InputData::Laser(offline) = &offline_input.data else {
        panic!("laser data expected")
    };
    for name in ["scanmatch", "gridfast"] {
        let mut off = filter(name);
        for r in offline.records.iter().take(SCANS) {
            off.process(r).unwrap();
        }
        let mut node = filter(name);
        let mut stepper = ScanStepper::new(&OdomSource::None, &Default::default()).unwrap();
        assert!(stepper.laser_only());
        for (k, r) in raw.records.iter().take(SCANS).enumerate() {
            let scan = r.scan.as_ref().unwrap();
            let stamp = ros_msg::stamp(r.t).unwrap_or(Stamp { sec: 0, nanosec: 0 });
            let msg = ros_msg::decode_laser_scan(&ros_msg::encode_laser_scan(stamp, "laser", scan))
                .unwrap();
            // The odometry handed in is ignored in the laser-only mode.
            let odd = Pose2::new(100.0 + k as f64, -5.0, 1.0);
            let rec = stepper
                .step(node.as_mut(), &msg, odd, scan.sensor_pose)
                .unwrap();
            let want = offline.records[k].odometry;
            assert!(
                (rec.odometry.x - want.x).abs() < 1e-9
                    && (rec.odometry.y - want.y).abs() < 1e-9
                    && (rec.odometry.theta - want.theta).abs() < 1e-9,
                "{name}: scan {k}: odometry {:?}, offline {want:?}",
                rec.odometry
            );
        }
        let (a, b) = (node.pose(), off.pose());
        assert!(
            (a.x - b.x).abs() < 1e-9
                && (a.y - b.y).abs() < 1e-9
                && (a.theta - b.theta).abs() < 1e-9,
            "{name}: node {a:?} vs offline {b:?}"
        );
        // The robot moved: the laser odometry is not the origin held.
        assert!(a.x.hypot(a.y) > 0.5, "{name}: {a:?}");
        assert_eq!(node.map(), off.map(), "{name}: maps differ");
    }
}

#[test]
fn odometry_from_a_topic_is_taken_as_given() {
    let mut stepper =
        ScanStepper::new(&OdomSource::Topic("/odom".into()), &Default::default()).unwrap();
    assert!(!stepper.laser_only());
    let (raw, _) = slam_io::open_dataset(&fixture(), None).unwrap();
    let Dataset::Scan(raw) = raw else {
        panic!("laser data expected")
    };
    let scan = raw.records[0].scan.as_ref().unwrap();
    let msg = ros_msg::decode_laser_scan(&ros_msg::encode_laser_scan(
        ros_msg::stamp(1.0).unwrap(),
        "laser",
        scan,
    ))
    .unwrap();
    let mut f = filter("scanmatch");
    let given = Pose2::new(1.0, 2.0, 0.3);
    let rec = stepper
        .step(f.as_mut(), &msg, given, Pose2::IDENTITY)
        .unwrap();
    assert_eq!(rec.odometry, given);
}
