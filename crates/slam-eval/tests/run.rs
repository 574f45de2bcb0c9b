//! The run functions and the factory against independent truth: the simulator's true poses
//! (with the RMSE computed here, not by the metrics code), hand-made trajectories with
//! known errors, and the filters' own names.

use slam_eval::factory::{filters, DataKind, FactoryError, FilterConfig};
use slam_eval::metrics::{ate, rpe};
use slam_eval::{
    run_landmarks, run_landmarks_observed, run_scans, Flow, LandmarkProgress, RunError, RunOptions,
};
use slam_models::{Pose2, TimedPose};
use slam_sim::scenario::{generate, ScenarioOptions};
use slam_sim::{LandmarkSimRun, SimOutput};

fn loop_run(steps: usize) -> LandmarkSimRun {
    let opts = ScenarioOptions {
        steps: Some(steps),
        ..Default::default()
    };
    match generate("loop", &opts).unwrap() {
        SimOutput::Landmark(run) => run,
        SimOutput::Laser(_) => panic!("loop is a landmark scenario"),
    }
}

/// RMSE of the position error, computed here from the simulator's true poses.
fn rmse(est: &[TimedPose], truth: &[Pose2]) -> f64 {
    assert_eq!(est.len(), truth.len());
    let s: f64 = est
        .iter()
        .zip(truth)
        .map(|(e, t)| (e.pose.x - t.x).powi(2) + (e.pose.y - t.y).powi(2))
        .sum();
    (s / truth.len() as f64).sqrt()
}

#[test]
fn ekf_run_on_the_simulator_matches_its_truth() {
    let sim = loop_run(200);
    let mut parsed = FilterConfig::from_toml("filter = \"ekf\"\n").unwrap();
    assert!(parsed.apply_sim_noise(&sim.noise_models()).any());
    let mut filter = parsed
        .config
        .build_landmark(sim.dataset.initial_pose, 0)
        .unwrap();
    let run = run_landmarks(filter.as_mut(), &sim.dataset, &RunOptions::default()).unwrap();
    let n = sim.dataset.steps.len();
    assert_eq!(
        (run.online.len(), run.estimates.len(), run.updates.len()),
        (n, n, n)
    );
    assert!(run.full_path.is_none(), "the EKF keeps no path");
    // Every step's observations reached the filter's update.
    for (info, step) in run.updates.iter().zip(&sim.dataset.steps) {
        assert_eq!(info.observations, step.observations.len());
    }
    // ATE "as is" is the RMSE against the simulator's true poses (same frame, same times).
    let own = rmse(&run.online, &sim.true_poses);
    let ate = run.metrics.ate_rmse_m.unwrap();
    assert!((ate - own).abs() < 1e-12, "{ate} vs {own}");
    assert_eq!(run.metrics.online_ate_rmse_m, run.metrics.ate_rmse_m);
    // With the true noise models the EKF is consistent: a NEES per step, and far more than
    // half of them inside the 95 % χ²(3) band (0.95 expected; the EKF's linearisation
    // lowers it a little).
    assert!(run.estimates.iter().all(|e| e.nees.is_some()));
    let in_band = run.metrics.nees_pose_in_band_fraction.unwrap();
    assert!(in_band > 0.8, "{in_band}");
    // Every true landmark seen is mapped, matched by id.
    assert!(run.metrics.landmark_rmse_m.is_some());
    assert_eq!(run.metrics.filter, "ekf");
    assert_eq!(run.metrics.steps, n);
    assert!(run.metrics.wall_s >= 0.0);
}

#[test]
fn fastslam_run_returns_the_full_slam_path() {
    let sim = loop_run(60);
    let mut parsed = FilterConfig::from_toml("filter = \"fastslam2\"\nparticles = 20\n").unwrap();
    parsed.apply_sim_noise(&sim.noise_models());
    let mut filter = parsed
        .config
        .build_landmark(sim.dataset.initial_pose, 3)
        .unwrap();
    let run = run_landmarks(filter.as_mut(), &sim.dataset, &RunOptions::default()).unwrap();
    let full = run.full_path.as_ref().expect("FastSLAM keeps a path");
    assert_eq!(full.len(), sim.dataset.steps.len());
    // Paired with the steps' times, ending at the filter's pose.
    for (p, s) in full.iter().zip(&sim.dataset.steps) {
        assert_eq!(p.t, s.t);
    }
    assert_eq!(full.last().unwrap().pose, filter.pose());
    assert_eq!(run.trajectory(), &full[..]);
    // The `ate_*` figures score the full path, the `online_*` ones the online estimates.
    let own = rmse(full, &sim.true_poses);
    assert!((run.metrics.ate_rmse_m.unwrap() - own).abs() < 1e-12);
    let own_online = rmse(&run.online, &sim.true_poses);
    assert!((run.metrics.online_ate_rmse_m.unwrap() - own_online).abs() < 1e-12);
    assert!(run.updates.iter().all(|u| u.n_eff.is_some()));
}

#[test]
fn the_observer_sees_every_step_and_can_stop_the_run() {
    let sim = loop_run(30);
    let mut filter = FilterConfig::default_for("ekf")
        .unwrap()
        .build_landmark(sim.dataset.initial_pose, 0)
        .unwrap();
    let mut seen = Vec::new();
    let mut observer = |p: &LandmarkProgress<'_>| {
        seen.push((p.step, p.steps, p.online.len()));
        Ok(if p.step == 9 {
            Flow::Stop
        } else {
            Flow::Continue
        })
    };
    let err = run_landmarks_observed(
        filter.as_mut(),
        &sim.dataset,
        &RunOptions::default(),
        &mut observer,
    )
    .unwrap_err();
    assert!(
        matches!(
            err,
            RunError::Stopped {
                done: 10,
                steps: 30
            }
        ),
        "{err}"
    );
    let expected: Vec<_> = (0..10).map(|k| (k, 30, k + 1)).collect();
    assert_eq!(seen, expected);

    // An observer's error comes back unchanged, downcastable to its own type.
    #[derive(Debug)]
    struct Mine;
    impl std::fmt::Display for Mine {
        fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            f.write_str("mine")
        }
    }
    impl std::error::Error for Mine {}
    let mut failing = |_: &LandmarkProgress<'_>| Err(Mine.into());
    let err = run_landmarks_observed(
        filter.as_mut(),
        &sim.dataset,
        &RunOptions::default(),
        &mut failing,
    )
    .unwrap_err();
    match err {
        RunError::Observer { step: 0, source } => assert!(source.downcast::<Mine>().is_ok()),
        other => panic!("{other}"),
    }
}

#[test]
fn scan_run_scores_against_the_anchored_truth() {
    let opts = ScenarioOptions {
        steps: Some(40),
        ..Default::default()
    };
    let SimOutput::Laser(sim) = generate("office", &opts).unwrap() else {
        panic!("office is a laser scenario")
    };
    let mut filter = FilterConfig::default_for("scanmatch")
        .unwrap()
        .build_scan(0)
        .unwrap();
    let run = run_scans(filter.as_mut(), &sim.dataset, &RunOptions::default()).unwrap();
    let n = sim.dataset.records.len();
    assert_eq!((run.trajectory.len(), run.updates.len()), (n, n));
    let reference = run.reference.as_ref().unwrap();
    // The reference starts where the estimate starts (the first odometry pose, the office's
    // start: the simulated odometry starts at the true pose).
    assert!(reference[0].pose.approx_eq(&run.trajectory[0].pose, 1e-9));
    let own = ate(&run.trajectory, reference).unwrap();
    assert_eq!(run.metrics.ate_rmse_m, Some(own.rmse));
    assert!(own.rmse < 0.5, "scan matching over 40 scans: {}", own.rmse);
    // The filter's own map was asked for: re-rendering is refused by a filter that keeps no
    // scans, before the first step.
    let err = run_scans(
        filter.as_mut(),
        &sim.dataset,
        &RunOptions {
            map_resolution: Some(0.01),
            ..Default::default()
        },
    )
    .unwrap_err();
    assert!(matches!(err, RunError::CannotRender { .. }), "{err}");
}

#[test]
fn metrics_on_hand_made_trajectories() {
    // A square walked by the truth; the estimate is the truth shifted by (0.3, -0.4):
    // a 0.5 m error at every pose as is, none after alignment, and no relative error.
    let truth: Vec<TimedPose> = (0..8)
        .map(|k| TimedPose {
            t: k as f64,
            pose: Pose2::new((k % 4) as f64, (k / 4) as f64, 0.1 * k as f64),
        })
        .collect();
    let shifted: Vec<TimedPose> = truth
        .iter()
        .map(|p| TimedPose {
            t: p.t,
            pose: Pose2::new(p.pose.x + 0.3, p.pose.y - 0.4, p.pose.theta),
        })
        .collect();
    let a = ate(&shifted, &truth).unwrap();
    assert!((a.rmse - 0.5).abs() < 1e-12);
    assert!(a.rmse_aligned < 1e-9);
    // Rotating the whole estimate about the origin by 90°: poses at distance r from the
    // origin err by r·√2, and alignment removes it all.
    let rotated: Vec<TimedPose> = truth
        .iter()
        .map(|p| TimedPose {
            t: p.t,
            pose: Pose2::new(0.0, 0.0, std::f64::consts::FRAC_PI_2).compose(&p.pose),
        })
        .collect();
    let a = ate(&rotated, &truth).unwrap();
    let own = (truth
        .iter()
        .map(|p| 2.0 * (p.pose.x.powi(2) + p.pose.y.powi(2)))
        .sum::<f64>()
        / truth.len() as f64)
        .sqrt();
    assert!((a.rmse - own).abs() < 1e-12, "{} vs {own}", a.rmse);
    assert!(a.rmse_aligned < 1e-9);
    let r = rpe(&rotated, &truth).unwrap();
    assert!(r.trans_mean < 1e-12 && r.rot_mean_deg < 1e-9);
}

#[test]
fn each_tag_builds_its_filter() {
    for info in filters() {
        // `graph` serves both kinds of data: the kind picks the front end.
        let text = format!("filter = \"{}\"\n", info.name);
        let parsed = FilterConfig::from_toml_for_kind(info.name, info.kind, &text).unwrap();
        assert_eq!(parsed.config.name(), info.name);
        assert_eq!(parsed.config.kind(), info.kind);
        let name = match info.kind {
            DataKind::Landmark => parsed
                .config
                .build_landmark(Pose2::default(), 0)
                .unwrap()
                .name()
                .to_string(),
            DataKind::Laser => parsed.config.build_scan(0).unwrap().name().to_string(),
        };
        assert_eq!(name, info.name);
        // The other kind's build is refused.
        let wrong = match info.kind {
            DataKind::Landmark => parsed.config.build_scan(0).err(),
            DataKind::Laser => parsed.config.build_landmark(Pose2::default(), 0).err(),
        };
        assert!(matches!(wrong, Some(FactoryError::WrongKind { .. })));
        // The written table reads back as the same configuration.
        let again =
            FilterConfig::from_toml_for_kind(info.name, info.kind, &parsed.config.table_toml())
                .unwrap();
        assert_eq!(again.config.table_toml(), parsed.config.table_toml());
    }
}

#[test]
fn bad_configs_are_clear_errors() {
    let err = |text: &str| FilterConfig::from_toml(text).unwrap_err().to_string();
    let e = err("filter = \"ukf\"\n");
    assert!(e.contains("`ukf`") && e.contains("fastslam2"), "{e}");
    let e = err("particles = 5\n");
    assert!(e.contains("no `filter` key"), "{e}");
    let e = err("filter = \"fastslam2\"\n\nparticels = 5\n");
    assert!(e.contains("particels") && e.contains("line 3"), "{e}");
    let e = err("filter = \"gridfast\"\nparticles = \"many\"\n");
    assert!(e.contains("line 2"), "{e}");
    // A FastSLAM 2.0 table (its `variant` key set) under the fastslam1 tag.
    let table = FilterConfig::default_for("fastslam2").unwrap().table_toml();
    let e = FilterConfig::from_toml_for("fastslam1", &table)
        .unwrap_err()
        .to_string();
    assert!(e.contains("variant") && e.contains("fastslam1"), "{e}");
    // scanmatch's keys from before it used the endpoint model (issue 21) are unknown now.
    let e = err("filter = \"scanmatch\"\nmin-score = 0.2\n");
    assert!(e.contains("min-score") && e.contains("line 2"), "{e}");
    let e = err("filter = \"scanmatch\"\n[matcher.correlative]\nlinear-window = 0.4\n");
    assert!(e.contains("matcher"), "{e}");
    // Its endpoint model's reach beyond the distance field's 15 cells names the key.
    let parsed =
        FilterConfig::from_toml("filter = \"scanmatch\"\n[matching]\nfield-radius = 1.0\n")
            .unwrap();
    let e = parsed.config.build_scan(0).err().unwrap().to_string();
    assert!(e.contains("matching.field-radius = 1"), "{e}");
    let mut ekf = FilterConfig::default_for("ekf").unwrap();
    assert!(matches!(
        ekf.set_particles(10),
        Err(FactoryError::NotAParticleFilter { filter: "ekf" })
    ));
    // A value the filter's constructor refuses names the filter.
    let parsed = FilterConfig::from_toml("filter = \"fastslam2\"\nparticles = 0\n").unwrap();
    let e = parsed
        .config
        .build_landmark(Pose2::default(), 0)
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("fastslam2") && e.contains("particles"), "{e}");
}

/// An array with more values than its fixed-size setting takes is refused with the key,
/// the line and both counts, in every filter's table and in `[laser-odometry]` (toml kept
/// the first values and dropped the rest: `slam run --config` ran with
/// `extra-motion-noise = [0.0, 0.0, 0.0, 99.0]` and nothing said the 99 was ignored).
#[test]
fn an_array_longer_than_its_setting_is_refused() {
    for (filter, kind, text, line, key) in [
        (
            "ekf",
            DataKind::Landmark,
            "filter = \"ekf\"\nextra-motion-noise = [0.0, 0.0, 0.0, 99.0]\n",
            2,
            "`extra-motion-noise` takes 3 values, the file gives 4",
        ),
        (
            "fastslam2",
            DataKind::Landmark,
            "\n[motion.odometry]\nalpha = [0.1, 0.1, 0.1, 0.1, 99.0]\n",
            3,
            "`motion.odometry.alpha` takes 4 values, the file gives 5",
        ),
        (
            "graph",
            DataKind::Laser,
            "\nloop-group-drift = [0.02, 0.005, 99.0]\n",
            2,
            "`loop-group-drift` takes 2 values, the file gives 3",
        ),
        (
            "gridfast",
            DataKind::Laser,
            "\n[laser-odometry]\nsearch-prior-std = [0.5, 0.3, 99.0]\n",
            3,
            "`laser-odometry.search-prior-std` takes 2 values, the file gives 3",
        ),
    ] {
        let e = FilterConfig::from_toml_for_kind(filter, kind, text)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(&format!("line {line}:")) && e.contains(key),
            "{filter}: {e}"
        );
        // The same arrays without the extra value are read.
        let whole = text.replace(", 99.0]", "]");
        FilterConfig::from_toml_for_kind(filter, kind, &whole)
            .unwrap_or_else(|e| panic!("{filter}: {whole}: {e}"));
    }
}

#[test]
fn a_config_file_keeps_its_own_noise_models() {
    let sim = loop_run(5);
    let mut parsed =
        FilterConfig::from_toml("filter = \"ekf\"\n[sensor]\nsigma-range = 0.5\n").unwrap();
    let applied = parsed.apply_sim_noise(&sim.noise_models());
    assert!(applied.motion && !applied.sensor);
}

#[test]
fn a_constructor_error_keeps_its_type() {
    // `particles = 0` is refused by FastSLAM's constructor: the factory's error holds the
    // crate's own typed error, whose ConfigError names the key and the bound.
    let parsed = FilterConfig::from_toml("filter = \"fastslam2\"\nparticles = 0\n").unwrap();
    let Some(FactoryError::Invalid { filter, source }) =
        parsed.config.build_landmark(Pose2::default(), 0).err()
    else {
        panic!("expected FactoryError::Invalid");
    };
    assert_eq!(filter, "fastslam2");
    let Some(slam_fastslam::FastSlamError::InvalidConfig(c)) =
        source.downcast_ref::<slam_fastslam::FastSlamError>()
    else {
        panic!("source is not a FastSlamError::InvalidConfig: {source:?}");
    };
    assert_eq!((c.key(), c.value.as_str()), ("particles".to_string(), "0"));
    // The same for a scan filter (grid FastSLAM's own error type).
    let parsed = FilterConfig::from_toml("filter = \"gridfast\"\nparticles = 0\n").unwrap();
    let Some(FactoryError::Invalid { source, .. }) = parsed.config.build_scan(0).err() else {
        panic!("expected FactoryError::Invalid");
    };
    assert!(
        source
            .downcast_ref::<slam_gridfast::GridFastError>()
            .is_some(),
        "{source:?}"
    );
    // std's source chain reaches it too.
    let e = FilterConfig::from_toml("filter = \"ekf\"\nmax-landmarks = 0\n")
        .unwrap()
        .config
        .build_landmark(Pose2::default(), 0)
        .err()
        .unwrap();
    let source = std::error::Error::source(&e).expect("a source");
    assert!(
        source.downcast_ref::<slam_ekf::EkfError>().is_some(),
        "{source:?}"
    );
}

#[test]
fn graph_without_a_kind_is_an_error_that_says_how() {
    // `graph` serves both kinds of data: a bare tag does not pick one silently.
    let e = FilterConfig::from_toml("filter = \"graph\"\n").unwrap_err();
    assert!(
        matches!(e, FactoryError::AmbiguousKind { filter: "graph" }),
        "{e}"
    );
    let text = e.to_string();
    assert!(
        text.contains("graph-landmark") && text.contains("from_toml_for_kind"),
        "{text}"
    );
    assert!(matches!(
        FilterConfig::from_toml_for("graph", ""),
        Err(FactoryError::AmbiguousKind { .. })
    ));
    assert!(matches!(
        FilterConfig::default_for("graph"),
        Err(FactoryError::AmbiguousKind { .. })
    ));
    // The kind-qualified tags, and the kind given by the caller, pick one each.
    let landmark = FilterConfig::from_toml("filter = \"graph-landmark\"\n").unwrap();
    assert_eq!(landmark.config.kind(), DataKind::Landmark);
    let laser = FilterConfig::from_toml("filter = \"graph-laser\"\n").unwrap();
    assert_eq!(laser.config.kind(), DataKind::Laser);
    let laser =
        FilterConfig::from_toml_for_kind("graph", DataKind::Laser, "filter = \"graph\"\n").unwrap();
    assert_eq!(laser.config.kind(), DataKind::Laser);
    // A tag of the other kind is refused.
    assert!(FilterConfig::from_toml_for_kind(
        "graph",
        DataKind::Laser,
        "filter = \"graph-landmark\"\n"
    )
    .is_err());
}

/// The run functions are the hand-written loop they replace: the same filter, seed and
/// data give bit-identical trajectories (what keeps every accuracy test's figures).
#[test]
fn the_run_functions_give_the_hand_loops_trajectory() {
    let sim = loop_run(80);
    let build = || {
        let mut parsed =
            FilterConfig::from_toml("filter = \"fastslam2\"\nparticles = 15\n").unwrap();
        parsed.apply_sim_noise(&sim.noise_models());
        parsed
            .config
            .build_landmark(sim.dataset.initial_pose, 5)
            .unwrap()
    };
    let mut by_hand = build();
    let mut online = Vec::new();
    for s in &sim.dataset.steps {
        by_hand.predict(&s.control).unwrap();
        by_hand.update(&s.observations).unwrap();
        online.push(by_hand.pose());
    }
    let mut by_run = build();
    let run = run_landmarks(by_run.as_mut(), &sim.dataset, &RunOptions::default()).unwrap();
    assert!(online.iter().zip(&run.online).all(|(a, b)| *a == b.pose));
    assert_eq!(by_hand.full_path(), by_run.full_path());
    assert_eq!(by_hand.landmarks(), run.landmarks);

    let opts = ScenarioOptions {
        steps: Some(60),
        ..Default::default()
    };
    let SimOutput::Laser(sim) = generate("office", &opts).unwrap() else {
        panic!("office is a laser scenario")
    };
    let build = || {
        FilterConfig::from_toml("filter = \"gridfast\"\nparticles = 6\n")
            .unwrap()
            .config
            .build_scan(9)
            .unwrap()
    };
    let mut by_hand = build();
    for r in &sim.dataset.records {
        by_hand.process(r).unwrap();
    }
    let mut by_run = build();
    let run = run_scans(by_run.as_mut(), &sim.dataset, &RunOptions::default()).unwrap();
    assert_eq!(by_hand.trajectory(), run.trajectory);
    assert_eq!(by_hand.map(), run.map);
}
