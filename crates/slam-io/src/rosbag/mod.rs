//! ROS bags → the same [`ScanDataset`] as a CARMEN log gives, whatever the container: ROS 2
//! MCAP files, ROS 2 sqlite3 files (`.db3`), rosbag2 folders (`metadata.yaml` + MCAP or
//! sqlite3 storage) and ROS 1 bags (`.bag`, format 2.0).
//!
//! **Containers** (`container.rs`), each reduced to a stream of (topic, type, encoding, log
//! time, bytes) so that everything below is shared: MCAP through Foxglove's `mcap` crate
//! (chunks uncompressed, zstd or lz4; feature `rosbag`); sqlite3 through SQLite (rusqlite,
//! `sqlite.rs`; feature `rosbag-sqlite`); ROS 1 bags by a reader of this module (`ros1.rs`;
//! chunks uncompressed, bz2 or lz4; feature `rosbag1`). A rosbag2 folder is read through its
//! `metadata.yaml` (`storage_identifier`, the files of `relative_file_paths` in order, and
//! `compression_mode: message` with zstd, which compresses each message). A file's
//! container is found from its first bytes, not its name. Messages must be CDR-encoded ROS 2
//! messages (little or big endian, `cdr.rs`) or ROS 1-serialised messages (`wire.rs`), one
//! decoder per message type for both (`msgs.rs`).
//!
//! **Topics.** The scans are the one `sensor_msgs/msg/LaserScan` topic (or `scan_topic`).
//! Odometry is the one `nav_msgs/msg/Odometry` topic (or `odom_topic`); when the bag has
//! none (or `odom_topic` is `/tf`) it is the `/tf` transform from the odometry frame
//! (`odom`, REP 105) to the robot's base frame. Two candidates and no choice is an error that
//! names them and the option to choose with. A bag with neither an odometry topic nor `/tf`
//! (or read with [`BagOptions::laser_only`]) gives the scans alone, every record's
//! odometry the identity ([`OdometrySource::None`]): the caller makes the odometry from the
//! scans (laser odometry). A `sensor_msgs/msg/Imu` topic named by
//! [`BagOptions::imu_topic`] gives its yaw rates ([`RosBag::yaw_rates`]), the rotation
//! prior of laser odometry; they are `angular_velocity.z` in the IMU's frame, taken as the
//! base frame's yaw rate (an IMU mounted level; its mounting is not read).
//!
//! **Laser mounting.** The scan's `header.frame_id` is located in the robot's base frame
//! (the odometry's child frame) by composing the `/tf_static` transforms from the base frame
//! to it; [`BagOptions::laser_pose`] replaces that (and is needed when `/tf_static` does
//! not link the two frames). Poses are projected on the plane: x, y and the quaternion's
//! yaw.
//!
//! **Time and pairing.** Every time is a message's `header.stamp` (not the recording
//! clock). The odometry poses are sorted by stamp; a scan at time t with t₀ ≤ t ≤ t₁ for
//! the odometry stamps t₀ < t₁ around it gets the linear interpolation
//! x = x₀ + s(x₁ − x₀), y likewise, θ = θ₀ + s·wrap(θ₁ − θ₀), s = (t − t₀)/(t₁ − t₀);
//! a scan stamped exactly at an odometry stamp gets that pose unchanged. A scan outside the
//! odometry's time span is left out and counted in [`RosBag::scans_outside_odometry`]
//! (and in the summary line); none inside is an error. The dataset holds one record per
//! odometry message (no scan) and one per scan, in time order, as a CARMEN log holds `ODOM`
//! and `FLASER` lines; an odometry message stamped exactly like a scan is that scan's
//! record.
//!
//! **Readings** (as `sensor_msgs/msg/LaserScan` defines them). Beam k points at
//! `angle_min + k·angle_increment`. A reading r with `range_min ≤ r < range_max` is a hit;
//! `+∞` ("no return within range_max") and r ≥ `range_max` are no-return readings; `NaN`,
//! `−∞` and r < `range_min` are invalid. Our [`LaserScan`] has no invalid marker, so
//! invalid readings become no-return readings as ROS's `slam_gmapping` treats short
//! readings; both kinds are stored as `range_max` and counted in the report.
//!
//! **Bounds**, as for the other readers: coordinates within ±10⁶ m, headings finite,
//! `0 ≤ range_min < range_max ≤ 1000` m, beam angles within one turn, a non-zero angle
//! increment; a value outside is an error naming the topic, the message and the bound.
//! The whole file is read into memory; every length inside a message is checked against the
//! bytes left before it is allocated.

pub(crate) mod cdr;
mod container;
pub(crate) mod msgs;
#[cfg(feature = "rosbag1")]
mod ros1;
mod ros1_record;
#[cfg(feature = "rosbag-sqlite")]
mod sqlite;
pub(crate) mod wire;

pub use ros1_record::{ros1_record, ros1_record_head};

pub use container::{BagFormat, TopicInfo};

use crate::error::{DatasetOption, IoError};
use msgs::{ScanMsg, StampedPose, LASER_SCAN, ODOMETRY};
use slam_models::{normalize_angle, LaserScan, Pose2, ScanDataset, ScanRecord, YawRate};
use std::collections::BTreeMap;
use std::path::Path;

// The bounds of every reader (`crate::bounds`): coordinates, ranges, beam angles.
use crate::bounds::{MAX_ANGLE, MAX_COORD, MAX_RANGE};
/// Longest span of odometry stamps, nanoseconds ([`crate::bounds::MAX_TIME_SPAN`], about
/// 116 days); a stamp outside it is a corrupted or unset (zero) stamp.
const MAX_TIME_SPAN_NS: i64 = crate::bounds::MAX_TIME_SPAN as i64 * 1_000_000_000;
/// The `/tf` topics.
const TF: &str = "/tf";
const TF_STATIC: &str = "/tf_static";

/// Choices the bag reader cannot make alone.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct BagOptions {
    /// The `sensor_msgs/msg/LaserScan` topic to read (needed when the bag has several).
    pub scan_topic: Option<String>,
    /// The `nav_msgs/msg/Odometry` topic to read, or `/tf` for the odom → base transform
    /// (needed when the bag has several odometry topics).
    pub odom_topic: Option<String>,
    /// The laser's pose in the robot's base frame (x, y metres, θ radians), replacing
    /// `/tf_static`.
    pub laser_pose: Option<Pose2>,
    /// The odometry frame of the `/tf` odometry chain (the parent; by default `odom`).
    pub odom_frame: Option<String>,
    /// The robot's base frame of the `/tf` odometry chain (the child), needed when several
    /// transforms leave the odometry frame (e.g. `odom → base_footprint` and
    /// `odom → base_link`).
    pub base_frame: Option<String>,
    /// Read the scans without odometry even when the bag has some (`--odometry none`):
    /// every record's odometry is then the identity and [`RosBag::odometry`] is
    /// [`OdometrySource::None`] (a bag without odometry is read so anyway).
    pub laser_only: bool,
    /// A `sensor_msgs/msg/Imu` topic whose `angular_velocity.z` is read into
    /// [`RosBag::yaw_rates`] (`--imu-topic`).
    pub imu_topic: Option<String>,
}

/// Where the odometry came from.
#[derive(Debug, Clone, PartialEq)]
pub enum OdometrySource {
    /// A `nav_msgs/msg/Odometry` topic.
    Topic(String),
    /// The `/tf` transform `parent → child`.
    Tf {
        /// The odometry frame (normally `odom`).
        parent: String,
        /// The robot's base frame.
        child: String,
    },
    /// None: the bag has no `nav_msgs/msg/Odometry` topic and no `/tf` topic, or
    /// [`BagOptions::laser_only`] was asked for. Every record is a scan with the identity
    /// as its odometry, and the base frame is the laser's (the laser is the robot, at
    /// [`BagOptions::laser_pose`] if given); the caller makes the odometry (laser
    /// odometry, `slam_grid::laser_odometry`).
    None,
}

/// A ROS bag as read: the dataset and what the reader chose and left out.
#[derive(Debug, Clone, PartialEq)]
pub struct RosBag {
    /// The container the bag was read from.
    pub format: BagFormat,
    /// One record per odometry message and per scan, in time order.
    pub dataset: ScanDataset,
    /// Every topic of the bag.
    pub topics: Vec<TopicInfo>,
    /// The scan topic read.
    pub scan_topic: String,
    /// The odometry read.
    pub odometry: OdometrySource,
    /// Number of odometry poses read (messages, or `/tf` transforms of the odometry edge).
    pub odometry_poses: usize,
    /// The scans' frame (`header.frame_id` of the first scan).
    pub laser_frame: String,
    /// The robot's base frame (the odometry's child frame).
    pub base_frame: String,
    /// The laser's pose in the base frame, and where it came from (`/tf_static`,
    /// `--laser-pose`, or `same frame`).
    pub laser_pose: (Pose2, &'static str),
    /// Scans stamped before the first or after the last odometry pose (left out).
    pub scans_outside_odometry: usize,
    /// Readings `+∞` or ≥ `range_max` (kept as no return).
    pub no_return_readings: usize,
    /// Readings NaN, `−∞` or < `range_min` (kept as no return).
    pub invalid_readings: usize,
    /// The yaw rates of [`BagOptions::imu_topic`] (time in seconds as the records',
    /// `angular_velocity.z` in rad/s), in time order; empty without that option.
    pub yaw_rates: Vec<YawRate>,
}

impl RosBag {
    /// One line: topics chosen, counts, laser geometry and mounting, what was left out.
    pub fn summary(&self, path: &Path) -> String {
        let recs = &self.dataset.records;
        let scans: Vec<&LaserScan> = recs.iter().filter_map(|r| r.scan.as_ref()).collect();
        let geometry = match scans.first() {
            Some(s) => format!(
                "{} beams from {:.1}° by {:.3}°, range_max {} m",
                s.len(),
                s.angle_min.to_degrees(),
                s.angle_increment.to_degrees(),
                s.max_range as f32
            ),
            None => "no scans".into(),
        };
        let odom = match &self.odometry {
            OdometrySource::Topic(t) => format!("odometry {t}"),
            OdometrySource::Tf { parent, child } => format!("odometry /tf {parent} → {child}"),
            OdometrySource::None => "no odometry".into(),
        };
        let poses = self.odometry_poses;
        let (p, from) = self.laser_pose;
        let span = match (recs.first(), recs.last()) {
            (Some(a), Some(b)) => b.t - a.t,
            _ => 0.0,
        };
        let mut s = format!(
            "{} {} ({}): scans {} ({} scans, {geometry}), {odom} ({poses} poses), over {span:.1} s; \
             laser frame {} at ({:.4} m, {:.4} m, {:.4} rad) in {} ({from})",
            self.format.ros(),
            path.display(),
            self.format.storage(),
            self.scan_topic,
            scans.len(),
            self.laser_frame,
            p.x,
            p.y,
            p.theta,
            self.base_frame,
        );
        if self.scans_outside_odometry > 0 {
            s.push_str(&format!(
                "; {} scan(s) outside the odometry's time span left out",
                self.scans_outside_odometry
            ));
        }
        if self.invalid_readings > 0 {
            s.push_str(&format!(
                "; {} invalid reading(s) (NaN, -inf, < range_min) kept as no return",
                self.invalid_readings
            ));
        }
        if !self.yaw_rates.is_empty() {
            s.push_str(&format!("; {} IMU yaw rates", self.yaw_rates.len()));
        }
        s
    }
}

/// Reads a ROS bag of any container (the name is historical: MCAP, sqlite3, ROS 1, a
/// rosbag2 folder) with the topics found automatically and the laser mounting from
/// `/tf_static`: the dataset only. See [`read_rosbag`].
pub fn read_mcap(path: &Path) -> Result<ScanDataset, IoError> {
    Ok(read_rosbag(path, &BagOptions::default())?.dataset)
}

/// The topics of a bag (any container) with their types, encodings,
/// counts and recording times, without decoding any message. A truncated or corrupt file
/// is an error.
pub fn bag_topics(path: &Path) -> Result<Vec<TopicInfo>, IoError> {
    container::for_each_message(path, |_, _| Ok(())).map(|(_, t)| t)
}

/// What `slam info` prints for a bag: every topic with its type, encoding, message count
/// and rate; the span of the recording; the geometry of each laser topic (from its first
/// message); the odometry sources (`nav_msgs/msg/Odometry` topics and the `/tf` edges);
/// the `/tf_static` edges. A message of those topics that does not decode is an error.
pub fn describe_bag(path: &Path) -> Result<String, IoError> {
    use std::fmt::Write as _;
    let mut first_scan: BTreeMap<String, ScanMsg> = BTreeMap::new();
    let mut odom_frames: BTreeMap<String, (String, String)> = BTreeMap::new();
    let mut edges: BTreeMap<(bool, String, String), (usize, Pose2)> = BTreeMap::new();
    let (bag, topics) = container::for_each_message(path, |file, m| {
        if !msgs::ENCODINGS.contains(&m.encoding) {
            return Ok(());
        }
        let fail = |e: wire::DecodeError| {
            bad(
                file,
                m.topic,
                m.index,
                format!("does not decode as {}: {e}", m.msg_type),
            )
        };
        match m.msg_type {
            LASER_SCAN if !first_scan.contains_key(m.topic) => {
                first_scan.insert(
                    m.topic.to_string(),
                    msgs::laser_scan(m.encoding, m.data).map_err(fail)?,
                );
            }
            ODOMETRY if !odom_frames.contains_key(m.topic) => {
                let p = msgs::odometry(m.encoding, m.data).map_err(fail)?;
                odom_frames.insert(m.topic.to_string(), (p.parent, p.child));
            }
            t if msgs::is_tf_message(t) && (m.topic == TF || m.topic == TF_STATIC) => {
                for p in msgs::tf_message(m.encoding, m.data).map_err(fail)? {
                    let e = edges
                        .entry((m.topic == TF_STATIC, p.parent, p.child))
                        .or_insert((0, p.pose));
                    e.0 += 1;
                    e.1 = p.pose;
                }
            }
            _ => {}
        }
        Ok(())
    })?;
    let t0 = topics.iter().map(|t| t.log_time_ns.0).min().unwrap_or(0);
    let t1 = topics.iter().map(|t| t.log_time_ns.1).max().unwrap_or(0);
    let span = (t1 - t0) as f64 * 1e-9;
    let count: usize = topics.iter().map(|t| t.count).sum();
    let files = bag.files.len();
    let mut s = format!(
        "{} {} ({files} {} file(s)): {} topic(s), {count} message(s) over {span:.1} s \
         (recorded from {:.3} s)\n",
        bag.format.ros(),
        path.display(),
        bag.format.storage(),
        topics.len(),
        t0 as f64 * 1e-9
    );
    // Names are shortened for the table: a hostile 64 KiB topic name must not set the width.
    let rows: Vec<(String, String, &TopicInfo)> = topics
        .iter()
        .map(|t| (shorten(&t.topic), shorten(&t.msg_type), t))
        .collect();
    let width = |f: fn(&(String, String, &TopicInfo)) -> usize, min: usize| {
        rows.iter().map(f).max().unwrap_or(min).max(min)
    };
    let w = width(|r| r.0.chars().count(), 5);
    let wt = width(|r| r.1.chars().count(), 4);
    let _ = writeln!(
        s,
        "  {:w$}  {:wt$}  encoding  messages  rate",
        "topic", "type"
    );
    for (topic, msg_type, t) in &rows {
        let dt = (t.log_time_ns.1 - t.log_time_ns.0) as f64 * 1e-9;
        // No rate from fewer than three messages: two latched messages a microsecond apart
        // are not a 10 kHz topic.
        let rate = if t.count >= MIN_RATE_MESSAGES && dt > 0.0 {
            format!("{:.1} Hz", (t.count - 1) as f64 / dt)
        } else {
            "-".into()
        };
        let _ = writeln!(
            s,
            "  {topic:w$}  {msg_type:wt$}  {:8}  {:8}  {rate}",
            shorten(&t.encoding),
            t.count
        );
    }
    for (topic, m) in &first_scan {
        let _ = writeln!(
            s,
            "laser {}: frame {:?}, {} beams from {:.2}° to {:.2}° by {:.3}°, range {} … {} m",
            shorten(topic),
            shorten(&m.header.frame_id),
            m.ranges.len(),
            m.angle_min.to_degrees(),
            m.angle_max.to_degrees(),
            m.angle_increment.to_degrees(),
            m.range_min as f32,
            m.range_max as f32
        );
    }
    if first_scan.is_empty() {
        let _ = writeln!(s, "laser: no {LASER_SCAN} topic");
    }
    // The odometry: the Odometry topics and the one /tf chain the reader would use (or the
    // candidates it would ask to choose between); the other /tf edges folded apart.
    let tf_edges: Vec<(String, String)> = edges
        .keys()
        .filter(|(st, _, _)| !st)
        .map(|(_, p, c)| (p.clone(), c.clone()))
        .collect();
    let chains = odometry_edges(&tf_edges, None, None);
    let arrow = |(p, c): &(String, String)| format!("{} → {}", shorten(p), shorten(c));
    let transforms =
        |(p, c): &(String, String)| edges.get(&(false, p.clone(), c.clone())).map_or(0, |e| e.0);
    for t in topics.iter().filter(|t| t.msg_type == msgs::IMU) {
        let _ = writeln!(
            s,
            "imu {}: {} messages (its yaw rate is the rotation prior of laser odometry with {} {})",
            t.topic,
            t.count,
            DatasetOption::ImuTopic,
            t.topic
        );
    }
    let mut odometry: Vec<String> = odom_frames
        .iter()
        .map(|(t, (p, c))| format!("{} ({} → {})", shorten(t), shorten(p), shorten(c)))
        .collect();
    let tf_note = if odometry.is_empty() {
        String::new()
    } else {
        format!(", with {} {TF}", DatasetOption::OdomTopic)
    };
    match chains.as_slice() {
        [] => {}
        [one] => odometry.push(format!(
            "/tf {} ({} transforms{tf_note})",
            arrow(one),
            transforms(one)
        )),
        many => odometry.push(format!(
            "/tf, one of {} (choose with {}{tf_note})",
            fold(many.iter().map(|e| arrow(e)).collect()),
            DatasetOption::BaseFrame
        )),
    }
    let _ = writeln!(
        s,
        "odometry: {}",
        if odometry.is_empty() {
            "none (no Odometry topic, no /tf odom → base transform): slam run makes it from the scans (laser odometry)"
                .into()
        } else {
            odometry.join("; ")
        }
    );
    let others: Vec<String> = tf_edges
        .iter()
        .filter(|e| !chains.contains(e))
        .map(|e| format!("{} ({})", arrow(e), transforms(e)))
        .collect();
    if !others.is_empty() {
        let _ = writeln!(
            s,
            "/tf, not odometry: {} edge(s): {}",
            others.len(),
            fold(others)
        );
    }
    let statics: Vec<String> = edges
        .iter()
        .filter(|((st, _, _), _)| *st)
        .map(|((_, p, c), (_, q))| {
            format!(
                "{} → {} at ({:.4} m, {:.4} m, {:.4} rad)",
                shorten(p),
                shorten(c),
                q.x,
                q.y,
                q.theta
            )
        })
        .collect();
    let _ = write!(
        s,
        "/tf_static: {}",
        if statics.is_empty() {
            "none".into()
        } else {
            format!("{} edge(s): {}", statics.len(), fold(statics))
        }
    );
    Ok(s)
}

/// Fewest messages a topic needs for `slam info` to give its rate.
const MIN_RATE_MESSAGES: usize = 3;
/// Most items a listing of `slam info` shows before folding the rest into a count.
const FOLD_AFTER: usize = 6;

/// The first [`FOLD_AFTER`] items joined by `; `, and how many more there are.
fn fold(items: Vec<String>) -> String {
    let more = items.len().saturating_sub(FOLD_AFTER);
    let mut s = items
        .into_iter()
        .take(FOLD_AFTER)
        .collect::<Vec<_>>()
        .join("; ");
    if more > 0 {
        s.push_str(&format!("; … and {more} more"));
    }
    s
}

/// A name shortened for a table or a listing (at most 60 characters and `…`).
fn shorten(s: &str) -> String {
    crate::text::shorten(s)
}

fn pick(
    path: &Path,
    topics: &[TopicInfo],
    msg_type: &str,
    chosen: Option<&str>,
    option: DatasetOption,
) -> Result<Option<String>, IoError> {
    let candidates: Vec<&TopicInfo> = topics.iter().filter(|t| t.msg_type == msg_type).collect();
    if let Some(c) = chosen {
        return match topics.iter().find(|t| t.topic == c) {
            Some(t) if t.msg_type == msg_type => Ok(Some(c.to_string())),
            Some(t) => Err(IoError::option(
                path,
                Some(c),
                option,
                format!("names a {} topic, expected {msg_type}", t.msg_type),
            )),
            None => Err(IoError::option(
                path,
                Some(c),
                option,
                format!(
                    "names a topic the bag does not have; {msg_type} topics: {}",
                    names(&candidates)
                ),
            )),
        };
    }
    match candidates.as_slice() {
        [] => Ok(None),
        [one] => Ok(Some(one.topic.clone())),
        many => Err(IoError::option(
            path,
            None,
            option,
            format!(
                "must choose one of the {} {msg_type} topics ({})",
                many.len(),
                names(many)
            ),
        )),
    }
}

fn names(t: &[&TopicInfo]) -> String {
    if t.is_empty() {
        return "none".into();
    }
    t.iter()
        .map(|t| t.topic.as_str())
        .collect::<Vec<_>>()
        .join(", ")
}

/// The topic's encoding must be one we decode; a ROS 1 connection whose message definition
/// is not the one we decode (its md5sum differs) is refused here too.
fn check_encoding(path: &Path, t: &TopicInfo) -> Result<(), IoError> {
    if msgs::ENCODINGS.contains(&t.encoding.as_str()) {
        return Ok(());
    }
    let what = match t.encoding.strip_prefix("ros1 md5sum ") {
        Some(md5) => format!(
            "the ROS 1 connection's message definition has md5sum {md5}, expected {} (the \
             standard {})",
            msgs::ros1_md5(&t.msg_type).unwrap_or("?"),
            t.msg_type
        ),
        None => format!(
            "message encoding {:?} is not supported (expected cdr, the ROS 2 encoding, or ros1)",
            t.encoding
        ),
    };
    Err(IoError::Bag {
        path: path.to_path_buf(),
        topic: t.topic.clone(),
        what,
    })
}

fn bad(path: &Path, topic: &str, index: usize, what: impl std::fmt::Display) -> IoError {
    IoError::Bag {
        path: path.to_path_buf(),
        topic: topic.to_string(),
        what: format!("message {}: {what}", index + 1),
    }
}

fn check_pose(path: &Path, topic: &str, index: usize, p: &StampedPose) -> Result<(), IoError> {
    for (v, what) in [(p.pose.x, "x"), (p.pose.y, "y")] {
        if !(v.is_finite() && v.abs() <= MAX_COORD) {
            return Err(bad(
                path,
                topic,
                index,
                format!(
                    "{} → {} {what} = {v} m is outside ±{MAX_COORD} m",
                    p.parent, p.child
                ),
            ));
        }
    }
    if !p.pose.theta.is_finite() {
        return Err(bad(path, topic, index, "heading is not finite"));
    }
    Ok(())
}

/// Reads a ROS bag (an MCAP, sqlite3 or ROS 1 bag file, or a rosbag2 folder) into a
/// [`ScanDataset`] by the rules of this module's documentation.
///
/// Errors name the file, the topic and what was expected: two candidate topics without a
/// choice, no odometry, an unknown message encoding, a message that does not decode (its
/// number on the topic and the byte where decoding stopped), a value out of bounds, a
/// truncated file (messages read before the damage), no scan within the odometry's time.
pub fn read_rosbag(path: &Path, options: &BagOptions) -> Result<RosBag, IoError> {
    let (bag, topics) = container::for_each_message(path, |_, _| Ok(()))?;
    let scan_topic = pick(
        path,
        &topics,
        LASER_SCAN,
        options.scan_topic.as_deref(),
        DatasetOption::ScanTopic,
    )?
    .ok_or_else(|| {
        IoError::invalid(
            path,
            format!(
                "no {LASER_SCAN} topic (topics: {})",
                names(&topics.iter().collect::<Vec<_>>())
            ),
        )
    })?;
    let tf_topic = topics
        .iter()
        .find(|t| t.topic == TF && msgs::is_tf_message(&t.msg_type));
    let odom_topic = match options.odom_topic.as_deref() {
        Some(TF) => None,
        chosen => pick(path, &topics, ODOMETRY, chosen, DatasetOption::OdomTopic)?,
    };
    if options.odom_topic.as_deref() == Some(TF) && tf_topic.is_none() {
        return Err(IoError::option(
            path,
            None,
            DatasetOption::OdomTopic,
            format!("{TF}: the bag has no {TF} topic"),
        ));
    }
    // No odometry in the bag, or none wanted: the scans alone.
    let laser_only = options.laser_only || (odom_topic.is_none() && tf_topic.is_none());
    let imu_topic = match options.imu_topic.as_deref() {
        Some(t) => pick(path, &topics, msgs::IMU, Some(t), DatasetOption::ImuTopic)?,
        None => None,
    };
    for t in &topics {
        let used = t.topic == scan_topic
            || Some(&t.topic) == imu_topic.as_ref()
            || (!laser_only && Some(&t.topic) == odom_topic.as_ref())
            || (!laser_only && odom_topic.is_none() && t.topic == TF)
            || (t.topic == TF_STATIC && msgs::is_tf_message(&t.msg_type));
        if used {
            check_encoding(path, t)?;
        }
    }

    let mut scans: Vec<ScanMsg> = Vec::new();
    let mut odom: Vec<StampedPose> = Vec::new();
    let mut tf: Vec<StampedPose> = Vec::new();
    let mut statics: Vec<StampedPose> = Vec::new();
    let mut yaw_rates: Vec<(i64, f64)> = Vec::new();
    container::for_each_message(path, |file, m| {
        let fail = |e: wire::DecodeError| {
            bad(
                file,
                m.topic,
                m.index,
                format!(
                    "(logged at {} s) does not decode as {}: {e}",
                    m.log_time_ns as f64 * 1e-9,
                    m.msg_type
                ),
            )
        };
        if m.topic == scan_topic {
            scans.push(msgs::laser_scan(m.encoding, m.data).map_err(fail)?);
        } else if Some(m.topic) == imu_topic.as_deref() {
            let (stamp, rate) = msgs::imu_yaw_rate(m.encoding, m.data).map_err(fail)?;
            if !rate.is_finite() {
                return Err(bad(
                    file,
                    m.topic,
                    m.index,
                    "angular_velocity.z is not finite",
                ));
            }
            yaw_rates.push((stamp, rate));
        } else if laser_only {
            // Odometry and /tf are not read.
        } else if Some(m.topic) == odom_topic.as_deref() {
            let p = msgs::odometry(m.encoding, m.data).map_err(fail)?;
            check_pose(file, m.topic, m.index, &p)?;
            odom.push(p);
        } else if m.topic == TF && msgs::is_tf_message(m.msg_type) && odom_topic.is_none() {
            for p in msgs::tf_message(m.encoding, m.data).map_err(fail)? {
                check_pose(file, m.topic, m.index, &p)?;
                tf.push(p);
            }
        } else if m.topic == TF_STATIC && msgs::is_tf_message(m.msg_type) {
            for p in msgs::tf_message(m.encoding, m.data).map_err(fail)? {
                check_pose(file, m.topic, m.index, &p)?;
                statics.push(p);
            }
        }
        Ok(())
    })?;

    yaw_rates.sort_by_key(|r| r.0);
    let yaw_rates = yaw_rates
        .into_iter()
        .map(|(t, rate)| YawRate {
            t: t as f64 * 1e-9,
            rate,
        })
        .collect();
    let (source, odom) = match odom_topic {
        _ if laser_only => (OdometrySource::None, Vec::new()),
        Some(t) => (OdometrySource::Topic(t), odom),
        None => {
            let (parent, child) = tf_odometry_edge(path, &tf, options)?;
            let poses = tf
                .into_iter()
                .filter(|p| p.parent == parent && p.child == child)
                .collect();
            (OdometrySource::Tf { parent, child }, poses)
        }
    };
    let mut bag = assemble(
        path,
        (bag.format, topics),
        scan_topic,
        source,
        odom,
        scans,
        &statics,
        options,
    )?;
    bag.yaw_rates = yaw_rates;
    Ok(bag)
}

/// The `/tf` edges (parent, child) that may be the odometry: those from the odometry frame
/// (`odom_frame`, by default `odom`; any frame when only `base_frame` is given) to
/// `base_frame` (any child when not given); when neither is given and no edge leaves
/// `odom`, the only edge of `/tf` if there is one.
fn odometry_edges<'e>(
    edges: &'e [(String, String)],
    odom_frame: Option<&str>,
    base_frame: Option<&str>,
) -> Vec<&'e (String, String)> {
    let parent_ok = |p: &str| match (odom_frame, base_frame) {
        (Some(o), _) => p == o,
        (None, Some(_)) => true,
        (None, None) => p == DEFAULT_ODOM_FRAME,
    };
    let found: Vec<&(String, String)> = edges
        .iter()
        .filter(|(p, c)| parent_ok(p) && base_frame.is_none_or(|b| b == c))
        .collect();
    match (found.is_empty(), odom_frame, base_frame, edges) {
        (true, None, None, [one]) => vec![one],
        _ => found,
    }
}

/// The odometry frame of REP 105.
const DEFAULT_ODOM_FRAME: &str = "odom";

/// The `/tf` edge that is the odometry ([`odometry_edges`]); none or several is an error
/// naming the edges and the options that choose.
fn tf_odometry_edge(
    path: &Path,
    tf: &[StampedPose],
    options: &BagOptions,
) -> Result<(String, String), IoError> {
    let mut edges: Vec<(String, String)> = tf
        .iter()
        .map(|p| (p.parent.clone(), p.child.clone()))
        .collect();
    edges.sort();
    edges.dedup();
    let (odom, base) = (options.odom_frame.as_deref(), options.base_frame.as_deref());
    let found = odometry_edges(&edges, odom, base);
    if let [one] = found.as_slice() {
        return Ok((*one).clone());
    }
    let list = |e: &[&(String, String)]| {
        fold(
            e.iter()
                .map(|(p, c)| format!("{} → {}", shorten(p), shorten(c)))
                .collect(),
        )
    };
    let wanted = format!(
        "{} → {}",
        odom.unwrap_or(if base.is_some() {
            "*"
        } else {
            DEFAULT_ODOM_FRAME
        }),
        base.unwrap_or("*")
    );
    let what = if found.is_empty() {
        format!(
            "expected one odometry transform {wanted}, found {}; name the chain with \
             --odom-frame and --base-frame",
            if edges.is_empty() {
                "no transform".to_string()
            } else {
                list(&edges.iter().collect::<Vec<_>>())
            }
        )
    } else {
        format!(
            "{} transforms {wanted} could be the odometry ({}); choose the base frame with \
             --base-frame (and the odometry frame with --odom-frame)",
            found.len(),
            list(&found)
        )
    };
    Err(IoError::Bag {
        path: path.to_path_buf(),
        topic: TF.into(),
        what,
    })
}

/// The pose of `frame` in `base` through the static transforms (parent → child edges; of
/// several edges into one child, the last): one look-up per frame of the chain, so a chain
/// of n frames costs O(n), not O(n²).
fn static_chain(statics: &[StampedPose], base: &str, frame: &str) -> Option<Pose2> {
    // Each frame has one parent in a tf tree; the last transform into a child wins.
    let parent: std::collections::HashMap<&str, &StampedPose> =
        statics.iter().map(|p| (p.child.as_str(), p)).collect();
    let mut pose = Pose2::IDENTITY;
    let mut at = frame;
    for _ in 0..=parent.len() {
        if at == base {
            return Some(pose);
        }
        let edge = parent.get(at)?;
        pose = edge.pose.compose(&pose);
        at = &edge.parent;
    }
    None
}

#[allow(clippy::too_many_arguments)]
fn assemble(
    path: &Path,
    (format, topics): (BagFormat, Vec<TopicInfo>),
    scan_topic: String,
    source: OdometrySource,
    mut odom: Vec<StampedPose>,
    scans: Vec<ScanMsg>,
    statics: &[StampedPose],
    options: &BagOptions,
) -> Result<RosBag, IoError> {
    let odom_name = match &source {
        OdometrySource::Topic(t) => t.clone(),
        OdometrySource::Tf { .. } => TF.to_string(),
        OdometrySource::None => String::new(),
    };
    let laser_only = source == OdometrySource::None;
    if odom.is_empty() && !laser_only {
        return Err(IoError::Bag {
            path: path.to_path_buf(),
            topic: odom_name,
            what: "no odometry pose".into(),
        });
    }
    odom.sort_by_key(|p| p.stamp_ns);
    // Without odometry every scan is in its (unbounded) time span.
    let (first, last) = match (odom.first(), odom.last()) {
        (Some(a), Some(b)) => (a.stamp_ns, b.stamp_ns),
        _ => (i64::MIN, i64::MAX),
    };
    if !laser_only && last - first > MAX_TIME_SPAN_NS {
        return Err(IoError::Bag {
            path: path.to_path_buf(),
            topic: odom_name,
            what: format!(
                "odometry stamps from {} s to {} s: expected a span within {} s (an unset or \
                 corrupted header.stamp?)",
                first as f64 * 1e-9,
                last as f64 * 1e-9,
                MAX_TIME_SPAN_NS / 1_000_000_000
            ),
        });
    }
    let laser_frame = scans
        .first()
        .map(|s| s.header.frame_id.clone())
        .unwrap_or_default();
    let base_frame = odom
        .first()
        .map_or_else(|| laser_frame.clone(), |p| p.child.clone());
    let mut mounts: BTreeMap<String, (Pose2, &'static str)> = BTreeMap::new();
    let mut mount = |frame: &str| -> Result<(Pose2, &'static str), IoError> {
        if let Some(m) = mounts.get(frame) {
            return Ok(*m);
        }
        let m = match options.laser_pose {
            Some(p) => (p, "option `laser_pose`"),
            None if frame == base_frame => (Pose2::IDENTITY, "same frame"),
            None => match static_chain(statics, &base_frame, frame) {
                Some(p) => (p, "/tf_static"),
                None => {
                    return Err(IoError::option(
                        path,
                        Some(TF_STATIC),
                        DatasetOption::LaserPose,
                        format!(
                            "is needed: no static transform chain from the base frame \
                             {base_frame:?} to the laser frame {frame:?} (give the laser's \
                             mounting x, y, theta in the base frame)"
                        ),
                    ))
                }
            },
        };
        mounts.insert(frame.to_string(), m);
        Ok(m)
    };

    let (t_first, t_last) = (first, last);
    let mut outside = 0usize;
    let (mut no_return, mut invalid) = (0usize, 0usize);
    // (stamp, is_scan, record)
    let mut timed: Vec<(i64, ScanRecord)> = Vec::with_capacity(odom.len() + scans.len());
    let mut scan_stamps = Vec::new();
    let mut first_mount = None;
    for (k, s) in scans.into_iter().enumerate() {
        let t = s.header.stamp_ns;
        if t < t_first || t > t_last {
            outside += 1;
            continue;
        }
        let m = mount(&s.header.frame_id)?;
        first_mount.get_or_insert(m);
        let scan = convert_scan(path, &scan_topic, k, s, m.0, &mut no_return, &mut invalid)?;
        scan_stamps.push(t);
        timed.push((
            t,
            ScanRecord {
                t: t as f64 * 1e-9,
                odometry: if laser_only {
                    Pose2::IDENTITY
                } else {
                    interpolate(&odom, t)
                },
                scan: Some(scan),
            },
        ));
    }
    if timed.is_empty() {
        return Err(IoError::Bag {
            path: path.to_path_buf(),
            topic: scan_topic,
            what: format!(
                "no scan within the odometry's time span ({} … {} s; {outside} scan(s) outside)",
                t_first as f64 * 1e-9,
                t_last as f64 * 1e-9
            ),
        });
    }
    scan_stamps.sort_unstable();
    for p in &odom {
        if scan_stamps.binary_search(&p.stamp_ns).is_err() {
            timed.push((
                p.stamp_ns,
                ScanRecord {
                    t: p.stamp_ns as f64 * 1e-9,
                    odometry: p.pose,
                    scan: None,
                },
            ));
        }
    }
    // Stable: at equal stamps, scans (pushed first) come before odometry records.
    timed.sort_by_key(|(t, _)| *t);
    let name = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    Ok(RosBag {
        format,
        dataset: ScanDataset {
            name,
            records: timed.into_iter().map(|(_, r)| r).collect(),
            ground_truth: None,
        },
        topics,
        scan_topic,
        odometry: source,
        odometry_poses: odom.len(),
        laser_frame,
        base_frame,
        laser_pose: first_mount.unwrap_or((Pose2::IDENTITY, "same frame")),
        scans_outside_odometry: outside,
        no_return_readings: no_return,
        invalid_readings: invalid,
        yaw_rates: Vec::new(),
    })
}

/// The odometry pose at `t` (within the span of `odom`, sorted by stamp): linear in x, y
/// and in the wrapped heading difference; exact at an odometry stamp (the last of equal
/// stamps).
fn interpolate(odom: &[StampedPose], t: i64) -> Pose2 {
    let i = odom.partition_point(|p| p.stamp_ns <= t);
    // odom[i - 1].stamp ≤ t < odom[i].stamp (i ≥ 1 since t ≥ the first stamp).
    let a = &odom[i.saturating_sub(1)];
    if a.stamp_ns == t || i >= odom.len() {
        return a.pose;
    }
    let b = &odom[i];
    let s = (t - a.stamp_ns) as f64 / (b.stamp_ns - a.stamp_ns) as f64;
    Pose2::new(
        a.pose.x + s * (b.pose.x - a.pose.x),
        a.pose.y + s * (b.pose.y - a.pose.y),
        normalize_angle(a.pose.theta + s * normalize_angle(b.pose.theta - a.pose.theta)),
    )
}

fn convert_scan(
    path: &Path,
    topic: &str,
    index: usize,
    s: ScanMsg,
    sensor_pose: Pose2,
    no_return: &mut usize,
    invalid: &mut usize,
) -> Result<LaserScan, IoError> {
    let fail = |what: String| bad(path, topic, index, what);
    if !(s.range_max.is_finite() && s.range_max > 0.0 && s.range_max <= MAX_RANGE) {
        return Err(fail(format!(
            "range_max = {} m, expected 0 < range_max ≤ {MAX_RANGE} m",
            s.range_max
        )));
    }
    if !(s.range_min >= 0.0 && s.range_min < s.range_max) {
        return Err(fail(format!(
            "range_min = {} m, expected 0 ≤ range_min < range_max = {} m",
            s.range_min, s.range_max
        )));
    }
    for (v, what) in [(s.angle_min, "angle_min"), (s.angle_max, "angle_max")] {
        if !(v.is_finite() && v.abs() <= MAX_ANGLE) {
            return Err(fail(format!("{what} = {v} rad is outside ±2π")));
        }
    }
    let n = s.ranges.len();
    let last = s.angle_min + s.angle_increment * n.saturating_sub(1) as f64;
    if !(s.angle_increment.is_finite()
        && (n <= 1 || s.angle_increment != 0.0)
        && last.abs() <= 2.0 * MAX_ANGLE)
    {
        return Err(fail(format!(
            "angle_increment = {} rad for {n} beams from angle_min = {} rad, expected a non-zero \
             increment whose beams stay within ±2 turns",
            s.angle_increment, s.angle_min
        )));
    }
    let ranges = s
        .ranges
        .iter()
        .map(|&r| {
            if r.is_nan() || r < s.range_min {
                *invalid += 1;
                s.range_max
            } else if r >= s.range_max {
                *no_return += 1;
                s.range_max
            } else {
                r
            }
        })
        .collect();
    Ok(LaserScan {
        angle_min: s.angle_min,
        angle_increment: s.angle_increment,
        ranges,
        max_range: s.range_max,
        sensor_pose,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sp(t: i64, x: f64, th: f64) -> StampedPose {
        StampedPose {
            stamp_ns: t,
            parent: "odom".into(),
            child: "base_link".into(),
            pose: Pose2::new(x, 0.0, th),
        }
    }

    #[test]
    fn interpolation_is_exact_at_stamps_and_wraps_heading() {
        let o = [sp(0, 0.0, 3.0), sp(10, 1.0, -3.0)];
        assert_eq!(interpolate(&o, 0), o[0].pose);
        assert_eq!(interpolate(&o, 10), o[1].pose);
        let m = interpolate(&o, 5);
        assert!((m.x - 0.5).abs() < 1e-15);
        // Half-way from 3 rad to −3 rad the short way round is ±π, not 0.
        assert!(
            (m.theta.abs() - std::f64::consts::PI).abs() < 1e-12,
            "{m:?}"
        );
    }

    #[test]
    fn odometry_spanning_decades_is_an_error() {
        let odom = vec![sp(0, 0.0, 0.0), sp(976_052_857_000_000_000, 1.0, 0.0)];
        let e = assemble(
            Path::new("x.mcap"),
            (BagFormat::Mcap, vec![]),
            "/scan".into(),
            OdometrySource::Topic("/odom".into()),
            odom,
            vec![],
            &[],
            &BagOptions::default(),
        )
        .unwrap_err();
        assert!(
            e.to_string()
                .contains("topic /odom: odometry stamps from 0 s"),
            "{e}"
        );
    }

    #[test]
    fn static_chain_composes_parent_to_child() {
        let e = |p: &str, c: &str, x: f64, th: f64| StampedPose {
            stamp_ns: 0,
            parent: p.into(),
            child: c.into(),
            pose: Pose2::new(x, 0.0, th),
        };
        let statics = [
            e("base_link", "mount", 1.0, std::f64::consts::FRAC_PI_2),
            e("mount", "laser", 2.0, 0.0),
        ];
        let p = static_chain(&statics, "base_link", "laser").unwrap();
        // The mount looks along +y, so 2 m along it is (1, 2) in the base frame.
        assert!(
            (p.x - 1.0).abs() < 1e-12 && (p.y - 2.0).abs() < 1e-12,
            "{p:?}"
        );
        assert!(static_chain(&statics, "base_link", "camera").is_none());
    }
}
