//! Issue 17: one glitched odometry record in a real log must not exhaust memory.
//!
//! `slam run --filter scanmatch` on `bench/intel.log` with one record's odometry moved by
//! 10 km used to ask for 18 GB and abort. The log is perturbed at test time and the built
//! binary run with its peak resident memory (VmHWM) sampled from `/proc`: each run must
//! stay under 100 MB, or stop with a clear error naming the cause.

mod common;
use common::dataset;

use std::io::Read;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::Duration;

/// `log` with the odometry of its middle FLASER record (laser and odometry pose fields)
/// moved by `dx` metres.
fn glitched(log: &str, dx: f64) -> String {
    let n_scans = log.lines().filter(|l| l.starts_with("FLASER ")).count();
    let mut k = 0;
    let mut out = String::with_capacity(log.len() + 64);
    for line in log.lines() {
        if line.starts_with("FLASER ") {
            k += 1;
            if k == n_scans / 2 {
                let mut f: Vec<String> = line.split_whitespace().map(str::to_string).collect();
                let n: usize = f[1].parse().unwrap();
                for i in [2 + n, 5 + n] {
                    let v: f64 = f[i].parse().unwrap();
                    f[i] = format!("{:.6}", v + dx);
                }
                out.push_str(&f.join(" "));
                out.push('\n');
                continue;
            }
        }
        out.push_str(line);
        out.push('\n');
    }
    assert_eq!(k, n_scans);
    out
}

/// Runs the built binary; returns exit code, stderr and the largest VmHWM (peak resident
/// set, MB) read from `/proc/<pid>/status` while it ran (`None` without `/proc`).
fn run_measured(args: &[&str]) -> (i32, String, Option<f64>) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_slam"))
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the slam binary runs");
    let status = format!("/proc/{}/status", child.id());
    let mut peak: Option<f64> = None;
    let code = loop {
        if let Ok(s) = std::fs::read_to_string(&status) {
            let kb = s
                .lines()
                .find(|l| l.starts_with("VmHWM:"))
                .and_then(|l| l.split_whitespace().nth(1))
                .and_then(|v| v.parse::<f64>().ok());
            if let Some(kb) = kb {
                peak = Some(peak.unwrap_or(0.0).max(kb / 1024.0));
            }
        }
        if let Some(st) = child.try_wait().unwrap() {
            break st.code().unwrap_or(-1);
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    let mut err = String::new();
    child
        .stderr
        .take()
        .unwrap()
        .read_to_string(&mut err)
        .unwrap();
    (code, err, peak)
}

#[test]
fn a_10_km_odometry_glitch_in_intel_stays_under_100_mb_or_is_a_clear_error() {
    let Some(intel) = dataset("bench/intel.log") else {
        return;
    };
    let dir = std::env::temp_dir().join(format!("slam-glitch-test-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let log = dir.join("intel-glitch.log");
    std::fs::write(
        &log,
        glitched(&std::fs::read_to_string(intel).unwrap(), 10_000.0),
    )
    .unwrap();
    let skip = dir.join("skip.toml");
    std::fs::write(&skip, "[odometry-jump]\non-jump = \"skip\"\n").unwrap();
    let unchecked = dir.join("unchecked.toml");
    std::fs::write(&unchecked, "[odometry-jump]\nmax-jump = 1e12\n").unwrap();
    let log = log.to_str().unwrap();
    // (config, what a failing run must say)
    let cases: [(Option<&Path>, &str); 3] = [
        // Default: the jump is an error naming it.
        (None, "odometry jumped 10000"),
        // Skipped on request: the run completes (with a warning).
        (Some(&skip), ""),
        // The jump check off: the grid refuses to span 10 km (its maximum extent).
        (Some(&unchecked), "maximum extent"),
    ];
    for (i, (config, why)) in cases.into_iter().enumerate() {
        let out = dir.join(format!("out{i}"));
        let mut args = vec![
            "run",
            "--filter",
            "scanmatch",
            "--dataset",
            log,
            "--quiet",
            "--out",
            out.to_str().unwrap(),
        ];
        if let Some(c) = config {
            args.extend(["--config", c.to_str().unwrap()]);
        }
        let (code, err, peak) = run_measured(&args);
        if let Some(mb) = peak {
            assert!(mb < 100.0, "case {i}: peak RSS {mb:.1} MB; stderr: {err}");
        }
        if why.is_empty() {
            assert_eq!(code, 0, "case {i}: {err}");
            assert!(err.contains("skipped 2 odometry jump"), "case {i}: {err}");
        } else {
            assert_ne!(code, 0, "case {i}");
            assert!(err.contains(why), "case {i}: expected `{why}` in: {err}");
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}
