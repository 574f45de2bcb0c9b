//! The ROS 2 messages the bag reader decodes, field by field as their `.msg` files define
//! them (`sensor_msgs/msg/LaserScan`, `nav_msgs/msg/Odometry`, `tf2_msgs/msg/TFMessage`).
//! Only the fields the reader uses are kept; the others are read past.

use super::cdr::{Cdr, CdrError};
use slam_models::Pose2;

/// `sensor_msgs/msg/LaserScan`.
pub(crate) const LASER_SCAN: &str = "sensor_msgs/msg/LaserScan";
/// `nav_msgs/msg/Odometry`.
pub(crate) const ODOMETRY: &str = "nav_msgs/msg/Odometry";
/// `tf2_msgs/msg/TFMessage`.
pub(crate) const TF_MESSAGE: &str = "tf2_msgs/msg/TFMessage";

/// `std_msgs/msg/Header`: the stamp in nanoseconds since the epoch and the frame.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Header {
    pub stamp_ns: i64,
    pub frame_id: String,
}

/// `builtin_interfaces/msg/Time` (int32 sec, uint32 nanosec) as nanoseconds.
fn time(c: &mut Cdr<'_>) -> Result<i64, CdrError> {
    let sec = c.i32("header.stamp.sec")?;
    let nsec = c.u32("header.stamp.nanosec")?;
    if nsec >= 1_000_000_000 {
        return Err(c.err(format!("header.stamp.nanosec < 10^9, found {nsec}")));
    }
    Ok(i64::from(sec) * 1_000_000_000 + i64::from(nsec))
}

fn header(c: &mut Cdr<'_>) -> Result<Header, CdrError> {
    let stamp_ns = time(c)?;
    let frame_id = c.string("header.frame_id")?;
    Ok(Header { stamp_ns, frame_id })
}

/// The laser scan as the message holds it (ranges widened to f64; NaN and ±∞ kept).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct ScanMsg {
    pub header: Header,
    pub angle_min: f64,
    pub angle_max: f64,
    pub angle_increment: f64,
    pub range_min: f64,
    pub range_max: f64,
    pub ranges: Vec<f64>,
}

/// Decodes a `sensor_msgs/msg/LaserScan`.
pub(crate) fn laser_scan(data: &[u8]) -> Result<ScanMsg, CdrError> {
    let mut c = Cdr::new(data)?;
    let header = header(&mut c)?;
    let angle_min = c.f32("angle_min")?;
    let angle_max = c.f32("angle_max")?;
    let angle_increment = c.f32("angle_increment")?;
    c.f32("time_increment")?;
    c.f32("scan_time")?;
    let range_min = c.f32("range_min")?;
    let range_max = c.f32("range_max")?;
    let ranges = c.seq_f32("ranges")?;
    // Intensities are not used; their count is still checked.
    let n = c.count("intensities", 4)?;
    for _ in 0..n {
        c.f32("intensities")?;
    }
    Ok(ScanMsg {
        header,
        angle_min,
        angle_max,
        angle_increment,
        range_min,
        range_max,
        ranges,
    })
}

/// A planar pose stamped in `parent` for `child` (an odometry message or one transform).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct StampedPose {
    pub stamp_ns: i64,
    pub parent: String,
    pub child: String,
    pub pose: Pose2,
}

/// The planar part of a 3-D pose: x, y and the yaw of the quaternion (x, y, z, w),
/// ψ = atan2(2(wz + xy), w² + x² − y² − z²) (the Z-Y-X Euler yaw, which for a unit
/// quaternion is the usual atan2(2(wz + xy), 1 − 2(y² + z²)); unchanged by the quaternion's
/// scale). A quaternion of zero length, or a non-finite one, is an error.
fn planar(c: &mut Cdr<'_>, what: &str) -> Result<Pose2, CdrError> {
    let x = c.f64(&format!("{what} x"))?;
    let y = c.f64(&format!("{what} y"))?;
    c.f64(&format!("{what} z"))?;
    let (qx, qy, qz, qw) = (
        c.f64("orientation x")?,
        c.f64("orientation y")?,
        c.f64("orientation z")?,
        c.f64("orientation w")?,
    );
    let norm = (qx * qx + qy * qy + qz * qz + qw * qw).sqrt();
    if !(norm > 1e-9 && norm.is_finite()) {
        return Err(c.err(format!(
            "a rotation quaternion of non-zero length, found ({qx}, {qy}, {qz}, {qw})"
        )));
    }
    let yaw = (2.0 * (qw * qz + qx * qy)).atan2(qw * qw + qx * qx - qy * qy - qz * qz);
    Ok(Pose2::new(x, y, yaw))
}

/// Decodes a `nav_msgs/msg/Odometry` (the pose; the twist and covariances are read past).
pub(crate) fn odometry(data: &[u8]) -> Result<StampedPose, CdrError> {
    let mut c = Cdr::new(data)?;
    let h = header(&mut c)?;
    let child = c.string("child_frame_id")?;
    let pose = planar(&mut c, "pose.pose.position")?;
    c.skip_f64s(36, "pose.covariance")?;
    c.skip_f64s(6, "twist.twist")?;
    c.skip_f64s(36, "twist.covariance")?;
    Ok(StampedPose {
        stamp_ns: h.stamp_ns,
        parent: h.frame_id,
        child,
        pose,
    })
}

/// Decodes a `tf2_msgs/msg/TFMessage` into its transforms (parent = header.frame_id).
pub(crate) fn tf_message(data: &[u8]) -> Result<Vec<StampedPose>, CdrError> {
    let mut c = Cdr::new(data)?;
    // A TransformStamped takes at least 8 (stamp) + 2·4 (strings) + 7·8 bytes.
    let n = c.count("transforms", 72)?;
    let mut out = Vec::with_capacity(n);
    for _ in 0..n {
        let h = header(&mut c)?;
        let child = c.string("child_frame_id")?;
        let pose = planar(&mut c, "transform.translation")?;
        out.push(StampedPose {
            stamp_ns: h.stamp_ns,
            parent: h.frame_id,
            child,
            pose,
        });
    }
    Ok(out)
}
