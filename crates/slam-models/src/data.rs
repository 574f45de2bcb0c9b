//! The data every reader, simulator and filter exchanges.
//!
//! Readers in `slam-io` and simulators in `slam-sim` both produce a [`LandmarkDataset`] or a
//! [`ScanDataset`]; filters consume their steps. Keeping these types here, at the bottom
//! layer, means simulated and real data go through exactly the same code paths.

use crate::detmath;
use crate::error::{ensure_finite, ModelError};
use crate::{Point2, Pose2};
use serde::{Deserialize, Serialize};

/// The two kinds of data, and of the filters that take them: what a scenario simulates, a
/// dataset holds and a filter runs on. One enum for the simulator, the readers and the
/// filter factory.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum DataKind {
    /// Range-bearing observations of point landmarks ([`LandmarkDataset`],
    /// `crate::LandmarkSlam`).
    Landmark,
    /// Odometry and laser scans ([`ScanDataset`], `crate::ScanSlam`).
    Laser,
}

impl DataKind {
    /// `"landmark"` or `"laser"`.
    pub fn as_str(self) -> &'static str {
        match self {
            DataKind::Landmark => "landmark",
            DataKind::Laser => "laser",
        }
    }
}

/// Identifier of a landmark (a Freiburg `world.dat` id, an MRCLAM subject number, or one the
/// filter assigned when data association is unknown).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub struct LandmarkId(pub u32);

impl std::fmt::Display for LandmarkId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}", self.0)
    }
}

/// A velocity control (PR §5.3): forward speed `v` [m/s] and turn rate `omega` [rad/s,
/// counter-clockwise positive], held constant for `dt` seconds.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct VelocityControl {
    /// Forward speed, m/s.
    pub v: f64,
    /// Turn rate, rad/s.
    pub omega: f64,
    /// Duration, s (≥ 0).
    pub dt: f64,
}

/// An odometry increment in rotation–translation–rotation form (PR §5.4, table 5.6):
/// turn by `rot1`, drive `trans` metres straight ahead, turn by `rot2` (radians, CCW positive).
///
/// `trans` may be negative: a robot reversing is then described with small rotations
/// instead of two half-turns (see [`crate::motion::OdometryModel::control_from_poses`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct OdometryControl {
    /// First rotation δrot1, radians.
    pub rot1: f64,
    /// Translation δtrans, metres (negative when reversing).
    pub trans: f64,
    /// Second rotation δrot2, radians.
    pub rot2: f64,
}

/// One control input: whichever kind the robot provides.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum Control {
    /// Velocity command (v, ω) over Δt.
    Velocity(VelocityControl),
    /// Odometry increment (δrot1, δtrans, δrot2).
    Odometry(OdometryControl),
}

impl Control {
    /// Rejects NaN/∞ components and negative durations.
    pub fn validate(&self) -> Result<(), ModelError> {
        match self {
            Control::Velocity(u) => {
                ensure_finite("velocity v", u.v)?;
                ensure_finite("velocity omega", u.omega)?;
                ensure_finite("velocity dt", u.dt)?;
                if u.dt < 0.0 {
                    return Err(ModelError::OutOfRange {
                        name: "dt",
                        value: u.dt,
                        expected: "dt >= 0",
                    });
                }
            }
            Control::Odometry(u) => {
                ensure_finite("odometry rot1", u.rot1)?;
                ensure_finite("odometry trans", u.trans)?;
                ensure_finite("odometry rot2", u.rot2)?;
            }
        }
        Ok(())
    }
}

/// A range-bearing observation of a point landmark in the robot frame.
///
/// `bearing` is measured counter-clockwise from the robot heading (radians), `range` is the
/// Euclidean distance in metres. `id` is the landmark's identity when data association is
/// known, `None` when it must be inferred.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RangeBearing {
    /// Range, metres (≥ 0).
    pub range: f64,
    /// Bearing, radians, CCW from the heading.
    pub bearing: f64,
    /// Known landmark identity, if any.
    pub id: Option<LandmarkId>,
}

impl RangeBearing {
    /// A validated observation: finite values, range ≥ 0. The bearing is kept as given
    /// (innovations normalise differences).
    pub fn new(range: f64, bearing: f64, id: Option<LandmarkId>) -> Result<Self, ModelError> {
        ensure_finite("range", range)?;
        ensure_finite("bearing", bearing)?;
        if range < 0.0 {
            return Err(ModelError::NegativeRange { range });
        }
        Ok(Self { range, bearing, id })
    }

    /// As the vector z = (r, φ).
    #[inline]
    pub fn to_vector(&self) -> crate::Vector2 {
        crate::Vector2::new(self.range, self.bearing)
    }
}

/// One planar laser scan.
///
/// Beam `k` (0-based) points at `angle_min + k·angle_increment` radians, counter-clockwise
/// from the sensor's heading; the sensor sits at `sensor_pose` in the robot frame. A reading
/// `ranges[k] >= max_range` means **no return** (nothing hit within range); it is kept in
/// the data unchanged so that writers reproduce the input, and [`LaserScan::is_hit`] tells the
/// two apart.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LaserScan {
    /// Angle of beam 0, radians, relative to the sensor heading.
    pub angle_min: f64,
    /// Angle between consecutive beams, radians.
    pub angle_increment: f64,
    /// Readings, metres. Values ≥ `max_range` mean "no return".
    pub ranges: Vec<f64>,
    /// Readings at or beyond this value are "no return", metres.
    pub max_range: f64,
    /// Pose of the sensor in the robot frame (the laser offset).
    pub sensor_pose: Pose2,
}

impl LaserScan {
    /// Number of beams.
    #[inline]
    pub fn len(&self) -> usize {
        self.ranges.len()
    }

    /// True when the scan has no beams.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.ranges.is_empty()
    }

    /// Angle of beam `k` relative to the sensor heading, radians.
    #[inline]
    pub fn beam_angle(&self, k: usize) -> f64 {
        self.angle_min + k as f64 * self.angle_increment
    }

    /// True when beam `k` hit something (its reading is below `max_range`).
    #[inline]
    pub fn is_hit(&self, k: usize) -> bool {
        self.ranges[k] < self.max_range
    }

    /// The standard 180° geometry of CARMEN `FLASER` logs for `n` beams: −90° to +90°
    /// inclusive for 181/361 beams (resolution 180°/(n−1)), −90° to +90° − res for 180/360
    /// beams (resolution 180°/n), and 180°/(n−1) for any other count.
    pub fn flaser_geometry(n: usize) -> (f64, f64) {
        use std::f64::consts::PI;
        let inc = match n {
            180 | 360 => PI / n as f64,
            0 | 1 => 0.0,
            _ => PI / (n - 1) as f64,
        };
        (-PI / 2.0, inc)
    }

    /// Checks that every reading and the geometry are finite and ranges non-negative.
    pub fn validate(&self) -> Result<(), ModelError> {
        ensure_finite("scan angle_min", self.angle_min)?;
        ensure_finite("scan angle_increment", self.angle_increment)?;
        ensure_finite("scan max_range", self.max_range)?;
        for &r in &self.ranges {
            ensure_finite("scan range", r)?;
            if r < 0.0 {
                return Err(ModelError::NegativeRange { range: r });
            }
        }
        Ok(())
    }

    /// End points of the hits in the robot frame (no-return beams skipped).
    pub fn hit_points(&self) -> Vec<Point2> {
        (0..self.len())
            .filter(|&k| self.is_hit(k))
            .map(|k| {
                let a = self.beam_angle(k);
                let r = self.ranges[k];
                self.sensor_pose
                    .transform_point(&Point2::new(r * detmath::cos(a), r * detmath::sin(a)))
            })
            .collect()
    }
}

/// A pose with a timestamp (seconds, in the clock of the dataset it came from).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TimedPose {
    /// Time, seconds.
    pub t: f64,
    /// The pose.
    pub pose: Pose2,
}

/// A yaw rate with its timestamp: the angular velocity about the vertical axis of the
/// robot's base frame (a `sensor_msgs/Imu`'s `angular_velocity.z` in that frame),
/// counter-clockwise positive, rad/s; the time in seconds, in the clock of the dataset it
/// goes with.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct YawRate {
    /// Time, seconds.
    pub t: f64,
    /// ω_z, rad/s.
    pub rate: f64,
}

/// One step of a landmark dataset: the control that moves the robot from the previous step
/// to this one, then the observations taken after that motion (Freiburg convention).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LandmarkStep {
    /// Time of the step, seconds (the step index when the data has no clock).
    pub t: f64,
    /// The motion since the previous step.
    pub control: Control,
    /// Observations taken after the motion.
    pub observations: Vec<RangeBearing>,
}

/// A whole landmark dataset, real or simulated.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct LandmarkDataset {
    /// Short name (for output folders and reports).
    pub name: String,
    /// The robot's initial pose (the world frame's origin for most datasets).
    pub initial_pose: Pose2,
    /// The steps in time order.
    pub steps: Vec<LandmarkStep>,
    /// True landmark positions, where known.
    pub landmarks: Option<Vec<(LandmarkId, Point2)>>,
    /// True robot trajectory, where known (times need not match the steps one to one).
    pub ground_truth: Option<Vec<TimedPose>>,
}

/// One record of a laser dataset: an odometry reading, with a scan when one was taken at
/// that time. Odometry is the robot's raw odometry pose (its own dead-reckoned frame), as
/// in CARMEN `ODOM` and `FLASER` lines; filters use the increment between records.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ScanRecord {
    /// Time, seconds.
    pub t: f64,
    /// Odometry pose at time `t`.
    pub odometry: Pose2,
    /// The scan taken at `t`, if any.
    pub scan: Option<LaserScan>,
}

/// A whole laser dataset, real or simulated.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct ScanDataset {
    /// Short name.
    pub name: String,
    /// Records in file order (times may repeat or step back slightly; keep the order).
    pub records: Vec<ScanRecord>,
    /// Ground-truth or reference trajectory, where known.
    pub ground_truth: Option<Vec<TimedPose>>,
}
