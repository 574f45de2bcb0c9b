//! `slam run --mcap`: the run written as an MCAP file of ROS 2 messages. The file's every
//! message is decoded by slam-io's own tests and by independent Python readers (`cargo
//! xtask eval mcap`); here the file written from a real bag is read back as a bag: the
//! topics and counts, the same records as the input, and the same trajectory when run again.

mod common;
use common::{scratch, slam};

use slam_io::rosbag::{bag_topics, read_rosbag, BagOptions};
use std::path::Path;

fn fixture(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../slam-io/tests/fixtures/rosbag")
        .join(name)
        .display()
        .to_string()
}

fn tum(path: &Path) -> Vec<Vec<f64>> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|l| l.split_whitespace().map(|f| f.parse().unwrap()).collect())
        .collect()
}

#[test]
fn a_bag_run_written_as_mcap_reads_back_as_the_same_bag() {
    let dir = scratch("roundtrip");
    let bag = fixture("intel-tf");
    let (out, mcap) = (dir.join("out"), dir.join("run.mcap"));
    let (r, text) = slam(&[
        "run",
        "--filter",
        "gridfast",
        "--particles",
        "10",
        "--dataset",
        &bag,
        "--quiet",
        "--out",
        out.to_str().unwrap(),
        "--mcap",
        mcap.to_str().unwrap(),
        "--mcap-every",
        "100",
    ]);
    r.unwrap();
    assert!(text.contains("ROS 2 messages"), "{text}");
    assert!(!dir.join("run.mcap.partial").exists());

    // Topics and counts: one pose, tf and particle cloud per record, the 200 scans, the
    // mounting once, a snapshot every 100 records plus the end.
    let input = read_rosbag(Path::new(&bag), &BagOptions::default()).unwrap();
    let n = input.dataset.records.len();
    let trajectory = tum(&out.join("trajectory.tum"));
    assert_eq!(trajectory.len(), n);
    let topics = bag_topics(&mcap).unwrap();
    let count = |t: &str| topics.iter().find(|i| i.topic == t).map(|i| i.count);
    let snaps = n / 100 + 1;
    for (topic, ty, want) in [
        ("/pose", "geometry_msgs/msg/PoseStamped", n),
        ("/tf", "tf2_msgs/msg/TFMessage", n),
        ("/particles", "geometry_msgs/msg/PoseArray", n),
        ("/scan", "sensor_msgs/msg/LaserScan", 200),
        ("/tf_static", "tf2_msgs/msg/TFMessage", 1),
        ("/map", "nav_msgs/msg/OccupancyGrid", snaps),
        ("/trajectory", "nav_msgs/msg/Path", snaps),
    ] {
        assert_eq!(count(topic), Some(want), "{topic}");
        let info = topics.iter().find(|i| i.topic == topic).unwrap();
        assert_eq!(
            (info.msg_type.as_str(), info.encoding.as_str()),
            (ty, "cdr")
        );
    }
    assert_eq!(topics.len(), 7);

    // Read as a bag: /scan, odometry from /tf odom → base_link, the laser mounting from
    // /tf_static: the records of the input bag (times to the nanosecond stamps, poses to
    // the quaternion round trip).
    let again = read_rosbag(&mcap, &BagOptions::default()).unwrap();
    assert_eq!(again.laser_pose.1, "/tf_static");
    let (p, q) = (again.laser_pose.0, input.laser_pose.0);
    assert!((p.x - q.x).abs() < 1e-12 && (p.theta - q.theta).abs() < 1e-12);
    assert_eq!(again.dataset.records.len(), n);
    for (a, b) in again.dataset.records.iter().zip(&input.dataset.records) {
        assert!((a.t - b.t).abs() < 1e-6);
        assert!((a.odometry.x - b.odometry.x).abs() < 1e-12);
        assert!((a.odometry.y - b.odometry.y).abs() < 1e-12);
        assert!((a.odometry.theta - b.odometry.theta).abs() < 1e-12);
        assert_eq!(a.scan.is_some(), b.scan.is_some());
        if let (Some(s), Some(t)) = (&a.scan, &b.scan) {
            assert_eq!(s.ranges, t.ranges);
            assert_eq!(s.max_range, t.max_range);
            assert_eq!(
                (s.angle_min, s.angle_increment),
                (t.angle_min, t.angle_increment)
            );
        }
    }

    // The written file is an input like any bag: the same filter gives the same path.
    let out2 = dir.join("out2");
    let (r, _) = slam(&[
        "run",
        "--filter",
        "gridfast",
        "--particles",
        "10",
        "--dataset",
        mcap.to_str().unwrap(),
        "--quiet",
        "--out",
        out2.to_str().unwrap(),
    ]);
    r.unwrap();
    let second = tum(&out2.join("trajectory.tum"));
    assert_eq!(second.len(), trajectory.len());
    for (a, b) in second.iter().zip(&trajectory) {
        for k in 1..8 {
            assert!((a[k] - b[k]).abs() < 1e-6, "{a:?} vs {b:?}");
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn mcap_paths_that_would_lose_data_are_refused_before_the_run() {
    let dir = scratch("refuse");
    let bag = dir.join("in.mcap");
    std::fs::copy(fixture("intel-odom.mcap"), &bag).unwrap();
    let before = std::fs::read(&bag).unwrap();
    let out = dir.join("out");
    let run = |mcap: &Path| {
        slam(&[
            "run",
            "--filter",
            "gridfast",
            "--dataset",
            bag.to_str().unwrap(),
            "--quiet",
            "--out",
            out.to_str().unwrap(),
            "--mcap",
            mcap.to_str().unwrap(),
        ])
        .0
        .unwrap_err()
        .to_string()
    };
    let e = run(&bag);
    assert!(e.contains("it is the --dataset input"), "{e}");
    assert_eq!(std::fs::read(&bag).unwrap(), before);
    let e = run(&out.join("run.mcap"));
    assert!(e.contains("inside the output folder"), "{e}");
    let notes = dir.join("notes.txt");
    std::fs::write(&notes, "mine").unwrap();
    let e = run(&notes);
    assert!(e.contains("not an MCAP file"), "{e}");
    assert_eq!(std::fs::read_to_string(&notes).unwrap(), "mine");
    // An MCAP file another program wrote (rosbags' writer): left alone without --force.
    let theirs = dir.join("theirs.mcap");
    std::fs::copy(fixture("intel-tf/intel-tf.mcap"), &theirs).unwrap();
    let e = run(&theirs);
    assert!(
        e.contains("an MCAP file slam did not write") && e.contains("--force replaces it"),
        "{e}"
    );
    assert_eq!(
        std::fs::read(&theirs).unwrap(),
        std::fs::read(fixture("intel-tf/intel-tf.mcap")).unwrap()
    );
    // With --force it is replaced by the run's MCAP (its header's library is slam's now);
    // --force never replaces a file that is not MCAP.
    let forced = |mcap: &Path| {
        slam(&[
            "run",
            "--filter",
            "scanmatch",
            "--dataset",
            bag.to_str().unwrap(),
            "--laser-pose",
            "0,0,0",
            "--quiet",
            "--out",
            dir.join("forced").to_str().unwrap(),
            "--mcap",
            mcap.to_str().unwrap(),
            "--force",
        ])
        .0
    };
    forced(&theirs).unwrap();
    let now = std::fs::read(&theirs).unwrap();
    assert_ne!(
        now,
        std::fs::read(fixture("intel-tf/intel-tf.mcap")).unwrap()
    );
    assert!(now.starts_with(b"\x89MCAP0\r\n"));
    assert!(now.windows(7).any(|w| w == b"slam-rs"), "not slam's MCAP");
    let e = forced(&notes).unwrap_err().to_string();
    assert!(e.contains("not an MCAP file"), "{e}");
    assert_eq!(std::fs::read_to_string(&notes).unwrap(), "mine");
    // A storage file of a rosbag2 folder given as the input.
    let folder = dir.join("bag");
    std::fs::create_dir_all(&folder).unwrap();
    std::fs::copy(
        fixture("intel-tf/metadata.yaml"),
        folder.join("metadata.yaml"),
    )
    .unwrap();
    std::fs::copy(
        fixture("intel-tf/intel-tf.mcap"),
        folder.join("intel-tf.mcap"),
    )
    .unwrap();
    let (r, _) = slam(&[
        "run",
        "--filter",
        "gridfast",
        "--dataset",
        folder.to_str().unwrap(),
        "--quiet",
        "--out",
        out.to_str().unwrap(),
        "--mcap",
        folder.join("intel-tf.mcap").to_str().unwrap(),
    ]);
    let e = r.unwrap_err().to_string();
    assert!(e.contains("inside the --dataset input folder"), "{e}");
    assert_eq!(
        std::fs::read(folder.join("intel-tf.mcap")).unwrap(),
        std::fs::read(fixture("intel-tf/intel-tf.mcap")).unwrap()
    );
    let e = run(&dir.join("no-such-folder/run.mcap"));
    assert!(e.contains("its folder cannot be used"), "{e}");
    // Nothing was run: no output folder.
    assert!(!out.join("metrics.json").exists());
    let (r, _) = slam(&[
        "run",
        "--filter",
        "ekf",
        "--sim",
        "loop",
        "--mcap-every",
        "5",
    ]);
    assert!(r.unwrap_err().to_string().contains("--mcap"));
    let _ = std::fs::remove_dir_all(&dir);
}
