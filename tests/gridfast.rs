//! Grid-based FastSLAM (slam-gridfast) on a prefix of the Intel benchmark log (real scans,
//! recovered odometry), scored by the Kümmerle et al. 2009 relations with slam-io.

mod common;

use slam::gridfast::{GridFastConfig, GridFastSlam};
use slam::models::{ScanSlam, TimedPose};

#[test]
fn intel_prefix_relations_error() {
    let (Some(log), Some(rel)) = (
        common::dataset("bench/intel.log"),
        common::dataset("slam-benchmark-relations/intel.relations"),
    ) else {
        return;
    };
    let data = slam::io::carmen::read_carmen(&log).unwrap().dataset;
    let relations = slam::io::relations::read_relations(&rel).unwrap();
    // The first 3,000 records (≈ 200 keyframe scans, the first ~10 minutes).
    let records = &data.records[..3000];
    let t_end = records.last().unwrap().t;
    let inside: Vec<_> = relations
        .iter()
        .filter(|r| r.t1.max(r.t2) <= t_end)
        .cloned()
        .collect();
    assert!(
        inside.len() > 300,
        "{} relations in the prefix",
        inside.len()
    );
    let odometry: Vec<TimedPose> = records
        .iter()
        .map(|r| TimedPose {
            t: r.t,
            pose: r.odometry,
        })
        .collect();
    let odo = slam::io::eval::relations_error(&odometry, &inside);
    let config = GridFastConfig {
        particles: 10,
        ..Default::default()
    };
    let mut slam = GridFastSlam::new(config, 42).unwrap();
    for r in records {
        slam.process(r).unwrap();
    }
    let traj = slam.trajectory();
    assert_eq!(traj.len(), records.len());
    let e = slam::io::eval::relations_error(&traj, &inside);
    eprintln!(
        "intel prefix: {} relations; odometry {:.3} m / {:.2} deg; gridfast {:.4} m / {:.3} deg",
        e.used, odo.trans_mean, odo.rot_mean_deg, e.trans_mean, e.rot_mean_deg
    );
    assert_eq!(e.dropped, 0);
    assert!(odo.trans_mean > 0.3);
    // GMapping's full-log figures are 0.057–0.070 m and 2.3–2.7°.
    assert!(e.trans_mean < 0.07 && e.rot_mean_deg < 3.0, "{e:?}");
}
