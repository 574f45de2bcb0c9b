//! A SLAM run written as an MCAP file of ROS 2 messages, for Foxglove and `ros2 bag play`.
//!
//! [`McapRunWriter`] is fed one [`RunStep`] per filter step and a [`RunEnd`] at the end;
//! it writes (profile `ros2`, `ros2msg` schemas with the standard message definitions,
//! `cdr` messages, zstd-compressed chunks):
//!
//! | topic | type | when |
//! | --- | --- | --- |
//! | `/pose` | `geometry_msgs/msg/PoseStamped` | every step: the estimate, frame `map` |
//! | `/tf` | `tf2_msgs/msg/TFMessage` | every step: `map → odom` (the correction, estimate ∘ odometry⁻¹) and `odom → base_link` (the odometry); `map → base_link` when the step has no odometry |
//! | `/tf_static` | `tf2_msgs/msg/TFMessage` | `base_link → laser` (the scan's sensor pose), at the first scan and whenever it changes |
//! | `/scan` | `sensor_msgs/msg/LaserScan` | every step with a scan, frame `laser` |
//! | `/particles` | `geometry_msgs/msg/PoseArray` | every step of a particle filter, frame `map` |
//! | `/trajectory` | `nav_msgs/msg/Path` | every `snapshot_every` steps the online estimates so far; last, the run's trajectory (the full-SLAM path where the filter has one) |
//! | `/map` | `nav_msgs/msg/OccupancyGrid` | the snapshots the caller gives, and the final map |
//! | `/landmarks` | `visualization_msgs/msg/MarkerArray` | the snapshots the caller gives, and the final map: means and 95 % covariance ellipses, with the true landmarks when known |
//! | `/ground_truth` | `nav_msgs/msg/Path` | at the end, when known |
//!
//! **Time.** A step's time t (seconds: the dataset's clock or the simulator's) is every
//! stamp of its messages and their MCAP log and publish time: `sec = ⌊t⌋`,
//! `nanosec = round((t − ⌊t⌋)·10⁹)`: the nearest nanosecond to t, where t·10⁹ in `f64`
//! would be off by up to 64 ns for a Unix-epoch clock (t itself is only as fine as its
//! `f64`: about 0.12 µs at today's epoch times). A time must be finite and in [0, 2³¹) s
//! (`builtin_interfaces/Time`'s range for a non-negative clock). The end's messages carry
//! the last step's time.
//!
//! **Frames** follow REP 105: `map` (the estimate's world frame), `odom` (the odometry's),
//! `base_link` (the robot), `laser` (the scan's frame).
//!
//! **Covariance ellipses.** A landmark with mean μ and covariance Σ = V diag(λ₁, λ₂) Vᵀ is
//! drawn as a flat cylinder centred at μ, its axes along V's columns with semi-axes
//! √(χ²₂(0.95)·λᵢ), χ²₂(0.95) = 5.991: the set (p − μ)ᵀ Σ⁻¹ (p − μ) ≤ 5.991 that holds the
//! landmark with 95 % probability under the Gaussian estimate.
//!
//! **Files.** The file is written beside its final path as `<name>.partial` and renamed
//! into place by [`McapRunWriter::finish`]; a writer dropped before that removes it, so an
//! interrupted run leaves no file that looks whole.

mod cdr_write;
pub(crate) mod msgs;

use crate::error::IoError;
use msgs::{Marker, MarkerKind, Stamp, Transform};
use slam_models::{GridMap, LandmarkEstimate, LaserScan, Point2, Pose2, TimedPose, WeightedPose};
use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

/// The world frame of the estimate (REP 105).
pub const MAP_FRAME: &str = "map";
/// The odometry frame (REP 105).
pub const ODOM_FRAME: &str = "odom";
/// The robot's base frame (REP 105).
pub const BASE_FRAME: &str = "base_link";
/// The laser's frame.
pub const LASER_FRAME: &str = "laser";

/// χ²(2) quantile at 0.95: the squared Mahalanobis radius of a 95 % ellipse in the plane.
pub const CHI2_2D_95: f64 = 5.991_464_547_107_979;

/// What the writer writes besides each step's messages.
#[derive(Debug, Clone, PartialEq)]
pub struct McapRunOptions {
    /// Steps between two `/trajectory` snapshots (at least 1); the caller gives its map and
    /// landmark snapshots at the same steps ([`McapRunWriter::snapshot_due`]). The messages
    /// of a snapshot grow with the run, so long runs want a stride: `slam run` takes about
    /// 100 snapshots per run.
    pub snapshot_every: usize,
    /// The true landmarks (simulated runs), drawn with every `/landmarks` message.
    pub true_landmarks: Vec<Point2>,
}

impl Default for McapRunOptions {
    fn default() -> Self {
        McapRunOptions {
            snapshot_every: 10,
            true_landmarks: Vec::new(),
        }
    }
}

/// One filter step, as the writer sees it.
#[derive(Debug, Clone, Copy)]
pub struct RunStep<'a> {
    /// Time, seconds (see the module doc for the range).
    pub t: f64,
    /// The estimate after the step (the robot's base in `map`).
    pub pose: Pose2,
    /// The odometry pose at `t` (the base in `odom`), where the data has one.
    pub odometry: Option<Pose2>,
    /// The scan taken at `t`, with its sensor pose on the robot.
    pub scan: Option<&'a LaserScan>,
    /// The particle cloud after the step (particle filters).
    pub particles: Option<&'a [WeightedPose]>,
    /// A map snapshot to write at this step (normally when
    /// [`snapshot_due`](McapRunWriter::snapshot_due)).
    pub map: Option<&'a GridMap>,
    /// A landmark snapshot to write at this step (landmark filters).
    pub landmarks: Option<&'a [LandmarkEstimate]>,
}

impl<'a> RunStep<'a> {
    /// A step with only a time and a pose.
    pub fn new(t: f64, pose: Pose2) -> Self {
        RunStep {
            t,
            pose,
            odometry: None,
            scan: None,
            particles: None,
            map: None,
            landmarks: None,
        }
    }
}

/// The end of a run.
#[derive(Debug, Clone, Copy, Default)]
pub struct RunEnd<'a> {
    /// The run's trajectory (what `trajectory.tum` holds: the full-SLAM path where the
    /// filter has one), written as the last `/trajectory` message.
    pub trajectory: &'a [TimedPose],
    /// The final map (laser filters).
    pub map: Option<&'a GridMap>,
    /// The final landmark map (landmark filters).
    pub landmarks: Option<&'a [LandmarkEstimate]>,
    /// The ground truth, where known, written as `/ground_truth`.
    pub ground_truth: Option<&'a [TimedPose]>,
}

/// Messages written per topic, returned by [`McapRunWriter::finish`].
pub type TopicCounts = BTreeMap<String, u64>;

type Inner = mcap::Writer<BufWriter<File>>;

/// Writes a run as an MCAP file of ROS 2 messages (module doc).
///
/// # Example
///
/// ```
/// use slam_io::mcap_out::{McapRunOptions, McapRunWriter, RunEnd, RunStep};
/// use slam_io::{Pose2, TimedPose};
///
/// let path = std::env::temp_dir().join(format!("doc-{}.mcap", std::process::id()));
/// let mut w = McapRunWriter::create(&path, McapRunOptions::default())?;
/// let mut trajectory = Vec::new();
/// for k in 0..3 {
///     let (t, pose) = (10.0 + k as f64, Pose2::new(k as f64, 0.0, 0.0));
///     let mut step = RunStep::new(t, pose);
///     step.odometry = Some(pose);
///     w.step(&step)?;
///     trajectory.push(TimedPose { t, pose });
/// }
/// let counts = w.finish(&RunEnd { trajectory: &trajectory, ..Default::default() })?;
/// assert_eq!((counts["/pose"], counts["/tf"], counts["/trajectory"]), (3, 3, 1));
/// # std::fs::remove_file(&path).unwrap();
/// # Ok::<(), slam_io::IoError>(())
/// ```
pub struct McapRunWriter {
    path: PathBuf,
    partial: PathBuf,
    writer: Option<Inner>,
    options: McapRunOptions,
    /// Channel id and next sequence number per topic.
    channels: BTreeMap<&'static str, (u16, u32)>,
    /// Schema id per message type.
    schemas: BTreeMap<&'static str, u16>,
    steps: usize,
    last_stamp: Option<Stamp>,
    online: Vec<(Stamp, Pose2)>,
    laser_mount: Option<Pose2>,
}

impl std::fmt::Debug for McapRunWriter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("McapRunWriter")
            .field("path", &self.path)
            .field("steps", &self.steps)
            .finish_non_exhaustive()
    }
}

impl McapRunWriter {
    /// Starts writing `path` (through `<path>.partial`, see the module doc). A
    /// `snapshot_every` of 0 is an error.
    pub fn create(path: &Path, options: McapRunOptions) -> Result<Self, IoError> {
        if options.snapshot_every == 0 {
            return Err(IoError::invalid(
                path,
                "snapshot_every must be at least 1 step",
            ));
        }
        let mut name = path.file_name().unwrap_or_default().to_os_string();
        name.push(".partial");
        let partial = path.with_file_name(name);
        let file = File::create(&partial).map_err(|e| IoError::io(&partial, e))?;
        let opts = mcap::WriteOptions::new()
            .profile("ros2")
            .library(concat!("slam-rs ", env!("CARGO_PKG_VERSION")))
            .compression(Some(mcap::Compression::Zstd))
            // Single-threaded compression: the same run gives the same bytes on any machine.
            .compression_threads(0);
        let writer = opts
            .create(BufWriter::new(file))
            .map_err(|e| IoError::invalid(&partial, format!("MCAP writer: {e}")))?;
        Ok(McapRunWriter {
            path: path.to_path_buf(),
            partial,
            writer: Some(writer),
            options,
            channels: BTreeMap::new(),
            schemas: BTreeMap::new(),
            steps: 0,
            last_stamp: None,
            online: Vec::new(),
            laser_mount: None,
        })
    }

    /// True when the next step is a snapshot step (every `snapshot_every`-th step, counting
    /// from 1): the caller then passes its map and landmarks in [`RunStep`], so that costly
    /// snapshots are made only when written.
    pub fn snapshot_due(&self) -> bool {
        (self.steps + 1) % self.options.snapshot_every == 0
    }

    /// Steps written so far.
    pub fn steps(&self) -> usize {
        self.steps
    }

    fn stamp(&self, t: f64, what: &str) -> Result<Stamp, IoError> {
        stamp_of(t).ok_or_else(|| {
            IoError::invalid(
                &self.path,
                format!(
                    "{what}: time {t} s has no ROS time stamp (a finite time in [0, 2^31) s is \
                     needed)"
                ),
            )
        })
    }

    /// Writes one message on `topic`, adding its schema and channel the first time.
    fn put(
        &mut self,
        topic: &'static str,
        msg_type: &'static str,
        stamp: Stamp,
        data: &[u8],
    ) -> Result<(), IoError> {
        let partial = self.partial.clone();
        let fail = |e: mcap::McapError| IoError::invalid(&partial, format!("MCAP writer: {e}"));
        let Some(w) = self.writer.as_mut() else {
            return Err(IoError::invalid(&partial, "the MCAP writer has failed"));
        };
        let schema_id = match self.schemas.get(msg_type) {
            Some(&id) => id,
            None => {
                let text = msgs::schema(msg_type).unwrap_or_default();
                let id = w
                    .add_schema(msg_type, "ros2msg", text.as_bytes())
                    .map_err(fail)?;
                self.schemas.insert(msg_type, id);
                id
            }
        };
        let (channel_id, sequence) = match self.channels.get_mut(topic) {
            Some(c) => {
                c.1 += 1;
                *c
            }
            None => {
                let mut meta = BTreeMap::new();
                meta.insert("offered_qos_profiles".to_string(), qos_profile(topic));
                let id = w
                    .add_channel(schema_id, topic, "cdr", &meta)
                    .map_err(fail)?;
                self.channels.insert(topic, (id, 1));
                (id, 1)
            }
        };
        let header = mcap::records::MessageHeader {
            channel_id,
            sequence,
            log_time: stamp.ns(),
            publish_time: stamp.ns(),
        };
        w.write_to_known_channel(&header, data).map_err(fail)
    }

    /// Writes one step's messages (table in the module doc).
    pub fn step(&mut self, s: &RunStep<'_>) -> Result<(), IoError> {
        let k = self.steps;
        let stamp = self.stamp(s.t, &format!("step {k}"))?;
        let snapshot = self.snapshot_due();
        self.put(
            "/pose",
            msgs::POSE_STAMPED,
            stamp,
            &msgs::pose_stamped(stamp, MAP_FRAME, &s.pose),
        )?;
        let tf = match s.odometry {
            Some(odom) => vec![
                Transform {
                    stamp,
                    parent: MAP_FRAME,
                    child: ODOM_FRAME,
                    pose: map_to_odom(&s.pose, &odom),
                },
                Transform {
                    stamp,
                    parent: ODOM_FRAME,
                    child: BASE_FRAME,
                    pose: odom,
                },
            ],
            None => vec![Transform {
                stamp,
                parent: MAP_FRAME,
                child: BASE_FRAME,
                pose: s.pose,
            }],
        };
        self.put("/tf", msgs::TF_MESSAGE, stamp, &msgs::tf_message(&tf))?;
        if let Some(scan) = s.scan {
            if self.laser_mount != Some(scan.sensor_pose) {
                self.laser_mount = Some(scan.sensor_pose);
                let mount = [Transform {
                    stamp,
                    parent: BASE_FRAME,
                    child: LASER_FRAME,
                    pose: scan.sensor_pose,
                }];
                self.put(
                    "/tf_static",
                    msgs::TF_MESSAGE,
                    stamp,
                    &msgs::tf_message(&mount),
                )?;
            }
            self.check_len(scan.ranges.len(), "scan beams")?;
            self.put(
                "/scan",
                msgs::LASER_SCAN,
                stamp,
                &msgs::laser_scan(stamp, LASER_FRAME, scan),
            )?;
        }
        if let Some(particles) = s.particles {
            self.check_len(particles.len(), "particles")?;
            let poses: Vec<Pose2> = particles.iter().map(|p| p.pose).collect();
            self.put(
                "/particles",
                msgs::POSE_ARRAY,
                stamp,
                &msgs::pose_array(stamp, MAP_FRAME, &poses),
            )?;
        }
        self.online.push((stamp, s.pose));
        if snapshot {
            let data = msgs::path(stamp, MAP_FRAME, &self.online);
            self.put("/trajectory", msgs::PATH, stamp, &data)?;
        }
        if let Some(map) = s.map {
            self.write_map(stamp, map)?;
        }
        if let Some(landmarks) = s.landmarks {
            self.write_landmarks(stamp, landmarks)?;
        }
        self.steps += 1;
        self.last_stamp = Some(stamp);
        Ok(())
    }

    fn check_len(&self, n: usize, what: &str) -> Result<(), IoError> {
        if n > u32::MAX as usize {
            return Err(IoError::invalid(
                &self.path,
                format!("{n} {what}: a ROS sequence holds at most 2^32 - 1"),
            ));
        }
        Ok(())
    }

    fn write_map(&mut self, stamp: Stamp, map: &GridMap) -> Result<(), IoError> {
        if map.width > u32::MAX as usize
            || map.height > u32::MAX as usize
            || map.cells.len() != map.width.saturating_mul(map.height)
        {
            return Err(IoError::invalid(
                &self.path,
                format!(
                    "map of {} × {} cells with {} values: a nav_msgs/OccupancyGrid needs \
                     width·height values and dimensions below 2^32",
                    map.width,
                    map.height,
                    map.cells.len()
                ),
            ));
        }
        if let Some((k, v)) = map
            .cells
            .iter()
            .enumerate()
            .find(|(_, &v)| !(-1..=100).contains(&v))
        {
            return Err(IoError::invalid(
                &self.path,
                format!("map cell {k} holds {v}: occupancy values are -1 (unknown) or 0..=100"),
            ));
        }
        if !(map.resolution > 0.0 && map.resolution.is_finite()) {
            return Err(IoError::invalid(
                &self.path,
                format!(
                    "map resolution {} m: a positive finite cell size is needed",
                    map.resolution
                ),
            ));
        }
        let data = msgs::occupancy_grid(stamp, MAP_FRAME, map);
        self.put("/map", msgs::OCCUPANCY_GRID, stamp, &data)
    }

    fn write_landmarks(
        &mut self,
        stamp: Stamp,
        landmarks: &[LandmarkEstimate],
    ) -> Result<(), IoError> {
        self.check_len(landmarks.len(), "landmarks")?;
        let markers = landmark_markers(landmarks, &self.options.true_landmarks);
        let data = msgs::marker_array(stamp, MAP_FRAME, &markers);
        self.put("/landmarks", msgs::MARKER_ARRAY, stamp, &data)
    }

    /// Writes the end of the run, closes the file and renames it into place; returns the
    /// number of messages written per topic.
    pub fn finish(mut self, end: &RunEnd<'_>) -> Result<TopicCounts, IoError> {
        let stamp = match (self.last_stamp, end.trajectory.last()) {
            (Some(s), _) => s,
            (None, Some(p)) => self.stamp(p.t, "the trajectory's last pose")?,
            (None, None) => Stamp { sec: 0, nanosec: 0 },
        };
        self.check_len(end.trajectory.len(), "trajectory poses")?;
        let path = self.timed(end.trajectory, "trajectory")?;
        let data = msgs::path(stamp, MAP_FRAME, &path);
        self.put("/trajectory", msgs::PATH, stamp, &data)?;
        if let Some(map) = end.map {
            self.write_map(stamp, map)?;
        }
        if let Some(landmarks) = end.landmarks {
            self.write_landmarks(stamp, landmarks)?;
        }
        if let Some(gt) = end.ground_truth {
            self.check_len(gt.len(), "ground-truth poses")?;
            let path = self.timed(gt, "ground truth")?;
            let data = msgs::path(stamp, MAP_FRAME, &path);
            self.put("/ground_truth", msgs::PATH, stamp, &data)?;
        }
        let mut w = self
            .writer
            .take()
            .ok_or_else(|| IoError::invalid(&self.partial, "the MCAP writer has failed"))?;
        let summary = w
            .finish()
            .map_err(|e| IoError::invalid(&self.partial, format!("MCAP writer: {e}")))?;
        let mut file = w.into_inner();
        std::io::Write::flush(&mut file).map_err(|e| IoError::io(&self.partial, e))?;
        drop(file);
        std::fs::rename(&self.partial, &self.path).map_err(|e| IoError::io(&self.path, e))?;
        let mut counts = TopicCounts::new();
        if let Some(stats) = summary.stats {
            for (id, n) in stats.channel_message_counts {
                if let Some(ch) = summary.channels.get(&id) {
                    counts.insert(ch.topic.clone(), n);
                }
            }
        }
        Ok(counts)
    }

    fn timed(&self, poses: &[TimedPose], what: &str) -> Result<Vec<(Stamp, Pose2)>, IoError> {
        poses
            .iter()
            .enumerate()
            .map(|(k, p)| Ok((self.stamp(p.t, &format!("{what} pose {k}"))?, p.pose)))
            .collect()
    }
}

impl Drop for McapRunWriter {
    fn drop(&mut self) {
        if self.writer.take().is_some() {
            // Not finished: the partial file is not a run.
            let _ = std::fs::remove_file(&self.partial);
        }
    }
}

/// `builtin_interfaces/Time` of t seconds: ⌊t⌋ and the rounded nanoseconds (carried into
/// the seconds at 10⁹); `None` when t is not finite or outside [0, 2³¹).
pub(crate) fn stamp_of(t: f64) -> Option<Stamp> {
    if !(t.is_finite() && (0.0..2_147_483_648.0).contains(&t)) {
        return None;
    }
    let sec = t.floor();
    // t − ⌊t⌋ is exact in f64: it is the fractional bits of t.
    let mut nanosec = ((t - sec) * 1e9).round() as u32;
    let mut sec = sec as i64;
    if nanosec >= 1_000_000_000 {
        nanosec -= 1_000_000_000;
        sec += 1;
    }
    let sec = i32::try_from(sec).ok()?;
    Some(Stamp { sec, nanosec })
}

/// The `map → odom` transform that puts the odometry's base pose `odom` on the estimate
/// `pose`: T_map_odom = T_map_base · T_odom_base⁻¹.
pub fn map_to_odom(pose: &Pose2, odom: &Pose2) -> Pose2 {
    pose.compose(&odom.inverse())
}

/// The 95 % ellipse of a 2×2 covariance: semi-axes (a ≥ b) in metres and the angle of the
/// a-axis from x (radians), from the eigen-decomposition Σ = V diag(λ₁, λ₂) Vᵀ, semi-axis
/// √(χ²₂(0.95)·λ). A negative eigenvalue (a covariance that lost its definiteness) is
/// taken as 0.
pub fn ellipse_95(cov: &slam_models::Matrix2) -> (f64, f64, f64) {
    let (sxx, syy) = (cov[(0, 0)], cov[(1, 1)]);
    let sxy = 0.5 * (cov[(0, 1)] + cov[(1, 0)]);
    let mean = 0.5 * (sxx + syy);
    let r = (0.25 * (sxx - syy).powi(2) + sxy * sxy).sqrt();
    let (l1, l2) = (mean + r, mean - r);
    let angle = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    (
        (CHI2_2D_95 * l1.max(0.0)).sqrt(),
        (CHI2_2D_95 * l2.max(0.0)).sqrt(),
        angle,
    )
}

/// The `/landmarks` markers: a `DELETEALL` (landmarks the filter dropped disappear), one
/// flat cylinder per landmark (its 95 % ellipse, namespace `ellipses`, id = the landmark's
/// id), the means as one sphere list (`landmarks`), and the true landmarks as one cube list
/// (`true_landmarks`) when known.
fn landmark_markers<'a>(landmarks: &[LandmarkEstimate], truth: &[Point2]) -> Vec<Marker<'a>> {
    let mut out = Vec::with_capacity(landmarks.len() + 3);
    out.push(Marker {
        ns: "",
        id: 0,
        kind: None,
        pose: Pose2::default(),
        scale: [0.0; 3],
        rgba: [0.0; 4],
        points: Vec::new(),
    });
    for (k, l) in landmarks.iter().enumerate() {
        let (a, b, angle) = ellipse_95(&l.covariance);
        out.push(Marker {
            ns: "ellipses",
            // The landmark's id where it fits a marker id, else a negative one of its own.
            id: i32::try_from(l.id.0)
                .unwrap_or_else(|_| i32::try_from(k).map_or(i32::MIN, |k| -1 - k)),
            kind: Some(MarkerKind::Cylinder),
            pose: Pose2::new(l.mean.x, l.mean.y, angle),
            // A floor on the size keeps a nearly certain landmark visible.
            scale: [(2.0 * a).max(1e-3), (2.0 * b).max(1e-3), 0.01],
            rgba: [0.2, 0.4, 1.0, 0.35],
            points: Vec::new(),
        });
    }
    out.push(Marker {
        ns: "landmarks",
        id: 0,
        kind: Some(MarkerKind::SphereList),
        pose: Pose2::default(),
        scale: [0.15, 0.15, 0.15],
        rgba: [0.1, 0.2, 0.9, 1.0],
        points: landmarks.iter().map(|l| (l.mean.x, l.mean.y)).collect(),
    });
    if !truth.is_empty() {
        out.push(Marker {
            ns: "true_landmarks",
            id: 0,
            kind: Some(MarkerKind::CubeList),
            pose: Pose2::default(),
            scale: [0.12, 0.12, 0.12],
            rgba: [0.1, 0.7, 0.1, 1.0],
            points: truth.iter().map(|p| (p.x, p.y)).collect(),
        });
    }
    out
}

/// The `offered_qos_profiles` channel metadata `ros2 bag play` republishes with (the
/// rosbag2 YAML with integer policies, metadata version ≤ 8 as Humble writes it; later
/// releases' decoder, rosbag2_storage `qos.cpp`, detects the integer form and reads it
/// too): reliable, keep last;
/// `/tf_static` and `/map` transient local with depth 1 (latched, as tf2's static
/// broadcaster and map_server publish them, so RViz's late subscribers get them), the
/// others volatile with depth 10.
fn qos_profile(topic: &str) -> String {
    let (durability, depth) = if topic == "/tf_static" || topic == "/map" {
        (1, 1)
    } else {
        (2, 10)
    };
    format!(
        "- history: 1\n  depth: {depth}\n  reliability: 1\n  durability: {durability}\n  \
         deadline:\n    sec: 0\n    nsec: 0\n  lifespan:\n    sec: 0\n    nsec: 0\n  \
         liveliness: 1\n  liveliness_lease_duration:\n    sec: 0\n    nsec: 0\n  \
         avoid_ros_namespace_conventions: false"
    )
}

#[cfg(test)]
mod tests;
