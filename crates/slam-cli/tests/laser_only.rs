//! Laser-only mapping (issue 32): recordings without odometry, and `--odometry none`, through
//! `slam info` and every laser filter. The bags are slam-io's fixtures written by the Python
//! `rosbags` package (make_laser_only_fixtures.py) from the first 200 scans of the real Intel
//! log: `/scan` only, and `/scan` + `/imu` (its yaw rate derived from the log's odometry,
//! with noise) in MCAP and in a ROS 1 bag.

mod common;
use common::{bag_fixture as fixture, scratch, slam, tum, Trajectory};

/// Runs `filter` on `bag` with `extra` options; the trajectory and the printed text.
fn run(filter: &str, bag: &str, extra: &[&str]) -> (Trajectory, String) {
    let out = scratch(&format!("{filter}-{}", bag.replace('.', "-")));
    let o = out.join("out");
    let bag_path = fixture(bag);
    let args = [
        &["run", "--filter", filter, "--dataset", &bag_path][..],
        extra,
        &["--quiet", "--out", o.to_str().unwrap()],
    ]
    .concat();
    let (r, text) = slam(&args);
    r.unwrap_or_else(|e| panic!("{filter} on {bag}: {e}"));
    (tum(&o.join("trajectory.tum")), text)
}

/// Every laser filter runs on the laser-only bag: the input line says there is no odometry
/// and that laser odometry made it; one pose per scan, every pose finite. Accuracy is NOT
/// asserted here: on these keyframe scans (about 3 s and 0.66 m apart) laser odometry loses
/// track at sharp turns (docs/results.md, "Laser-only mapping").
#[test]
fn every_laser_filter_runs_on_a_bag_without_odometry() {
    for filter in ["scanmatch", "graph", "gridfast"] {
        let extra: &[&str] = if filter == "gridfast" {
            &["--particles", "5"]
        } else {
            &[]
        };
        let (traj, text) = run(filter, "intel-laser-only.mcap", extra);
        assert!(
            text.contains("no odometry")
                && text.contains("odometry: none in the recording — laser odometry"),
            "{text}"
        );
        assert_eq!(traj.len(), 200, "{filter}");
        assert!(traj
            .values()
            .all(|p| p.0.is_finite() && p.1.is_finite() && p.2.is_finite()));
    }
}

/// `--imu-topic /imu` uses the IMU's yaw rate as the rotation prior (said on the input line)
/// and reads the same from MCAP and from the ROS 1 bag: the same trajectory bit for bit.
#[test]
fn the_imu_yaw_rate_is_the_rotation_prior_in_mcap_and_ros1() {
    let (a, text) = run(
        "scanmatch",
        "intel-laser-imu.mcap",
        &["--imu-topic", "/imu"],
    );
    assert!(
        text.contains("the IMU's yaw rate as rotation prior on 199 scans"),
        "{text}"
    );
    let (b, _) = run("scanmatch", "intel-laser-imu.bag", &["--imu-topic", "/imu"]);
    assert_eq!(a, b);
    let (c, text) = run("scanmatch", "intel-laser-imu.mcap", &[]);
    assert!(!text.contains("rotation prior"), "{text}");
    assert_ne!(a, c);
}

/// `slam info` on the laser-only bags: no odometry (laser odometry will make it), and the
/// IMU topic with the option that uses it.
#[test]
fn info_says_there_is_no_odometry_and_names_the_imu() {
    let (r, text) = slam(&["info", &fixture("intel-laser-only.mcap")]);
    r.unwrap();
    assert!(
        text.contains("odometry: none") && text.contains("laser odometry"),
        "{text}"
    );
    for bag in ["intel-laser-imu.mcap", "intel-laser-imu.bag"] {
        let (r, text) = slam(&["info", &fixture(bag)]);
        r.unwrap();
        assert!(
            text.contains("imu /imu: 3421 messages") && text.contains("--imu-topic /imu"),
            "{text}"
        );
    }
}

/// `--odometry none` on a bag that has odometry withholds it (said on the input line), and
/// on a simulated laser scenario too.
#[test]
fn odometry_none_withholds_recorded_odometry() {
    let (traj, text) = run("scanmatch", "intel-odom.mcap", &["--odometry", "none"]);
    assert!(
        text.contains("odometry: withheld (--odometry none)"),
        "{text}"
    );
    // One record per scan: the odometry messages are not read.
    assert_eq!(traj.len(), 200);
    let out = scratch("sim-none");
    let o = out.join("out");
    let (r, text) = slam(&[
        "run",
        "--filter",
        "scanmatch",
        "--sim",
        "office",
        "--steps",
        "40",
        "--odometry",
        "none",
        "--quiet",
        "--out",
        o.to_str().unwrap(),
    ]);
    r.unwrap();
    assert!(
        text.contains("odometry: withheld (--odometry none)"),
        "{text}"
    );
}

/// The aligned ATE (m) of a run's metrics.json.
fn aligned_ate(dir: &std::path::Path) -> f64 {
    let text = std::fs::read_to_string(dir.join("metrics.json")).unwrap();
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    v["ate_rmse_aligned_m"].as_f64().unwrap()
}

/// Runs `filter` on the simulated office with `--odometry none` and `extra` options into
/// `out`; what it printed.
fn office_without_odometry(filter: &str, out: &std::path::Path, extra: &[&str]) -> String {
    let o = out.to_str().unwrap();
    let base = [
        "run",
        "--filter",
        filter,
        "--sim",
        "office",
        "--odometry",
        "none",
    ];
    let args = [&base[..], extra, &["--quiet", "--out", o]].concat();
    let (r, text) = slam(&args);
    r.unwrap_or_else(|e| panic!("{filter}: {e}"));
    text
}

/// The simulated office without odometry (issue 32's bar): every laser filter on laser
/// odometry alone ends within 0.5 m aligned ATE of the simulator's ground truth over the
/// first 150 scans (about 2–4 s of CPU each; the whole two laps took 61 s in CI; on
/// 2026-12-03 the three ended 0.07, 0.07 and 0.12 m off, and without laser odometry the
/// filters have no motion between scans). The
/// run's config.toml holds the laser odometry's table, and a `[laser-odometry]` table in
/// `--config` is used (one map of every scan: "1 local maps" on the input line).
#[test]
fn every_laser_filter_maps_the_office_without_odometry() {
    let out = scratch("office-none");
    for filter in ["scanmatch", "graph", "gridfast"] {
        let o = out.join(filter);
        let extra: &[&str] = if filter == "gridfast" {
            &["--steps", "150", "--particles", "10"]
        } else {
            &["--steps", "150"]
        };
        let text = office_without_odometry(filter, &o, extra);
        let ate = aligned_ate(&o);
        assert!(ate < 0.5, "{filter}: aligned ATE {ate} m\n{text}");
        let config = std::fs::read_to_string(o.join("config.toml")).unwrap();
        assert!(config.contains("[laser-odometry]"), "{config}");
        // On laser odometry gridfast's proposal reaches back over a metre-long wrong step
        // (the indoor preset's window is ±0.3 m).
        if filter == "gridfast" {
            assert!(config.contains("search-range-xy = 1.0"), "{config}");
        }
    }
    let file = out.join("one-map.toml");
    std::fs::write(
        &file,
        "filter = \"scanmatch\"\n[laser-odometry]\nsubmap-scans = 0\n",
    )
    .unwrap();
    let o = out.join("one-map");
    let extra = ["--steps", "60", "--config", file.to_str().unwrap()];
    let text = office_without_odometry("scanmatch", &o, &extra);
    assert!(text.contains(", 1 local maps"), "{text}");
    let config = std::fs::read_to_string(o.join("config.toml")).unwrap();
    assert!(config.contains("submap-scans = 0"), "{config}");
}

/// Laser odometry keeps the narrow match around constant velocity unless a wide match fits
/// clearly better (`wide-margin`): on the whole simulated office, scenario seed 2 (589
/// scans, two laps, about 10 s of CPU), scan matching on laser odometry alone ends within
/// 0.3 m aligned ATE of the simulator's ground truth (0.063 m on 2026-12-03; 1.299 m when
/// the best of the wide searches was taken on every scan, the default before).
#[test]
fn the_office_second_seed_stays_on_track_without_odometry() {
    let o = scratch("office-none-seed2").join("out");
    let text = office_without_odometry("scanmatch", &o, &["--seed", "2"]);
    let ate = aligned_ate(&o);
    assert!(ate < 0.3, "aligned ATE {ate} m\n{text}");
}
