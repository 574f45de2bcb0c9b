//! `slam run` and `slam info` on ROS bags (the fixtures of slam-io, written by the Python
//! `rosbags` package from the first 875 lines of the real Intel log): MCAP, sqlite3 and
//! ROS 1 containers of the same messages.

mod common;
use common::{dataset, scratch, slam};

use slam_cli::Outcome;
use std::collections::BTreeMap;
use std::path::Path;
use std::process::Command;

fn fixture(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../slam-io/tests/fixtures/rosbag")
        .join(name)
        .display()
        .to_string()
}

/// TUM lines → time in µs → (x, y, yaw), the last line of each time.
fn tum(path: &Path) -> BTreeMap<i64, (f64, f64, f64)> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut m = BTreeMap::new();
    for l in text
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
    {
        let v: Vec<f64> = l.split_whitespace().map(|f| f.parse().unwrap()).collect();
        let yaw = 2.0 * v[6].atan2(v[7]);
        m.insert((v[0] * 1e6).round() as i64, (v[1], v[2], yaw));
    }
    m
}

/// `slam run --filter gridfast` on `dataset` (with `extra` options) into a new scratch
/// folder; the trajectory and what the run printed.
fn gridfast(name: &str, dataset: &str, extra: &[&str]) -> (BTreeMap<i64, (f64, f64, f64)>, String) {
    let out = scratch(name);
    let o = out.join("out");
    let args = [
        &["run", "--filter", "gridfast", "--dataset", dataset][..],
        extra,
        &["--quiet", "--out", o.to_str().unwrap()],
    ]
    .concat();
    let (r, text) = slam(&args);
    r.unwrap_or_else(|e| panic!("{dataset}: {e}"));
    (tum(&o.join("trajectory.tum")), text)
}

#[test]
fn gridfast_on_every_container_follows_the_carmen_run_at_every_scan() {
    let runs: Vec<_> = [
        ("intel-odom.mcap", "ROS 2 bag", "(MCAP)"),
        ("intel-odom-db3", "ROS 2 bag", "(sqlite3)"),
        ("intel-odom.bag", "ROS 1 bag", "(ROS 1 bag)"),
    ]
    .into_iter()
    .map(|(name, ros, storage)| {
        let (traj, text) = gridfast(name, &fixture(name), &["--laser-pose", "0,0,0"]);
        assert!(
            text.contains(ros)
                && text.contains(storage)
                && text.contains("scans /scan (40 scans, 180 beams")
                && text.contains("odometry /odom")
                && text.contains("(--laser-pose)"),
            "{text}"
        );
        (name, traj)
    })
    .collect();
    let Some(log) = dataset("bench/intel.log") else {
        return;
    };
    // The lines the bags were made from, as a CARMEN log, through the same filter.
    let src = std::fs::read_to_string(log).unwrap();
    let head: String = src.lines().take(875).map(|l| format!("{l}\n")).collect();
    let dir = scratch("carmen");
    let log = dir.join("intel-head.log");
    std::fs::write(&log, &head).unwrap();
    let (carmen, _) = gridfast("carmen-run", log.to_str().unwrap(), &[]);
    let scan_times: Vec<i64> = head
        .lines()
        .filter(|l| l.starts_with("FLASER"))
        .map(|l| {
            let f: Vec<&str> = l.split_whitespace().collect();
            (f[f.len() - 3].parse::<f64>().unwrap() * 1e6).round() as i64
        })
        .collect();
    assert_eq!(scan_times.len(), 40);
    // Same seed, same scans (to float32), same odometry: the same estimate at every scan.
    for (name, traj) in &runs {
        for &t in &scan_times {
            let (p, q) = (traj[&t], carmen[&t]);
            assert!(
                (p.0 - q.0).abs() < 1e-5 && (p.1 - q.1).abs() < 1e-5 && (p.2 - q.2).abs() < 1e-5,
                "{name} at {t} µs: bag {p:?}, CARMEN {q:?}"
            );
        }
    }
}

#[test]
fn a_bag_folder_runs_and_info_describes_it() {
    let out = scratch("folder");
    let bag = fixture("intel-tf");
    let (r, text) = slam(&[
        "run",
        "--filter",
        "gridfast",
        "--dataset",
        &bag,
        "--quiet",
        "--out",
        out.to_str().unwrap(),
    ]);
    r.unwrap();
    assert!(
        text.contains("odometry /tf odom → base_link") && text.contains("(/tf_static)"),
        "{text}"
    );
    assert!(out.join("map.pgm").is_file());

    let (r, text) = slam(&["info", &bag]);
    assert!(matches!(r, Ok(Outcome::Described)));
    for want in [
        "3 topic(s), 872 message(s)",
        "/scan       sensor_msgs/msg/LaserScan  cdr             40",
        "/tf         tf2_msgs/msg/TFMessage     cdr            831",
        "180 beams from -90.00° to 89.00° by 1.000°, range 0 … 81.83 m",
        "odometry: /tf odom → base_link (831 transforms)",
        "/tf_static: base_link → laser at (0.1200 m, -0.0300 m, 0.0500 rad)",
    ] {
        assert!(text.contains(want), "{want:?} missing from\n{text}");
    }
    let (_, text) = slam(&["info", &fixture("intel-odom.mcap")]);
    assert!(
        text.contains("odometry: /odom (odom → base_link)"),
        "{text}"
    );
}

#[test]
fn info_describes_sqlite_and_ros1_bags() {
    for (name, head, ty, tf) in [
        (
            "intel-tf.db3",
            "ROS 2 bag",
            "(1 sqlite3 file(s)): 3 topic(s), 872 message(s)",
            "tf2_msgs/msg/TFMessage",
        ),
        (
            "intel-tf.bag",
            "ROS 1 bag",
            "(1 ROS 1 bag file(s)): 3 topic(s), 872 message(s)",
            "tf2_msgs/msg/TFMessage",
        ),
    ] {
        let (r, text) = slam(&["info", &fixture(name)]);
        assert!(matches!(r, Ok(Outcome::Described)), "{name}");
        assert!(text.starts_with(head) && text.contains(ty), "{text}");
        let enc = if head == "ROS 1 bag" { "ros1" } else { "cdr " };
        for want in [
            format!("/scan       sensor_msgs/msg/LaserScan  {enc}"),
            format!("/tf         {tf}     {enc}"),
            "180 beams from -90.00° to 89.00° by 1.000°, range 0 … 81.83 m".into(),
            "odometry: /tf odom → base_link (831 transforms)".into(),
            "/tf_static: base_link → laser at (0.1200 m, -0.0300 m, 0.0500 rad)".into(),
        ] {
            assert!(text.contains(&want), "{want:?} missing from\n{text}");
        }
    }
    for name in ["intel-odom-db3", "intel-odom.bag"] {
        let (_, text) = slam(&["info", &fixture(name)]);
        assert!(
            text.contains("odometry: /odom (odom → base_link)") && text.contains("831"),
            "{text}"
        );
    }
}

#[test]
fn info_describes_the_other_formats() {
    let Some(log) = dataset("bench/intel.log") else {
        return;
    };
    let (r, text) = slam(&["info", log.to_str().unwrap()]);
    r.unwrap();
    assert!(
        text.contains("910 FLASER, 13700 ODOM")
            && text.contains("laser: 180 beams from -90.00° by 1.000°, no return at 81.83 m"),
        "{text}"
    );
    let Some(dir) = dataset("freiburg-robot-mapping") else {
        return;
    };
    let (r, text) = slam(&["info", dir.to_str().unwrap()]);
    r.unwrap();
    assert!(text.starts_with("Freiburg course data"), "{text}");
}

#[test]
fn bag_mistakes_are_one_line_errors() {
    let bin = env!("CARGO_BIN_EXE_slam");
    let run = |args: &[&str]| {
        let o = Command::new(bin).args(args).output().unwrap();
        (
            o.status.code().unwrap_or(-1),
            String::from_utf8_lossy(&o.stderr).into_owned(),
        )
    };
    let out = scratch("errors");
    let o = out.to_str().unwrap();
    let two = ["/scan, /scan_rear", "--scan-topic"];
    for (bag, wants) in [
        ("bad-two-scans.mcap", &two[..]),
        ("bad-two-scans.db3", &two[..]),
        ("bad-two-scans.bag", &two[..]),
        ("bad-no-odom.mcap", &["no odometry"][..]),
        ("bad-no-odom.bag", &["no odometry"][..]),
    ] {
        let (code, err) = run(&[
            "run",
            "--filter",
            "gridfast",
            "--dataset",
            &fixture(bag),
            "--out",
            o,
        ]);
        assert_ne!(code, 0);
        assert_eq!(err.lines().count(), 1, "{err}");
        assert!(
            err.contains(bag) && wants.iter().all(|w| err.contains(w)),
            "{err}"
        );
    }
    let (code, err) = run(&[
        "run",
        "--filter",
        "gridfast",
        "--dataset",
        &fixture("intel-odom.mcap"),
        "--laser-pose",
        "1,2",
        "--out",
        o,
    ]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("x,y,theta"), "{err}");
    // A bag option on a dataset that is not a bag is refused, not ignored.
    let freiburg = scratch("freiburg");
    std::fs::write(freiburg.join("world.dat"), "1 2 1\n").unwrap();
    std::fs::write(
        freiburg.join("sensor_data.dat"),
        "ODOMETRY 0 1 0\nSENSOR 1 1.0 0.5\n",
    )
    .unwrap();
    let (code, err) = run(&[
        "run",
        "--filter",
        "ekf",
        "--dataset",
        freiburg.to_str().unwrap(),
        "--scan-topic",
        "/scan",
        "--out",
        o,
    ]);
    assert_ne!(code, 0);
    assert!(err.contains("--scan-topic applies to ROS bags"), "{err}");
}
