//! The ROS messages the bag reader decodes, field by field as their `.msg` files define
//! them (`sensor_msgs/msg/LaserScan`, `nav_msgs/msg/Odometry`, `tf2_msgs/msg/TFMessage`),
//! in either serialisation: `cdr` (ROS 2) or `ros1` (the message encodings' names in
//! MCAP). The fields are the same in ROS 1 and ROS 2 but for the header's `seq` and the
//! stamp's signedness, which [`Wire::header_stamp`] handles. Only the fields the reader uses
//! are kept; the others are read past.

use super::cdr::Cdr;
use super::wire::{DecodeError, Ros1, Wire};
use slam_models::Pose2;

/// `sensor_msgs/msg/LaserScan`.
pub(crate) const LASER_SCAN: &str = "sensor_msgs/msg/LaserScan";
/// `nav_msgs/msg/Odometry`.
pub(crate) const ODOMETRY: &str = "nav_msgs/msg/Odometry";
/// `sensor_msgs/msg/Imu`.
pub(crate) const IMU: &str = "sensor_msgs/msg/Imu";
/// `tf2_msgs/msg/TFMessage`.
pub(crate) const TF_MESSAGE: &str = "tf2_msgs/msg/TFMessage";
/// ROS 1's older `tf/tfMessage`, the same fields as `tf2_msgs/TFMessage` (many ROS 1 bags
/// record `/tf` with it).
const TF_MESSAGE_ROS1: &str = "tf/msg/tfMessage";

/// The message encodings decoded: CDR (ROS 2) and ROS 1 serialisation.
pub(crate) const ENCODINGS: [&str; 2] = ["cdr", "ros1"];

/// True for the transform message types (`tf2_msgs/msg/TFMessage`, ROS 1's `tf/tfMessage`).
pub(crate) fn is_tf_message(msg_type: &str) -> bool {
    msg_type == TF_MESSAGE || msg_type == TF_MESSAGE_ROS1
}

/// The MD5 sum ROS 1 gives each message definition (`gendeps --md5`, recorded in every
/// ROS 1 connection): a bag whose sum differs holds another definition under the same name.
pub(crate) fn ros1_md5(msg_type: &str) -> Option<&'static str> {
    match msg_type {
        LASER_SCAN => Some("90c7ef2dc6895d81024acba2ac42f369"),
        ODOMETRY => Some("cd5e73d190d741a2f92e81eda573aca7"),
        IMU => Some("6a62c6daae103f4ff57a132d6f95cec2"),
        TF_MESSAGE | TF_MESSAGE_ROS1 => Some("94810edda583a504dfda3829e70d7eec"),
        _ => None,
    }
}

/// Runs `decode` on `data` in the serialisation `encoding` names (one of [`ENCODINGS`]).
fn decode<T>(
    encoding: &str,
    data: &[u8],
    decode: impl FnOnce(&mut dyn Wire) -> Result<T, DecodeError>,
) -> Result<T, DecodeError> {
    match encoding {
        "cdr" => decode(&mut Cdr::new(data)?),
        "ros1" => decode(&mut Ros1::new(data)),
        other => Err(DecodeError {
            offset: 0,
            what: format!("a message encoding of {ENCODINGS:?}, found {other:?}"),
            wire: "message",
        }),
    }
}

/// `std_msgs/msg/Header`: the stamp in nanoseconds since the epoch and the frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Header {
    /// The stamp, nanoseconds since the epoch.
    pub stamp_ns: i64,
    /// The frame (`frame_id`).
    pub frame_id: String,
}

fn header(c: &mut dyn Wire) -> Result<Header, DecodeError> {
    let stamp_ns = c.header_stamp()?;
    let frame_id = c.string("header.frame_id")?;
    Ok(Header { stamp_ns, frame_id })
}

/// The laser scan as the message holds it (ranges widened to f64; NaN and ±∞ kept).
#[derive(Debug, Clone, PartialEq)]
pub struct ScanMsg {
    /// The header.
    pub header: Header,
    /// Angle of the first beam, radians (counter-clockwise from the frame's x axis).
    pub angle_min: f64,
    /// Angle of the last beam, radians.
    pub angle_max: f64,
    /// Angle between beams, radians.
    pub angle_increment: f64,
    /// Readings below it are invalid, metres.
    pub range_min: f64,
    /// Readings above it are invalid (no return), metres.
    pub range_max: f64,
    /// The readings, metres.
    pub ranges: Vec<f64>,
}

/// Decodes a `sensor_msgs/msg/LaserScan` serialised as `encoding` says.
pub fn laser_scan(encoding: &str, data: &[u8]) -> Result<ScanMsg, DecodeError> {
    decode(encoding, data, laser_scan_fields)
}

fn laser_scan_fields(c: &mut dyn Wire) -> Result<ScanMsg, DecodeError> {
    let header = header(c)?;
    let angle_min = c.f32("angle_min")?;
    let angle_max = c.f32("angle_max")?;
    let angle_increment = c.f32("angle_increment")?;
    c.f32("time_increment")?;
    c.f32("scan_time")?;
    let range_min = c.f32("range_min")?;
    let range_max = c.f32("range_max")?;
    let ranges = c.seq_f32("ranges")?;
    // Intensities are not used; their count is still checked.
    c.seq_f32("intensities")?;
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
pub struct StampedPose {
    /// The stamp, nanoseconds since the epoch.
    pub stamp_ns: i64,
    /// The parent frame (`header.frame_id`).
    pub parent: String,
    /// The child frame (`child_frame_id`).
    pub child: String,
    /// The child's planar pose in the parent frame (the quaternion's yaw).
    pub pose: Pose2,
}

/// The planar part of a 3-D pose: x, y and the yaw of the quaternion (x, y, z, w),
/// ψ = atan2(2(wz + xy), w² + x² − y² − z²) (the Z-Y-X Euler yaw, which for a unit
/// quaternion is the usual atan2(2(wz + xy), 1 − 2(y² + z²)); unchanged by the quaternion's
/// scale). A quaternion of zero length, or a non-finite one, is an error.
fn planar(c: &mut dyn Wire, what: &str) -> Result<Pose2, DecodeError> {
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
pub fn odometry(encoding: &str, data: &[u8]) -> Result<StampedPose, DecodeError> {
    decode(encoding, data, odometry_fields)
}

fn odometry_fields(c: &mut dyn Wire) -> Result<StampedPose, DecodeError> {
    let h = header(c)?;
    let child = c.string("child_frame_id")?;
    let pose = planar(c, "pose.pose.position")?;
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
pub fn tf_message(encoding: &str, data: &[u8]) -> Result<Vec<StampedPose>, DecodeError> {
    decode(encoding, data, tf_fields)
}

fn tf_fields(c: &mut dyn Wire) -> Result<Vec<StampedPose>, DecodeError> {
    // A TransformStamped takes at least 8 (stamp) + 2·4 (strings) + 7·8 bytes.
    let n = c.count("transforms", 72)?;
    let mut out = Vec::with_capacity(n);
    for _ in 0..n {
        let h = header(c)?;
        let child = c.string("child_frame_id")?;
        let pose = planar(c, "transform.translation")?;
        out.push(StampedPose {
            stamp_ns: h.stamp_ns,
            parent: h.frame_id,
            child,
            pose,
        });
    }
    Ok(out)
}

/// The yaw rate of a `sensor_msgs/msg/Imu`: its stamp (ns) and `angular_velocity.z`
/// (rad/s, about the IMU frame's z axis); the orientation, covariances and linear
/// acceleration are read past.
pub(crate) fn imu_yaw_rate(encoding: &str, data: &[u8]) -> Result<(i64, f64), DecodeError> {
    decode(encoding, data, |c| {
        let h = header(c)?;
        c.skip_f64s(4, "orientation")?;
        c.skip_f64s(9, "orientation_covariance")?;
        c.f64("angular_velocity.x")?;
        c.f64("angular_velocity.y")?;
        let rate = c.f64("angular_velocity.z")?;
        c.skip_f64s(9, "angular_velocity_covariance")?;
        c.skip_f64s(3, "linear_acceleration")?;
        c.skip_f64s(9, "linear_acceleration_covariance")?;
        Ok((h.stamp_ns, rate))
    })
}
