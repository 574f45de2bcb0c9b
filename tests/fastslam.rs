//! FastSLAM 1.0 / 2.0 on real data (Freiburg course data, UTIAS MRCLAM) and on the
//! simulated `loop` and `clutter` scenarios, judged against ground truth. (The thread-count
//! determinism test is in the crate, `slam-fastslam/src/filter.rs`.)

mod common;

use slam::eval::metrics::{ate, landmark_error};
use slam::fastslam::{Association, FastSlam, FastSlamConfig, Variant};
use slam::models::measurement::RangeBearingModel;
use slam::models::motion::{MotionModels, OdometryModel, VelocityModel};
use slam::models::{LandmarkDataset, LandmarkId, LandmarkSlam, Pose2, TimedPose};
use slam::sim::scenario::{generate, ScenarioOptions};
use slam::sim::{LandmarkSimRun, SimOutput};

/// Runs a filter over a dataset (slam-eval's loop); returns the best particle's pose after
/// every step.
fn run(f: &mut FastSlam, d: &LandmarkDataset) -> Vec<TimedPose> {
    slam::eval::run_landmarks(f, d, &Default::default())
        .expect("run")
        .online
}

fn sim(name: &str, seed: u64, steps: Option<usize>) -> LandmarkSimRun {
    match generate(
        name,
        &ScenarioOptions {
            seed,
            steps,
            ..Default::default()
        },
    ) {
        Ok(SimOutput::Landmark(r)) => r,
        other => panic!("{name} did not give a landmark run: {:?}", other.err()),
    }
}

/// The filter configured with the simulator's own noise models and sensor footprint.
fn sim_config(r: &LandmarkSimRun, variant: Variant, particles: usize) -> FastSlamConfig {
    FastSlamConfig {
        variant,
        particles,
        motion: r.motion,
        sensor: r.sensor,
        max_range: Some(r.sensor_config.max_range),
        fov: Some(r.sensor_config.fov),
        ..Default::default()
    }
}

/// Noise-free dead reckoning with the data's own controls.
fn dead_reckoning(d: &LandmarkDataset, motion: &MotionModels) -> Vec<Pose2> {
    let mut p = d.initial_pose;
    d.steps
        .iter()
        .map(|s| {
            p = motion.predict(&p, &s.control);
            p
        })
        .collect()
}

/// The course data: Q = 0.01·I (σr = σφ = 0.1), odometry noise a few percent.
fn freiburg_config(variant: Variant) -> FastSlamConfig {
    FastSlamConfig {
        variant,
        particles: 100,
        motion: MotionModels {
            odometry: OdometryModel::new([0.01, 0.001, 0.01, 0.001]),
            velocity: VelocityModel::default(),
        },
        sensor: RangeBearingModel::new(0.1, 0.1),
        association: Association::Known,
        ..Default::default()
    }
}

fn freiburg(variant: Variant) {
    let Some(dir) = common::dataset("freiburg-robot-mapping") else {
        return;
    };
    let d = slam::io::freiburg::read_freiburg(&dir).expect("course data reads");
    let truth = d.landmarks.clone().expect("world.dat");
    let mut f = FastSlam::new(freiburg_config(variant), d.initial_pose, 7).unwrap();
    run(&mut f, &d);
    let e = landmark_error(&f.landmarks(), &truth, true);
    println!(
        "Freiburg {}: 100 particles, landmark RMSE {:.4} m (aligned {:.4} m), {} matched",
        f.name(),
        e.rmse,
        e.rmse_aligned,
        e.matched
    );
    assert_eq!(e.matched, truth.len());
    assert_eq!(e.spurious, 0);
    assert!(e.rmse_aligned <= 0.05, "aligned RMSE {}", e.rmse_aligned);
}

#[test]
fn freiburg_fastslam1_landmarks_within_5cm() {
    freiburg(Variant::FastSlam1);
}

#[test]
fn freiburg_fastslam2_landmarks_within_5cm() {
    freiburg(Variant::FastSlam2);
}

/// FastSLAM 2.0 with a single particle (Montemerlo et al. 2003 §5): after 1.1 laps the robot
/// is back among the first landmarks, and its pose error is small again: every seed ends
/// within 0.25 m, the mean end error is under a third of dead reckoning's, and in each seed
/// the end error is below the largest error the filter reached during the lap (the loop
/// closure pulled it back).
#[test]
fn loop_fastslam2_single_particle_closes_the_loop() {
    let (mut sum, mut sum_dr) = (0.0, 0.0);
    for seed in 0..4 {
        let r = sim("loop", seed, None);
        let mut f = FastSlam::new(
            sim_config(&r, Variant::FastSlam2, 1),
            r.dataset.initial_pose,
            11,
        )
        .unwrap();
        let traj = run(&mut f, &r.dataset);
        let peak = traj
            .iter()
            .zip(&r.true_poses)
            .map(|(e, t)| e.pose.distance(t))
            .fold(0.0, f64::max);
        let truth_end = r.true_poses.last().unwrap();
        let dr = dead_reckoning(&r.dataset, &r.motion);
        let dr_err = dr.last().unwrap().distance(truth_end);
        let err = f.pose().distance(truth_end);
        let lm = landmark_error(&f.landmarks(), r.dataset.landmarks.as_ref().unwrap(), true);
        println!(
            "loop seed {seed}: FastSLAM 2.0 M=1 final error {err:.3} m (peak {peak:.3} m; dead \
             reckoning {dr_err:.3} m), landmark RMSE {:.3} m",
            lm.rmse
        );
        assert!(err < 0.25 && err < peak, "seed {seed}: {err} (peak {peak})");
        assert_eq!(lm.matched, 50);
        sum += err;
        sum_dr += dr_err;
    }
    assert!(
        sum < sum_dr / 3.0,
        "mean end error {} vs dead reckoning {}",
        sum / 4.0,
        sum_dr / 4.0
    );
}

/// Hidden ids, 10 % missed detections and one false alarm per scan: maximum-likelihood
/// association with negative evidence keeps the map close to the 50 true landmarks although
/// about 330 false alarms are seen per run.
///
/// Judged on the median of ten seeds, not on one run: a single run is a lottery (measured
/// over seeds 0..100, a run has ≤ 12 spurious landmarks, ≥ 45 matched and RMSE < 0.5 m all
/// at once only 32–37 % of the time, with the odd run losing track of a third of the map),
/// while the median of ten runs is stable. Over ten groups of ten seeds, with the simulator
/// noise of rand_distr (before) and of `slam_models::sampling` (now), the group medians
/// were 6.5–16 spurious, ≥ 49.5 matched and RMSE 0.30–0.51 m for both variants.
#[test]
fn clutter_does_not_persist() {
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        0.5 * (v[(v.len() - 1) / 2] + v[v.len() / 2])
    };
    for variant in [Variant::FastSlam1, Variant::FastSlam2] {
        let (mut spurious, mut matched, mut rmse) = (Vec::new(), Vec::new(), Vec::new());
        for seed in 0..10 {
            let r = sim("clutter", seed, None);
            let n_clutter = r.is_clutter.iter().flatten().filter(|c| **c).count();
            let mut f =
                FastSlam::new(sim_config(&r, variant, 10), r.dataset.initial_pose, 5).unwrap();
            run(&mut f, &r.dataset);
            let truth = r.dataset.landmarks.as_ref().unwrap();
            let lms = f.landmarks();
            let e = landmark_error(&lms, truth, false);
            let err = f.pose().distance(r.true_poses.last().unwrap());
            println!(
                "clutter seed {seed} {}: {} false alarms seen, map {} landmarks: {} matched, \
                 {} spurious; RMSE {:.3} m; final pose error {err:.3} m",
                f.name(),
                n_clutter,
                lms.len(),
                e.matched,
                e.spurious,
                e.rmse
            );
            assert!(n_clutter > 200, "seed {seed}: {n_clutter} false alarms");
            spurious.push(e.spurious as f64);
            matched.push(e.matched as f64);
            rmse.push(e.rmse);
        }
        let (s, m, r) = (median(spurious), median(matched), median(rmse));
        println!(
            "clutter {variant:?}, median of 10 seeds: {s} spurious, {m} matched, RMSE {r:.3} m"
        );
        assert!(
            s <= 16.0,
            "{variant:?}: median {s} spurious landmarks persisted"
        );
        assert!(m >= 48.0, "{variant:?}: median {m} of 50 landmarks matched");
        assert!(r < 0.55, "{variant:?}: median landmark RMSE {r} m");
    }
}

/// UTIAS MRCLAM Dataset 1, robot 1 (resampled copy, with Vicon ground truth): the absolute
/// trajectory error and the landmark map error of FastSLAM 2.0, next to dead reckoning.
#[test]
fn mrclam_robot1_beats_dead_reckoning() {
    let Some(dir) = common::dataset("utias-mrclam/MRCLAM_Dataset1_resampled") else {
        return;
    };
    let d = slam::io::mrclam::read_mrclam(&dir, 1).expect("MRCLAM reads");
    let gt = d.ground_truth.clone().expect("ground truth");
    let truth = d.landmarks.clone().expect("landmarks");
    // Generous velocity noise: at 50 Hz the per-step noise of the textbook α's averages
    // out, and the real odometry drifts by metres.
    let motion = MotionModels {
        velocity: VelocityModel::new([5.0, 1.0, 1.0, 5.0, 0.1, 1.0]),
        odometry: OdometryModel::default(),
    };
    let cfg = FastSlamConfig {
        variant: Variant::FastSlam2,
        particles: 20,
        motion,
        sensor: RangeBearingModel::new(0.15, 0.05),
        association: Association::Known,
        ..Default::default()
    };
    let mut f = FastSlam::new(cfg, d.initial_pose, 1).unwrap();
    let traj = run(&mut f, &d);
    let dr: Vec<TimedPose> = dead_reckoning(&d, &motion)
        .into_iter()
        .zip(&d.steps)
        .map(|(pose, s)| TimedPose { t: s.t, pose })
        .collect();
    let a = ate(&traj, &gt).expect("ATE");
    let a_dr = ate(&dr, &gt).expect("ATE");
    let lm = landmark_error(&f.landmarks(), &truth, true);
    println!(
        "MRCLAM 1 robot 1: FastSLAM 2.0 (20 particles) ATE {:.3} m (aligned {:.3}), landmark RMSE {:.3} m \
         (aligned {:.3}, {} matched); dead reckoning ATE {:.3} m (aligned {:.3})",
        a.rmse, a.rmse_aligned, lm.rmse, lm.rmse_aligned, lm.matched, a_dr.rmse, a_dr.rmse_aligned
    );
    assert!(a.rmse < 0.25 * a_dr.rmse && a.rmse_aligned < 0.3);
    // Landmarks 11 and 17 come out swapped (each estimate sits within 0.6 m of the *other*
    // one's surveyed position): the measurements of barcodes 18 and 61 disagree with
    // Barcodes.dat/Landmark_Groundtruth.dat, so the RMSE above is dominated by them. The
    // other 13 are judged after SE(2) alignment (the map's frame is only anchored by the
    // initial pose, and the whole solution drifts as one).
    assert_eq!(lm.matched, 15);
    let swapped = |id: &LandmarkId| id.0 == 11 || id.0 == 17;
    let est13: Vec<_> = f
        .landmarks()
        .into_iter()
        .filter(|e| !swapped(&e.id))
        .collect();
    let truth13: Vec<_> = truth.iter().copied().filter(|t| !swapped(&t.0)).collect();
    let lm13 = landmark_error(&est13, &truth13, true);
    println!(
        "MRCLAM landmarks other than 11/17: RMSE {:.3} m, aligned {:.3} m ({} matched)",
        lm13.rmse, lm13.rmse_aligned, lm13.matched
    );
    assert_eq!(lm13.matched, 13);
    assert!(
        lm13.rmse_aligned < 0.35,
        "aligned RMSE {}",
        lm13.rmse_aligned
    );
}
