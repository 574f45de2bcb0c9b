//! Opening a dataset by path, whatever its format.

use crate::error::{DatasetOption, IoError};
use slam_models::{DataKind, LandmarkDataset, Pose2, ScanDataset, TimedPose};
use std::path::Path;

/// What [`open_dataset_with`] may need besides the path: the MRCLAM robot, and for ROS bags
/// the topics and the laser mounting (see `rosbag::BagOptions`). Options that do not apply
/// to the format found are an error, not ignored.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct DatasetOptions {
    /// MRCLAM robot number (default 1).
    pub robot: Option<u32>,
    /// ROS bags: the `sensor_msgs/msg/LaserScan` topic.
    pub scan_topic: Option<String>,
    /// ROS bags: the `nav_msgs/msg/Odometry` topic, or `/tf`.
    pub odom_topic: Option<String>,
    /// ROS bags: the laser's pose in the robot's base frame, replacing `/tf_static`.
    pub laser_pose: Option<Pose2>,
    /// ROS bags: the odometry frame of the `/tf` odometry chain (default `odom`).
    pub odom_frame: Option<String>,
    /// ROS bags: the robot's base frame of the `/tf` odometry chain.
    pub base_frame: Option<String>,
    /// Laser data: the recording's odometry is not wanted (`--odometry none`): a ROS bag
    /// is read without it, and [`OpenedDataset::has_odometry`] is false for any laser data.
    pub laser_only: bool,
    /// ROS bags: a `sensor_msgs/msg/Imu` topic whose yaw rates are read
    /// ([`OpenedDataset::yaw_rates`]).
    pub imu_topic: Option<String>,
}

impl DatasetOptions {
    fn bag_option(&self) -> Option<DatasetOption> {
        if self.scan_topic.is_some() {
            Some(DatasetOption::ScanTopic)
        } else if self.odom_topic.is_some() {
            Some(DatasetOption::OdomTopic)
        } else if self.laser_pose.is_some() {
            Some(DatasetOption::LaserPose)
        } else if self.odom_frame.is_some() {
            Some(DatasetOption::OdomFrame)
        } else if self.base_frame.is_some() {
            Some(DatasetOption::BaseFrame)
        } else if self.imu_topic.is_some() {
            Some(DatasetOption::ImuTopic)
        } else {
            None
        }
    }
}

/// The kind of data [`open_dataset_with`] would read at `path`, told from the path alone (a
/// folder's listing, a file's first 16 bytes), so that a filter given the wrong kind of data
/// is refused before a large input is read: a Freiburg or MRCLAM folder holds landmark data,
/// a ROS bag or any other file (read as a CARMEN log) laser data; `None` for a missing path
/// or a folder that is neither (opening it then says why).
pub fn dataset_kind(path: &Path) -> Option<DataKind> {
    if is_bag(path) {
        return Some(DataKind::Laser);
    }
    if path.is_dir() {
        let landmark =
            path.join("sensor_data.dat").is_file() || path.join("Barcodes.dat").is_file();
        return landmark.then_some(DataKind::Landmark);
    }
    path.is_file().then_some(DataKind::Laser)
}

/// True when `path` is a ROS bag: a folder with `metadata.yaml` (rosbag2), or a file that
/// starts like an MCAP file, an SQLite database (rosbag2's `.db3`) or a ROS 1 bag.
fn is_bag(path: &Path) -> bool {
    if path.is_dir() {
        return path.join("metadata.yaml").is_file();
    }
    let mut head = [0u8; 16];
    let n = std::fs::File::open(path)
        .and_then(|mut f| std::io::Read::read(&mut f, &mut head))
        .unwrap_or(0);
    let head = &head[..n];
    [
        &b"\x89MCAP0\r\n"[..],
        b"SQLite format 3\0",
        b"#ROSBAG V",
        b"#ROSRECORD V",
    ]
    .iter()
    .any(|m| head.starts_with(m))
}

#[cfg(feature = "rosbag")]
fn open_bag(path: &Path, o: &DatasetOptions) -> Result<OpenedDataset, IoError> {
    let opts = crate::rosbag::BagOptions {
        scan_topic: o.scan_topic.clone(),
        odom_topic: o.odom_topic.clone(),
        laser_pose: o.laser_pose,
        odom_frame: o.odom_frame.clone(),
        base_frame: o.base_frame.clone(),
        laser_only: o.laser_only,
        imu_topic: o.imu_topic.clone(),
    };
    let bag = crate::rosbag::read_rosbag(path, &opts)?;
    Ok(OpenedDataset {
        description: bag.summary(path),
        has_odometry: bag.odometry != crate::rosbag::OdometrySource::None,
        yaw_rates: bag.yaw_rates,
        dataset: Dataset::Scan(bag.dataset),
    })
}

#[cfg(not(feature = "rosbag"))]
fn open_bag(path: &Path, _: &DatasetOptions) -> Result<OpenedDataset, IoError> {
    Err(IoError::invalid(
        path,
        "a ROS bag, but slam-io was built without its `rosbag` feature",
    ))
}

/// A dataset opened by [`open_dataset_report`]: what [`open_dataset_with`] gives, and what
/// laser-only mapping needs to know.
#[derive(Debug, Clone, PartialEq)]
pub struct OpenedDataset {
    /// The data.
    pub dataset: Dataset,
    /// One line: what was found ([`open_dataset_with`]'s).
    pub description: String,
    /// Laser data whose records carry the recording's odometry: false for a ROS bag
    /// without odometry (its records' odometry is the identity) and for any laser data
    /// opened with [`DatasetOptions::laser_only`]; true for landmark data.
    pub has_odometry: bool,
    /// The yaw rates of [`DatasetOptions::imu_topic`], in time order (seconds, the
    /// records' clock; rad/s); empty without it.
    pub yaw_rates: Vec<slam_models::YawRate>,
}

/// [`open_dataset_with`], saying also whether the laser data has odometry and giving the
/// IMU's yaw rates when asked for.
pub fn open_dataset_report(path: &Path, o: &DatasetOptions) -> Result<OpenedDataset, IoError> {
    if is_bag(path) && o.robot.is_none() {
        return open_bag(path, o);
    }
    let (dataset, description) = open_dataset_with(path, o)?;
    let laser = matches!(dataset, Dataset::Scan(_));
    Ok(OpenedDataset {
        dataset,
        description,
        has_odometry: !(laser && o.laser_only),
        yaw_rates: Vec::new(),
    })
}

/// A dataset of either kind.
#[derive(Debug, Clone, PartialEq)]
pub enum Dataset {
    /// Landmark data (Freiburg course data, MRCLAM, simulated landmark worlds).
    Landmark(LandmarkDataset),
    /// Laser data (CARMEN logs, simulated laser worlds).
    Scan(ScanDataset),
}

/// Opens `path` and says in one line what was found ([`open_dataset_with`] without ROS bag
/// options).
pub fn open_dataset(path: &Path, robot: Option<u32>) -> Result<(Dataset, String), IoError> {
    open_dataset_with(
        path,
        &DatasetOptions {
            robot,
            ..Default::default()
        },
    )
}

/// Opens `path` and says in one line what was found.
///
/// * an MCAP file, an SQLite file (`.db3`) or a ROS 1 bag (by their first bytes), or a
///   folder with `metadata.yaml` → a ROS bag (`rosbag`, with the topic and mounting
///   options);
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
/// # let _ = slam_io::DatasetOptions::default();
/// assert!(what.starts_with("Freiburg course data"));
/// let Dataset::Landmark(d) = data else { unreachable!() };
/// assert_eq!(d.steps.len(), 1);
/// # std::fs::remove_dir_all(&dir)?;
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn open_dataset_with(path: &Path, o: &DatasetOptions) -> Result<(Dataset, String), IoError> {
    let robot = o.robot;
    if is_bag(path) {
        if robot.is_some() {
            return Err(IoError::option(
                path,
                None,
                DatasetOption::Robot,
                "applies to MRCLAM folders; this is a ROS bag",
            ));
        }
        let opened = open_bag(path, o)?;
        return Ok((opened.dataset, opened.description));
    }
    if let Some(option) = o.bag_option() {
        return Err(IoError::option(
            path,
            None,
            option,
            "applies to ROS bags (MCAP, .db3 or ROS 1 .bag files, or folders with metadata.yaml)",
        ));
    }
    if path.is_dir() {
        if path.join("sensor_data.dat").is_file() {
            if robot.is_some() {
                return Err(IoError::option(
                    path,
                    None,
                    DatasetOption::Robot,
                    "applies to MRCLAM folders; this is a Freiburg folder",
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
        return Err(IoError::option(
            path,
            None,
            DatasetOption::Robot,
            "applies to MRCLAM folders only",
        ));
    }
    let log = crate::carmen::read_carmen(path)?;
    let msg = log.summary(path);
    Ok((Dataset::Scan(log.dataset), msg))
}

/// A description of what the dataset at `path` holds, for `slam info`: for a ROS bag its
/// topics, types, counts, rates, span, laser geometry, odometry sources and static
/// transforms; for a CARMEN log its record counts and laser geometry; for a Freiburg folder
/// the line [`open_dataset`] prints; for an MRCLAM folder that line for every robot whose
/// `RobotN_Odometry.dat` it holds (N = 1–5), since `slam run` reads one robot at a time.
pub fn dataset_info(path: &Path) -> Result<String, IoError> {
    if is_bag(path) {
        #[cfg(feature = "rosbag")]
        return crate::rosbag::describe_bag(path);
        #[cfg(not(feature = "rosbag"))]
        return open_bag(path, &DatasetOptions::default()).map(|o| o.description);
    }
    if path.is_dir() {
        let robots: Vec<u32> = (1..=5)
            .filter(|n| path.join(format!("Robot{n}_Odometry.dat")).is_file())
            .collect();
        if path.join("Barcodes.dat").is_file() && robots.len() > 1 {
            let mut s = format!(
                "MRCLAM folder {}: {} robots ({}; one is read at a time, chosen with {})",
                path.display(),
                robots.len(),
                robots
                    .iter()
                    .map(|n| n.to_string())
                    .collect::<Vec<_>>()
                    .join(", "),
                DatasetOption::Robot
            );
            for n in robots {
                s.push('\n');
                s.push_str(&open_dataset(path, Some(n))?.1);
            }
            return Ok(s);
        }
        return open_dataset(path, None).map(|(_, s)| s);
    }
    let log = crate::carmen::read_carmen(path)?;
    let mut s = log.summary(path);
    let mut seen: Vec<(usize, u64, u64, u64)> = Vec::new();
    for scan in log.dataset.records.iter().filter_map(|r| r.scan.as_ref()) {
        let key = (
            scan.len(),
            scan.angle_min.to_bits(),
            scan.angle_increment.to_bits(),
            scan.max_range.to_bits(),
        );
        if seen.contains(&key) {
            continue;
        }
        seen.push(key);
        let p = scan.sensor_pose;
        s.push_str(&format!(
            "\nlaser: {} beams from {:.2}° by {:.3}°, no return at {} m, sensor at ({:.3}, {:.3}, {:.3}) in the robot frame",
            scan.len(),
            scan.angle_min.to_degrees(),
            scan.angle_increment.to_degrees(),
            scan.max_range,
            p.x,
            p.y,
            p.theta
        ));
        if seen.len() == 4 {
            s.push_str("\nlaser: … (more geometries)");
            break;
        }
    }
    Ok(s)
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
