//! Helpers shared by the slam-cli integration tests (each test file has `mod common;`).
#![allow(dead_code)]

use slam_cli::{main_with_args, CliError, Outcome};
use std::path::{Path, PathBuf};
use std::process::Command;

/// A fresh, empty folder under the system temp dir, unique to this test binary and test.
pub fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!(
        "slam-cli-{}-{}-{name}",
        env!("CARGO_CRATE_NAME"),
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Runs the program in-process; returns the outcome and what it printed.
pub fn slam(args: &[&str]) -> (Result<Outcome, CliError>, String) {
    let mut out = Vec::new();
    let all = std::iter::once("slam").chain(args.iter().copied());
    let r = main_with_args(all, &mut out);
    (r, String::from_utf8(out).unwrap())
}

/// Runs the built binary; returns exit code, stdout, stderr.
pub fn slam_bin(args: &[&str]) -> (i32, String, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_slam"))
        .args(args)
        .output()
        .unwrap();
    (
        o.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// `../shared/datasets/<rel>` beside the checkout (or under `$SLAM_DATASETS`); `None` with a
/// SKIPPED line when missing, a failure under `CI=true`.
pub fn dataset(rel: &str) -> Option<PathBuf> {
    let base = std::env::var_os("SLAM_DATASETS")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/datasets"));
    let p = base.join(rel);
    if p.exists() {
        return Some(p);
    }
    if std::env::var("CI").is_ok_and(|v| v == "true" || v == "1") {
        panic!("dataset {} is missing and CI=true", p.display());
    }
    eprintln!("SKIPPED: dataset {} not found", p.display());
    None
}

/// A ROS bag fixture of slam-io (`crates/slam-io/tests/fixtures/rosbag/<name>`).
pub fn bag_fixture(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../slam-io/tests/fixtures/rosbag")
        .join(name)
        .display()
        .to_string()
}

/// A trajectory: time in µs → (x, y, yaw).
pub type Trajectory = std::collections::BTreeMap<i64, (f64, f64, f64)>;

/// TUM lines → time in µs → (x, y, yaw), the last line of each time.
pub fn tum(path: &Path) -> Trajectory {
    let text = std::fs::read_to_string(path).unwrap();
    let mut m = Trajectory::new();
    for l in text
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
    {
        let v: Vec<f64> = l.split_whitespace().map(|f| f.parse().unwrap()).collect();
        let yaw = 2.0 * v[6].atan2(v[7]);
        m.insert((v[0] * 1e6).round() as i64, (v[1], v[2], yaw));
    }
    m
}
