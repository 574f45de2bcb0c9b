//! What a scan filter's state looks like as ROS 2 messages: one place that builds them, for
//! the DDS node (`slam ros2`) and the Foxglove live view (`--live`) alike.
//!
//! | output | type | content |
//! | --- | --- | --- |
//! | [`Out::Map`] | `nav_msgs/msg/OccupancyGrid` | the filter's best map, frame `map` |
//! | [`Out::Tf`] | `tf2_msgs/msg/TFMessage` | `map → odom` = estimate ∘ odometry⁻¹ (and, for a view of a file, `odom → base_link`, the odometry) |
//! | [`Out::TfStatic`] | `tf2_msgs/msg/TFMessage` | `base_link → laser` (the scan's sensor pose) |
//! | [`Out::Pose`] | `geometry_msgs/msg/PoseWithCovarianceStamped` | the estimate in `map`, with the particle cloud's covariance (zero for a filter without one) |
//! | [`Out::Trajectory`] | `nav_msgs/msg/Path` | the filter's best trajectory, each pose at its scan's stamp |
//! | [`Out::Particles`] | `geometry_msgs/msg/PoseArray` | the particles, for particle filters |
//! | [`Out::Scan`] | `sensor_msgs/msg/LaserScan` | the scan just processed, frame `laser` |

use crate::convert::cloud_covariance;
use slam_io::ros_msg::{self, Stamp, Transform};
use slam_models::{LaserScan, Pose2, ScanSlam};

/// One output stream.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Out {
    /// The occupancy grid.
    Map,
    /// `map → odom` (and `odom → base` in a view of a file).
    Tf,
    /// `base → laser`.
    TfStatic,
    /// The pose estimate with its covariance.
    Pose,
    /// The best trajectory.
    Trajectory,
    /// The particle cloud.
    Particles,
    /// The scan.
    Scan,
}

impl Out {
    /// Every output.
    pub const ALL: [Out; 7] = [
        Out::Map,
        Out::Tf,
        Out::TfStatic,
        Out::Pose,
        Out::Trajectory,
        Out::Particles,
        Out::Scan,
    ];

    /// The ROS 2 message type, `pkg/msg/Type`.
    pub fn ros_type(self) -> &'static str {
        match self {
            Out::Map => "nav_msgs/msg/OccupancyGrid",
            Out::Tf | Out::TfStatic => "tf2_msgs/msg/TFMessage",
            Out::Pose => "geometry_msgs/msg/PoseWithCovarianceStamped",
            Out::Trajectory => "nav_msgs/msg/Path",
            Out::Particles => "geometry_msgs/msg/PoseArray",
            Out::Scan => "sensor_msgs/msg/LaserScan",
        }
    }

    /// The default topic (REP 105 / the ROS conventions: `/map`, `/tf`, `/tf_static`, …).
    pub fn default_topic(self) -> &'static str {
        match self {
            Out::Map => "/map",
            Out::Tf => "/tf",
            Out::TfStatic => "/tf_static",
            Out::Pose => "/pose",
            Out::Trajectory => "/trajectory",
            Out::Particles => "/particles",
            Out::Scan => "/scan",
        }
    }
}

/// The frame names (REP 105 defaults: `map`, `odom`, `base_link`, `laser`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Frames {
    /// The world frame of the estimate and the map.
    pub map: String,
    /// The odometry frame.
    pub odom: String,
    /// The robot's base frame.
    pub base: String,
    /// The laser's frame (scans republished in a view of a file).
    pub laser: String,
}

impl Default for Frames {
    fn default() -> Self {
        Frames {
            map: "map".into(),
            odom: "odom".into(),
            base: "base_link".into(),
            laser: "laser".into(),
        }
    }
}

/// Which outputs a step produces besides `Tf` and `Pose` (always) and `Particles` (particle
/// filters).
#[derive(Debug, Clone, Copy, Default)]
pub struct Include<'a> {
    /// The map (costly: the filter renders it).
    pub map: bool,
    /// The trajectory (its length grows with the run).
    pub trajectory: bool,
    /// `odom → base` in `/tf`, for a view without a robot that publishes it.
    pub odom_tf: bool,
    /// The scan, republished in the laser frame with `base → laser` on `/tf_static`.
    pub scan: Option<&'a LaserScan>,
}

/// `map → odom`: the transform that puts the odometry's base pose `odom` on the estimate
/// `pose`, T_map_odom = T_map_base · T_odom_base⁻¹.
pub fn map_to_odom(pose: &Pose2, odom: &Pose2) -> Pose2 {
    slam_io::mcap_out::map_to_odom(pose, odom)
}

/// The messages of the filter's state after a scan stamped `stamp` whose odometry was
/// `odom`, in the order they should go out (the transforms first).
pub fn step_messages(
    stamp: Stamp,
    filter: &dyn ScanSlam,
    odom: &Pose2,
    frames: &Frames,
    include: Include<'_>,
) -> Vec<(Out, Vec<u8>)> {
    let pose = filter.pose();
    let mut out = Vec::with_capacity(7);
    if let Some(scan) = include.scan {
        out.push((
            Out::TfStatic,
            ros_msg::encode_tf_message(&[Transform {
                stamp,
                parent: &frames.base,
                child: &frames.laser,
                pose: scan.sensor_pose,
            }]),
        ));
    }
    let correction = map_to_odom(&pose, odom);
    let mut tf = vec![Transform {
        stamp,
        parent: &frames.map,
        child: &frames.odom,
        pose: correction,
    }];
    if include.odom_tf {
        tf.push(Transform {
            stamp,
            parent: &frames.odom,
            child: &frames.base,
            pose: *odom,
        });
    }
    out.push((Out::Tf, ros_msg::encode_tf_message(&tf)));
    let cloud = filter.particles();
    let cov = cloud
        .as_deref()
        .and_then(cloud_covariance)
        .unwrap_or([[0.0; 3]; 3]);
    out.push((
        Out::Pose,
        ros_msg::encode_pose_with_covariance(stamp, &frames.map, &pose, &cov),
    ));
    if let Some(cloud) = &cloud {
        let poses: Vec<Pose2> = cloud.iter().map(|p| p.pose).collect();
        out.push((
            Out::Particles,
            ros_msg::encode_pose_array(stamp, &frames.map, &poses),
        ));
    }
    if let Some(scan) = include.scan {
        out.push((
            Out::Scan,
            ros_msg::encode_laser_scan(stamp, &frames.laser, scan),
        ));
    }
    if include.trajectory {
        out.push((Out::Trajectory, trajectory_message(stamp, filter, frames)));
    }
    if include.map {
        out.push((
            Out::Map,
            ros_msg::encode_occupancy_grid(stamp, &frames.map, &filter.map()),
        ));
    }
    out
}

/// The filter's trajectory as a `nav_msgs/Path` in the map frame, each pose at its own
/// stamp (a pose whose time has no `builtin_interfaces/Time` is left out).
pub fn trajectory_message(stamp: Stamp, filter: &dyn ScanSlam, frames: &Frames) -> Vec<u8> {
    path_message(stamp, &filter.trajectory(), frames)
}

/// `nav_msgs/Path` of `trajectory` in the map frame, each pose at its own time (poses at a
/// time outside `builtin_interfaces/Time`'s range are left out).
pub fn path_message(
    stamp: Stamp,
    trajectory: &[slam_models::TimedPose],
    frames: &Frames,
) -> Vec<u8> {
    let path: Vec<(Stamp, Pose2)> = trajectory
        .iter()
        .filter_map(|p| Some((ros_msg::stamp(p.t)?, p.pose)))
        .collect();
    ros_msg::encode_path(stamp, &frames.map, &path)
}
