//! Shared helpers of the cross-crate tests (`tests/*.rs`, each `mod common;`).
#![allow(dead_code)]

use std::path::PathBuf;

/// `../shared/datasets` beside the checkout, or `$SLAM_DATASETS` when set.
pub fn datasets_dir() -> PathBuf {
    std::env::var_os("SLAM_DATASETS")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/datasets"))
}

/// The path of a file or folder under the datasets directory, or `None` (after printing why)
/// when it is missing on a user's machine. Under CI (`CI=true`) a missing dataset is a
/// failure, never a silent skip.
pub fn dataset(rel: &str) -> Option<PathBuf> {
    let p = datasets_dir().join(rel);
    if p.exists() {
        return Some(p);
    }
    if std::env::var("CI")
        .map(|v| v == "true" || v == "1")
        .unwrap_or(false)
    {
        panic!(
            "dataset {} is missing and CI=true: dataset tests must run in CI",
            p.display()
        );
    }
    eprintln!(
        "SKIPPED: dataset {} not found (set SLAM_DATASETS to its folder)",
        p.display()
    );
    None
}

/// Runs a scan filter over `records` with slam-eval's run function (the one loop every
/// front end calls), without a reference to score against.
pub fn run_scans(
    filter: &mut dyn slam::models::ScanSlam,
    records: &[slam::models::ScanRecord],
) -> slam::eval::ScanRun {
    let data = slam::models::ScanDataset {
        name: "test".into(),
        records: records.to_vec(),
        ground_truth: None,
    };
    slam::eval::run_scans(filter, &data, &Default::default()).expect("the run")
}

/// The simulated `office` run of `seed` (defaults: two laps, 181-beam laser): its records
/// and its ground truth (one pose per record).
pub fn office(seed: u64) -> (Vec<slam::models::ScanRecord>, Vec<slam::models::TimedPose>) {
    let opts = slam::sim::scenario::ScenarioOptions {
        seed,
        ..Default::default()
    };
    let Ok(slam::sim::SimOutput::Laser(run)) = slam::sim::scenario::generate("office", &opts)
    else {
        panic!("office scenario did not generate a laser run");
    };
    let truth = run.dataset.ground_truth.expect("office has ground truth");
    (run.dataset.records, truth)
}

/// Position RMSE of an estimate against the truth after expressing both relative to
/// their first pose (a filter's world frame is the odometry frame of record 0).
pub fn rmse(est: &[slam::models::TimedPose], truth: &[slam::models::TimedPose]) -> f64 {
    assert_eq!(est.len(), truth.len());
    let (e0, t0) = (est[0].pose, truth[0].pose);
    let s: f64 = est
        .iter()
        .zip(truth)
        .map(|(e, t)| e0.between(&e.pose).distance(&t0.between(&t.pose)).powi(2))
        .sum();
    (s / est.len() as f64).sqrt()
}

/// The odometry of the records as a trajectory (dead reckoning).
pub fn dead_reckoning(records: &[slam::models::ScanRecord]) -> Vec<slam::models::TimedPose> {
    records
        .iter()
        .map(|r| slam::models::TimedPose {
            t: r.t,
            pose: r.odometry,
        })
        .collect()
}
