//! Hostile recordings through `slam run` (issue 32), generated at test time: ROS 1 bags
//! (format 2.0, unindexed, written here from wiki.ros.org/Bags/Format/2.0) whose scans have
//! no return at all. Verdict: a one-line error naming the bag and saying there is nothing to
//! map, before any output (it used to end with an error naming the staging folder's
//! `map.pgm`, an internal file).

mod common;
use common::{scratch, slam_bin};
use slam_io::rosbag::ros1_record as record;

/// A ROS 1 `sensor_msgs/LaserScan` body at `sec` s with `ranges` (range_max 30 m, 1° apart).
fn scan(sec: u32, ranges: &[f32]) -> Vec<u8> {
    let mut b = Vec::new();
    for v in [0u32, sec, 0, 5] {
        b.extend(v.to_le_bytes()); // seq, stamp sec, stamp nsec, frame_id length
    }
    b.extend(b"laser");
    let inc = std::f32::consts::PI / 180.0;
    let min = -std::f32::consts::FRAC_PI_2;
    for v in [min, min + 179.0 * inc, inc, 0.0, 0.0, 0.0, 30.0] {
        b.extend(v.to_le_bytes());
    }
    b.extend((ranges.len() as u32).to_le_bytes());
    for r in ranges {
        b.extend(r.to_le_bytes());
    }
    b.extend(0u32.to_le_bytes());
    b
}

/// An unindexed ROS 1 bag of three `/scan` messages with `ranges` each.
fn bag(name: &str, ranges: &[f32]) -> std::path::PathBuf {
    let mut b = b"#ROSBAG V2.0\n".to_vec();
    b.extend(record(
        &[
            ("op", &[0x03]),
            ("index_pos", &0u64.to_le_bytes()),
            ("conn_count", &1u32.to_le_bytes()),
            ("chunk_count", &0u32.to_le_bytes()),
        ],
        &[],
    ));
    let conn = record(
        &[
            ("type", b"sensor_msgs/LaserScan"),
            ("md5sum", b"90c7ef2dc6895d81024acba2ac42f369"),
        ],
        &[],
    );
    // A connection's data is its fields alone (no data-length field of their own).
    b.extend(record(
        &[
            ("op", &[0x07]),
            ("conn", &0u32.to_le_bytes()),
            ("topic", b"/scan"),
        ],
        &conn[4..conn.len() - 4],
    ));
    for sec in 100..103u32 {
        let mut t = sec.to_le_bytes().to_vec();
        t.extend(0u32.to_le_bytes());
        b.extend(record(
            &[("op", &[0x02]), ("conn", &0u32.to_le_bytes()), ("time", &t)],
            &scan(sec, ranges),
        ));
    }
    let p = scratch(name).join("scans.bag");
    std::fs::write(&p, b).unwrap();
    p
}

/// Scans whose every beam is +inf (no return within range), and scans of no beams at all:
/// every laser filter refuses with one line naming the bag, before writing anything.
#[test]
fn scans_without_a_single_return_are_a_clear_error_for_every_laser_filter() {
    for (name, ranges) in [
        ("no-return", vec![f32::INFINITY; 180]),
        ("no-beams", Vec::new()),
    ] {
        let p = bag(name, &ranges);
        for filter in ["scanmatch", "gridfast", "graph"] {
            let out = p.parent().unwrap().join(format!("out-{filter}"));
            let (code, _, err) = slam_bin(&[
                "run",
                "--filter",
                filter,
                "--dataset",
                p.to_str().unwrap(),
                "--quiet",
                "--out",
                out.to_str().unwrap(),
            ]);
            assert_ne!(code, 0, "{name} {filter}");
            assert_eq!(err.lines().count(), 1, "{err}");
            assert!(
                err.contains(p.to_str().unwrap())
                    && err.contains("none of its 3 scan(s) has a return")
                    && err.contains("nothing to map")
                    && !err.contains(".slam-partial"),
                "{name} {filter}: {err}"
            );
            assert!(!out.join("map.pgm").exists());
        }
    }
}

/// Fuzzing `slam optimize` (a g2o file truncated to its first vertex) gave "slam: error:
/// optimize: nothing to optimise: every node is fixed", naming no file; an edge whose
/// information entries overflow (1e300) gave "normal equations are not positive definite"
/// the same way. The optimiser's errors about the graph now name the graph file.
#[test]
fn optimizer_errors_about_a_graph_name_its_file() {
    let dir = scratch("optimize-errors");
    for (name, text, what) in [
        (
            "one-vertex.g2o",
            "VERTEX_SE2 0 0 0 0\n",
            "nothing to optimise: every node is fixed",
        ),
        (
            "overflowing-information.g2o",
            "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0\nEDGE_SE2 0 1 1 0 0 1e300 0 0 1e300 0 1e300\n",
            "normal equations are not positive definite",
        ),
    ] {
        let g = dir.join(name);
        std::fs::write(&g, text).unwrap();
        let out = dir.join(format!("out-{name}"));
        let (code, _, err) = slam_bin(&[
            "optimize",
            g.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]);
        assert_eq!(code, 1, "{err}");
        assert_eq!(err.lines().count(), 1, "{err}");
        assert!(
            err.contains(&format!("optimize {}: {what}", g.display())),
            "{name}: {err}"
        );
    }
}
