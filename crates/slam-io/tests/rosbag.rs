//! The ROS bag reader against bags written by an independent writer (the Python `rosbags`
//! package, `tests/fixtures/rosbag/make_fixtures.py`) from the start of the real Intel log:
//! the truth is the CARMEN log itself, read by the CARMEN reader. The same messages in every
//! container (MCAP, sqlite3, ROS 1) must give the same records.
// Every container's fixtures are read, so every bag feature is needed (all are default).
#![cfg(all(feature = "rosbag", feature = "rosbag-sqlite", feature = "rosbag1"))]

use slam_io::carmen::read_carmen;
use slam_io::rosbag::{read_mcap, read_rosbag, BagFormat, BagOptions, OdometrySource, RosBag};
use slam_io::{IoError, Pose2, ScanRecord};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The FLASER lines of intel.log the fixtures were made from (make_fixtures.py's `SCANS`):
/// the log's lines up to its 200th FLASER line.
const SCANS: usize = 200;
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

/// The CARMEN records of the lines the fixtures were made from: the log up to and with its
/// `SCANS`-th FLASER line.
fn source() -> Option<Vec<ScanRecord>> {
    let log = dataset("bench/intel.log")?;
    let text = std::fs::read_to_string(log).unwrap();
    let mut head = String::new();
    let mut flasers = 0;
    for l in text.lines() {
        head.push_str(l);
        head.push('\n');
        flasers += usize::from(l.starts_with("FLASER "));
        if flasers == SCANS {
            break;
        }
    }
    assert_eq!(flasers, SCANS, "intel.log has fewer FLASER lines");
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
    assert_eq!(flasers.len(), SCANS);
    assert_eq!(bag.iter().filter(|r| r.scan.is_some()).count(), SCANS);
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
        msg.contains("/tf_static") && msg.contains("option `laser_pose` is needed"),
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
    assert_eq!(r.laser_pose, (Pose2::IDENTITY, "option `laser_pose`"));
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
        line.contains(&format!("{SCANS} scans")) && line.contains("/odom"),
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

/// A bag with `/scan` only reads as its three scans, each a record whose odometry is the
/// identity, the base frame the laser's, and says "no odometry"; `laser_only` reads a bag
/// that has odometry the same way.
fn laser_only(path: &Path) {
    let r = read_rosbag(path, &BagOptions::default()).unwrap();
    assert_eq!(r.odometry, OdometrySource::None);
    assert_eq!((r.odometry_poses, r.dataset.records.len()), (0, 3));
    assert!(r
        .dataset
        .records
        .iter()
        .all(|r| r.odometry == Pose2::IDENTITY && r.scan.is_some()));
    assert_eq!(r.base_frame, r.laser_frame);
    assert!(
        r.summary(path).contains("no odometry"),
        "{}",
        r.summary(path)
    );
}

/// `laser_only` drops a bag's odometry: the same scans as with it, every odometry the
/// identity.
#[test]
fn laser_only_reads_the_scans_without_the_odometry() {
    let mount = BagOptions {
        laser_pose: Some(Pose2::IDENTITY),
        ..Default::default()
    };
    let with = read_rosbag(&fixture("intel-odom.mcap"), &mount).unwrap();
    let without = read_rosbag(
        &fixture("intel-odom.mcap"),
        &BagOptions {
            laser_only: true,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(without.odometry, OdometrySource::None);
    let scans = |b: &RosBag| -> Vec<(f64, slam_io::LaserScan)> {
        b.dataset
            .records
            .iter()
            .filter_map(|r| Some((r.t, r.scan.clone()?)))
            .collect()
    };
    assert_eq!(scans(&with), scans(&without));
    assert_eq!(without.dataset.records.len(), SCANS);
    assert!(without
        .dataset
        .records
        .iter()
        .all(|r| r.odometry == Pose2::IDENTITY));
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
        m.contains("/scan, /scan_rear") && m.contains("option `scan_topic` must choose"),
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

    // No odometry: the scans alone (laser-only mapping makes the odometry).
    laser_only(&fixture("bad-no-odom.mcap"));

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
    assert!(damaged("bad-two-scans.mcap", 300, 0x2545_f491_4f6c_dd1d) > 0);
}

/// Reads `runs` copies of the fixture `name`, each with 4 bytes changed anywhere (a fixed
/// xorshift sequence from `seed`, so the test is repeatable): each read must return, an
/// error or a dataset, never panic. Returns how many were errors.
fn damaged(name: &str, runs: usize, seed: u64) -> usize {
    let clean = std::fs::read(fixture(name)).unwrap();
    let p = temp(&format!("damaged-{name}"));
    let o = BagOptions {
        scan_topic: Some("/scan".into()),
        laser_pose: Some(Pose2::IDENTITY),
        ..Default::default()
    };
    let mut state = seed;
    let mut errors = 0;
    for _ in 0..runs {
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
    errors
}

#[test]
fn foreign_storage_and_whole_file_compression_are_refused_by_name() {
    let d = temp("foreign-bag");
    std::fs::create_dir_all(&d).unwrap();
    std::fs::copy(fixture("intel-tf.db3"), d.join("x_0.db3")).unwrap();
    let meta = |storage: &str, mode: &str| {
        std::fs::write(
            d.join("metadata.yaml"),
            format!(
                "rosbag2_bagfile_information:\n  compression_format: zstd\n  compression_mode: \
                 {mode}\n  storage_identifier: {storage}\n  relative_file_paths:\n  - x_0.db3\n"
            ),
        )
        .unwrap()
    };
    meta("leveldb", "''");
    let e = read_mcap(&d).unwrap_err();
    assert!(matches!(e, IoError::Invalid { .. }));
    assert!(
        e.to_string().contains("\"leveldb\" is not supported"),
        "{e}"
    );
    meta("sqlite3", "file");
    let e = read_mcap(&d).unwrap_err().to_string();
    assert!(e.contains("compression_mode file"), "{e}");
    // The same folder without compression reads like the bare file.
    meta("sqlite3", "''");
    let a = read_rosbag(&d, &BagOptions::default()).unwrap();
    let b = read_rosbag(&fixture("intel-tf.db3"), &BagOptions::default()).unwrap();
    assert_eq!(a.dataset.records, b.dataset.records);
}

/// Every container of the same messages: (fixture, its container, its odometry source).
const ODOM_BAGS: [(&str, BagFormat); 3] = [
    ("intel-odom.mcap", BagFormat::Mcap),
    ("intel-odom-db3", BagFormat::Sqlite3),
    ("intel-odom.bag", BagFormat::Ros1),
];
const TF_BAGS: [(&str, BagFormat); 3] = [
    ("intel-tf", BagFormat::Mcap),
    ("intel-tf.db3", BagFormat::Sqlite3),
    ("intel-tf.bag", BagFormat::Ros1),
];

fn read(name: &str, o: &BagOptions) -> RosBag {
    read_rosbag(&fixture(name), o).unwrap_or_else(|e| panic!("{name}: {e}"))
}

#[test]
fn sqlite_and_ros1_odometry_bags_give_the_carmen_records() {
    let opts = BagOptions {
        laser_pose: Some(Pose2::IDENTITY),
        ..Default::default()
    };
    let carmen = source();
    let mcap = read("intel-odom.mcap", &opts);
    for (name, format) in ODOM_BAGS {
        let r = read(name, &opts);
        assert_eq!(r.format, format, "{name}");
        assert_eq!(r.scan_topic, "/scan");
        assert_eq!(r.odometry, OdometrySource::Topic("/odom".into()));
        assert_eq!(r.no_return_readings, mcap.no_return_readings);
        assert_eq!(r.invalid_readings, 0);
        // The same float32 readings and float64 poses in every container: equal records.
        assert_eq!(r.dataset.records, mcap.dataset.records, "{name}");
        let line = r.summary(&fixture(name));
        assert!(
            line.starts_with(format.ros()) && line.contains(&format!("{SCANS} scans")),
            "{line}"
        );
        if let Some(c) = &carmen {
            check_against_carmen(&r.dataset.records, c);
        }
    }
}

#[test]
fn sqlite_and_ros1_tf_bags_give_the_same_records_and_the_static_mounting() {
    let d = BagOptions::default();
    let mcap = read("intel-tf", &d);
    let mount = Pose2::new(MOUNT.0, MOUNT.1, MOUNT.2);
    let carmen = source();
    for (name, format) in TF_BAGS {
        let r = read(name, &d);
        assert_eq!(r.format, format, "{name}");
        assert_eq!(
            r.odometry,
            OdometrySource::Tf {
                parent: "odom".into(),
                child: "base_link".into()
            }
        );
        assert_eq!(r.laser_pose.1, "/tf_static");
        assert_pose(&r.laser_pose.0, &mount, 1e-12, name);
        assert_eq!(r.dataset.records, mcap.dataset.records, "{name}");
        if let Some(c) = &carmen {
            check_against_carmen(&r.dataset.records, c);
        }
    }
    // ROS 1's older tf/tfMessage on /tf reads like tf2_msgs/TFMessage: its three scans are
    // the records of the same stamps in the full bag.
    let old = read("tf-old.bag", &d);
    let tf = old.topics.iter().find(|t| t.topic == "/tf").unwrap();
    assert_eq!(tf.msg_type, "tf/msg/tfMessage");
    assert_eq!(old.laser_pose.1, "/tf_static");
    let scans: Vec<&ScanRecord> = old
        .dataset
        .records
        .iter()
        .filter(|r| r.scan.is_some())
        .collect();
    assert_eq!(scans.len(), 3);
    for r in scans {
        assert!(mcap.dataset.records.contains(r), "{}", r.t);
    }
}

/// A copy of a fixture in the scratch folder, changed by SQL (sqlite3 bags).
fn sql(name: &str, new: &str, statement: &str) -> PathBuf {
    let p = temp(new);
    std::fs::copy(fixture(name), &p).unwrap();
    let db = rusqlite::Connection::open(&p).unwrap();
    db.execute_batch(statement).unwrap();
    drop(db);
    p
}

fn err_at(p: &Path, o: &BagOptions) -> String {
    match read_rosbag(p, o) {
        Ok(_) => panic!("{} read without error", p.display()),
        Err(e) => e.to_string(),
    }
}

#[test]
fn sqlite_and_ros1_mistakes_are_errors_that_say_so() {
    let d = BagOptions::default();
    for name in ["bad-two-scans.db3", "bad-two-scans.bag"] {
        let m = err(name, &d);
        assert!(
            m.contains("/scan, /scan_rear") && m.contains("option `scan_topic` must choose"),
            "{m}"
        );
        let o = BagOptions {
            scan_topic: Some("/scan_rear".into()),
            laser_pose: Some(Pose2::IDENTITY),
            ..Default::default()
        };
        let r = read_rosbag(&fixture(name), &o).unwrap();
        assert_eq!(r.scan_topic, "/scan_rear");
        assert_eq!(
            r.dataset
                .records
                .iter()
                .filter(|r| r.scan.is_some())
                .count(),
            3
        );
    }
    let o = BagOptions {
        scan_topic: Some("/scan".into()),
        laser_pose: Some(Pose2::IDENTITY),
        ..Default::default()
    };

    // sqlite3: not a bag, no odometry, a message cut short, another encoding.
    let p = sql("bad-two-scans.db3", "other.db3", "DROP TABLE messages;");
    let m = err_at(&p, &o);
    assert!(m.contains("`topics` and `messages` tables"), "{m}");
    let p = sql(
        "bad-two-scans.db3",
        "no-odom.db3",
        "DELETE FROM messages WHERE topic_id = (SELECT id FROM topics WHERE name = '/odom');
         DELETE FROM topics WHERE name = '/odom';",
    );
    let r = read_rosbag(&p, &o).unwrap();
    assert_eq!(r.odometry, OdometrySource::None);
    assert!(r
        .dataset
        .records
        .iter()
        .all(|r| r.odometry == Pose2::IDENTITY));
    let p = sql(
        "bad-two-scans.db3",
        "cut.db3",
        "UPDATE messages SET data = substr(data, 1, 40) WHERE id = (SELECT id FROM messages
         WHERE topic_id = (SELECT id FROM topics WHERE name = '/scan') ORDER BY id LIMIT 1 OFFSET 1);",
    );
    let m = err_at(&p, &o);
    assert!(
        m.contains("topic /scan: message 2")
            && m.contains("does not decode as sensor_msgs/msg/LaserScan")
            && m.contains("of the CDR body"),
        "{m}"
    );
    let p = sql(
        "bad-two-scans.db3",
        "json.db3",
        "UPDATE topics SET serialization_format = 'json' WHERE name = '/scan';",
    );
    let m = err_at(&p, &o);
    assert!(
        m.contains("topic /scan") && m.contains("\"json\"") && m.contains("expected cdr"),
        "{m}"
    );

    // ROS 1: no odometry, a message cut short, another LaserScan definition (md5sum).
    laser_only(&fixture("bad-no-odom.bag"));
    let m = err("bad-corrupt.bag", &o);
    assert!(
        m.contains("topic /scan: message 2")
            && m.contains("does not decode as sensor_msgs/msg/LaserScan")
            && m.contains("of the ROS 1 body"),
        "{m}"
    );
    let md5 = b"90c7ef2dc6895d81024acba2ac42f369";
    let mut bytes = std::fs::read(fixture("bad-two-scans.bag")).unwrap();
    let mut patched = 0;
    for k in 0..bytes.len() - md5.len() {
        if &bytes[k..k + md5.len()] == md5 {
            bytes[k..k + md5.len()].copy_from_slice(b"00000000000000000000000000000000");
            patched += 1;
        }
    }
    assert!(patched >= 2, "the LaserScan md5sum of both scan topics");
    let p = temp("md5.bag");
    std::fs::write(&p, &bytes).unwrap();
    let m = err_at(&p, &o);
    assert!(
        m.contains("topic /scan")
            && m.contains("md5sum 00000000000000000000000000000000")
            && m.contains("expected 90c7ef2dc6895d81024acba2ac42f369"),
        "{m}"
    );
}

#[test]
fn truncated_sqlite_and_ros1_bags_are_errors_that_say_how_far_reading_got() {
    for (name, what) in [
        ("intel-tf.db3", "truncated or corrupt sqlite3"),
        ("intel-odom.bag", "truncated or corrupt ROS 1 bag"),
        ("intel-tf.bag", "truncated or corrupt ROS 1 bag"),
    ] {
        let bytes = std::fs::read(fixture(name)).unwrap();
        let p = temp(&format!("cut-{name}"));
        let mut got_far = false;
        for k in 1..40 {
            let len = bytes.len() * k / 40;
            std::fs::write(&p, &bytes[..len]).unwrap();
            let e = err_at(&p, &BagOptions::default());
            assert!(
                e.contains(what) || e.contains("not a bag"),
                "{name} cut at {len}: {e}"
            );
            got_far |= e.contains("message(s) read before the damage")
                && !e.contains(" 0 message(s)")
                && e.contains("the last logged at");
        }
        // The ROS 1 reader reads up to the damage; SQLite's pages are checked first.
        if name.ends_with(".bag") {
            assert!(got_far, "{name}: no cut reported messages read");
        }
    }
    // The index of a ROS 1 bag cut away whole, at its `index_pos` (a cut between records,
    // every message still there): still an error.
    let bytes = std::fs::read(fixture("bad-two-scans.bag")).unwrap();
    let key = b"index_pos=";
    let k = bytes.windows(key.len()).position(|w| w == key).unwrap() + key.len();
    let index_pos = u64::from_le_bytes(bytes[k..k + 8].try_into().unwrap()) as usize;
    assert!(index_pos > 4096 && index_pos < bytes.len());
    let p = temp("no-index.bag");
    std::fs::write(&p, &bytes[..index_pos]).unwrap();
    let e = err_at(&p, &BagOptions::default());
    assert!(
        e.contains("truncated or corrupt ROS 1 bag") && e.contains("0 chunk-info record(s)"),
        "{e}"
    );
    // The same bytes as an unindexed bag (`index_pos` 0, as rosbag leaves a recording that
    // was cut short): every message is read.
    let mut unindexed = bytes[..index_pos].to_vec();
    unindexed[k..k + 8].copy_from_slice(&0u64.to_le_bytes());
    std::fs::write(&p, &unindexed).unwrap();
    let o = BagOptions {
        scan_topic: Some("/scan".into()),
        laser_pose: Some(Pose2::IDENTITY),
        ..Default::default()
    };
    let a = read_rosbag(&p, &o).unwrap();
    let b = read_rosbag(&fixture("bad-two-scans.bag"), &o).unwrap();
    assert_eq!(a.dataset.records, b.dataset.records);
    assert_eq!(a.topics, b.topics);
}

#[test]
fn damaged_sqlite_and_ros1_bags_never_panic() {
    assert!(damaged("bad-two-scans.bag", 300, 0x9e37_79b9_7f4a_7c15) > 0);
    assert!(damaged("bad-two-scans.db3", 100, 0x6a09_e667_f3bc_c908) > 0);
}

/// Special readings and values out of bounds, in every container (the bad-bounds bags,
/// make_fixtures.py's `bounds_bag`, written by rosbags): NaN, ±∞ and out-of-range readings
/// are read as LaserScan defines them; each broken topic is an error naming the file, the
/// topic, the message and the bound, the bounds of every other reader (coordinates within
/// ±10⁶ m, 0 ≤ range_min < range_max ≤ 1000 m, angles within one turn, a non-zero angle
/// increment, odometry stamps within 10⁷ s of each other); the valid topics beside them read.
#[test]
fn special_readings_and_values_out_of_bounds_in_every_container() {
    let o = |scan: &str, odom: &str| BagOptions {
        scan_topic: Some(scan.into()),
        odom_topic: Some(odom.into()),
        laser_pose: Some(Pose2::IDENTITY),
        ..Default::default()
    };
    for (name, format) in [
        ("bad-bounds.mcap", BagFormat::Mcap),
        ("bad-bounds.db3", BagFormat::Sqlite3),
        ("bad-bounds.bag", BagFormat::Ros1),
    ] {
        let r = read(name, &o("/scan", "/odom"));
        assert_eq!(r.format, format);
        let scans = r.dataset.records.iter().filter(|r| r.scan.is_some());
        assert_eq!(scans.count(), 3, "{name}");
        // The readings LaserScan defines as special (beams 0–4 of /scan_odd: NaN, −∞, +∞,
        // range_max + 1, −1): invalid, invalid, no return, no return, invalid; all kept as
        // no-return beams (range_max), counted apart; every other beam as on /scan.
        let odd = read(name, &o("/scan_odd", "/odom"));
        assert_eq!(odd.invalid_readings, 3 * 3, "{name}");
        let mut no_return = r.no_return_readings;
        for (a, b) in r.dataset.records.iter().zip(&odd.dataset.records) {
            assert_eq!(a.t, b.t);
            let (Some(sa), Some(sb)) = (&a.scan, &b.scan) else {
                assert_eq!(a, b);
                continue;
            };
            for k in 0..5 {
                assert!(!sb.is_hit(k), "{name} beam {k}");
                assert_eq!(sb.ranges[k], sb.max_range);
                no_return -= usize::from(!sa.is_hit(k));
            }
            no_return += 2;
            assert_eq!(sa.ranges[5..], sb.ranges[5..]);
        }
        assert_eq!(odd.no_return_readings, no_return, "{name}");
        for (scan, odom, wants) in [
            (
                "/scan_far",
                "/odom",
                &[
                    "topic /scan_far: message 1",
                    "range_max = 2000 m, expected 0 < range_max ≤ 1000 m",
                ][..],
            ),
            (
                "/scan_flat",
                "/odom",
                &[
                    "topic /scan_flat: message 1",
                    "angle_increment = 0 rad",
                    "expected a non-zero increment",
                ],
            ),
            (
                "/scan_wide",
                "/odom",
                &[
                    "topic /scan_wide: message 1",
                    "angle_min = -10 rad is outside ±2π",
                ],
            ),
            (
                "/scan_short",
                "/odom",
                &[
                    "topic /scan_short: message 1",
                    "range_min = 81.83",
                    "expected 0 ≤ range_min < range_max",
                ],
            ),
            (
                "/scan",
                "/odom_far",
                &[
                    "topic /odom_far: message 1",
                    "odom → base_link x = 2000000 m is outside ±1000000 m",
                ],
            ),
            (
                "/scan",
                "/odom_nan",
                &[
                    "topic /odom_nan: message 1",
                    "a rotation quaternion of non-zero length, found (0, 0, NaN, NaN)",
                ],
            ),
            (
                "/scan",
                "/odom_unset",
                &[
                    "topic /odom_unset",
                    "odometry stamps from 0 s",
                    "expected a span within 10000000 s",
                ],
            ),
        ] {
            let m = err(name, &o(scan, odom));
            assert!(
                m.contains(name) && wants.iter().all(|w| m.contains(w)),
                "{name} {scan} {odom}: {m}"
            );
        }
    }
}

/// The laser + IMU fixtures (make_laser_only_fixtures.py, the `rosbags` writer): `/imu`'s
/// `angular_velocity.z` read from MCAP and from the ROS 1 bag (whose `sensor_msgs/Imu`
/// md5sum is checked) are the same 3421 rates, sampled every 0.2 s, and they follow the
/// heading rate of the CARMEN log's odometry they were derived from (white noise of
/// 0.01 rad/s and a bias of 0.002 rad/s added: mean absolute difference below 0.012 rad/s,
/// where a wrong field would differ by the rate itself). The scans are those of the
/// odometry bag, and there is no odometry.
#[test]
fn imu_yaw_rates_are_read_from_mcap_and_ros1() {
    let o = BagOptions {
        imu_topic: Some("/imu".into()),
        ..Default::default()
    };
    let mcap = read_rosbag(&fixture("intel-laser-imu.mcap"), &o).unwrap();
    let bag1 = read_rosbag(&fixture("intel-laser-imu.bag"), &o).unwrap();
    assert_eq!(mcap.odometry, OdometrySource::None);
    assert_eq!(mcap.yaw_rates.len(), 3421);
    assert_eq!(mcap.yaw_rates, bag1.yaw_rates);
    assert!(mcap
        .yaw_rates
        .windows(2)
        .all(|w| (w[1].t - w[0].t - 0.2).abs() < 1e-6));
    let mount = BagOptions {
        laser_pose: Some(Pose2::IDENTITY),
        ..Default::default()
    };
    let with_odom = read_rosbag(&fixture("intel-odom.mcap"), &mount).unwrap();
    let scans = |b: &RosBag| -> Vec<slam_io::LaserScan> {
        b.dataset
            .records
            .iter()
            .filter_map(|r| r.scan.clone())
            .collect()
    };
    assert_eq!(scans(&mcap), scans(&with_odom));
    assert!(mcap.summary(Path::new("x")).contains("3421 IMU yaw rates"));
    // Without --imu-topic the IMU is not read; a topic of another type is refused.
    let plain = read_rosbag(&fixture("intel-laser-imu.mcap"), &BagOptions::default()).unwrap();
    assert!(plain.yaw_rates.is_empty());
    let m = err(
        "intel-laser-imu.mcap",
        &BagOptions {
            imu_topic: Some("/scan".into()),
            ..Default::default()
        },
    );
    assert!(
        m.contains("option `imu_topic`") && m.contains("sensor_msgs/msg/Imu"),
        "{m}"
    );

    let Some(records) = source() else { return };
    // The odometry's heading rate over each interval of distinct stamps, in whole
    // microseconds (the log's precision; the IMU samples fall on odometry stamps).
    let us = |t: f64| (t * 1e6).round() as i64;
    let mut pieces: Vec<(i64, i64, f64)> = Vec::new();
    let mut prev = (us(records[0].t), records[0].odometry.theta);
    for r in &records[1..] {
        let t = us(r.t);
        if t - prev.0 > 1000 {
            let d = r.odometry.theta - prev.1;
            let d = d.sin().atan2(d.cos());
            pieces.push((prev.0, t, d / ((t - prev.0) as f64 * 1e-6)));
            prev = (t, r.odometry.theta);
        }
    }
    let mut diff = 0.0;
    for w in &mcap.yaw_rates {
        let t = us(w.t);
        let p = pieces
            .iter()
            .find(|p| p.0 <= t && t < p.1)
            .unwrap_or(pieces.last().unwrap());
        diff += (w.rate - p.2).abs();
    }
    let mean = diff / mcap.yaw_rates.len() as f64;
    assert!(mean < 0.012, "mean |imu − odometry rate| = {mean} rad/s");
}

// ---------------------------------------------------------------------------------------
// ROS 1 bags written by the OFFICIAL writer, `rosbag.Bag` of Debian's python3-rosbag
// (make_rosbag1_fixtures.py), from the same CARMEN lines: the truth is again the CARMEN log.

/// make_rosbag1_fixtures.py's `OFFSET`: the odom-offset bag's odometry is OFFSET ⊕ o.
const OFFSET: (f64, f64, f64) = (20.0, -6.0, 0.8);
/// make_rosbag1_fixtures.py's `TWO_CHAIN_SCALE`: odom → base_link is the log's odometry
/// with its translation scaled by this.
const TWO_CHAIN_SCALE: f64 = 1.05;

/// The scans of a bag, in order.
fn scans_of(b: &RosBag) -> Vec<(f64, slam_io::LaserScan)> {
    b.dataset
        .records
        .iter()
        .filter_map(|r| Some((r.t, r.scan.clone()?)))
        .collect()
}

/// The CARMEN records with every odometry pose o replaced by `f(o)`.
fn carmen_mapped(carmen: &[ScanRecord], f: impl Fn(&Pose2) -> Pose2) -> Vec<ScanRecord> {
    carmen
        .iter()
        .map(|r| ScanRecord {
            odometry: f(&r.odometry),
            ..r.clone()
        })
        .collect()
}

/// The 2010 index bag: every index data record's data length is count × 24 (the ROS 1.1
/// writer's `sizeof(IndexEntry)`), not count × 12 (checked here on the file's bytes, so the
/// fixture cannot silently lose the defect); read by entry count, as the official reader
/// does, it gives the CARMEN records, the same as the `rosbags`-written odometry bag.
#[test]
fn a_bag_with_2010_index_records_reads_in_full() {
    let path = fixture("rosbag1-index-2010.bag");
    let bytes = std::fs::read(&path).unwrap();
    // Every index data record: header fields op=0x04, ver, conn, count (in any order).
    let (mut seen, mut pos) = (0, 13);
    let u32_at = |p: usize| u32::from_le_bytes(bytes[p..p + 4].try_into().unwrap()) as usize;
    while pos < bytes.len() {
        let hlen = u32_at(pos);
        let (mut p, mut op, mut count) = (pos + 4, 0u8, None);
        while p < pos + 4 + hlen {
            let flen = u32_at(p);
            let f = &bytes[p + 4..p + 4 + flen];
            if f == [b'o', b'p', b'=', 4] {
                op = 4;
            } else if let Some(v) = f.strip_prefix(b"count=") {
                count = Some(u32::from_le_bytes(v.try_into().unwrap()) as usize);
            }
            p += 4 + flen;
        }
        let dlen = u32_at(p);
        pos = p + 4 + dlen;
        if op == 4 {
            let count = count.unwrap();
            assert_eq!(dlen, 24 * count, "index record at {p}");
            seen += 1;
            // The entries really are 12 bytes each: continue after them.
            pos = p + 4 + 12 * count;
        }
    }
    assert!(seen > 100, "{seen} index records");
    let mount = BagOptions {
        laser_pose: Some(Pose2::IDENTITY),
        ..Default::default()
    };
    let r = read_rosbag(&path, &mount).unwrap();
    assert_eq!(r.format, BagFormat::Ros1);
    assert_eq!(r.odometry, OdometrySource::Topic("/odom".into()));
    let other = read_rosbag(&fixture("intel-odom.bag"), &mount).unwrap();
    assert_eq!(r.dataset.records, other.dataset.records);
    let Some(carmen) = source() else { return };
    check_against_carmen(&r.dataset.records, &carmen);
}

/// The laser-only and laser + IMU bags of the official writer: no odometry, the scans of
/// the `rosbags`-written bags, and the IMU's 3421 yaw rates equal to those of
/// intel-laser-imu.mcap (the same formula and seed, another writer and container).
#[test]
fn official_laser_only_and_imu_bags_read_like_the_rosbags_ones() {
    let imu = BagOptions {
        imu_topic: Some("/imu".into()),
        ..Default::default()
    };
    let reference = read_rosbag(&fixture("intel-laser-imu.mcap"), &imu).unwrap();
    for name in ["rosbag1-laser-only.bag", "rosbag1-laser-imu.bag"] {
        let o = if name.contains("imu") {
            imu.clone()
        } else {
            BagOptions::default()
        };
        let r = read_rosbag(&fixture(name), &o).unwrap();
        assert_eq!(r.odometry, OdometrySource::None, "{name}");
        assert_eq!(r.dataset.records.len(), SCANS, "{name}");
        assert_eq!(scans_of(&r), scans_of(&reference), "{name}");
        assert!(r.summary(Path::new(name)).contains("no odometry"));
        if name.contains("imu") {
            assert_eq!(r.yaw_rates.len(), 3421);
            assert_eq!(r.yaw_rates, reference.yaw_rates);
        }
    }
}

/// The bag whose odometry starts away from the origin: every odometry pose is OFFSET ⊕ the
/// CARMEN one (the first (20, −6, 0.8)), the scans unchanged.
#[test]
fn odometry_away_from_the_origin_is_read_as_written() {
    let mount = BagOptions {
        laser_pose: Some(Pose2::IDENTITY),
        ..Default::default()
    };
    let r = read_rosbag(&fixture("rosbag1-odom-offset.bag"), &mount).unwrap();
    let first = r.dataset.records[0].odometry;
    assert_pose(
        &first,
        &Pose2::new(OFFSET.0, OFFSET.1, OFFSET.2),
        1e-9,
        "first",
    );
    let Some(carmen) = source() else { return };
    let t = Pose2::new(OFFSET.0, OFFSET.1, OFFSET.2);
    let moved = carmen_mapped(&carmen, |o| {
        let p = t.compose(o);
        // The quaternion the bag holds gives the heading back in (−π, π].
        Pose2::new(p.x, p.y, p.theta.sin().atan2(p.theta.cos()))
    });
    check_against_carmen(&r.dataset.records, &moved);
}

/// Two odometry chains out of `odom` in `/tf` (odom → base_footprint, odom → base_link):
/// without `base_frame` the reader refuses, naming both and the option; with it, the chain
/// named is read (base_footprint: the CARMEN odometry; base_link: its translation × 1.05)
/// and the laser mounting is found through `/tf_static` from that frame (base_footprint →
/// base_link → laser, or base_link → laser: MOUNT either way).
#[test]
fn two_odometry_chains_are_told_apart_by_the_base_frame() {
    let path = fixture("rosbag1-two-chains.bag");
    let e = read_rosbag(&path, &BagOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        // The option by its library or CLI name (`base_frame`, `--base-frame`).
        e.contains("base_footprint")
            && e.contains("base_link")
            && (e.contains("base_frame") || e.contains("base-frame")),
        "{e}"
    );
    let carmen = source();
    let mount = Pose2::new(MOUNT.0, MOUNT.1, MOUNT.2);
    for (base, scale) in [("base_footprint", 1.0), ("base_link", TWO_CHAIN_SCALE)] {
        let o = BagOptions {
            base_frame: Some(base.into()),
            ..Default::default()
        };
        let r = read_rosbag(&path, &o).unwrap();
        assert_eq!(
            r.odometry,
            OdometrySource::Tf {
                parent: "odom".into(),
                child: base.into()
            }
        );
        for rec in &r.dataset.records {
            if let Some(s) = &rec.scan {
                assert_pose(&s.sensor_pose, &mount, 1e-12, base);
            }
        }
        if let Some(carmen) = &carmen {
            let want = carmen_mapped(carmen, |o| Pose2::new(scale * o.x, scale * o.y, o.theta));
            check_against_carmen(&r.dataset.records, &want);
        }
    }
}
