//! Opening a dataset by path, whatever its format.

use crate::error::IoError;
use slam_models::{LandmarkDataset, ScanDataset, TimedPose};
use std::path::Path;

/// A dataset of either kind.
#[derive(Debug, Clone, PartialEq)]
pub enum Dataset {
    /// Landmark data (Freiburg course data, MRCLAM, simulated landmark worlds).
    Landmark(LandmarkDataset),
    /// Laser data (CARMEN logs, simulated laser worlds).
    Scan(ScanDataset),
}

/// Opens `path` and says in one line what was found.
///
/// * a folder with `sensor_data.dat` → Freiburg course data ([`crate::freiburg`]);
/// * a folder with `Barcodes.dat` → MRCLAM ([`crate::mrclam`]), robot `robot` (default 1);
/// * a file → a CARMEN log, plain or gzip ([`crate::carmen`]).
///
/// The summary line names the format, the counts of steps/records, observations or scans,
/// whether ground truth is present, and what the reader left out (invalid observations,
/// other robots' barcodes, unknown record types).
///
/// # Example
///
/// ```
/// use slam_io::{open_dataset, Dataset};
/// let dir = std::env::temp_dir().join(format!("slam-io-doc-{}", std::process::id()));
/// std::fs::create_dir_all(&dir)?;
/// std::fs::write(dir.join("world.dat"), "1 2 1\n")?;
/// std::fs::write(dir.join("sensor_data.dat"), "ODOMETRY 0 1 0\nSENSOR 1 1.0 0.5\n")?;
/// let (data, what) = open_dataset(&dir, None)?;
/// assert!(what.starts_with("Freiburg course data"));
/// let Dataset::Landmark(d) = data else { unreachable!() };
/// assert_eq!(d.steps.len(), 1);
/// # std::fs::remove_dir_all(&dir)?;
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn open_dataset(path: &Path, robot: Option<u32>) -> Result<(Dataset, String), IoError> {
    if path.is_dir() {
        if path.join("sensor_data.dat").is_file() {
            if robot.is_some() {
                return Err(IoError::invalid(
                    path,
                    "--robot applies to MRCLAM folders; this is a Freiburg folder",
                ));
            }
            let r = crate::freiburg::read_freiburg_report(path)?;
            let d = &r.dataset;
            let obs: usize = d.steps.iter().map(|s| s.observations.len()).sum();
            let mut msg = format!(
                "Freiburg course data {}: {} odometry steps, {} observations, {} true landmarks, {}",
                path.display(),
                d.steps.len(),
                obs,
                d.landmarks.as_ref().map_or(0, |l| l.len()),
                if d.ground_truth.is_some() { "ground truth trajectory" } else { "no ground truth trajectory" },
            );
            if !r.skipped.is_empty() {
                let lines: Vec<String> = r.skipped.iter().map(|s| s.line.to_string()).collect();
                msg.push_str(&format!(
                    "; {} invalid observation(s) left out (line {})",
                    r.skipped.len(),
                    lines.join(", ")
                ));
            }
            return Ok((Dataset::Landmark(r.dataset), msg));
        }
        if path.join("Barcodes.dat").is_file() {
            let robot = robot.unwrap_or(1);
            let r = crate::mrclam::read_mrclam_report(path, robot)?;
            let d = &r.dataset;
            let obs: usize = d.steps.iter().map(|s| s.observations.len()).sum();
            let msg = format!(
                "MRCLAM {} ({}), robot {robot}: {} velocity steps over {:.1} s, {} landmark observations, {} other-robot observations skipped, {} other left out, {} true landmarks, {}",
                path.display(),
                if r.resampled { "resampled 0.02 s grid" } else { "raw" },
                d.steps.len(),
                duration(d.steps.first().map(|s| s.t), d.steps.last().map(|s| s.t)),
                obs,
                r.other_robot_observations,
                r.skipped.len(),
                d.landmarks.as_ref().map_or(0, |l| l.len()),
                match &d.ground_truth {
                    Some(g) => format!("ground truth ({} poses)", g.len()),
                    None => "no ground truth".into(),
                },
            );
            return Ok((Dataset::Landmark(r.dataset), msg));
        }
        return Err(IoError::NotFound {
            path: path.to_path_buf(),
            what:
                "folder is neither Freiburg course data (sensor_data.dat) nor MRCLAM (Barcodes.dat)"
                    .into(),
        });
    }
    if !path.exists() {
        return Err(IoError::NotFound {
            path: path.to_path_buf(),
            what: "no such file or folder".into(),
        });
    }
    if robot.is_some() {
        return Err(IoError::invalid(
            path,
            "--robot applies to MRCLAM folders only",
        ));
    }
    let log = crate::carmen::read_carmen(path)?;
    let msg = log.summary(path);
    Ok((Dataset::Scan(log.dataset), msg))
}

fn duration(a: Option<f64>, b: Option<f64>) -> f64 {
    match (a, b) {
        (Some(a), Some(b)) => b - a,
        _ => 0.0,
    }
}

/// Noise-free dead reckoning of a landmark dataset: the pose after each step when every
/// control is applied with the default motion models' mean motion `g(u, x)`, starting at
/// `initial_pose`; times are the steps' times.
pub fn dead_reckoning(d: &LandmarkDataset) -> Vec<TimedPose> {
    let models = slam_models::motion::MotionModels::default();
    let mut p = d.initial_pose;
    d.steps
        .iter()
        .map(|s| {
            p = models.predict(&p, &s.control);
            TimedPose { t: s.t, pose: p }
        })
        .collect()
}

/// The odometry poses of a scan dataset as a trajectory (the "no SLAM" baseline).
pub fn odometry_trajectory(d: &ScanDataset) -> Vec<TimedPose> {
    d.records
        .iter()
        .map(|r| TimedPose {
            t: r.t,
            pose: r.odometry,
        })
        .collect()
}
