//! Grid-based FastSLAM on a simulated loop corridor with ground truth: the loop closes,
//! every proposal beats odometry, and the output does not depend on the thread count.

mod support;

use slam_gridfast::{GridFastConfig, GridFastSlam, Proposal};
use slam_models::{Pose2, ScanRecord, ScanSlam, TimedPose};
use support::simulate;

/// Position RMSE of an estimate against the truth after expressing both relative to
/// their first pose (the filter's world frame is the odometry frame of record 0).
fn rmse(est: &[TimedPose], truth: &[Pose2]) -> f64 {
    assert_eq!(est.len(), truth.len());
    let (e0, t0) = (est[0].pose, truth[0]);
    let s: f64 = est
        .iter()
        .zip(truth)
        .map(|(e, t)| e0.between(&e.pose).distance(&t0.between(t)).powi(2))
        .sum();
    (s / est.len() as f64).sqrt()
}

fn run(records: &[ScanRecord], config: GridFastConfig, threads: usize) -> (Vec<TimedPose>, usize) {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    let mut slam = GridFastSlam::new(config, 42).unwrap();
    let mut processed = 0;
    pool.install(|| {
        for r in records {
            processed += slam.process(r).unwrap().processed_scan as usize;
        }
    });
    (slam.trajectory(), processed)
}

#[test]
fn simulated_loop_closes_and_output_is_thread_count_independent() {
    let (records, truth) = simulate(3);
    let odometry: Vec<TimedPose> = records
        .iter()
        .map(|r| TimedPose {
            t: r.t,
            pose: r.odometry,
        })
        .collect();
    let odo_err = rmse(&odometry, &truth);
    let config = GridFastConfig {
        particles: 8,
        ..Default::default()
    };
    let (one, processed) = run(&records, config.clone(), 1);
    let (two, _) = run(&records, config, 2);
    // One pose per input record, scans skipped between updates.
    assert_eq!(one.len(), records.len());
    assert!(
        processed > 40 && processed < records.len() / 3,
        "{processed} updates"
    );
    // Bit-identical whatever the thread count.
    assert!(one
        .iter()
        .zip(&two)
        .all(|(a, b)| a.pose == b.pose && a.t == b.t));
    let err = rmse(&one, &truth);
    eprintln!("simulated loop: odometry RMSE {odo_err:.3} m, gridfast improved RMSE {err:.3} m");
    assert!(
        odo_err > 1.0,
        "the odometry must be bad for the test to mean anything: {odo_err}"
    );
    assert!(err < 0.1, "gridfast RMSE {err} m");
}

#[test]
fn every_proposal_beats_odometry_on_the_simulated_loop() {
    let (records, truth) = simulate(5);
    let odometry: Vec<TimedPose> = records
        .iter()
        .map(|r| TimedPose {
            t: r.t,
            pose: r.odometry,
        })
        .collect();
    let odo_err = rmse(&odometry, &truth);
    eprintln!("dead reckoning: RMSE {odo_err:.3} m");
    for proposal in [
        Proposal::Odometry,
        Proposal::ScanMatchedOdometry,
        Proposal::Improved,
    ] {
        let config = GridFastConfig {
            particles: 10,
            proposal,
            search_range_xy: if std::env::var_os("GF_NOSEARCH").is_some() {
                0.0
            } else {
                0.3
            },
            search_range_theta: if std::env::var_os("GF_NOSEARCH").is_some() {
                0.0
            } else {
                0.3
            },
            ..Default::default()
        };
        let (traj, _) = run(&records, config, 2);
        let err = rmse(&traj, &truth);
        eprintln!("{proposal:?}: RMSE {err:.3} m");
        // The odometry proposal with 10 particles cannot close the loop but must still
        // beat dead reckoning; the scan-matching proposals must close it.
        let bound = if proposal == Proposal::Odometry {
            0.8 * odo_err
        } else {
            0.15
        };
        assert!(err < bound, "{proposal:?}: RMSE {err} m");
    }
}
