//! slam-grid on simulated and real laser data: matching accuracy in the simulated office,
//! scan-matching odometry on a real log with perturbed odometry, and mapping with known
//! poses on the CSAIL course log.

mod common;

use rand::{Rng, SeedableRng};
use slam::grid::{
    InverseSensorModel, LikelihoodParams, OccupancyGrid, RangeData, RefinedCorrelativeMatcher,
    ScanMatchConfig, ScanMatchOdometry,
};
use slam::models::{normalize_angle, Pose2, TimedPose};
use slam::sim::laser::LaserScanner;
use slam::sim::scenario::{generate, ScenarioOptions};
use slam::sim::SimOutput;

/// Outcome of the office matching trials.
struct Trials {
    ok: usize,
    n: usize,
    median_err: f64,
    p99_err: f64,
    median_rot_deg: f64,
    /// Translation error histogram over [0, 2.5, 5, 7.5, 10, 20, 50) mm and beyond.
    hist: [usize; 7],
}

/// Builds the office map at `res` from every scan of the simulated run (seed 1) at its
/// true pose, then matches `n` fresh scans, each simulated at a random true pose of the
/// run, from a random initial offset up to 0.3 m (uniform in a disk) and 10°. Trial `i`
/// draws everything from its own stream (`seed`, `i`), so the outcome does not depend on
/// how rayon spreads the trials over threads.
fn office_trials(res: f64, n: usize, seed: u64) -> Trials {
    use rayon::prelude::*;
    let opts = ScenarioOptions {
        seed: 1,
        ..Default::default()
    };
    let Ok(SimOutput::Laser(run)) = generate("office", &opts) else {
        panic!("office scenario did not generate a laser run");
    };
    let gt = run.dataset.ground_truth.as_ref().expect("ground truth");
    // Distances to lines fitted through the hit means (`LikelihoodParams::surface_lines`).
    let params = LikelihoodParams {
        surface_lines: true,
        ..Default::default()
    };
    let mut grid = OccupancyGrid::new(res, InverseSensorModel::default())
        .with_likelihood(params)
        .expect("valid likelihood parameters");
    let mut poses = Vec::new();
    for (rec, truth) in run.dataset.records.iter().zip(gt) {
        if let Some(scan) = &rec.scan {
            grid.integrate_scan(&truth.pose, scan);
            poses.push(truth.pose);
        }
    }
    let scanner = LaserScanner::default();
    // The refinement with a narrower Gaussian than the field's (see
    // `GaussNewtonMatcher::sigma`).
    let mut matcher = RefinedCorrelativeMatcher::default();
    matcher.refine.sigma = 0.02;
    let errors: Vec<(f64, f64)> = (0..n as u64)
        .into_par_iter()
        .map(|i| {
            let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(seed.wrapping_mul(1_000_003) + i);
            let truth = poses[rng.random_range(0..poses.len())];
            let scan = scanner.scan(&run.world, &truth, &mut rng);
            let r = 0.3 * rng.random::<f64>().sqrt();
            let a = rng.random_range(0.0..std::f64::consts::TAU);
            let dth = rng.random_range(-10f64..=10.0).to_radians();
            let initial = Pose2::new(
                truth.x + r * a.cos(),
                truth.y + r * a.sin(),
                truth.theta + dth,
            );
            let prepared =
                RangeData::new(&scan, grid.sensor_model()).expect("valid simulated scan");
            let m = matcher
                .match_prepared(&grid, &prepared, &initial)
                .expect("match");
            let e = m.pose.distance(&truth);
            let de = normalize_angle(m.pose.theta - truth.theta)
                .abs()
                .to_degrees();
            (e, de)
        })
        .collect();
    let ok = errors
        .iter()
        .filter(|(e, de)| *e < 0.01 && *de < 0.5)
        .count();
    let mut hist = [0; 7];
    for (e, _) in &errors {
        let k = [0.0025, 0.005, 0.0075, 0.01, 0.02, 0.05]
            .iter()
            .position(|&b| *e < b)
            .unwrap_or(6);
        hist[k] += 1;
    }
    let mut errs: Vec<f64> = errors.iter().map(|e| e.0).collect();
    let mut rots: Vec<f64> = errors.iter().map(|e| e.1).collect();
    errs.sort_by(f64::total_cmp);
    rots.sort_by(f64::total_cmp);
    Trials {
        ok,
        n,
        median_err: errs[n / 2],
        p99_err: errs[(n * 99) / 100],
        median_rot_deg: rots[n / 2],
        hist,
    }
}

/// Issue #7: matching a scan simulated in the `office` world against its map (5 cm cells,
/// as in the scan-matching odometry) from offsets up to 0.3 m and 10° converges within
/// 1 cm and 0.5° of the simulator's true pose in ≥ 99 % of 1,000 random trials
/// (correlative + Gauss-Newton refinement). The field measures to lines fitted through the
/// map's mean hit positions (`LikelihoodParams::surface_lines`, off by default); with
/// distances to mean hit points (the default) the same trials gave 94.7 %, the refinement
/// settling a few millimetres off the truth even when started on it (none of the failures
/// was the correlative search's). The margin is thin: map seeds 1–5 × trial seeds 7 and
/// 2024 gave 98.8–99.9 % (9 of 10 at or above 99 %); the failures are refinements along a
/// corridor where only door jambs and walls seen through doors fix the position along it.
#[test]
fn office_matching_from_large_offsets() {
    let t = office_trials(0.05, 1000, 2024);
    println!(
        "office, 5 cm grid: {}/{} within 1 cm and 0.5°; translation error median {:.4} m, \
         p99 {:.4} m; rotation error median {:.3}°; translation errors in mm \
         [0,2.5,5,7.5,10,20,50,∞): {:?}",
        t.ok, t.n, t.median_err, t.p99_err, t.median_rot_deg, t.hist
    );
    assert!(t.ok * 100 >= 99 * t.n, "5 cm: {}/{}", t.ok, t.n);
    assert!(t.median_err < 0.005 && t.p99_err < 0.01);
}

/// Reads a perturbed copy of a corrected log (odometry replaced, ground truth written by
/// `perturb-odometry`) into a temporary directory.
fn perturbed(site: &str, seed: u64) -> Option<(slam::models::ScanDataset, Vec<TimedPose>)> {
    let log = common::dataset(&format!("radish-corrected/{site}-corrected.log.gz"))?;
    let tool = common::datasets_dir().join("../tools/perturb-odometry");
    if !tool.exists() {
        eprintln!("SKIPPED: {} not found", tool.display());
        return None;
    }
    let dir =
        std::env::temp_dir().join(format!("slam-grid-perturbed-{}-{site}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let prefix = dir.join(site);
    let status = std::process::Command::new("python3")
        .arg(&tool)
        .arg(&log)
        .arg(&prefix)
        .arg("--seed")
        .arg(seed.to_string())
        .status()
        .expect("run perturb-odometry");
    assert!(status.success(), "perturb-odometry failed");
    let data = slam::io::carmen::read_carmen(&prefix.with_extension("log"))
        .expect("read perturbed log")
        .dataset;
    let gt = slam::io::tum::read_tum(&dir.join(format!("{site}.gt.tum"))).expect("read truth");
    let _ = std::fs::remove_dir_all(&dir);
    Some((data, gt))
}

#[test]
fn scanmatch_beats_odometry_on_perturbed_intel() {
    let Some((data, gt)) = perturbed("intel", 7) else {
        return;
    };
    let mut f =
        ScanMatchOdometry::new(ScanMatchConfig::default(), Pose2::IDENTITY, 0).expect("config");
    let all = slam::eval::run_scans(&mut f, &data, &Default::default())
        .expect("run")
        .trajectory;
    assert_eq!(all.len(), data.records.len());
    // The ground truth has one pose per scan; each scan shares its time with the ODOM record
    // before it, whose pose is the uncorrected prediction. Score the scan records.
    let at_scans = |traj: &[TimedPose]| -> Vec<TimedPose> {
        traj.iter()
            .zip(&data.records)
            .filter(|(_, r)| r.scan.is_some())
            .map(|(p, _)| *p)
            .collect()
    };
    // Both start in their own frame: the ground truth is anchored on each one's first pose.
    use slam::eval::metrics::{anchor_at_first_match, ate, rpe};
    let est = at_scans(&all);
    let odo = at_scans(&slam::io::odometry_trajectory(&data));
    let (gt_sm, gt_od) = (
        anchor_at_first_match(&est, &gt),
        anchor_at_first_match(&odo, &gt),
    );
    let ate_sm = ate(&est, &gt_sm).expect("ate");
    let rpe_sm = rpe(&est, &gt_sm).expect("rpe");
    let ate_od = ate(&odo, &gt_od).expect("ate");
    let rpe_od = rpe(&odo, &gt_od).expect("rpe");
    println!(
        "intel (perturbed, seed 7), {} records, {} match failures:\n  scanmatch: ATE {:.3} m \
         (aligned {:.3} m), RPE {:.4} m / {:.3}°\n  odometry:  ATE {:.3} m (aligned {:.3} m), \
         RPE {:.4} m / {:.3}°",
        data.records.len(),
        f.match_failures(),
        ate_sm.rmse,
        ate_sm.rmse_aligned,
        rpe_sm.trans_mean,
        rpe_sm.rot_mean_deg,
        ate_od.rmse,
        ate_od.rmse_aligned,
        rpe_od.trans_mean,
        rpe_od.rot_mean_deg
    );
    // Loose bounds that plain odometry fails by far.
    assert!(ate_sm.rmse < 1.0, "scanmatch ATE {}", ate_sm.rmse);
    assert!(ate_od.rmse > 1.0, "odometry ATE {}", ate_od.rmse);
    // Per-scan translation error is at the level of the reference itself (GMapping's poses,
    // a few cm); the rotational drift is what odometry gets wrong.
    assert!(
        rpe_sm.rot_mean_deg < 0.5 * rpe_od.rot_mean_deg,
        "scanmatch rotational RPE {} vs odometry {}",
        rpe_sm.rot_mean_deg,
        rpe_od.rot_mean_deg
    );
}

/// Mapping with known poses (the log's poses): integrates every scan of `rel` at its pose
/// into a 5 cm grid, checks the map agrees with its own scans (the end points of every 10th
/// scan, < 15 m, on or next to an occupied cell: a misregistered log smears walls and fails
/// this: Intel with its raw odometry poses (`bench/intel.log`) scores 40.7 %, its corrected
/// log 96.4 %), and exports it as a PNG and a ROS map_server PGM + YAML that reads back.
fn known_poses_map_is_clean(rel: &str, name: &str) {
    let Some(path) = common::dataset(rel) else {
        return;
    };
    let data = slam::io::carmen::read_carmen(&path)
        .expect("read the log")
        .dataset;
    let mut grid = OccupancyGrid::new(0.05, InverseSensorModel::default());
    let mut scans = 0;
    for rec in &data.records {
        if let Some(scan) = &rec.scan {
            grid.integrate_scan(&rec.odometry, scan);
            scans += 1;
        }
    }
    let (mut on, mut total) = (0usize, 0usize);
    for rec in data.records.iter().filter(|r| r.scan.is_some()).step_by(10) {
        let Some(scan) = &rec.scan else { continue };
        for p in scan
            .hit_points()
            .into_iter()
            .filter(|p| p.coords.norm() < 15.0)
        {
            let c = grid.world_to_cell(&rec.odometry.transform_point(&p));
            total += 1;
            let near = (-1..=1).any(|dy| {
                (-1..=1).any(|dx| {
                    grid.probability(slam::grid::CellIndex::new(c.x + dx, c.y + dy)) > 0.5
                })
            });
            on += usize::from(near);
        }
    }
    let ratio = on as f64 / total as f64;
    println!(
        "{name}: {:.1} % of {total} end points (< 15 m) on occupied cells",
        100.0 * ratio
    );
    assert!(
        ratio > 0.9,
        "{name}: map inconsistent with its own scans: {ratio}"
    );
    let map = grid.to_grid_map();
    let dir = std::env::temp_dir().join(format!("slam-grid-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    #[cfg(feature = "png")]
    slam::viz::picture::Picture::new()
        .map(&map)
        .save_png(&dir.join("map.png"))
        .expect("write png");
    slam::io::ros_map::write_ros_map(&dir, "map", &map).expect("write ROS map");
    let back = slam::io::ros_map::read_ros_map(&dir.join("map.yaml")).expect("read ROS map");
    assert_eq!((back.width, back.height), (map.width, map.height));
    println!(
        "{name}: {scans} scans, map {}x{} cells, written to {}",
        map.width,
        map.height,
        dir.display()
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn csail_known_poses_give_a_clean_map() {
    known_poses_map_is_clean("freiburg-robot-mapping/csail.log", "csail");
}

#[test]
fn intel_corrected_log_gives_a_clean_map() {
    known_poses_map_is_clean("radish-corrected/intel-corrected.log.gz", "intel-corrected");
}
