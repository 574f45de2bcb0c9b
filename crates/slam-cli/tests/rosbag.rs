//! `slam run` and `slam info` on ROS bags (the fixtures of slam-io, written by the Python
//! `rosbags` package from the real Intel log up to its 200th scan, 3827 lines): MCAP,
//! sqlite3 and ROS 1 containers of the same messages.

mod common;
use common::{bag_fixture as fixture, dataset, scratch, slam, tum, Trajectory};

use slam_cli::Outcome;
use std::process::Command;

/// The scans in the fixtures (make_fixtures.py's `SCANS`). Their message counts below
/// (3616 odometry messages, 3817 messages in a /tf bag) are the log's: one odometry message
/// per distinct stamp of its first 3827 lines (`awk` over the log gives the same).
const SCANS: usize = 200;

/// `slam run --filter scanmatch` on `dataset` (with `extra` options) into a new scratch
/// folder; the trajectory and what the run printed (see [`SAME_XY`] for why not gridfast).
fn scanmatch(name: &str, dataset: &str, extra: &[&str]) -> (Trajectory, String) {
    let out = scratch(name);
    let o = out.join("out");
    let args = [
        &["run", "--filter", "scanmatch", "--dataset", dataset][..],
        extra,
        &["--quiet", "--out", o.to_str().unwrap()],
    ]
    .concat();
    let (r, text) = slam(&args);
    r.unwrap_or_else(|e| panic!("{dataset}: {e}"));
    (tum(&o.join("trajectory.tum")), text)
}

/// The laser mounting on the tf bags' `/tf_static` (make_fixtures.py's `MOUNT`).
const MOUNT: (f64, f64, f64) = (0.12, -0.03, 0.05);

/// The CARMEN lines the bags were made from (intel.log up to its `SCANS`-th FLASER line)
/// as a log file, with every FLASER line's laser pose set to odometry ⊕ `mount` (the
/// CARMEN reader's laser offset is laser pose ⊖ odometry pose) when one is given; and the
/// scan times in µs. `None` when the dataset is missing.
fn carmen_head(name: &str, mount: Option<(f64, f64, f64)>) -> Option<(String, Vec<i64>)> {
    let log = dataset("bench/intel.log")?;
    let src = std::fs::read_to_string(log).unwrap();
    let (mut head, mut times) = (String::new(), Vec::new());
    for l in src.lines() {
        let mut f: Vec<String> = l.split_whitespace().map(str::to_string).collect();
        if f.first().map(String::as_str) == Some("FLASER") {
            let n: usize = f[1].parse().unwrap();
            let v: Vec<f64> = f[2 + n..2 + n + 7]
                .iter()
                .map(|x| x.parse().unwrap())
                .collect();
            if let Some((mx, my, mt)) = mount {
                let (ox, oy, ot) = (v[3], v[4], v[5]);
                let laser = [
                    ox + ot.cos() * mx - ot.sin() * my,
                    oy + ot.sin() * mx + ot.cos() * my,
                    ot + mt,
                ];
                for (k, x) in laser.iter().enumerate() {
                    f[2 + n + k] = format!("{x:.12}");
                }
            }
            times.push((v[6] * 1e6).round() as i64);
        }
        head.push_str(&f.join(" "));
        head.push('\n');
        if times.len() == SCANS {
            break;
        }
    }
    assert_eq!(times.len(), SCANS, "intel.log has fewer FLASER lines");
    let path = scratch(name).join("intel-head.log");
    std::fs::write(&path, head).unwrap();
    Some((path.to_str().unwrap().to_string(), times))
}

/// How far the bag runs may be from the CARMEN run at a scan (m, and rad). The runs use
/// scan-matching odometry, which has no random draws: the same scans (to float32) and
/// odometry give the same estimate to far below this, although not to the bit (the
/// odometry goes through a quaternion or a /tf chain and back). Grid FastSLAM is not used
/// here: since its scorer rounds end points to 1/1024 of a cell, a 10⁻¹⁶ difference in the
/// input can change a particle's draw, and the runs drift apart by centimetres within 200
/// scans (seen: 8 cm with 10 particles, 1.7 cm with one), which says nothing about the
/// reader.
const SAME_XY: f64 = 1e-5;
const SAME_THETA: f64 = 1e-5;

/// Same scans, same odometry: the same estimate at every scan, within [`SAME_XY`] and
/// [`SAME_THETA`].
fn assert_same_at_scans(runs: &[(&str, Trajectory)], carmen: &Trajectory, scan_times: &[i64]) {
    for (name, traj) in runs {
        for &t in scan_times {
            let (p, q) = (traj[&t], carmen[&t]);
            assert!(
                (p.0 - q.0).abs() < SAME_XY
                    && (p.1 - q.1).abs() < SAME_XY
                    && (p.2 - q.2).abs() < SAME_THETA,
                "{name} at {t} µs: bag {p:?}, CARMEN {q:?}"
            );
        }
    }
}

#[test]
fn scanmatch_on_every_odometry_bag_follows_the_carmen_run_at_every_scan() {
    let runs: Vec<_> = [
        ("intel-odom.mcap", "ROS 2 bag", "(MCAP)"),
        ("intel-odom-db3", "ROS 2 bag", "(sqlite3)"),
        ("intel-odom.bag", "ROS 1 bag", "(ROS 1 bag)"),
    ]
    .into_iter()
    .map(|(name, ros, storage)| {
        let (traj, text) = scanmatch(name, &fixture(name), &["--laser-pose", "0,0,0"]);
        assert!(
            text.contains(ros)
                && text.contains(storage)
                && text.contains(&format!("scans /scan ({SCANS} scans, 180 beams"))
                && text.contains("odometry /odom")
                && text.contains("(--laser-pose)"),
            "{text}"
        );
        (name, traj)
    })
    .collect();
    // The lines the bags were made from, as a CARMEN log, through the same filter.
    let Some((log, scan_times)) = carmen_head("carmen", None) else {
        return;
    };
    let (carmen, _) = scanmatch("carmen-run", &log, &[]);
    assert_same_at_scans(&runs, &carmen, &scan_times);
}

/// The `/tf` bags of every container, odometry from `odom → base_link` and the laser
/// mounted off-centre by `/tf_static`, against the CARMEN lines whose FLASER laser poses
/// carry the same offset: the mounting and the `/tf` odometry reach the filter as the
/// CARMEN reader's laser offset and ODOM poses do.
#[test]
fn scanmatch_on_every_tf_bag_follows_the_carmen_run_with_the_same_laser_offset() {
    let runs: Vec<_> = [
        ("intel-tf", "(MCAP)"),
        ("intel-tf.db3", "(sqlite3)"),
        ("intel-tf.bag", "(ROS 1 bag)"),
    ]
    .into_iter()
    .map(|(name, storage)| {
        let (traj, text) = scanmatch(name, &fixture(name), &[]);
        assert!(
            text.contains(storage)
                && text.contains(&format!("scans /scan ({SCANS} scans, 180 beams"))
                && text.contains("odometry /tf odom → base_link")
                && text.contains("(0.1200 m, -0.0300 m, 0.0500 rad) in base_link (/tf_static)"),
            "{text}"
        );
        (name, traj)
    })
    .collect();
    let Some((log, scan_times)) = carmen_head("carmen-mounted", Some(MOUNT)) else {
        return;
    };
    let (carmen, _) = scanmatch("carmen-mounted-run", &log, &[]);
    assert_same_at_scans(&runs, &carmen, &scan_times);
    // The offset matters: the centred CARMEN run is another trajectory (by more than 1 cm
    // at some scan).
    let Some((centred, _)) = carmen_head("carmen-centred", None) else {
        return;
    };
    let (other, _) = scanmatch("carmen-centred-run", &centred, &[]);
    let moved = scan_times.iter().any(|t| {
        let (p, q) = (other[t], carmen[t]);
        (p.0 - q.0).abs() > 0.01 || (p.1 - q.1).abs() > 0.01
    });
    assert!(moved, "the laser offset changed nothing");
}

#[test]
fn a_bag_folder_runs_and_info_describes_it() {
    let out = scratch("folder");
    let bag = fixture("intel-tf");
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
        "3 topic(s), 3817 message(s)",
        "/scan       sensor_msgs/msg/LaserScan  cdr            200",
        "/tf         tf2_msgs/msg/TFMessage     cdr           3616",
        "180 beams from -90.00° to 89.00° by 1.000°, range 0 … 81.83 m",
        "odometry: /tf odom → base_link (3616 transforms)",
        "/tf_static: 1 edge(s): base_link → laser at (0.1200 m, -0.0300 m, 0.0500 rad)",
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
            "(1 sqlite3 file(s)): 3 topic(s), 3817 message(s)",
            "tf2_msgs/msg/TFMessage",
        ),
        (
            "intel-tf.bag",
            "ROS 1 bag",
            "(1 ROS 1 bag file(s)): 3 topic(s), 3817 message(s)",
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
            "odometry: /tf odom → base_link (3616 transforms)".into(),
            "/tf_static: 1 edge(s): base_link → laser at (0.1200 m, -0.0300 m, 0.0500 rad)".into(),
        ] {
            assert!(text.contains(&want), "{want:?} missing from\n{text}");
        }
    }
    for name in ["intel-odom-db3", "intel-odom.bag"] {
        let (_, text) = slam(&["info", &fixture(name)]);
        assert!(
            text.contains("odometry: /odom (odom → base_link)") && text.contains("3616"),
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
    // MRCLAM: every robot, each with as many velocity steps as its odometry file has
    // data lines.
    let Some(dir) = dataset("utias-mrclam/MRCLAM_Dataset1") else {
        return;
    };
    let (r, text) = slam(&["info", dir.to_str().unwrap()]);
    r.unwrap();
    assert!(
        text.starts_with("MRCLAM folder") && text.contains("5 robots"),
        "{text}"
    );
    for n in 1..=5 {
        let odometry = std::fs::read_to_string(dir.join(format!("Robot{n}_Odometry.dat"))).unwrap();
        let lines = odometry
            .lines()
            .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
            .count();
        let want = format!("robot {n}: {lines} velocity steps");
        assert!(text.contains(&want), "{want:?} missing from\n{text}");
    }
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
