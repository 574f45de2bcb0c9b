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
    let offline = offline_odometry("intel-laser-only", &raw);
    for name in ["scanmatch", "gridfast"] {
        let (node, records) = through_the_node(name, &raw.records[..SCANS], &Default::default());
        let off = offline_run(name, &offline[..SCANS]);
        assert_same_run(
            name,
            node.as_ref(),
            &records,
            off.as_ref(),
            &offline[..SCANS],
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
    laser: &slam_grid::LaserOdometryConfig,
) -> (Box<dyn ScanSlam>, Vec<slam_models::ScanRecord>) {
    let mut node = filter(name);
    let mut stepper = ScanStepper::new(&OdomSource::None, laser).unwrap();
    assert!(stepper.laser_only());
    let mut given = Vec::new();
    for (k, r) in raw.iter().enumerate() {
        let scan = r.scan.as_ref().unwrap();
        let odd = Pose2::new(100.0 + k as f64, -5.0, 1.0);
        given.extend(
            stepper
                .step(node.as_mut(), &message(r), odd, scan.sensor_pose)
                .unwrap(),
        );
        // A scan waits at most `branch-lag` scans for its pose (with 0, not at all).
        assert!(stepper.waiting() <= laser.branch_lag);
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

/// The odometry `slam run` makes for `raw` read as a recording without any (slam-eval's
/// `withhold_odometry`: laser odometry over the records), one record per record of `raw`.
fn offline_odometry(name: &str, raw: &slam_io::ScanDataset) -> Vec<slam_models::ScanRecord> {
    let mut input = input::Input {
        name: name.into(),
        label: name.into(),
        description: String::new(),
        times_are_indices: false,
        simulated: false,
        data: InputData::Laser(raw.clone()),
        laser_odometry: None,
    };
    input::withhold_odometry(
        &mut input,
        &[],
        input::NoOdometry::InRecording,
        &Default::default(),
    )
    .unwrap();
    let InputData::Laser(offline) = input.data else {
        panic!("laser data expected")
    };
    offline.records
}

/// Record `r`'s scan as the node receives it: a `sensor_msgs/LaserScan` message (f32 ranges
/// and angles, the stamp in nanoseconds).
fn message(r: &slam_models::ScanRecord) -> ros_msg::ScanMsg {
    let stamp = ros_msg::stamp(r.t).unwrap_or(Stamp { sec: 0, nanosec: 0 });
    let scan = r.scan.as_ref().expect("a scan record");
    ros_msg::decode_laser_scan(&ros_msg::encode_laser_scan(stamp, "laser", scan)).unwrap()
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
    // The scans as the node sees them: through a LaserScan message.
    raw.records.retain(|r| r.scan.is_some());
    for r in &mut raw.records {
        let sensor_pose = r.scan.as_ref().unwrap().sensor_pose;
        r.scan = Some(slam_ros::convert::scan_from_msg(&message(r), sensor_pose));
    }
    let offline = offline_odometry("csail", &raw);
    let (node, given) = through_the_node("scanmatch", &raw.records, &Default::default());
    let off = offline_run("scanmatch", &offline);
    assert_same_run("scanmatch", node.as_ref(), &given, off.as_ref(), &offline);
    // The branches mattered here: decided at once (no scan waits), the odometry is another.
    let at_once = slam_grid::LaserOdometryConfig {
        branch_lag: 0,
        ..Default::default()
    };
    let (_, single) = through_the_node("scanmatch", &raw.records, &at_once);
    let apart = single
        .iter()
        .zip(&offline)
        .map(|(s, o)| {
            let d = s.odometry.between(&o.odometry);
            d.x.hypot(d.y)
        })
        .fold(0.0, f64::max);
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
    let msg = message(&raw.records[0]);
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
