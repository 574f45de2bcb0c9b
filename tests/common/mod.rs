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
