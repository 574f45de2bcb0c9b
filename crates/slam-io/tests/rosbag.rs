//! The ROS 2 bag reader against bags written by an independent writer (the Python `rosbags`
//! package, `tests/fixtures/rosbag/make_fixtures.py`) from the start of the real Intel log:
//! the truth is the CARMEN log itself, read by the CARMEN reader.
#![cfg(feature = "rosbag")]

use slam_io::carmen::read_carmen;
use slam_io::rosbag::{read_mcap, read_rosbag, BagOptions, OdometrySource};
use slam_io::{IoError, Pose2, ScanRecord};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Lines of intel.log the fixtures were made from (up to its 40th FLASER line).
const SOURCE_LINES: usize = 875;
/// The laser mounting written to `/tf_static` by make_fixtures.py (`MOUNT`).
const MOUNT: (f64, f64, f64) = (0.12, -0.03, 0.05);

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures/rosbag")
        .join(name)
}

/// `../shared/datasets` beside the checkout (or `$SLAM_DATASETS`); `None` with a SKIPPED
/// line when missing, a failure under `CI=true`.
fn dataset(rel: &str) -> Option<PathBuf> {
    let base = std::env::var_os("SLAM_DATASETS")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/datasets"));
    let p = base.join(rel);
    if p.exists() {
        return Some(p);
    }
    if std::env::var("CI").is_ok_and(|v| v == "true" || v == "1") {
        panic!("dataset {} is missing and CI=true", p.display());
    }
    eprintln!("SKIPPED: dataset {} not found", p.display());
    None
}

fn temp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("slam-io-rosbag-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

/// The CARMEN records of the lines the fixtures were made from.
fn source() -> Option<Vec<ScanRecord>> {
    let log = dataset("bench/intel.log")?;
    let text = std::fs::read_to_string(log).unwrap();
    let head: String = text
        .lines()
        .take(SOURCE_LINES)
        .map(|l| format!("{l}\n"))
        .collect();
    let p = temp("intel-head.log");
    std::fs::write(&p, head).unwrap();
    Some(read_carmen(&p).unwrap().dataset.records)
}

/// A time as whole microseconds (the CARMEN log's resolution; an f64 Unix time holds
/// about 0.1 µs).
fn ns(t: f64) -> i64 {
    (t * 1e6).round() as i64
}

fn assert_pose(a: &Pose2, b: &Pose2, tol: f64, what: &str) {
    assert!(
        (a.x - b.x).abs() <= tol && (a.y - b.y).abs() <= tol && (a.theta - b.theta).abs() <= tol,
        "{what}: {a:?} vs {b:?}"
    );
}

/// Every FLASER line is a scan record at its time with the same readings (to float32
/// precision), beam angles, no-return beams and odometry; every other stamp of the source
/// is an odometry record holding the first ODOM pose of that stamp.
fn check_against_carmen(bag: &[ScanRecord], carmen: &[ScanRecord]) {
    let mut by_stamp: BTreeMap<i64, Vec<&ScanRecord>> = BTreeMap::new();
    for r in bag {
        by_stamp.entry(ns(r.t)).or_default().push(r);
    }
    let flasers: Vec<&ScanRecord> = carmen.iter().filter(|r| r.scan.is_some()).collect();
    assert_eq!(flasers.len(), 40);
    assert_eq!(bag.iter().filter(|r| r.scan.is_some()).count(), 40);
    for c in &flasers {
        let recs = &by_stamp[&ns(c.t)];
        assert_eq!(recs.len(), 1, "one record at {}", c.t);
        let (b, cs) = (recs[0], c.scan.as_ref().unwrap());
        let bs = b.scan.as_ref().expect("a scan record");
        assert!((b.t - c.t).abs() < 1e-6);
        assert_pose(&b.odometry, &c.odometry, 1e-9, "odometry at a scan");
        assert_eq!(bs.len(), cs.len());
        assert!((bs.angle_min - cs.angle_min).abs() < 1e-6);
        assert!((bs.angle_increment - cs.angle_increment).abs() < 1e-7);
        assert!((bs.max_range - cs.max_range).abs() < 1e-5);
        for k in 0..cs.len() {
            assert_eq!(bs.is_hit(k), cs.is_hit(k), "beam {k} at {}", c.t);
            if cs.is_hit(k) {
                assert!((bs.ranges[k] - cs.ranges[k]).abs() <= 1e-6 * cs.ranges[k].max(1.0));
            }
        }
    }
    let mut first_odom: BTreeMap<i64, &ScanRecord> = BTreeMap::new();
    for r in carmen {
        first_odom.entry(ns(r.t)).or_insert(r);
    }
    assert_eq!(
        by_stamp.len(),
        first_odom.len(),
        "one record per distinct stamp"
    );
    for (t, c) in &first_odom {
        let b = by_stamp[t][0];
        if c.scan.is_none() && !flasers.iter().any(|f| ns(f.t) == *t) {
            assert!(b.scan.is_none());
            assert_pose(&b.odometry, &c.odometry, 1e-9, "odometry record");
        }
    }
    // Time order.
    assert!(bag.windows(2).all(|w| w[0].t <= w[1].t));
}

#[test]
fn odometry_bag_gives_the_carmen_scans_and_poses() {
    // The laser frame is not linked to base_link in this bag: the mounting must be given.
    let e = read_rosbag(&fixture("intel-odom.mcap"), &BagOptions::default()).unwrap_err();
    let msg = e.to_string();
    assert!(
        msg.contains("/tf_static") && msg.contains("--laser-pose"),
        "{msg}"
    );
    let Some(carmen) = source() else { return };
    let opts = BagOptions {
        laser_pose: Some(Pose2::IDENTITY),
        ..Default::default()
    };
    let r = read_rosbag(&fixture("intel-odom.mcap"), &opts).unwrap();
    assert_eq!(r.scan_topic, "/scan");
    assert_eq!(r.odometry, OdometrySource::Topic("/odom".into()));
    assert_eq!(r.laser_pose, (Pose2::IDENTITY, "--laser-pose"));
    check_against_carmen(&r.dataset.records, &carmen);
    assert_eq!(r.scans_outside_odometry, 0);
    assert_eq!(r.invalid_readings, 0);
    // The CARMEN reader's no-return readings are the bag's +inf readings.
    let no_return: usize = carmen
        .iter()
        .filter_map(|c| c.scan.as_ref())
        .map(|s| (0..s.len()).filter(|&k| !s.is_hit(k)).count())
        .sum();
    assert!(no_return > 0);
    assert_eq!(r.no_return_readings, no_return);
    let line = r.summary(&fixture("intel-odom.mcap"));
    assert!(
        line.contains("40 scans") && line.contains("/odom"),
        "{line}"
    );
}

#[test]
fn tf_bag_folder_gives_the_same_records_and_the_static_mounting() {
    let folder = fixture("intel-tf");
    let r = read_rosbag(&folder, &BagOptions::default()).unwrap();
    assert_eq!(
        r.odometry,
        OdometrySource::Tf {
            parent: "odom".into(),
            child: "base_link".into()
        }
    );
    assert_eq!(r.laser_pose.1, "/tf_static");
    let mount = Pose2::new(MOUNT.0, MOUNT.1, MOUNT.2);
    for rec in &r.dataset.records {
        if let Some(s) = &rec.scan {
            assert_pose(&s.sensor_pose, &mount, 1e-12, "mounting");
        }
    }
    let line = r.summary(&folder);
    assert!(
        line.contains("/tf odom → base_link") && line.contains("/tf_static"),
        "{line}"
    );
    // --laser-pose replaces /tf_static.
    let p = Pose2::new(0.5, 0.0, 0.0);
    let o = BagOptions {
        laser_pose: Some(p),
        ..Default::default()
    };
    let r2 = read_rosbag(&folder, &o).unwrap();
    assert_eq!(
        r2.dataset
            .records
            .iter()
            .find_map(|r| r.scan.as_ref())
            .unwrap()
            .sensor_pose,
        p
    );
    let Some(carmen) = source() else { return };
    check_against_carmen(&r.dataset.records, &carmen);
    // The same data as the /odom bag, record by record.
    let o = BagOptions {
        laser_pose: Some(mount),
        ..Default::default()
    };
    let odom = read_rosbag(&fixture("intel-odom.mcap"), &o).unwrap();
    assert_eq!(odom.dataset.records.len(), r.dataset.records.len());
    for (a, b) in odom.dataset.records.iter().zip(&r.dataset.records) {
        assert_eq!(a.t, b.t);
        assert_pose(&a.odometry, &b.odometry, 1e-12, "tf vs odom");
        assert_eq!(a.scan.is_some(), b.scan.is_some());
        if let (Some(sa), Some(sb)) = (&a.scan, &b.scan) {
            assert_eq!(sa.ranges, sb.ranges);
            assert_pose(&sa.sensor_pose, &sb.sensor_pose, 1e-12, "mounting");
        }
    }
}

#[test]
fn big_endian_cdr_reads_like_little_endian() {
    let o = BagOptions {
        laser_pose: Some(Pose2::IDENTITY),
        ..Default::default()
    };
    let be = read_rosbag(&fixture("big-endian.mcap"), &o).unwrap();
    let le = read_rosbag(&fixture("intel-odom.mcap"), &o).unwrap();
    let scans: Vec<&ScanRecord> = be.dataset.records.iter().collect();
    assert_eq!(scans.len(), 3);
    for b in scans {
        let a = le
            .dataset
            .records
            .iter()
            .find(|a| a.t == b.t && a.scan.is_some())
            .unwrap();
        assert_eq!(a, b);
    }
}

fn err(name: &str, o: &BagOptions) -> String {
    match read_rosbag(&fixture(name), o) {
        Ok(_) => panic!("{name} read without error"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn ambiguous_missing_and_broken_topics_are_errors_that_say_so() {
    let d = BagOptions::default();
    let m = err("bad-two-scans.mcap", &d);
    assert!(
        m.contains("/scan, /scan_rear") && m.contains("--scan-topic"),
        "{m}"
    );
    let o = BagOptions {
        scan_topic: Some("/scan_rear".into()),
        laser_pose: Some(Pose2::IDENTITY),
        ..Default::default()
    };
    let r = read_rosbag(&fixture("bad-two-scans.mcap"), &o).unwrap();
    assert_eq!(r.scan_topic, "/scan_rear");
    let o = BagOptions {
        scan_topic: Some("/odom".into()),
        ..Default::default()
    };
    let m = err("bad-two-scans.mcap", &o);
    assert!(
        m.contains("nav_msgs/msg/Odometry topic, expected sensor_msgs/msg/LaserScan"),
        "{m}"
    );
    let o = BagOptions {
        odom_topic: Some("/wheel".into()),
        ..Default::default()
    };
    let m = err("intel-odom.mcap", &o);
    assert!(m.contains("topic /wheel") && m.contains("/odom"), "{m}");

    let m = err("bad-no-odom.mcap", &d);
    assert!(m.contains("no odometry") && m.contains("/tf"), "{m}");

    let m = err("bad-corrupt.mcap", &d);
    assert!(
        m.contains("topic /scan: message 2")
            && m.contains("does not decode as sensor_msgs/msg/LaserScan"),
        "{m}"
    );

    let m = err("bad-encoding.mcap", &d);
    assert!(
        m.contains("topic /scan") && m.contains("\"json\"") && m.contains("expected cdr"),
        "{m}"
    );
}

#[test]
fn truncated_and_damaged_files_are_errors_not_panics() {
    let bytes = std::fs::read(fixture("intel-odom.mcap")).unwrap();
    let p = temp("cut.mcap");
    // Every cut is an error; the message says how far reading got.
    for k in 1..40 {
        let len = bytes.len() * k / 40;
        std::fs::write(&p, &bytes[..len]).unwrap();
        let e = read_mcap(&p).unwrap_err().to_string();
        assert!(
            e.contains("truncated or corrupt MCAP") || e.contains("not an MCAP file"),
            "cut at {len}: {e}"
        );
        if k == 20 {
            assert!(e.contains(" message(s) read before the damage"), "{e}");
        }
    }
    // Bytes changed anywhere in an uncompressed bag: an error or a reading, never a panic
    // (a fixed pseudo-random sequence of positions, so the test is repeatable).
    let clean = std::fs::read(fixture("bad-two-scans.mcap")).unwrap();
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let o = BagOptions {
        scan_topic: Some("/scan".into()),
        laser_pose: Some(Pose2::IDENTITY),
        ..Default::default()
    };
    let mut errors = 0;
    for _ in 0..300 {
        let mut b = clean.clone();
        for _ in 0..4 {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let at = (state % b.len() as u64) as usize;
            b[at] = (state >> 32) as u8;
        }
        std::fs::write(&p, &b).unwrap();
        if read_rosbag(&p, &o).is_err() {
            errors += 1;
        }
    }
    assert!(errors > 0);
}

#[test]
fn sqlite_storage_and_foreign_folders_are_refused_by_name() {
    let d = temp("sqlite-bag");
    std::fs::create_dir_all(&d).unwrap();
    std::fs::write(
        d.join("metadata.yaml"),
        "rosbag2_bagfile_information:\n  storage_identifier: sqlite3\n  relative_file_paths:\n  - x_0.db3\n",
    )
    .unwrap();
    let e = read_mcap(&d).unwrap_err();
    assert!(matches!(e, IoError::Invalid { .. }));
    assert!(
        e.to_string().contains("\"sqlite3\" is not supported"),
        "{e}"
    );
}
