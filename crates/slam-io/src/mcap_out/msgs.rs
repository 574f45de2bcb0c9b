//! The ROS 2 messages the run writer emits: their `.msg` definitions (the `ros2msg` schema
//! text an MCAP reader decodes with) and their CDR encoders, field by field in the order
//! the definitions give (ROS 2 Humble to Jazzy; the message types used have not changed
//! between them).
//!
//! A schema is the message's own definition followed, for every type it uses (transitively,
//! each once), by a line of 80 `=`, the line `MSG: pkg/Type` and that type's definition:
//! the concatenated form rosbag2 and the `rosbags` package write and Foxglove, `mcap-ros2`
//! and `ros2 bag play` read. Field types are written fully qualified (`std_msgs/Header`).

use super::cdr_write::CdrWriter;
use slam_models::{GridMap, LaserScan, Pose2};

/// The definitions, as `pkg/msg/Type` and the `.msg` text with fully qualified field types
/// (the constants of `visualization_msgs/Marker` kept; comments left out).
const DEFINITIONS: &[(&str, &str)] = &[
    ("builtin_interfaces/msg/Time", "int32 sec\nuint32 nanosec\n"),
    (
        "builtin_interfaces/msg/Duration",
        "int32 sec\nuint32 nanosec\n",
    ),
    (
        "std_msgs/msg/Header",
        "builtin_interfaces/Time stamp\nstring frame_id\n",
    ),
    (
        "std_msgs/msg/ColorRGBA",
        "float32 r\nfloat32 g\nfloat32 b\nfloat32 a\n",
    ),
    (
        "geometry_msgs/msg/Point",
        "float64 x\nfloat64 y\nfloat64 z\n",
    ),
    (
        "geometry_msgs/msg/Vector3",
        "float64 x\nfloat64 y\nfloat64 z\n",
    ),
    (
        "geometry_msgs/msg/Quaternion",
        "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n",
    ),
    (
        "geometry_msgs/msg/Pose",
        "geometry_msgs/Point position\ngeometry_msgs/Quaternion orientation\n",
    ),
    (
        "geometry_msgs/msg/PoseStamped",
        "std_msgs/Header header\ngeometry_msgs/Pose pose\n",
    ),
    (
        "geometry_msgs/msg/PoseWithCovariance",
        "geometry_msgs/Pose pose\nfloat64[36] covariance\n",
    ),
    (
        "geometry_msgs/msg/PoseWithCovarianceStamped",
        "std_msgs/Header header\ngeometry_msgs/PoseWithCovariance pose\n",
    ),
    (
        "geometry_msgs/msg/PoseArray",
        "std_msgs/Header header\ngeometry_msgs/Pose[] poses\n",
    ),
    (
        "geometry_msgs/msg/Transform",
        "geometry_msgs/Vector3 translation\ngeometry_msgs/Quaternion rotation\n",
    ),
    (
        "geometry_msgs/msg/TransformStamped",
        "std_msgs/Header header\nstring child_frame_id\ngeometry_msgs/Transform transform\n",
    ),
    (
        "tf2_msgs/msg/TFMessage",
        "geometry_msgs/TransformStamped[] transforms\n",
    ),
    (
        "nav_msgs/msg/MapMetaData",
        "builtin_interfaces/Time map_load_time\nfloat32 resolution\nuint32 width\n\
         uint32 height\ngeometry_msgs/Pose origin\n",
    ),
    (
        "nav_msgs/msg/OccupancyGrid",
        "std_msgs/Header header\nnav_msgs/MapMetaData info\nint8[] data\n",
    ),
    (
        "nav_msgs/msg/Path",
        "std_msgs/Header header\ngeometry_msgs/PoseStamped[] poses\n",
    ),
    (
        "sensor_msgs/msg/LaserScan",
        "std_msgs/Header header\nfloat32 angle_min\nfloat32 angle_max\n\
         float32 angle_increment\nfloat32 time_increment\nfloat32 scan_time\n\
         float32 range_min\nfloat32 range_max\nfloat32[] ranges\nfloat32[] intensities\n",
    ),
    (
        "sensor_msgs/msg/CompressedImage",
        "std_msgs/Header header\nstring format\nuint8[] data\n",
    ),
    (
        "visualization_msgs/msg/UVCoordinate",
        "float32 u\nfloat32 v\n",
    ),
    (
        "visualization_msgs/msg/MeshFile",
        "string filename\nuint8[] data\n",
    ),
    (
        "visualization_msgs/msg/Marker",
        "int32 ARROW=0\nint32 CUBE=1\nint32 SPHERE=2\nint32 CYLINDER=3\nint32 LINE_STRIP=4\n\
         int32 LINE_LIST=5\nint32 CUBE_LIST=6\nint32 SPHERE_LIST=7\nint32 POINTS=8\n\
         int32 TEXT_VIEW_FACING=9\nint32 MESH_RESOURCE=10\nint32 TRIANGLE_LIST=11\n\
         int32 ADD=0\nint32 MODIFY=0\nint32 DELETE=2\nint32 DELETEALL=3\n\
         std_msgs/Header header\nstring ns\nint32 id\nint32 type\nint32 action\n\
         geometry_msgs/Pose pose\ngeometry_msgs/Vector3 scale\nstd_msgs/ColorRGBA color\n\
         builtin_interfaces/Duration lifetime\nbool frame_locked\n\
         geometry_msgs/Point[] points\nstd_msgs/ColorRGBA[] colors\n\
         string texture_resource\nsensor_msgs/CompressedImage texture\n\
         visualization_msgs/UVCoordinate[] uv_coordinates\nstring text\n\
         string mesh_resource\nvisualization_msgs/MeshFile mesh_file\n\
         bool mesh_use_embedded_materials\n",
    ),
    (
        "visualization_msgs/msg/MarkerArray",
        "visualization_msgs/Marker[] markers\n",
    ),
];

/// `sensor_msgs/msg/LaserScan`.
pub(crate) const LASER_SCAN: &str = "sensor_msgs/msg/LaserScan";
/// `tf2_msgs/msg/TFMessage`.
pub(crate) const TF_MESSAGE: &str = "tf2_msgs/msg/TFMessage";
/// `nav_msgs/msg/OccupancyGrid`.
pub(crate) const OCCUPANCY_GRID: &str = "nav_msgs/msg/OccupancyGrid";
/// `nav_msgs/msg/Path`.
pub(crate) const PATH: &str = "nav_msgs/msg/Path";
/// `geometry_msgs/msg/PoseStamped`.
pub(crate) const POSE_STAMPED: &str = "geometry_msgs/msg/PoseStamped";
/// `geometry_msgs/msg/PoseArray`.
pub(crate) const POSE_ARRAY: &str = "geometry_msgs/msg/PoseArray";
/// `visualization_msgs/msg/MarkerArray`.
pub(crate) const MARKER_ARRAY: &str = "visualization_msgs/msg/MarkerArray";

fn definition(name: &str) -> Option<&'static str> {
    DEFINITIONS
        .iter()
        .find(|(n, _)| *n == name)
        .map(|(_, text)| *text)
}

/// The complex field types of a definition as `pkg/msg/Type` (constants and primitives
/// left out; `[]` and `[N]` stripped).
fn field_types(text: &str) -> Vec<String> {
    text.lines()
        .filter_map(|line| {
            let ty = line.split_whitespace().next()?;
            if line.contains('=') {
                return None;
            }
            let ty = ty.split('[').next().unwrap_or(ty);
            let (pkg, name) = ty.split_once('/')?;
            Some(format!("{pkg}/msg/{name}"))
        })
        .collect()
}

/// The `ros2msg` schema text of `name` (`pkg/msg/Type`): its definition, then every type
/// it uses, depth first, each once. `None` for a type not in this module's table.
pub fn schema(name: &str) -> Option<String> {
    let mut out = definition(name)?.to_string();
    let mut seen = vec![name.to_string()];
    let mut stack: Vec<String> = field_types(definition(name)?).into_iter().rev().collect();
    while let Some(ty) = stack.pop() {
        if seen.contains(&ty) {
            continue;
        }
        let text = definition(&ty)?;
        out.push_str(&"=".repeat(80));
        out.push_str("\nMSG: ");
        out.push_str(&ty.replacen("/msg/", "/", 1));
        out.push('\n');
        out.push_str(text);
        stack.extend(field_types(text).into_iter().rev());
        seen.push(ty);
    }
    Some(out)
}

/// A `builtin_interfaces/msg/Time`: whole seconds and nanoseconds (0 ≤ nanosec < 10⁹).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub struct Stamp {
    /// Whole seconds.
    pub sec: i32,
    /// Nanoseconds, 0 ≤ nanosec < 10⁹.
    pub nanosec: u32,
}

impl Stamp {
    /// Nanoseconds since the epoch (the MCAP log time); stamps are never negative here.
    /// Nanoseconds since the epoch (stamps before it count as 0 s).
    pub fn ns(self) -> u64 {
        u64::from(self.sec.max(0) as u32) * 1_000_000_000 + u64::from(self.nanosec)
    }
}

fn header(w: &mut CdrWriter, stamp: Stamp, frame: &str) {
    w.i32(stamp.sec);
    w.u32(stamp.nanosec);
    w.string(frame);
}

/// `geometry_msgs/Pose` of a planar pose: (x, y, 0) and the rotation about z by θ,
/// q = (0, 0, sin θ/2, cos θ/2).
fn pose(w: &mut CdrWriter, p: &Pose2) {
    w.f64(p.x);
    w.f64(p.y);
    w.f64(0.0);
    let (s, c) = (0.5 * p.theta).sin_cos();
    w.f64(0.0);
    w.f64(0.0);
    w.f64(s);
    w.f64(c);
}

/// `geometry_msgs/msg/PoseStamped`.
pub fn pose_stamped(stamp: Stamp, frame: &str, p: &Pose2) -> Vec<u8> {
    let mut w = CdrWriter::new();
    header(&mut w, stamp, frame);
    pose(&mut w, p);
    w.into_bytes()
}

/// `nav_msgs/msg/Path`: every pose stamped with its own time, all in `frame`; `stamp` is
/// the path's. The caller guarantees fewer than 2³² poses.
pub fn path(stamp: Stamp, frame: &str, poses: &[(Stamp, Pose2)]) -> Vec<u8> {
    let mut w = CdrWriter::new();
    header(&mut w, stamp, frame);
    w.count(poses.len());
    for (t, p) in poses {
        header(&mut w, *t, frame);
        pose(&mut w, p);
    }
    w.into_bytes()
}

/// `geometry_msgs/msg/PoseWithCovarianceStamped` of a planar pose with its 3×3 covariance
/// `cov` over (x, y, θ) (row-major, m² and rad²): the 6×6 row-major covariance over
/// (x, y, z, roll, pitch, yaw) with the planar entries at rows/columns 0, 1 and 5 and zeros
/// elsewhere (REP 103's order).
pub fn pose_with_covariance(stamp: Stamp, frame: &str, p: &Pose2, cov: &[[f64; 3]; 3]) -> Vec<u8> {
    let mut w = CdrWriter::new();
    header(&mut w, stamp, frame);
    pose(&mut w, p);
    const AT: [usize; 3] = [0, 1, 5];
    let mut full = [0.0; 36];
    for (i, row) in cov.iter().enumerate() {
        for (j, v) in row.iter().enumerate() {
            full[AT[i] * 6 + AT[j]] = *v;
        }
    }
    for v in full {
        w.f64(v);
    }
    w.into_bytes()
}

/// `geometry_msgs/msg/PoseArray`. The caller guarantees fewer than 2³² poses.
pub fn pose_array(stamp: Stamp, frame: &str, poses: &[Pose2]) -> Vec<u8> {
    let mut w = CdrWriter::new();
    header(&mut w, stamp, frame);
    w.count(poses.len());
    for p in poses {
        pose(&mut w, p);
    }
    w.into_bytes()
}

/// One planar transform: the pose of `child` in `parent` at `stamp`.
#[derive(Debug, Clone, PartialEq)]
pub struct Transform<'a> {
    /// The transform's time.
    pub stamp: Stamp,
    /// The parent frame (`header.frame_id`).
    pub parent: &'a str,
    /// The child frame (`child_frame_id`).
    pub child: &'a str,
    /// The child's pose in the parent frame.
    pub pose: Pose2,
}

/// `tf2_msgs/msg/TFMessage`.
pub fn tf_message(transforms: &[Transform<'_>]) -> Vec<u8> {
    let mut w = CdrWriter::new();
    w.count(transforms.len());
    for t in transforms {
        header(&mut w, t.stamp, t.parent);
        w.string(t.child);
        // geometry_msgs/Transform has the layout of Pose (Vector3 + Quaternion).
        pose(&mut w, &t.pose);
    }
    w.into_bytes()
}

/// `sensor_msgs/msg/LaserScan` of `scan` in `frame`: `angle_max` is the last beam's angle,
/// `range_min` 0, `range_max` the scan's `max_range`, and a reading at or beyond it is
/// written `+inf` (ROS: no return within `range_max`); no intensities, no timing. The
/// caller guarantees fewer than 2³² beams.
pub fn laser_scan(stamp: Stamp, frame: &str, scan: &LaserScan) -> Vec<u8> {
    let mut w = CdrWriter::new();
    header(&mut w, stamp, frame);
    let n = scan.ranges.len();
    w.f32(scan.angle_min);
    w.f32(scan.beam_angle(n.saturating_sub(1)));
    w.f32(scan.angle_increment);
    w.f32(0.0);
    w.f32(0.0);
    w.f32(0.0);
    w.f32(scan.max_range);
    w.count(n);
    for &r in &scan.ranges {
        w.f32(if r >= scan.max_range {
            f64::INFINITY
        } else {
            r
        });
    }
    w.count(0);
    w.into_bytes()
}

/// `nav_msgs/msg/OccupancyGrid` of `map` in `frame`: the grid's layout is ROS's already
/// (row 0 at the bottom, origin the lower-left corner of cell (0, 0), unrotated, values −1
/// unknown and 0–100 occupancy percent, as map_server publishes). The caller guarantees the
/// dimensions fit `uint32` and `cells.len() = width·height`.
pub fn occupancy_grid(stamp: Stamp, frame: &str, map: &GridMap) -> Vec<u8> {
    let mut w = CdrWriter::new();
    header(&mut w, stamp, frame);
    w.i32(stamp.sec);
    w.u32(stamp.nanosec);
    w.f32(map.resolution);
    w.u32(map.width as u32);
    w.u32(map.height as u32);
    pose(&mut w, &Pose2::new(map.origin.x, map.origin.y, 0.0));
    w.count(map.cells.len());
    for &c in &map.cells {
        w.i8(c);
    }
    w.into_bytes()
}

/// `visualization_msgs/Marker` types used.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum MarkerKind {
    /// `CYLINDER` (3): a flat one is a covariance ellipse.
    Cylinder = 3,
    /// `SPHERE_LIST` (7): one sphere per point.
    SphereList = 7,
    /// `CUBE_LIST` (6): one cube per point.
    CubeList = 6,
}

/// A marker as this writer draws them (the fields it leaves at their defaults are not
/// listed: no lifetime, no texture or mesh, no text).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Marker<'a> {
    pub ns: &'a str,
    pub id: i32,
    /// `None` is the `DELETEALL` action (3), which clears every marker of the display.
    pub kind: Option<MarkerKind>,
    pub pose: Pose2,
    pub scale: [f64; 3],
    pub rgba: [f64; 4],
    /// Points (x, y; z = 0) of a list marker.
    pub points: Vec<(f64, f64)>,
}

/// `visualization_msgs/msg/MarkerArray`, every marker stamped `stamp` in `frame`. The
/// caller guarantees fewer than 2³² markers and points per marker.
pub(crate) fn marker_array(stamp: Stamp, frame: &str, markers: &[Marker<'_>]) -> Vec<u8> {
    let mut w = CdrWriter::new();
    w.count(markers.len());
    for m in markers {
        header(&mut w, stamp, frame);
        w.string(m.ns);
        w.i32(m.id);
        w.i32(m.kind.map_or(0, |k| k as i32));
        // ADD = 0, DELETEALL = 3.
        w.i32(if m.kind.is_some() { 0 } else { 3 });
        pose(&mut w, &m.pose);
        for s in m.scale {
            w.f64(s);
        }
        for c in m.rgba {
            w.f32(c);
        }
        // lifetime 0 (forever), frame_locked false.
        w.i32(0);
        w.u32(0);
        w.bool(false);
        w.count(m.points.len());
        for &(x, y) in &m.points {
            w.f64(x);
            w.f64(y);
            w.f64(0.0);
        }
        w.count(0); // colors
        w.string(""); // texture_resource
        header(&mut w, stamp, ""); // texture: CompressedImage
        w.string("");
        w.count(0);
        w.count(0); // uv_coordinates
        w.string(""); // text
        w.string(""); // mesh_resource
        w.string(""); // mesh_file.filename
        w.count(0); // mesh_file.data
        w.bool(false);
    }
    w.into_bytes()
}
