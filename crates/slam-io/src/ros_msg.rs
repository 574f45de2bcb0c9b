//! ROS 2 messages as CDR bytes, for a live node and a live view (the `slam-ros` crate): the
//! encoders of the MCAP run writer ([`crate::mcap_out`]) and the decoders of the bag reader
//! ([`crate::rosbag`]), one implementation each, re-exported here.
//!
//! Every encoded message is OMG CDR (XCDR version 1, little endian) with its 4-byte
//! encapsulation header `00 01 00 00`, the form DDS puts in a sample's serialized payload and
//! MCAP/Foxglove call `cdr`. The decoders take the same bytes (header included) and check
//! every count against the bytes left before allocating.
//!
//! Types are named `pkg/msg/Type`; [`dds_type_name`] gives the DDS name ROS 2's middlewares
//! register (`sensor_msgs::msg::dds_::LaserScan_`).

pub use crate::mcap_out::msgs::{
    laser_scan as encode_laser_scan, occupancy_grid as encode_occupancy_grid, path as encode_path,
    pose_array as encode_pose_array, pose_with_covariance as encode_pose_with_covariance, schema,
    tf_message as encode_tf_message, Stamp, Transform,
};
pub use crate::rosbag::msgs::{Header, ScanMsg, StampedPose};
pub use crate::rosbag::wire::DecodeError;

/// `builtin_interfaces/msg/Time` of `t` seconds (⌊t⌋ and the nearest nanosecond); `None` when
/// `t` is not finite or outside [0, 2³¹) s.
pub fn stamp(t: f64) -> Option<Stamp> {
    crate::mcap_out::stamp_of(t)
}

/// Decodes a CDR `sensor_msgs/msg/LaserScan` (ranges widened to `f64`, NaN and ±∞ kept).
pub fn decode_laser_scan(data: &[u8]) -> Result<ScanMsg, DecodeError> {
    crate::rosbag::msgs::laser_scan("cdr", data)
}

/// Decodes a CDR `nav_msgs/msg/Odometry`: its stamp, frames and the planar pose (the yaw of
/// the quaternion); the twist and covariances are read past.
pub fn decode_odometry(data: &[u8]) -> Result<StampedPose, DecodeError> {
    crate::rosbag::msgs::odometry("cdr", data)
}

/// Decodes a CDR `tf2_msgs/msg/TFMessage` into its planar transforms.
pub fn decode_tf_message(data: &[u8]) -> Result<Vec<StampedPose>, DecodeError> {
    crate::rosbag::msgs::tf_message("cdr", data)
}

/// Decodes a CDR `rosgraph_msgs/msg/Clock` (one `builtin_interfaces/Time`): nanoseconds
/// since the epoch.
pub fn decode_clock(data: &[u8]) -> Result<i64, DecodeError> {
    let mut c = crate::rosbag::cdr::Cdr::new(data)?;
    use crate::rosbag::wire::Wire as _;
    c.header_stamp()
}

/// Decodes a CDR `std_msgs/msg/String`.
pub fn decode_string(data: &[u8]) -> Result<String, DecodeError> {
    let mut c = crate::rosbag::cdr::Cdr::new(data)?;
    use crate::rosbag::wire::Wire as _;
    c.string("data")
}

/// The DDS type name ROS 2 registers for `pkg/msg/Type`: `pkg::msg::dds_::Type_` (the
/// rmw implementations' mangling, e.g. `sensor_msgs::msg::dds_::LaserScan_`).
pub fn dds_type_name(ros_type: &str) -> String {
    let mut parts: Vec<&str> = ros_type.split('/').collect();
    let name = parts.pop().unwrap_or_default();
    format!("{}::dds_::{}_", parts.join("::"), name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dds_names_follow_the_rmw_mangling() {
        assert_eq!(
            dds_type_name("sensor_msgs/msg/LaserScan"),
            "sensor_msgs::msg::dds_::LaserScan_"
        );
        assert_eq!(
            dds_type_name("tf2_msgs/msg/TFMessage"),
            "tf2_msgs::msg::dds_::TFMessage_"
        );
    }

    /// `builtin_interfaces/Time` {sec 7, nanosec 5} after the CDR LE header: two `uint32`s.
    #[test]
    fn clock_decodes_the_bytes_of_the_spec() {
        let bytes = [0, 1, 0, 0, 7, 0, 0, 0, 5, 0, 0, 0];
        assert_eq!(decode_clock(&bytes).unwrap(), 7_000_000_005);
        assert!(decode_clock(&bytes[..8]).is_err());
    }

    /// A `TFMessage` of one `map → odom` transform, laid out by hand from the CDR rules
    /// (XCDR1 LE, alignment from the body's start): count 1 at 0, stamp at 4 and 8, the
    /// frame "map" (length 4 with its NUL) at 12, "odom" (length 5) at 20, padding from 29 to
    /// 32, then translation x, y, z and rotation x, y, z, w as `float64` at 32 … 88.
    #[test]
    fn tf_message_bytes_follow_the_cdr_rules() {
        let pose = slam_models::Pose2::new(1.5, -2.0, std::f64::consts::FRAC_PI_2);
        let bytes = encode_tf_message(&[Transform {
            stamp: Stamp { sec: 7, nanosec: 9 },
            parent: "map",
            child: "odom",
            pose,
        }]);
        assert_eq!(bytes.len(), 4 + 88);
        let b = &bytes[4..];
        let u32_at = |o: usize| u32::from_le_bytes(b[o..o + 4].try_into().unwrap());
        let f64_at = |o: usize| f64::from_le_bytes(b[o..o + 8].try_into().unwrap());
        assert_eq!(&bytes[..4], &[0, 1, 0, 0]);
        assert_eq!((u32_at(0), u32_at(4), u32_at(8)), (1, 7, 9));
        assert_eq!((u32_at(12), &b[16..20]), (4, &b"map\0"[..]));
        assert_eq!((u32_at(20), &b[24..29]), (5, &b"odom\0"[..]));
        assert_eq!(&b[29..32], &[0, 0, 0]);
        assert_eq!((f64_at(32), f64_at(40), f64_at(48)), (1.5, -2.0, 0.0));
        let half = std::f64::consts::FRAC_PI_4;
        assert_eq!((f64_at(56), f64_at(64)), (0.0, 0.0));
        assert!((f64_at(72) - half.sin()).abs() < 1e-15 && (f64_at(80) - half.cos()).abs() < 1e-15);
        // And the bag reader's decoder reads it back.
        let back = decode_tf_message(&bytes).unwrap();
        assert_eq!(
            (back[0].parent.as_str(), back[0].child.as_str()),
            ("map", "odom")
        );
        assert!((back[0].pose.theta - pose.theta).abs() < 1e-12);
    }

    /// `PoseWithCovarianceStamped`: header (stamp, "map"), then 7 `float64` of the pose at
    /// body offset 16, then the 6×6 covariance with (x, y, yaw) at rows/columns 0, 1, 5.
    #[test]
    fn pose_with_covariance_puts_the_planar_entries_at_x_y_yaw() {
        let cov = [[1.0, 2.0, 3.0], [4.0, 5.0, 6.0], [7.0, 8.0, 9.0]];
        let bytes = encode_pose_with_covariance(
            Stamp { sec: 0, nanosec: 0 },
            "map",
            &slam_models::Pose2::new(0.0, 0.0, 0.0),
            &cov,
        );
        let b = &bytes[4..];
        // 8 (stamp) + 4 + 4 ("map\0") = 16, already 8-aligned; 7 f64 → 72; 36 f64 → 360.
        assert_eq!(b.len(), 16 + 56 + 288);
        let c = |i: usize, j: usize| {
            let o = 72 + 8 * (6 * i + j);
            f64::from_le_bytes(b[o..o + 8].try_into().unwrap())
        };
        assert_eq!((c(0, 0), c(0, 1), c(0, 5)), (1.0, 2.0, 3.0));
        assert_eq!((c(1, 0), c(5, 5), c(5, 1)), (4.0, 9.0, 8.0));
        assert_eq!((c(2, 2), c(3, 0), c(0, 4)), (0.0, 0.0, 0.0));
    }

    /// `std_msgs/String` "ab": length 3 (with the NUL), bytes, NUL.
    #[test]
    fn string_decodes_the_bytes_of_the_spec() {
        let bytes = [0, 1, 0, 0, 3, 0, 0, 0, b'a', b'b', 0];
        assert_eq!(decode_string(&bytes).unwrap(), "ab");
    }
}
