//! The node's laser-only mode (`--odom-topic none`) against `slam run` on a laser-only
//! recording: the same scans, as messages through the node's processing core
//! ([`slam_ros::ScanStepper`]) and offline as `slam run` reads a recording without odometry
//! (slam-eval's `withhold_odometry`: [`slam_grid::laser_odometry()`] over the records, then
//! the filter), must give the same estimates: offline, laser odometry follows an ambiguous
//! step as branches and decides it `branch-lag` scans later; the node does the same, its
//! scans waiting for the decision.

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
        let (node, records) = through_the_node(name, &raw.records[..SCANS]);
        let off = offline_run(name, &offline.records[..SCANS]);
        assert_same_run(
            name,
            node.as_ref(),
            &records,
            off.as_ref(),
            &offline.records[..SCANS],
        );
        // The robot moved: the laser odometry is not the origin held.
        let a = node.pose();
        assert!(a.x.hypot(a.y) > 0.5, "{name}: {a:?}");
    }
}

/// The filter `name` stepped through the node's core with `raw`'s scans as messages (the
/// odometry handed in, ignored in the laser-only mode, is nonsense on purpose), then
/// finished as the node finishes at shutdown; the filter and every record it was given.
fn through_the_node(
    name: &str,
    raw: &[slam_models::ScanRecord],
) -> (Box<dyn ScanSlam>, Vec<slam_models::ScanRecord>) {
    let mut node = filter(name);
    let mut stepper = ScanStepper::new(&OdomSource::None, &Default::default()).unwrap();
    assert!(stepper.laser_only());
    let mut given = Vec::new();
    for (k, r) in raw.iter().enumerate() {
        let scan = r.scan.as_ref().unwrap();
        let stamp = ros_msg::stamp(r.t).unwrap_or(Stamp { sec: 0, nanosec: 0 });
        let msg =
            ros_msg::decode_laser_scan(&ros_msg::encode_laser_scan(stamp, "laser", scan)).unwrap();
        let odd = Pose2::new(100.0 + k as f64, -5.0, 1.0);
        given.extend(
            stepper
                .step(node.as_mut(), &msg, odd, scan.sensor_pose)
                .unwrap(),
        );
        // A scan waits at most `branch-lag` scans for its pose.
        assert!(stepper.waiting() <= slam_grid::LaserOdometryConfig::default().branch_lag);
        assert_eq!(given.len() + stepper.waiting(), k + 1);
    }
    given.extend(stepper.finish(node.as_mut()).unwrap());
    assert_eq!(stepper.waiting(), 0);
    (node, given)
}

/// The filter `name` over `records` as `slam run` steps it.
fn offline_run(name: &str, records: &[slam_models::ScanRecord]) -> Box<dyn ScanSlam> {
    let mut off = filter(name);
    for r in records {
        off.process(r).unwrap();
    }
    off
}

/// Every record's odometry, the final pose and the map agree to 1e-9.
fn assert_same_run(
    name: &str,
    node: &dyn ScanSlam,
    given: &[slam_models::ScanRecord],
    off: &dyn ScanSlam,
    offline: &[slam_models::ScanRecord],
) {
    let near = |a: Pose2, b: Pose2| {
        (a.x - b.x).abs() < 1e-9 && (a.y - b.y).abs() < 1e-9 && (a.theta - b.theta).abs() < 1e-9
    };
    assert_eq!(given.len(), offline.len(), "{name}: records given");
    for (k, (g, o)) in given.iter().zip(offline).enumerate() {
        // Stamps go through nanoseconds on the wire.
        assert!(
            (g.t - o.t).abs() < 1e-6,
            "{name}: scan {k}: time {} vs {}",
            g.t,
            o.t
        );
        assert!(
            near(g.odometry, o.odometry),
            "{name}: scan {k}: odometry {:?}, offline {:?}",
            g.odometry,
            o.odometry
        );
    }
    let (a, b) = (node.pose(), off.pose());
    assert!(near(a, b), "{name}: node {a:?} vs offline {b:?}");
    assert_eq!(node.map(), off.map(), "{name}: maps differ");
}

/// Where the laser odometry switches branches (csail without odometry: its 65° turn and
/// the headings after it), the node still makes `slam run`'s estimates, and it does not
/// with the branches off in the node alone (so the test can tell).
#[test]
fn laser_only_node_follows_branches_like_slam_run() {
    let Some(log) = dataset("bench/csail.log") else {
        return;
    };
    let mut raw = slam_io::carmen::read_carmen(&log).unwrap().dataset;
    // The scans as the node sees them: through a LaserScan message (f32 ranges and angles).
    raw.records.retain(|r| r.scan.is_some());
    for r in &mut raw.records {
        let scan = r.scan.as_ref().unwrap();
        let stamp = ros_msg::stamp(r.t).unwrap_or(Stamp { sec: 0, nanosec: 0 });
        let msg =
            ros_msg::decode_laser_scan(&ros_msg::encode_laser_scan(stamp, "laser", scan)).unwrap();
        r.scan = Some(slam_ros::convert::scan_from_msg(&msg, scan.sensor_pose));
    }
    let mut offline_input = input::Input {
        name: "csail".into(),
        label: "csail".into(),
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
    let scans: Vec<slam_models::ScanRecord> = raw
        .records
        .into_iter()
        .filter(|r| r.scan.is_some())
        .collect();
    let offline: Vec<slam_models::ScanRecord> = offline
        .records
        .iter()
        .filter(|r| r.scan.is_some())
        .cloned()
        .collect();
    let (node, given) = through_the_node("scanmatch", &scans);
    let off = offline_run("scanmatch", &offline);
    assert_same_run("scanmatch", node.as_ref(), &given, off.as_ref(), &offline);
    // The branches mattered here: decided at once, the node's odometry is another.
    let mut at_once = ScanStepper::new(
        &OdomSource::None,
        &slam_grid::LaserOdometryConfig {
            branch_lag: 0,
            ..Default::default()
        },
    )
    .unwrap();
    let mut f = filter("scanmatch");
    let mut apart = 0.0f64;
    for (r, o) in scans.iter().zip(&offline) {
        let scan = r.scan.as_ref().unwrap();
        let stamp = ros_msg::stamp(r.t).unwrap_or(Stamp { sec: 0, nanosec: 0 });
        let msg =
            ros_msg::decode_laser_scan(&ros_msg::encode_laser_scan(stamp, "laser", scan)).unwrap();
        let recs = at_once
            .step(f.as_mut(), &msg, Pose2::IDENTITY, scan.sensor_pose)
            .unwrap();
        assert_eq!(recs.len(), 1, "no lag, no wait");
        let d = recs[0].odometry.between(&o.odometry);
        apart = apart.max(d.x.hypot(d.y));
    }
    assert!(
        apart > 1.0,
        "single decisions within {apart} m of the branches'"
    );
}

/// The datasets folder's file `rel`, or `None` after saying why (a failure under CI).
fn dataset(rel: &str) -> Option<PathBuf> {
    let dir = std::env::var_os("SLAM_DATASETS")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/datasets")
        });
    let p = dir.join(rel);
    if p.exists() {
        return Some(p);
    }
    if std::env::var("CI").is_ok_and(|v| v == "true" || v == "1") {
        panic!("dataset {} is missing and CI=true", p.display());
    }
    eprintln!(
        "SKIPPED: dataset {} not found (set SLAM_DATASETS)",
        p.display()
    );
    None
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
    assert_eq!(
        rec.len(),
        1,
        "a topic's odometry: the scan goes to the filter at once"
    );
    assert_eq!(rec[0].odometry, given);
}
