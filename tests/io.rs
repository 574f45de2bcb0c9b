//! slam-io on the real datasets of `../shared/datasets`: every reader on every file, and
//! the metrics on the benchmark figures the dataset README states.

mod common;

use slam::eval::metrics as eval;
use slam::io::{carmen, freiburg, mrclam, relations, tum};
use slam_models::{LandmarkId, Pose2, TimedPose};

#[test]
fn freiburg_course_data() {
    let Some(dir) = common::dataset("freiburg-robot-mapping") else {
        return;
    };
    let r = freiburg::read_freiburg_report(&dir).unwrap();
    let d = &r.dataset;
    // README: 331 ODOMETRY and 1212 SENSOR lines, one with a negative range (line 1541).
    assert_eq!(d.steps.len(), 331);
    let obs: usize = d.steps.iter().map(|s| s.observations.len()).sum();
    assert_eq!(obs, 1211);
    assert_eq!(r.skipped.len(), 1);
    assert_eq!(r.skipped[0].line, 1541);
    assert!(d
        .steps
        .iter()
        .all(|s| !s.observations.is_empty() && s.observations.len() <= 7));
    let lms = d.landmarks.as_ref().unwrap();
    assert_eq!(lms.len(), 9);
    assert_eq!(lms[0], (LandmarkId(1), slam_models::Point2::new(2.0, 1.0)));
    assert_eq!(d.initial_pose, Pose2::IDENTITY);
    assert!(d.ground_truth.is_none());

    // README check: dead-reckon the first 20 steps and compare the observations with
    // world.dat: residual std ≈ 0.10 m in range and ≈ 0.05 rad in bearing.
    let dr = slam::io::dead_reckoning(d);
    let (mut er, mut eb) = (Vec::new(), Vec::new());
    for (s, p) in d.steps.iter().zip(&dr).take(20) {
        for z in &s.observations {
            let (_, m) = lms.iter().find(|(id, _)| Some(*id) == z.id).unwrap();
            let q = p.pose.inverse_transform_point(m);
            er.push(z.range - q.coords.norm());
            eb.push(slam_models::normalize_angle(z.bearing - q.y.atan2(q.x)));
        }
    }
    let rms = |v: &[f64]| (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt();
    println!(
        "Freiburg first 20 steps: range residual rms {:.3} m, bearing {:.3} rad",
        rms(&er),
        rms(&eb)
    );
    assert!(rms(&er) < 0.25 && rms(&eb) < 0.12);

    let (ds, msg) = slam::io::open_dataset(&dir, None).unwrap();
    assert!(matches!(ds, slam::io::Dataset::Landmark(_)));
    assert!(
        msg.contains("331 odometry steps") && msg.contains("line 1541"),
        "{msg}"
    );
    assert!(slam::io::open_dataset(&dir, Some(1)).is_err());
}

#[test]
fn freiburg_round_trip_through_writer() {
    let Some(dir) = common::dataset("freiburg-robot-mapping") else {
        return;
    };
    let mut d = freiburg::read_freiburg(&dir).unwrap();
    d.initial_pose = Pose2::new(1.0, 2.0, 0.3);
    d.ground_truth = Some(vec![TimedPose {
        t: 0.0,
        pose: Pose2::new(1.0, 2.0, 0.3),
    }]);
    for (k, s) in d.steps.iter_mut().enumerate() {
        s.t = 10.0 + 0.1 * k as f64;
    }
    let out = std::env::temp_dir().join(format!("slam-io-it-freiburg-{}", std::process::id()));
    freiburg::write_freiburg(&out, &d).unwrap();
    let mut back = freiburg::read_freiburg(&out).unwrap();
    back.name = d.name.clone();
    assert_eq!(back.steps, d.steps);
    assert_eq!(back.landmarks, d.landmarks);
    assert_eq!(back.initial_pose, d.initial_pose);
    let g = back.ground_truth.as_ref().unwrap();
    assert!(g[0].pose.approx_eq(&d.initial_pose, 1e-12));
    std::fs::remove_dir_all(&out).ok();
}

/// Observations of robot 1 by barcode, counted independently of the reader with awk:
/// 5723 rows, of which other robots' barcodes (14, 41, 32, 23; robot 1's own is 5)
/// account for 226 + 239 + 269 + 218 = 952.
const ROBOT1_ROWS: usize = 5723;
const ROBOT1_OTHER_ROBOTS: usize = 952;

#[test]
fn mrclam_raw_robot1() {
    let Some(dir) = common::dataset("utias-mrclam/MRCLAM_Dataset1") else {
        return;
    };
    let r = mrclam::read_mrclam_report(&dir, 1).unwrap();
    let d = &r.dataset;
    assert!(!r.resampled);
    assert_eq!(d.steps.len(), 97_890);
    assert_eq!(d.steps[0].t, 1248272272.841);
    assert_eq!(d.steps.last().unwrap().t, 1248273763.319);
    let obs: usize = d.steps.iter().map(|s| s.observations.len()).sum();
    assert_eq!(r.other_robot_observations, ROBOT1_OTHER_ROBOTS);
    assert!(r.skipped.is_empty(), "{:?}", r.skipped);
    assert_eq!(obs, ROBOT1_ROWS - ROBOT1_OTHER_ROBOTS);
    // Ids are landmark subjects 6..=20; ranges and bearings within the README's spans.
    for z in d.steps.iter().flat_map(|s| &s.observations) {
        let id = z.id.unwrap().0;
        assert!((6..=20).contains(&id));
        assert!((1.0..=9.3).contains(&z.range) && (-0.58..=0.48).contains(&z.bearing));
    }
    assert_eq!(d.landmarks.as_ref().unwrap().len(), 15);
    assert!(d.ground_truth.is_none());
    let (_, msg) = slam::io::open_dataset(&dir, Some(1)).unwrap();
    assert!(
        msg.contains("raw") && msg.contains("952 other-robot"),
        "{msg}"
    );
    assert!(mrclam::read_mrclam(&dir, 9).is_err());
}

#[test]
fn mrclam_resampled_robot1_against_ground_truth() {
    let Some(dir) = common::dataset("utias-mrclam/MRCLAM_Dataset1_resampled") else {
        return;
    };
    let r = mrclam::read_mrclam_report(&dir, 1).unwrap();
    let d = &r.dataset;
    assert!(r.resampled);
    assert_eq!(d.steps.len(), 75_000);
    assert_eq!(r.other_robot_observations, ROBOT1_OTHER_ROBOTS);
    let obs: usize = d.steps.iter().map(|s| s.observations.len()).sum();
    assert_eq!(obs + r.skipped.len(), ROBOT1_ROWS - ROBOT1_OTHER_ROBOTS);
    let gt = d.ground_truth.as_ref().unwrap();
    assert_eq!(gt.len(), 75_000);
    // First ground-truth row: 0 3.5732 -3.3328 2.3408.
    assert!(d
        .initial_pose
        .approx_eq(&Pose2::new(3.5732, -3.3328, 2.3408), 1e-12));

    // The observations agree with ground truth + true landmarks: this checks the barcode
    // mapping, the bearing convention and the step each measurement is attached to.
    let lms = d.landmarks.as_ref().unwrap();
    let mut res = Vec::new();
    for (s, g) in d.steps.iter().zip(gt) {
        for z in &s.observations {
            let (_, m) = lms.iter().find(|(id, _)| Some(*id) == z.id).unwrap();
            let q = g.pose.inverse_transform_point(m);
            res.push((z.range - q.coords.norm()).abs());
        }
    }
    res.sort_by(f64::total_cmp);
    let median = res[res.len() / 2];
    println!("MRCLAM robot 1: median |range residual| against ground truth {median:.3} m");
    assert!(median < 0.2, "median range residual {median}");

    // Dead reckoning from the true initial pose, scored against ground truth.
    let dr = slam::io::dead_reckoning(d);
    let ate = eval::ate(&dr, gt).unwrap();
    println!(
        "MRCLAM robot 1 dead reckoning: ATE {:.3} m, aligned {:.3} m over {} poses",
        ate.rmse, ate.rmse_aligned, ate.matched
    );
    assert_eq!(ate.matched, 75_000);
    // Odometry alone drifts by metres over 25 minutes but stays within the 15 × 8 m arena scale.
    assert!(ate.rmse > 0.3 && ate.rmse < 20.0, "{ate:?}");
    assert!(ate.rmse_aligned <= ate.rmse);
    // Over the first 10 s the robot barely moves: dead reckoning is still within 0.1 m.
    let early = eval::ate(&dr[..500], &gt[..500]).unwrap();
    assert!(early.rmse < 0.1, "{early:?}");
}

#[test]
fn carmen_bench_and_radish_logs() {
    // (file, FLASER scans, ODOM records, beams, no-return threshold) from the README tables,
    // except the no-return threshold: the tables give the no-return code (Acapulco's 51.25
    // is the log's largest reading, which occurs once; 51.15 occurs 9,264 times and is the
    // code), and the threshold is the lowest reading of the code's jitter band, counted with
    // a script over the logs' FLASER readings: Freiburg-101 writes 81.83 (5 times) beside
    // 81.91; FHW 51.05 (607) beside 51.1 (40); Edmonton 51.09 … 51.16 (8, 94, 2, 211, 2991,
    // 61); Acapulco 51.09 … 51.16 (3, 13, 3020, 9264, 37). The nearest reading below each
    // band is at least 0.14 m below it (Acapulco's 50.95).
    // Last: the no-return readings (at or above the threshold), counted by the same script.
    let radish = [
        ("intel", 910, 14541, 180, 81.83, 4172),
        ("freiburg-101", 292, 4569, 360, 81.83, 12_555),
        ("csail", 406, 2394, 361, 81.91, 3907),
        ("belgioioso", 395, 4442, 361, 81.91, 699),
        ("fhw", 488, 13935, 180, 51.05, 647),
        ("edmonton", 340, 6351, 180, 51.09, 3367),
        ("acapulco", 861, 12142, 181, 51.09, 12_339),
    ];
    for (site, scans, odom, beams, max, no_returns) in radish {
        let Some(p) = common::dataset(&format!("radish-corrected/{site}-corrected.log.gz")) else {
            return;
        };
        let log = carmen::read_carmen(&p).unwrap();
        let recs = &log.dataset.records;
        let n_scans = recs.iter().filter(|r| r.scan.is_some()).count();
        assert_eq!((n_scans, recs.len() - n_scans), (scans, odom), "{site}");
        assert_eq!(log.unknown_records.get("NEFF"), Some(&scans), "{site}");
        assert_eq!(log.flaser_max_range, Some(max), "{site}");
        let s = recs.iter().find_map(|r| r.scan.as_ref()).unwrap();
        assert_eq!(s.len(), beams);
        assert!((s.beam_angle(0) + std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        let last = s.beam_angle(beams - 1).to_degrees();
        let want = if beams % 180 == 0 {
            90.0 - 180.0 / beams as f64
        } else {
            90.0
        };
        assert!((last - want).abs() < 1e-9, "{site}: last beam at {last}°");
        assert_eq!(s.sensor_pose, Pose2::IDENTITY);
        // No-return readings are kept and told apart from hits.
        let no_ret = recs
            .iter()
            .filter_map(|r| r.scan.as_ref())
            .flat_map(|s| (0..s.len()).filter(move |&k| !s.is_hit(k)))
            .count();
        assert_eq!(no_ret, no_returns, "{site}");
    }
    for (site, scans, odom) in [
        ("intel", 910, 13_700),
        ("csail", 406, 1988),
        ("fhw", 488, 13_453),
    ] {
        let Some(p) = common::dataset(&format!("bench/{site}.log")) else {
            return;
        };
        let (ds, msg) = slam::io::open_dataset(&p, None).unwrap();
        let slam::io::Dataset::Scan(d) = ds else {
            panic!("{site} is not a scan dataset")
        };
        let n_scans = d.records.iter().filter(|r| r.scan.is_some()).count();
        assert_eq!(
            (n_scans, d.records.len() - n_scans),
            (scans, odom),
            "{site}"
        );
        assert!(msg.contains("CARMEN"), "{msg}");
    }
    // The course's CSAIL log: ROBOTLASER1 lines of 361 beams, 0.5°, max range 80 m,
    // 81.91 = no return. (Its README says "385 laser scans"; the file has 686 lines of 385
    // fields each.)
    let Some(p) = common::dataset("freiburg-robot-mapping/csail.log") else {
        return;
    };
    let log = carmen::read_carmen(&p).unwrap();
    let recs = &log.dataset.records;
    assert_eq!(recs.len(), 686);
    assert_eq!(log.record_counts.get("ROBOTLASER1"), Some(&686));
    assert_eq!(recs[0].odometry, Pose2::IDENTITY);
    let s = recs[1].scan.as_ref().unwrap();
    assert_eq!((s.len(), s.max_range), (361, 80.0));
    assert!((s.angle_min + std::f64::consts::FRAC_PI_2).abs() < 1e-6);
    assert!((s.angle_increment.to_degrees() - 0.5).abs() < 1e-3);
    assert!(s.sensor_pose.approx_eq(&Pose2::IDENTITY, 1e-12));
    assert!(recs
        .iter()
        .flat_map(|r| &r.scan.as_ref().unwrap().ranges)
        .all(|&r| r >= 0.28));
}

#[test]
fn relations_and_tum_files() {
    for (f, n) in [("intel", 2984), ("fr079", 1685), ("mit-killian", 4677)] {
        let Some(p) = common::dataset(&format!("slam-benchmark-relations/{f}.relations")) else {
            return;
        };
        let rel = relations::read_relations(&p).unwrap();
        assert_eq!(rel.len(), n, "{f}");
        if f == "intel" {
            assert_eq!(rel.iter().filter(|r| r.t2 < r.t1).count(), 6);
            assert_eq!(rel[0].t1, 976052905.167303);
        }
        assert!(rel.iter().all(|r| r.delta.x.hypot(r.delta.y) < 5.05));
    }
    let Some(p) = common::dataset("bench/intel.ref.tum") else {
        return;
    };
    let t = tum::read_tum(&p).unwrap();
    assert_eq!(t.len(), 13_700);
    assert_eq!(t[0].t, 976052857.337536);
}

/// The relations metric on the Intel benchmark, with the README's figures: the recovered
/// raw odometry scores ≈ 7.4 m mean translational error, GMapping's own trajectory
/// 0.057 m / 2.32°.
#[test]
fn relations_metric_reproduces_intel_figures() {
    let (Some(log), Some(rel), Some(reff)) = (
        common::dataset("bench/intel.log"),
        common::dataset("slam-benchmark-relations/intel.relations"),
        common::dataset("bench/intel.ref.tum"),
    ) else {
        return;
    };
    let rel = relations::read_relations(&rel).unwrap();
    let d = carmen::read_carmen(&log).unwrap().dataset;
    let odo = slam::io::odometry_trajectory(&d);
    let r = eval::relations_error(&odo, &rel);
    println!("intel.log raw odometry: {r:?}");
    assert!((r.trans_mean - 7.4).abs() < 0.1, "{r:?}");
    let g = tum::read_tum(&reff).unwrap();
    let r = eval::relations_error(&g, &rel);
    println!("intel.ref.tum (GMapping): {r:?}");
    assert!((r.trans_mean - 0.057).abs() < 0.0015, "{r:?}");
    assert!((r.rot_mean_deg - 2.32).abs() < 0.05, "{r:?}");
    assert!(r.used > 2900, "{r:?}");
}

/// Pictures and writers on real data: the files land in cargo's per-test temp folder
/// (`CARGO_TARGET_TMPDIR/io-pictures`) to be looked at.
#[test]
#[cfg(feature = "png")]
fn pictures_and_writers_on_real_data() {
    use slam::viz::picture::{self, Picture, Series};
    use slam_models::{GridMap, LandmarkEstimate, Matrix2, Point2, WeightedPose};
    let out = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("io-pictures");
    std::fs::create_dir_all(&out).unwrap();

    // Freiburg: dead reckoning, true landmarks, and "estimates" at the true positions with
    // a made-up covariance, plus a particle cloud around the last pose.
    if let Some(dir) = common::dataset("freiburg-robot-mapping") {
        let d = freiburg::read_freiburg(&dir).unwrap();
        let dr: Vec<Pose2> = slam::io::dead_reckoning(&d)
            .iter()
            .map(|p| p.pose)
            .collect();
        let lms = d.landmarks.clone().unwrap();
        let est: Vec<LandmarkEstimate> = lms
            .iter()
            .map(|(id, p)| LandmarkEstimate {
                id: *id,
                mean: Point2::new(p.x + 0.1, p.y - 0.1),
                covariance: Matrix2::new(0.04, 0.015, 0.015, 0.02),
            })
            .collect();
        let last = *dr.last().unwrap();
        let parts: Vec<WeightedPose> = (0..200)
            .map(|k| {
                let a = k as f64 * 2.399;
                let r = 0.3 * (k as f64 / 200.0).sqrt();
                WeightedPose {
                    pose: Pose2::new(last.x + r * a.cos(), last.y + r * a.sin(), 0.0),
                    weight: 1.0 / 200.0,
                }
            })
            .collect();
        Picture::new()
            .title("Freiburg course data: dead reckoning")
            .trajectory(&dr, picture::RED, "dead reckoning")
            .true_landmarks(&lms)
            .landmarks(&est, "synthetic estimates, 95 %")
            .particles(&parts)
            .save_png(&out.join("freiburg.png"))
            .unwrap();
        slam::io::landmarks_csv::write_landmarks_csv(&out.join("freiburg-landmarks.csv"), &est)
            .unwrap();
        let back = slam::io::landmarks_csv::read_landmarks_csv(&out.join("freiburg-landmarks.csv"))
            .unwrap();
        assert_eq!(back, est);
        let e = eval::landmark_error(&est, &lms, true);
        assert!(
            (e.rmse - 0.02f64.sqrt()).abs() < 1e-9 && e.rmse_aligned < 1e-9,
            "{e:?}"
        );
    }

    // MRCLAM: ground truth and dead reckoning, true landmarks.
    if let Some(dir) = common::dataset("utias-mrclam/MRCLAM_Dataset1_resampled") {
        let d = mrclam::read_mrclam(&dir, 1).unwrap();
        let gt: Vec<Pose2> = d
            .ground_truth
            .as_ref()
            .unwrap()
            .iter()
            .map(|p| p.pose)
            .collect();
        let dr: Vec<Pose2> = slam::io::dead_reckoning(&d)
            .iter()
            .map(|p| p.pose)
            .collect();
        Picture::new()
            .title("MRCLAM 1, robot 1: dead reckoning")
            .ground_truth(&gt)
            .trajectory(&dr, picture::RED, "dead reckoning")
            .true_landmarks(d.landmarks.as_ref().unwrap())
            .save_png(&out.join("mrclam-robot1.png"))
            .unwrap();
        slam::io::tum::write_tum(
            &out.join("mrclam-robot1-dr.tum"),
            &slam::io::dead_reckoning(&d),
        )
        .unwrap();
    }

    // Intel: a crude map of the scan end points at GMapping's poses (a real grid mapper is
    // not this crate's job), written as PNG and as a map_server map, then read back.
    if let (Some(log), Some(reff)) = (
        common::dataset("bench/intel.log"),
        common::dataset("bench/intel.ref.tum"),
    ) {
        let d = carmen::read_carmen(&log).unwrap().dataset;
        let reference = tum::read_tum(&reff).unwrap();
        let sorted = eval::sorted_by_time(&reference);
        let res = 0.1;
        let (ox, oy, w, h) = (-20.0, -25.0, 500, 500);
        let mut map = GridMap::unknown(res, Point2::new(ox, oy), w, h);
        for r in &d.records {
            let (Some(scan), Some(i)) = (&r.scan, eval::lookup(&sorted, r.t, 0.006)) else {
                continue;
            };
            let pose = sorted[i].pose;
            for q in scan.hit_points() {
                if let Some((ix, iy)) = map.cell_of(&pose.transform_point(&q)) {
                    map.cells[iy * w + ix] = 100;
                }
            }
            if let Some((ix, iy)) = map.cell_of(&pose.translation()) {
                map.cells[iy * w + ix] = 0;
            }
        }
        let odo: Vec<Pose2> = slam::io::odometry_trajectory(&d)
            .iter()
            .map(|p| p.pose)
            .collect();
        let refp: Vec<Pose2> = reference.iter().map(|p| p.pose).collect();
        Picture::new()
            .map(&map)
            .title("bench/intel.log: scan end points at GMapping's poses")
            .trajectory(&refp, picture::RED, "GMapping")
            .trajectory(&odo, picture::PURPLE, "odometry")
            .save_png(&out.join("intel.png"))
            .unwrap();
        slam::io::ros_map::write_ros_map(&out, "intel-map", &map).unwrap();
        let back = slam::io::ros_map::read_ros_map(&out.join("intel-map.yaml")).unwrap();
        assert_eq!(back, map);
        // CARMEN round trip of the real log.
        let p = out.join("intel-rewritten.log.gz");
        carmen::write_carmen(&p, &d).unwrap();
        let again = carmen::read_carmen(&p).unwrap().dataset;
        assert_eq!(again.records.len(), d.records.len());
        for (a, b) in d.records.iter().zip(&again.records) {
            assert_eq!((a.t, a.odometry), (b.t, b.odometry));
            assert_eq!(
                a.scan.as_ref().map(|s| &s.ranges),
                b.scan.as_ref().map(|s| &s.ranges)
            );
        }
    }

    // A NEES-style series with its 95 % band for 50 runs of a 3-dof error.
    let x: Vec<f64> = (0..200).map(|i| i as f64).collect();
    let y: Vec<f64> = x
        .iter()
        .map(|t| 3.0 + 0.6 * (t * 0.13).sin() + if *t > 150.0 { 1.5 } else { 0.0 })
        .collect();
    let band = eval::chi2_band(3, 50, 0.95);
    picture::plot_series(
        &out.join("nees.png"),
        &x,
        &[Series {
            y: &y,
            colour: picture::RED,
        }],
        Some(band),
    )
    .unwrap();
    println!("pictures in {}", out.display());
}

/// Simulated datasets round-trip through the writers and readers: Freiburg for landmark
/// scenarios (odometry and velocity controls), CARMEN for laser scenarios.
#[test]
fn simulated_data_round_trips() {
    use slam::sim::scenario::{generate, ScenarioOptions};
    use slam::sim::SimOutput;
    let out = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("io-sim-round-trip");
    std::fs::create_dir_all(&out).unwrap();
    let opts = ScenarioOptions {
        seed: 7,
        steps: Some(300),
        ..Default::default()
    };
    let SimOutput::Landmark(run) = generate("loop", &opts).unwrap() else {
        panic!("loop is a landmark scenario")
    };
    let dir = out.join("loop");
    freiburg::write_freiburg(&dir, &run.dataset).unwrap();
    let back = freiburg::read_freiburg_report(&dir).unwrap();
    assert!(back.skipped.is_empty());
    let d = &run.dataset;
    assert_eq!(back.dataset.steps, d.steps);
    assert_eq!(back.dataset.landmarks, d.landmarks);
    assert_eq!(back.dataset.initial_pose, d.initial_pose);
    let (g0, g1) = (
        d.ground_truth.as_ref().unwrap(),
        back.dataset.ground_truth.as_ref().unwrap(),
    );
    assert_eq!(g0.len(), g1.len());
    for (a, b) in g0.iter().zip(g1) {
        assert_eq!(a.t, b.t);
        assert!(a.pose.approx_eq(&b.pose, 1e-12));
    }
    // Noise-free dead reckoning of the data and of the read-back data agree exactly.
    assert_eq!(
        slam::io::dead_reckoning(d),
        slam::io::dead_reckoning(&back.dataset)
    );

    // Velocity controls are written as the odometry increment with the same end pose.
    let vopts = ScenarioOptions {
        velocity: true,
        ..opts.clone()
    };
    let SimOutput::Landmark(vrun) = generate("loop", &vopts).unwrap() else {
        panic!()
    };
    let vdir = out.join("loop-velocity");
    freiburg::write_freiburg(&vdir, &vrun.dataset).unwrap();
    let vback = freiburg::read_freiburg(&vdir).unwrap();
    let (a, b) = (
        slam::io::dead_reckoning(&vrun.dataset),
        slam::io::dead_reckoning(&vback),
    );
    for (p, q) in a.iter().zip(&b) {
        assert!(p.pose.approx_eq(&q.pose, 1e-9), "{p:?} vs {q:?}");
    }

    // Hidden ids are written as -1 and read back as `None`.
    let SimOutput::Landmark(crun) = generate("clutter", &opts).unwrap() else {
        panic!()
    };
    if crun
        .dataset
        .steps
        .iter()
        .flat_map(|s| &s.observations)
        .any(|z| z.id.is_none())
    {
        freiburg::write_freiburg(&out.join("clutter"), &crun.dataset).unwrap();
        let cback = freiburg::read_freiburg(&out.join("clutter")).unwrap();
        let ids = |d: &slam::models::LandmarkDataset| -> Vec<Option<slam::models::LandmarkId>> {
            d.steps
                .iter()
                .flat_map(|s| &s.observations)
                .map(|z| z.id)
                .collect()
        };
        assert_eq!(ids(&cback), ids(&crun.dataset));
    }

    let lopts = ScenarioOptions {
        seed: 3,
        steps: Some(40),
        ..Default::default()
    };
    let SimOutput::Laser(lrun) = generate("office", &lopts).unwrap() else {
        panic!("office is a laser scenario")
    };
    for name in ["office.log", "office.log.gz"] {
        let p = out.join(name);
        carmen::write_carmen(&p, &lrun.dataset).unwrap();
        let back = carmen::read_carmen(&p).unwrap();
        assert!(back.unknown_records.is_empty());
        assert_eq!(back.dataset.ground_truth, lrun.dataset.ground_truth);
        assert_eq!(back.dataset.records.len(), lrun.dataset.records.len());
        for (a, b) in lrun.dataset.records.iter().zip(&back.dataset.records) {
            assert_eq!((a.t, a.odometry), (b.t, b.odometry));
            match (&a.scan, &b.scan) {
                (None, None) => {}
                (Some(x), Some(y)) => {
                    assert_eq!(x.ranges, y.ranges);
                    assert_eq!(
                        (x.angle_min, x.angle_increment, x.max_range),
                        (y.angle_min, y.angle_increment, y.max_range)
                    );
                    assert!(x.sensor_pose.approx_eq(&y.sensor_pose, 1e-12));
                }
                _ => panic!("scan presence differs"),
            }
        }
    }
}

/// The raw and resampled MRCLAM copies describe the same run: dead reckoning of the raw
/// odometry (100 Hz, irregular), started at the resampled ground truth and shifted by the
/// README's clock offset (t = 0 ↔ 1248272263.32 s ± 0.05 s), tracks the resampled dead
/// reckoning, and scores a similar ATE against ground truth.
#[test]
fn mrclam_raw_and_resampled_agree() {
    let (Some(raw_dir), Some(res_dir)) = (
        common::dataset("utias-mrclam/MRCLAM_Dataset1"),
        common::dataset("utias-mrclam/MRCLAM_Dataset1_resampled"),
    ) else {
        return;
    };
    const OFFSET: f64 = 1248272263.32;
    let res = mrclam::read_mrclam(&res_dir, 1).unwrap();
    let gt = res.ground_truth.clone().unwrap();
    let mut raw = mrclam::read_mrclam(&raw_dir, 1).unwrap();
    for s in &mut raw.steps {
        s.t -= OFFSET;
    }
    let sorted = eval::sorted_by_time(&gt);
    let i = eval::lookup(&sorted, raw.steps[0].t, 0.011).unwrap();
    raw.initial_pose = sorted[i].pose;
    let dr_raw = slam::io::dead_reckoning(&raw);
    let a_raw = eval::ate_with(&dr_raw, &gt, 0.011).unwrap();
    let a_res = eval::ate(&slam::io::dead_reckoning(&res), &gt).unwrap();
    println!(
        "MRCLAM robot 1 dead reckoning ATE: raw {:.3} m (aligned {:.3}, {} poses), resampled {:.3} m (aligned {:.3})",
        a_raw.rmse, a_raw.rmse_aligned, a_raw.matched, a_res.rmse, a_res.rmse_aligned
    );
    assert!(a_raw.matched > 60_000, "{a_raw:?}");
    assert!(
        (a_raw.rmse - a_res.rmse).abs() < 0.5 * a_res.rmse,
        "{a_raw:?} vs {a_res:?}"
    );
}
