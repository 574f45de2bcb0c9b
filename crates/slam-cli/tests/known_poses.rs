//! `slam run --filter known-poses --poses FILE.tum`: the poses from a TUM file, matched to
//! the scans by time. Checked against the log's own poses: a GMapping-corrected log whose
//! scan poses, written out as TUM and given back with `--poses`, must give the very same
//! map as the log's own odometry fields.

mod common;
use common::{dataset, scratch, slam};
use slam_io::{Dataset, TimedPose};

/// The scan records' poses of a corrected log, as TUM, through slam-io's CARMEN reader.
fn scan_poses(log: &std::path::Path) -> Vec<TimedPose> {
    let (d, _) = slam_io::open_dataset(log, None).unwrap();
    let Dataset::Scan(d) = d else {
        panic!("not a laser log")
    };
    d.records
        .iter()
        .filter(|r| r.scan.is_some())
        .map(|r| TimedPose {
            t: r.t,
            pose: r.odometry,
        })
        .collect()
}

fn map_of(log: &str, poses: Option<&str>, out: &std::path::Path) -> Vec<u8> {
    let mut args = vec![
        "run",
        "--filter",
        "known-poses",
        "--dataset",
        log,
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ];
    if let Some(p) = poses {
        args.extend(["--poses", p]);
    }
    let (r, text) = slam(&args);
    assert!(r.is_ok(), "{r:?} {text}");
    std::fs::read(out.join("map.pgm")).unwrap()
}

/// Intel (times distinct) and CSAIL (every time printed as 1.13486e+09: the scans take
/// the file's poses in order): the same map bytes with --poses as without.
#[test]
fn poses_from_tum_give_the_same_map_as_the_logs_own() {
    for site in ["intel", "csail"] {
        let Some(log) = dataset(&format!("radish-corrected/{site}-corrected.log.gz")) else {
            return;
        };
        let dir = scratch(&format!("known-poses-{site}"));
        let tum = dir.join("poses.tum");
        slam_io::tum::write_tum(&tum, &scan_poses(&log)).unwrap();
        let own = map_of(log.to_str().unwrap(), None, &dir.join("own"));
        let given = map_of(
            log.to_str().unwrap(),
            Some(tum.to_str().unwrap()),
            &dir.join("given"),
        );
        assert!(own == given, "{site}: the maps differ");
        let _ = std::fs::remove_dir_all(&dir);
    }
}

/// A scan without a pose in the file, a file that is not TUM, and --poses with another
/// filter are clear errors.
#[test]
fn missing_poses_and_misuse_are_clear_errors() {
    let Some(log) = dataset("radish-corrected/intel-corrected.log.gz") else {
        return;
    };
    let dir = scratch("known-poses-bad");
    let mut poses = scan_poses(&log);
    let dropped = poses.remove(100);
    let tum = dir.join("poses.tum");
    slam_io::tum::write_tum(&tum, &poses).unwrap();
    let run = |filter: &str, tum: &std::path::Path| {
        slam(&[
            "run",
            "--filter",
            filter,
            "--dataset",
            log.to_str().unwrap(),
            "--poses",
            tum.to_str().unwrap(),
            "--out",
            dir.join("out").to_str().unwrap(),
            "--quiet",
        ])
        .0
    };
    let e = run("known-poses", &tum).unwrap_err().to_string();
    assert!(
        e.contains("poses.tum") && e.contains(&format!("t = {} s", dropped.t)),
        "{e}"
    );
    let bad = dir.join("bad.tum");
    std::fs::write(&bad, "1.0 2.0 3.0\n").unwrap();
    let e = run("known-poses", &bad).unwrap_err().to_string();
    assert!(e.contains("bad.tum") && e.contains(":1"), "{e}");
    let e = run("gridfast", &tum).unwrap_err().to_string();
    assert!(e.contains("--poses applies to --filter known-poses"), "{e}");
    let _ = std::fs::remove_dir_all(&dir);
}
