//! UTIAS MRCLAM (Leung et al., IJRR 2011): one robot of a `MRCLAM_Dataset*` folder.
//!
//! Files used, for robot N: `Barcodes.dat` (`subject barcode`), `Landmark_Groundtruth.dat`
//! (`subject x y x_sd y_sd`), `RobotN_Odometry.dat` (`time v ω`), `RobotN_Measurement.dat`
//! (`time barcode range bearing`) and, when present, `RobotN_Groundtruth.dat`
//! (`time x y θ`). Two variants are recognised:
//!
//! * **raw** (original files: `#` headers, absolute Unix times);
//! * **resampled** (the 0.02 s grid of `sampleMRCLAMdataSet.m`, relative times). Its times
//!   are printed with 5 significant digits, so odometry and ground-truth rows get the time
//!   `row × 0.02 s`; measurement times are used as printed.
//!
//! The variant is told apart by the first odometry time (relative if below 10⁸ s).
//!
//! **Steps.** Odometry row k at time t_k gives step k: its control is
//! `Control::Velocity { v, ω of row k−1, dt = t_k − t_(k−1) }` (the previous command held
//! until t_k; duplicate timestamps give dt = 0), and step 0 has a zero control. A
//! measurement at time τ is attached to the first step with t_k ≥ τ (within 1 ns), i.e. the
//! step whose interval (t_(k−1), t_k] contains it; measurements before t_0 go to step 0.
//!
//! **Identities.** The second measurement column is a *barcode*; it is mapped to a subject
//! through `Barcodes.dat`, and the observation's id is `LandmarkId(subject)`. Subjects 1–5
//! are robots: those observations are left out and counted in
//! [`MrclamData::other_robot_observations`]. Unknown barcodes, measurements after the last
//! odometry time and negative ranges are left out and listed in [`MrclamData::skipped`].
//!
//! **Bounds** ([`crate::bounds`]): times within ±10¹⁰ s, within 10⁷ s of the file's first
//! time (odometry and ground truth also in time order); `v` within ±100 m/s and
//! `ω` within ±100 rad/s; ranges at most 1000 m and bearings within ±2π rad; landmark and
//! ground-truth coordinates within ±10⁶ m, their standard deviations within 0 … 10⁶ m;
//! headings within ±10⁴ rad. A violation is an error naming the file, line, field and bound.
//!
//! **Frame.** Landmarks and ground truth are in the Vicon world frame. When ground truth
//! is present, the initial pose is the ground-truth pose nearest to t_0 (if within 0.1 s),
//! so estimates share the ground truth's frame; otherwise it is the origin.

use crate::bounds::{TimeSpan, MAX_COORD, MAX_SPEED, MAX_TIME, MAX_TIME_SPAN, MAX_TURN_RATE};
use crate::error::IoError;
use crate::report::Skipped;
use crate::text::{read_text, TextFile};
use slam_models::{
    Control, LandmarkDataset, LandmarkId, LandmarkStep, Point2, Pose2, RangeBearing, TimedPose,
    VelocityControl,
};
use std::collections::HashMap;
use std::path::Path;

/// The MRCLAM robots are subjects 1 to 5.
const ROBOT_SUBJECTS: std::ops::RangeInclusive<u32> = 1..=5;
/// Relative times (resampled variant) are below this, absolute Unix times above.
const ABSOLUTE_TIME_MIN: f64 = 1e8;
/// Row spacing of the resampled variant, seconds.
const RESAMPLED_DT: f64 = 0.02;

/// One robot's data from an MRCLAM folder, and what was left out.
#[derive(Debug, Clone, PartialEq)]
pub struct MrclamData {
    /// The data: `Control::Velocity` steps, ids = landmark subjects 6–20.
    pub dataset: LandmarkDataset,
    /// True for the resampled variant (0.02 s grid, relative time).
    pub resampled: bool,
    /// Observations of other robots' barcodes, left out for landmark SLAM.
    pub other_robot_observations: usize,
    /// Other observations left out (unknown barcode, outside the odometry time span,
    /// negative range), with their lines.
    pub skipped: Vec<Skipped>,
}

/// Reads robot `robot` (1–5) of an MRCLAM folder; see the module docs for what is left out
/// ([`read_mrclam_report`] reports it).
pub fn read_mrclam(dir: &Path, robot: u32) -> Result<LandmarkDataset, IoError> {
    read_mrclam_report(dir, robot).map(|d| d.dataset)
}

fn need(dir: &Path, name: &str) -> Result<std::path::PathBuf, IoError> {
    let p = dir.join(name);
    if p.is_file() {
        Ok(p)
    } else {
        Err(IoError::NotFound {
            path: dir.to_path_buf(),
            what: format!("not an MRCLAM folder for this robot: {name} is missing"),
        })
    }
}

/// Reads robot `robot` (1–5) of an MRCLAM folder with a report of what was left out.
pub fn read_mrclam_report(dir: &Path, robot: u32) -> Result<MrclamData, IoError> {
    if !ROBOT_SUBJECTS.contains(&robot) {
        return Err(IoError::NotFound {
            path: dir.to_path_buf(),
            what: format!("MRCLAM has robots 1 to 5, robot {robot} was asked for"),
        });
    }
    let barcodes = parse_barcodes(&read_text(&need(dir, "Barcodes.dat")?)?)?;
    let landmarks = parse_landmarks(&read_text(&need(dir, "Landmark_Groundtruth.dat")?)?)?;
    let odo_file = read_text(&need(dir, &format!("Robot{robot}_Odometry.dat"))?)?;
    let meas_file = read_text(&need(dir, &format!("Robot{robot}_Measurement.dat"))?)?;
    let (odo, resampled) = parse_odometry(&odo_file)?;
    let gt_path = dir.join(format!("Robot{robot}_Groundtruth.dat"));
    let ground_truth = if gt_path.is_file() {
        Some(parse_ground_truth(&read_text(&gt_path)?, resampled)?)
    } else {
        None
    };

    // Steps: row k's time; control = previous row's (v, ω) held until t_k.
    let mut steps: Vec<LandmarkStep> = Vec::with_capacity(odo.len());
    for (k, &(t, _, _)) in odo.iter().enumerate() {
        let control = if k == 0 {
            VelocityControl {
                v: 0.0,
                omega: 0.0,
                dt: 0.0,
            }
        } else {
            let (tp, v, omega) = odo[k - 1];
            VelocityControl {
                v,
                omega,
                dt: (t - tp).max(0.0),
            }
        };
        steps.push(LandmarkStep {
            t,
            control: Control::Velocity(control),
            observations: Vec::new(),
        });
    }

    let mut other_robot_observations = 0;
    let mut skipped = Vec::new();
    let times: Vec<f64> = odo.iter().map(|o| o.0).collect();
    let mut skip = |line: usize, reason: String| {
        skipped.push(Skipped {
            path: meas_file.path.clone(),
            line,
            reason,
        })
    };
    meas_file.ensure_not_empty("measurement lines `time barcode range bearing`")?;
    // Measurement rows are not in strict time order; each must be near the odometry's span.
    for mut l in meas_file.data_lines() {
        let tau = l.f64_in("time", -MAX_TIME, MAX_TIME, "s")?;
        if (tau - times[0]).abs() > MAX_TIME_SPAN {
            return Err(l.out_of_bounds(
                "time",
                tau,
                format!(
                    "within {MAX_TIME_SPAN} s of the first odometry time ({})",
                    times[0]
                ),
            ));
        }
        let code = l.u64("barcode")?;
        let range = l.range("range")?;
        let bearing = l.angle("bearing")?;
        l.end("`time barcode range bearing`")?;
        let Some(&subject) = u32::try_from(code).ok().and_then(|c| barcodes.get(&c)) else {
            skip(l.no, format!("barcode {code} is not in Barcodes.dat"));
            continue;
        };
        if ROBOT_SUBJECTS.contains(&subject) {
            other_robot_observations += 1;
            continue;
        }
        let k = times.partition_point(|&t| t < tau - 1e-9);
        if k == times.len() {
            skip(l.no, format!("time {tau} is after the last odometry time"));
            continue;
        }
        match RangeBearing::new(range, bearing, Some(LandmarkId(subject))) {
            Ok(z) => steps[k].observations.push(z),
            Err(e) => skip(l.no, format!("observation left out: {e}")),
        }
    }

    let initial_pose = ground_truth
        .as_deref()
        .and_then(|gt| nearest_pose(gt, times[0], 0.1))
        .unwrap_or(Pose2::IDENTITY);
    let dir_name = dir
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "mrclam".into());
    Ok(MrclamData {
        dataset: LandmarkDataset {
            name: format!("{dir_name}-robot{robot}"),
            initial_pose,
            steps,
            landmarks: Some(landmarks),
            ground_truth,
        },
        resampled,
        other_robot_observations,
        skipped,
    })
}

/// The pose of `traj` (sorted by time) nearest in time to `t`, if within `max_dt`.
fn nearest_pose(traj: &[TimedPose], t: f64, max_dt: f64) -> Option<Pose2> {
    let i = traj.partition_point(|p| p.t < t);
    let cands = [i.checked_sub(1), (i < traj.len()).then_some(i)];
    cands
        .into_iter()
        .flatten()
        .map(|j| traj[j])
        .filter(|p| (p.t - t).abs() <= max_dt)
        .min_by(|a, b| (a.t - t).abs().total_cmp(&(b.t - t).abs()))
        .map(|p| p.pose)
}

/// `subject barcode` → map barcode → subject.
pub(crate) fn parse_barcodes(f: &TextFile) -> Result<HashMap<u32, u32>, IoError> {
    f.ensure_not_empty("lines `subject barcode`")?;
    let mut m = HashMap::new();
    for mut l in f.data_lines() {
        let subject = l.u64("subject")?;
        let code = l.u64("barcode")?;
        l.end("`subject barcode`")?;
        let (Ok(subject), Ok(code)) = (u32::try_from(subject), u32::try_from(code)) else {
            return Err(l.error("subject and barcode below 2^32", l.text));
        };
        if m.insert(code, subject).is_some() {
            return Err(l.error("a barcode not listed before", l.text));
        }
    }
    Ok(m)
}

/// `subject x y x_sd y_sd` → true landmarks.
pub(crate) fn parse_landmarks(f: &TextFile) -> Result<Vec<(LandmarkId, Point2)>, IoError> {
    f.ensure_not_empty("lines `subject x y x_sd y_sd`")?;
    let mut out = Vec::new();
    for mut l in f.data_lines() {
        let s = l.u64("subject")?;
        let x = l.coord("x")?;
        let y = l.coord("y")?;
        l.f64_in("x std-dev", 0.0, MAX_COORD, "m")?;
        l.f64_in("y std-dev", 0.0, MAX_COORD, "m")?;
        l.end("`subject x y x_sd y_sd`")?;
        let s = u32::try_from(s).map_err(|_| l.error("a subject below 2^32", l.text))?;
        out.push((LandmarkId(s), Point2::new(x, y)));
    }
    Ok(out)
}

/// One odometry row: (t [s], v [m/s], ω [rad/s]).
pub(crate) type OdometryRow = (f64, f64, f64);

/// `time v ω` rows; returns (t, v, ω) and whether the file is the resampled variant.
pub(crate) fn parse_odometry(f: &TextFile) -> Result<(Vec<OdometryRow>, bool), IoError> {
    f.ensure_not_empty("lines `time v w`")?;
    let mut rows = Vec::new();
    let mut resampled = false;
    let mut span = TimeSpan::default();
    for (k, mut l) in f.data_lines().enumerate() {
        let t = l.time("time", &mut span)?;
        let v = l.f64_in("forward velocity v", -MAX_SPEED, MAX_SPEED, "m/s")?;
        let w = l.f64_in("angular velocity w", -MAX_TURN_RATE, MAX_TURN_RATE, "rad/s")?;
        l.end("`time v w`")?;
        if k == 0 {
            resampled = t < ABSOLUTE_TIME_MIN;
        }
        let t = if resampled {
            k as f64 * RESAMPLED_DT
        } else {
            t
        };
        if let Some(&(tp, _, _)) = rows.last() {
            if t < tp {
                return Err(l.error(format!("a time ≥ the previous one ({tp})"), l.text));
            }
        }
        rows.push((t, v, w));
    }
    Ok((rows, resampled))
}

/// `time x y θ` rows (time = row × 0.02 s in the resampled variant).
pub(crate) fn parse_ground_truth(f: &TextFile, resampled: bool) -> Result<Vec<TimedPose>, IoError> {
    f.ensure_not_empty("lines `time x y theta`")?;
    let mut out: Vec<TimedPose> = Vec::new();
    let mut span = TimeSpan::default();
    for (k, mut l) in f.data_lines().enumerate() {
        let t = l.time("time", &mut span)?;
        let x = l.coord("x")?;
        let y = l.coord("y")?;
        let th = l.heading("theta")?;
        l.end("`time x y theta`")?;
        let t = if resampled {
            k as f64 * RESAMPLED_DT
        } else {
            t
        };
        if out.last().is_some_and(|p| t < p.t) {
            return Err(l.error("a time ≥ the previous one", l.text));
        }
        out.push(TimedPose {
            t,
            pose: Pose2::new(x, y, th),
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::text::from_str;

    fn write(dir: &Path, name: &str, text: &str) {
        std::fs::write(dir.join(name), text).unwrap();
    }

    #[test]
    fn small_raw_folder() {
        let dir = std::env::temp_dir().join(format!("slam-io-mrclam-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        write(&dir, "Barcodes.dat", "# h\n 1\t5\n 2\t14\n 6\t72\n");
        write(
            &dir,
            "Landmark_Groundtruth.dat",
            "# h\n 6\t1.5\t2.5\t0.001\t0.001\n",
        );
        write(
            &dir,
            "Robot1_Odometry.dat",
            "# h\n1000000000.0 0.1 0.0\n1000000000.5 0.2 0.1\n1000000001.0 0.0 0.0\n",
        );
        write(
            &dir,
            "Robot1_Measurement.dat",
            "# h\n999999999.0 72 1.0 0.1\n1000000000.2 14 2.0 0.0\n1000000000.5 72 1.5 0.2\n\
             1000000000.6 72 1.6 0.2\n1000000000.7 99 1.0 0.0\n1000000002.0 72 1.0 0.0\n",
        );
        let r = read_mrclam_report(&dir, 1).unwrap();
        let d = &r.dataset;
        assert!(!r.resampled);
        assert_eq!(d.steps.len(), 3);
        // Step 1 moves with row 0's command for 0.5 s, step 2 with row 1's.
        assert_eq!(
            d.steps[1].control,
            Control::Velocity(VelocityControl {
                v: 0.1,
                omega: 0.0,
                dt: 0.5
            })
        );
        assert_eq!(
            d.steps[2].control,
            Control::Velocity(VelocityControl {
                v: 0.2,
                omega: 0.1,
                dt: 0.5
            })
        );
        // Before t0 → step 0; at t1 exactly → step 1; in (t1, t2] → step 2.
        let counts: Vec<usize> = d.steps.iter().map(|s| s.observations.len()).collect();
        assert_eq!(counts, vec![1, 1, 1]);
        assert_eq!(d.steps[1].observations[0].range, 1.5);
        assert_eq!(d.steps[2].observations[0].id, Some(LandmarkId(6)));
        assert_eq!(r.other_robot_observations, 1);
        assert_eq!(r.skipped.len(), 2); // barcode 99, and after the last odometry time
        assert!(d.ground_truth.is_none());
        assert_eq!(d.initial_pose, Pose2::IDENTITY);
        assert!(read_mrclam(&dir, 2).is_err());
        assert!(read_mrclam(&dir, 6).is_err());
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn error_paths() {
        // Resampled (relative) times are re-derived from the row index, so this is fine;
        // absolute times must not go back.
        assert!(parse_odometry(&from_str("o.dat", "1 2 3\n0.5 1 1\n")).is_ok());
        let e = parse_odometry(&from_str("o.dat", "1e9 2 3\n999999999 1 1\n"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("o.dat:2") && e.contains("previous"), "{e}");
        for (text, want) in [
            ("", "empty"),
            ("1 2\n", "line ended early"),
            ("1 2 nan\n", "not finite"),
        ] {
            let e = parse_odometry(&from_str("o.dat", text))
                .unwrap_err()
                .to_string();
            assert!(e.contains(want), "{text:?} → {e}");
        }
        let e = parse_barcodes(&from_str("b.dat", "1 5\n2 5\n"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("b.dat:2"), "{e}");
        let e = parse_landmarks(&from_str("l.dat", "6 1 2 3\n"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("y std-dev"), "{e}");
    }
}
