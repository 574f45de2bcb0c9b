//! From ROS messages to the filters' vocabulary: a `sensor_msgs/LaserScan` to a
//! [`LaserScan`], odometry looked up at a scan's stamp, the laser's mounting from
//! `/tf_static`, and a pose cloud's mean and covariance for `/pose`.

use slam_io::ros_msg::{ScanMsg, StampedPose};
use slam_models::angle::angle_diff;
use slam_models::{normalize_angle, LaserScan, Pose2, WeightedPose};
use std::collections::VecDeque;

/// Seconds of a stamp in nanoseconds since the epoch.
pub fn secs(ns: i64) -> f64 {
    ns as f64 * 1e-9
}

/// The filter's scan of a ROS scan taken by a sensor at `sensor_pose` in the robot frame.
///
/// ROS (REP 117): a reading that is NaN, ±∞ or below `range_min` is not a measurement; above
/// `range_max` it is no return. Both become `range_max` (no return: the filters' rule is
/// `r ≥ max_range`); the other readings are kept as they are, so a reading above
/// `range_max` also stays no return. Beam k is at `angle_min + k·angle_increment`.
pub fn scan_from_msg(msg: &ScanMsg, sensor_pose: Pose2) -> LaserScan {
    let max_range = msg.range_max;
    let ranges = msg
        .ranges
        .iter()
        .map(|&r| {
            if r.is_finite() && r >= msg.range_min {
                r
            } else {
                max_range
            }
        })
        .collect();
    LaserScan {
        angle_min: msg.angle_min,
        angle_increment: msg.angle_increment,
        ranges,
        max_range,
        sensor_pose,
    }
}

/// What the odometry says at a stamp.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum OdomAt {
    /// A pose at the stamp: a message's own, or interpolated between the two around it.
    Pose(Pose2),
    /// The stamp is after the newest odometry (it may still come); the newest pose.
    Ahead(Pose2),
    /// No odometry at all yet, or the stamp is before the oldest kept.
    Missing,
}

/// The last odometry poses (`odom → base`), oldest first, at most `capacity` of them.
#[derive(Debug, Clone)]
pub struct OdomBuffer {
    poses: VecDeque<(i64, Pose2)>,
    capacity: usize,
}

impl OdomBuffer {
    /// An empty buffer keeping at most `capacity` (≥ 2) poses.
    pub fn new(capacity: usize) -> Self {
        OdomBuffer {
            poses: VecDeque::with_capacity(capacity.max(2)),
            capacity: capacity.max(2),
        }
    }

    /// Adds a pose stamped `ns`; one older than the newest is put in stamp order, one at the
    /// newest's stamp replaces it.
    pub fn push(&mut self, ns: i64, pose: Pose2) {
        let at = self.poses.partition_point(|(t, _)| *t <= ns);
        if at > 0 && self.poses[at - 1].0 == ns {
            self.poses[at - 1].1 = pose;
            return;
        }
        self.poses.insert(at, (ns, pose));
        while self.poses.len() > self.capacity {
            self.poses.pop_front();
        }
    }

    /// The pose at `ns`: linear in x, y and the wrapped heading difference between the two
    /// poses around it (`p = a + s·(b − a)`, `s = (ns − t_a)/(t_b − t_a)`).
    pub fn at(&self, ns: i64) -> OdomAt {
        let (Some(first), Some(last)) = (self.poses.front(), self.poses.back()) else {
            return OdomAt::Missing;
        };
        if ns > last.0 {
            return OdomAt::Ahead(last.1);
        }
        if ns < first.0 {
            return OdomAt::Missing;
        }
        let i = self.poses.partition_point(|(t, _)| *t < ns);
        let (tb, b) = self.poses[i];
        if tb == ns || i == 0 {
            return OdomAt::Pose(b);
        }
        let (ta, a) = self.poses[i - 1];
        let s = (ns - ta) as f64 / (tb - ta) as f64;
        OdomAt::Pose(Pose2::new(
            a.x + s * (b.x - a.x),
            a.y + s * (b.y - a.y),
            normalize_angle(a.theta + s * angle_diff(b.theta, a.theta)),
        ))
    }

    /// Poses kept.
    pub fn len(&self) -> usize {
        self.poses.len()
    }

    /// True when no pose is kept.
    pub fn is_empty(&self) -> bool {
        self.poses.is_empty()
    }
}

/// The static transforms (`/tf_static`): each child frame's parent and pose in it.
#[derive(Debug, Clone, Default)]
pub struct StaticTf {
    edges: Vec<(String, String, Pose2)>,
}

impl StaticTf {
    /// Adds or replaces the transform of `t.child`.
    pub fn insert(&mut self, t: StampedPose) {
        self.edges.retain(|(_, child, _)| *child != t.child);
        self.edges.push((t.parent, t.child, t.pose));
    }

    /// The pose of `frame` in `base`, following parents up from `frame` (at most 16 links);
    /// identity when they are the same frame, `None` when `frame` does not reach `base`.
    pub fn pose_in(&self, base: &str, frame: &str) -> Option<Pose2> {
        let mut pose = Pose2::IDENTITY;
        let mut at = frame;
        for _ in 0..16 {
            if at == base {
                return Some(pose);
            }
            let (parent, _, p) = self.edges.iter().find(|(_, c, _)| c == at)?;
            pose = p.compose(&pose);
            at = parent;
        }
        None
    }
}

/// The weighted mean and the 3×3 covariance over (x, y, θ) of a particle cloud (weights
/// normalised here; the heading mean is the circular mean atan2(Σ wᵢ sin θᵢ, Σ wᵢ cos θᵢ)
/// and the heading deviations are wrapped to (−π, π]). `None` for an empty cloud or zero
/// total weight.
pub fn cloud_covariance(cloud: &[WeightedPose]) -> Option<[[f64; 3]; 3]> {
    let total: f64 = cloud.iter().map(|p| p.weight).sum();
    if cloud.is_empty() || !(total > 0.0 && total.is_finite()) {
        return None;
    }
    let (mut mx, mut my, mut s, mut c) = (0.0, 0.0, 0.0, 0.0);
    for p in cloud {
        let w = p.weight / total;
        mx += w * p.pose.x;
        my += w * p.pose.y;
        s += w * p.pose.theta.sin();
        c += w * p.pose.theta.cos();
    }
    let mt = s.atan2(c);
    let mut cov = [[0.0; 3]; 3];
    for p in cloud {
        let w = p.weight / total;
        let d = [p.pose.x - mx, p.pose.y - my, angle_diff(p.pose.theta, mt)];
        for i in 0..3 {
            for j in 0..3 {
                cov[i][j] += w * d[i] * d[j];
            }
        }
    }
    Some(cov)
}

#[cfg(test)]
mod tests {
    use super::*;
    use slam_io::ros_msg::Header;

    fn msg(ranges: Vec<f64>) -> ScanMsg {
        ScanMsg {
            header: Header {
                stamp_ns: 0,
                frame_id: "laser".into(),
            },
            angle_min: -1.0,
            angle_max: 1.0,
            angle_increment: 0.5,
            range_min: 0.1,
            range_max: 10.0,
            ranges,
        }
    }

    #[test]
    fn invalid_readings_become_no_return() {
        let s = scan_from_msg(
            &msg(vec![1.0, f64::NAN, f64::INFINITY, 0.05, 12.0]),
            Pose2::new(0.1, 0.0, 0.0),
        );
        assert_eq!(s.ranges, vec![1.0, 10.0, 10.0, 10.0, 12.0]);
        assert!(s.is_hit(0));
        assert!((1..5).all(|k| !s.is_hit(k)));
        assert_eq!(s.beam_angle(4), 1.0);
        assert_eq!(s.sensor_pose, Pose2::new(0.1, 0.0, 0.0));
    }

    #[test]
    fn odometry_is_interpolated_across_the_heading_wrap() {
        let mut b = OdomBuffer::new(3);
        assert_eq!(b.at(5), OdomAt::Missing);
        b.push(10, Pose2::new(0.0, 0.0, 3.0));
        b.push(20, Pose2::new(1.0, 2.0, -3.0));
        // Half way from 3.0 to −3.0 the short way round (through π): 3.0 + 0.5·(2π − 6).
        match b.at(15) {
            OdomAt::Pose(p) => {
                assert!((p.x - 0.5).abs() < 1e-12 && (p.y - 1.0).abs() < 1e-12);
                let expect = normalize_angle(3.0 + 0.5 * (2.0 * std::f64::consts::PI - 6.0));
                assert!((p.theta - expect).abs() < 1e-12, "{}", p.theta);
            }
            other => panic!("{other:?}"),
        }
        assert_eq!(b.at(20), OdomAt::Pose(Pose2::new(1.0, 2.0, -3.0)));
        assert_eq!(b.at(21), OdomAt::Ahead(Pose2::new(1.0, 2.0, -3.0)));
        // Out of order, then past the capacity: the oldest goes.
        b.push(5, Pose2::IDENTITY);
        b.push(30, Pose2::IDENTITY);
        assert_eq!(b.len(), 3);
        assert_eq!(b.at(5), OdomAt::Missing);
    }

    #[test]
    fn static_transforms_chain_up_to_the_base() {
        let mut tf = StaticTf::default();
        let edge = |parent: &str, child: &str, pose| StampedPose {
            stamp_ns: 0,
            parent: parent.into(),
            child: child.into(),
            pose,
        };
        tf.insert(edge(
            "base_link",
            "mount",
            Pose2::new(1.0, 0.0, std::f64::consts::FRAC_PI_2),
        ));
        tf.insert(edge("mount", "laser", Pose2::new(1.0, 0.0, 0.0)));
        let p = tf.pose_in("base_link", "laser").unwrap();
        // One metre ahead, then one metre along the mount's x, which points along base y.
        assert!((p.x - 1.0).abs() < 1e-12 && (p.y - 1.0).abs() < 1e-12);
        assert_eq!(tf.pose_in("base_link", "base_link"), Some(Pose2::IDENTITY));
        assert_eq!(tf.pose_in("base_link", "camera"), None);
    }

    #[test]
    fn cloud_covariance_of_two_particles() {
        let cloud = [
            WeightedPose {
                pose: Pose2::new(1.0, 0.0, 0.1),
                weight: 1.0,
            },
            WeightedPose {
                pose: Pose2::new(-1.0, 0.0, -0.1),
                weight: 1.0,
            },
        ];
        let c = cloud_covariance(&cloud).unwrap();
        assert!((c[0][0] - 1.0).abs() < 1e-12);
        assert!((c[2][2] - 0.01).abs() < 1e-12);
        assert!((c[0][2] - 0.1).abs() < 1e-12);
        assert_eq!(c[1][1], 0.0);
        assert!(cloud_covariance(&[]).is_none());
    }
}
